//! PANDORA's layout (akshatdave/pandora, `dataio/Ours.py`; `shared/notes/published-layouts.md`):
//!
//! ```text
//! cameras.npz                    world_mat_<NN>, scale_mat_<NN>: keyed by the views' file stems
//! images_stokes/NN_s0.hdr        S0 (Radiance HDR, RGB)
//! images_stokes/NN_s0p1.hdr      S0 + S1, stored shifted so that every file is non-negative
//! images_stokes/NN_s0p2.hdr      S0 + S2
//! mask/NN.png                    object mask; mask_corrections/NN.png replaces it where present
//! images/NN.png                  colour picture (optional, what COLMAP saw)
//! ```
//!
//! Views are the stems of `images_stokes/*_s0.hdr` in name order, named by their stems; every view
//! is a training view. Read back, `S1 = s0p1 - s0` and `S2 = s0p2 - s0`. Written, stems are
//! `01`, `02`, ...; RGBE keeps about 1 % relative precision, and a Stokes vector whose `S0 + S1`
//! or `S0 + S2` is negative (beyond full polarization, from noise) is clamped to 0 there.

use super::check_size;
use super::nersp::{cameras_by_keys, read_camera_arrays, write_cameras};
use crate::io::hdr::{read_hdr, write_hdr};
use crate::io::png;
use crate::{visualize, Camera, Error, Image, Result, Scene, Split, Stokes, View};
use nalgebra::Matrix3x4;
use rayon::prelude::*;
use std::path::Path;

/// The camera file.
pub const CAMERAS: &str = "cameras.npz";
/// The Stokes folder.
pub const STOKES_FOLDER: &str = "images_stokes";
/// The suffix of a view's S0 file.
const S0_SUFFIX: &str = "_s0.hdr";

/// The view stems of `dir` (`images_stokes/<stem>_s0.hdr`), in name order.
fn stems(dir: &Path) -> Vec<String> {
    let Ok(entries) = std::fs::read_dir(dir.join(STOKES_FOLDER)) else { return Vec::new() };
    let mut stems: Vec<String> = entries
        .flatten()
        .filter_map(|e| e.file_name().to_str().and_then(|n| n.strip_suffix(S0_SUFFIX)).map(str::to_owned))
        .collect();
    stems.sort();
    stems
}

/// Whether `dir/images_stokes` holds PANDORA Stokes files (`NN_s0.hdr`).
pub fn recognise(dir: &Path) -> bool {
    !stems(dir).is_empty()
}

/// Read a PANDORA scene folder.
pub fn read(dir: &Path) -> Result<Scene> {
    let cameras_path = dir.join(CAMERAS);
    let stems = stems(dir);
    let arrays = read_camera_arrays(&cameras_path)?;
    let (world_mats, normalization) = cameras_by_keys(&cameras_path, &arrays, stems.iter().cloned())?;
    if let Some(missing) = stems.get(world_mats.len()) {
        return Err(Error::format(
            &cameras_path,
            format!("no world_mat_{missing} for {STOKES_FOLDER}/{missing}{S0_SUFFIX}"),
        ));
    }
    let views = stems
        .par_iter()
        .zip(&world_mats)
        .map(|(stem, world_mat)| {
            crate::io::input::file_name(stem).map_err(|why| Error::format(dir.join(STOKES_FOLDER), why))?;
            let stokes_file = |suffix: &str| dir.join(STOKES_FOLDER).join(format!("{stem}{suffix}"));
            let hdr = |suffix: &str| read_hdr(&stokes_file(suffix));
            let (s0, s0p1, s0p2) = (hdr(S0_SUFFIX)?, hdr("_s0p1.hdr")?, hdr("_s0p2.hdr")?);
            let unshift = |shifted: &Image<f32>, name: &str| -> Result<Image<f32>> {
                check_size(&stokes_file(name), shifted.size(), stokes_file(S0_SUFFIX).display(), s0.size())?;
                let data = shifted.data().iter().zip(s0.data()).map(|(a, b)| a - b).collect();
                Image::from_vec(s0.width(), s0.height(), 3, data)
            };
            let stokes = Stokes { s1: unshift(&s0p1, "_s0p1.hdr")?, s2: unshift(&s0p2, "_s0p2.hdr")?, s0 };
            let (w, h) = stokes.s0.size();
            let p: Matrix3x4<f64> = world_mat.fixed_view::<3, 4>(0, 0).into_owned();
            let camera = Camera::from_projection(&p, w as u32, h as u32).map_err(|e| e.in_file(&cameras_path))?;
            let mut view = View::new(stem.clone(), Split::Train, camera);
            view.projection = Some(*world_mat);
            view.stokes = Some(stokes);
            let corrected = dir.join("mask_corrections").join(format!("{stem}.png"));
            let mask = if corrected.exists() { corrected } else { dir.join("mask").join(format!("{stem}.png")) };
            let mask_image = read_mask(&mask)?;
            check_size(&mask, mask_image.size(), stokes_file(S0_SUFFIX).display(), (w, h))?;
            view.mask = Some(mask_image);
            Ok(view)
        })
        .collect::<Result<Vec<View>>>()?;
    let mut scene = Scene::new();
    scene.views = views;
    scene.normalization = normalization;
    Ok(scene)
}

