//! RMVP3D as its authors released it (as far as the NeRSP paper and issue 14 describe it): one
//! folder per object with every view's Stokes in one archive.
//!
//! ```text
//! cameras.npz               world_mat_i = K [R | t] (4x4), scale_mat_i, every view i (0-based)
//! images_stokes/0000.npz    S0, S1, S2: float32 H x W x 3, in the NeRSP loader's scale (halved
//!                           on load, as its s0/ s1/ s2/ arrays)
//! masks/0000.png            8-bit object mask
//! image/0000.png            8-bit preview of S0
//! ```
//!
//! Views are numbered in scene order; names come back as `000`, `001`, ... and every view is a
//! training view (the release's split is a choice of its users). Not checked against a download of
//! RMVP3D (none is reachable here): the layout is the one described to us.

use crate::io::{npy, png};
use crate::layout::{array_from_image, image_from_array};
use crate::{visualize, Camera, Error, Result, Scene, Split, Stokes, View};
use nalgebra::{Matrix3x4, Matrix4};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// The camera file.
pub const CAMERAS: &str = "cameras.npz";
/// The Stokes folder.
pub const STOKES_FOLDER: &str = "images_stokes";

fn file(dir: &Path, folder: &str, i: usize, ext: &str) -> PathBuf {
    dir.join(folder).join(format!("{i:04}.{ext}"))
}

/// Write every view of `scene` (Stokes and mask needed) into `dir`; the camera file last.
pub fn write(scene: &Scene, dir: &Path) -> Result<()> {
    scene.views.par_iter().enumerate().try_for_each(|(i, view)| {
        let missing = |what: &str| Error::invalid(format!("view {}: RMVP3D needs {what} for every view", view.name));
        let stokes = view.stokes.as_ref().ok_or_else(|| missing("Stokes images"))?;
        let mask = view.mask.as_ref().ok_or_else(|| missing("a mask"))?;
        let arrays: Vec<(String, npy::Array<f32>)> = [("S0", &stokes.s0), ("S1", &stokes.s1), ("S2", &stokes.s2)]
            .map(|(name, image)| (name.to_string(), array_from_image(image)))
            .into();
        npy::write_npz(&file(dir, STOKES_FOLDER, i, "npz"), &arrays)?;
        png::write_png_u8(&file(dir, "masks", i, "png"), mask)?;
        let preview = view.preview.clone().unwrap_or_else(|| visualize::preview(&stokes.s0));
        png::write_png_u8(&file(dir, "image", i, "png"), &preview)
    })?;
    let mut arrays = Vec::new();
    for (i, view) in scene.views.iter().enumerate() {
        let matrix = |m: Matrix4<f64>| npy::Array { shape: vec![4, 4], data: m.transpose().as_slice().to_vec() };
        arrays.push((format!("world_mat_{i}"), matrix(view.projection_matrix())));
        arrays.push((format!("scale_mat_{i}"), matrix(scene.normalization)));
    }
    npy::write_npz(&dir.join(CAMERAS), &arrays)
}

/// Read an RMVP3D object folder.
pub fn read(dir: &Path) -> Result<Scene> {
    let (world_mats, normalization) = crate::layout::nersp::read_cameras(&dir.join(CAMERAS))?;
    let views = world_mats
        .par_iter()
        .enumerate()
        .map(|(i, world_mat)| {
            let path = file(dir, STOKES_FOLDER, i, "npz");
            let arrays = npy::read_npz::<f32>(&path)?;
            let take = |name: &str| -> Result<crate::Image<f32>> {
                let array = arrays
                    .iter()
                    .find(|(n, _)| n == name)
                    .map(|(_, a)| a.clone())
                    .ok_or_else(|| Error::format(&path, format!("no array {name}")))?;
                image_from_array(&path, array)
            };
            let stokes = Stokes { s0: take("S0")?, s1: take("S1")?, s2: take("S2")? };
            stokes.validate().map_err(|e| e.in_file(&path))?;
            let (w, h) = stokes.s0.size();
            let p: Matrix3x4<f64> = world_mat.fixed_view::<3, 4>(0, 0).into_owned();
            let camera = Camera::from_projection(&p, w as u32, h as u32).map_err(|e| e.in_file(dir.join(CAMERAS)))?;
            let mut view = View::new(format!("{i:03}"), Split::Train, camera);
            view.projection = Some(*world_mat);
            view.stokes = Some(stokes);
            view.mask = Some(png::read_png_u8(&file(dir, "masks", i, "png"))?.channel(0));
            let preview = file(dir, "image", i, "png");
            if preview.is_file() {
                view.preview = Some(png::read_png_u8(&preview)?);
            }
            Ok(view)
        })
        .collect::<Result<Vec<View>>>()?;
    let mut scene = Scene::new();
    scene.views = views;
    scene.normalization = normalization;
    scene.validate()?;
    Ok(scene)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Image;
    use nalgebra::{Matrix3, Vector3};

    #[test]
    fn a_scene_reads_back_as_it_was_written() {
        let mut scene = Scene::new();
        for v in 0..2 {
            let k = Matrix3::new(50.0, 0.0, 8.0, 0.0, 50.0, 6.0, 0.0, 0.0, 1.0);
            let camera = Camera::new(k, Matrix3::identity(), Vector3::new(0.1 * v as f64, 0.0, 3.0), 16, 12);
            let mut view = View::new(format!("{v:03}"), Split::Train, camera);
            let ramp = |k: f32| {
                Image::from_vec(16, 12, 3, (0..16 * 12 * 3).map(|i| k * i as f32 / 576.0 - 0.1).collect()).unwrap()
            };
            view.stokes = Some(Stokes { s0: ramp(1.0), s1: ramp(0.2), s2: ramp(-0.1) });
            view.mask =
                Some(Image::from_vec(16, 12, 1, (0..192).map(|i| if i % 3 == 0 { 255 } else { 0 }).collect()).unwrap());
            scene.views.push(view);
        }
        scene.normalization = Matrix4::new_scaling(0.5);
        scene.normalization[(3, 3)] = 1.0;
        let dir = tempfile::tempdir().unwrap();
        write(&scene, dir.path()).unwrap();
        let back = read(dir.path()).unwrap();
        assert_eq!(back.normalization, scene.normalization);
        for (a, b) in back.views.iter().zip(&scene.views) {
            assert_eq!((&a.name, &a.stokes, &a.mask), (&b.name, &b.stokes, &b.mask));
            assert!((a.camera.k - b.camera.k).abs().max() < 1e-9 && (a.camera.t - b.camera.t).abs().max() < 1e-9);
        }
        // A damaged archive is named.
        std::fs::write(dir.path().join("images_stokes/0001.npz"), b"not a zip").unwrap();
        let err = read(dir.path()).unwrap_err().to_string();
        assert!(err.contains("0001.npz"), "{err}");
    }
}