/// A mask PNG: its alpha channel when it has one (cut-out tools write RGBA), else its first.
fn read_mask(path: &Path) -> Result<Image<u8>> {
    let mask = png::read_png_u8(path)?;
    let channel = if matches!(mask.channels(), 2 | 4) { mask.channels() - 1 } else { 0 };
    Ok(mask.channel(channel).map(|v| if v > 127 { 255 } else { 0 }))
}

/// Write every view of `scene` that has Stokes (a mask needed too) into `dir`, stems `01`,
/// `02`, ...; the camera file last.
pub fn write(scene: &Scene, dir: &Path) -> Result<()> {
    let views: Vec<&View> = scene.views.iter().filter(|v| v.stokes.is_some()).collect();
    if views.is_empty() {
        return Err(Error::invalid("PANDORA holds views with Stokes images; the scene has none"));
    }
    let stem = |i: usize| format!("{:02}", i + 1);
    views.par_iter().enumerate().try_for_each(|(i, view)| {
        let stokes = view.stokes.as_ref().expect("filtered");
        if stokes.s0.channels() != 3 {
            return Err(Error::invalid(format!("view {}: PANDORA's Stokes are RGB", view.name)));
        }
        let mask = view
            .mask
            .as_ref()
            .ok_or_else(|| Error::invalid(format!("view {}: PANDORA needs a mask for every view", view.name)))?;
        let shifted = |s: &Image<f32>| {
            let data = s.data().iter().zip(stokes.s0.data()).map(|(v, s0)| (v + s0).max(0.0)).collect();
            Image::from_vec(s.width(), s.height(), 3, data)
        };
        let file = |suffix: &str| dir.join(STOKES_FOLDER).join(format!("{}{suffix}", stem(i)));
        write_hdr(&file(S0_SUFFIX), &stokes.s0.map(|v| v.max(0.0)))?;
        write_hdr(&file("_s0p1.hdr"), &shifted(&stokes.s1)?)?;
        write_hdr(&file("_s0p2.hdr"), &shifted(&stokes.s2)?)?;
        png::write_png_u8(&dir.join("mask").join(format!("{}.png", stem(i))), mask)?;
        let preview = view.preview.clone().unwrap_or_else(|| visualize::preview(&stokes.s0));
        png::write_png_u8(&dir.join("images").join(format!("{}.png", stem(i))), &preview)
    })?;
    let keyed = views.iter().enumerate().map(|(i, view)| (stem(i), view.projection_matrix()));
    write_cameras(&dir.join(CAMERAS), keyed, &scene.normalization)
}
