//! RMVP3D's "original part" as its authors released it (`shared/notes/published-layouts.md`):
//! one folder per object with every view's Stokes in one archive.
//!
//! ```text
//! cameras.npz               world_mat_k = K [R | t] (4x4) and scale_mat_k of every view: keys
//!                           0-based (world_mat_0) or 1-based with two digits (world_mat_01,
//!                           which PolGS's reader tries first)
//! images_stokes/0000.npz    S0, S1, S2: float32 H x W x 3
//! mask/0000.png             8-bit object mask (the release's name; masks/ is read too)
//! image/0000.png            8-bit preview of S0 (optional)
//! ```
//!
//! Views are the Stokes archives in name order, the k-th paired with the k-th camera key; their
//! masks have the same file stem. There is no AoP map: the AoP comes from the Stokes. Names come
//! back as `000`, `001`, ... and every view is a training view (the release's split is its
//! users' choice). We write 0-based keys and `mask/`.

use super::nersp::{cameras_by_keys, read_camera_arrays, write_cameras};
use super::{check_size, read_sized};
use crate::io::{npy, png};
use crate::layout::{array_from_image, image_from_array};
use crate::{visualize, Camera, Error, Result, Scene, Split, Stokes, View};
use nalgebra::Matrix3x4;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// The camera file.
pub const CAMERAS: &str = "cameras.npz";
/// The Stokes folder.
pub const STOKES_FOLDER: &str = "images_stokes";
/// The mask folder as released, then the name older exports of ours used.
pub const MASK_FOLDERS: [&str; 2] = ["mask", "masks"];

/// Whether `dir/images_stokes` holds RMVP3D Stokes archives (`NNNN.npz`).
pub fn recognise(dir: &Path) -> bool {
    !stokes_files(dir).is_empty()
}

/// The Stokes archives of `dir`, in name order.
fn stokes_files(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir.join(STOKES_FOLDER)) else { return Vec::new() };
    let mut files: Vec<PathBuf> =
        entries.flatten().map(|e| e.path()).filter(|p| p.extension().is_some_and(|e| e == "npz")).collect();
    files.sort();
    files
}

/// Write every view of `scene` that has Stokes (a mask needed too) into `dir`; the camera file
/// last.
pub fn write(scene: &Scene, dir: &Path) -> Result<()> {
    let views: Vec<&View> = scene.views.iter().filter(|v| v.stokes.is_some()).collect();
    if views.is_empty() {
        return Err(Error::invalid("RMVP3D holds views with Stokes images; the scene has none"));
    }
    let file = |folder: &str, i: usize, ext: &str| dir.join(folder).join(format!("{i:04}.{ext}"));
    views.par_iter().enumerate().try_for_each(|(i, view)| {
        let stokes = view.stokes.as_ref().expect("filtered");
        let mask = view
            .mask
            .as_ref()
            .ok_or_else(|| Error::invalid(format!("view {}: RMVP3D needs a mask for every view", view.name)))?;
        let arrays: Vec<(String, npy::Array<f32>)> = [("S0", &stokes.s0), ("S1", &stokes.s1), ("S2", &stokes.s2)]
            .map(|(name, image)| (name.to_string(), array_from_image(image)))
            .into();
        npy::write_npz(&file(STOKES_FOLDER, i, "npz"), &arrays)?;
        png::write_png_u8(&file(MASK_FOLDERS[0], i, "png"), mask)?;
        let preview = view.preview.clone().unwrap_or_else(|| visualize::preview(&stokes.s0));
        png::write_png_u8(&file("image", i, "png"), &preview)
    })?;
    let keyed = views.iter().enumerate().map(|(i, view)| (i.to_string(), view.projection_matrix()));
    write_cameras(&dir.join(CAMERAS), keyed, &scene.normalization)
}

/// Read an RMVP3D object folder.
pub fn read(dir: &Path) -> Result<Scene> {
    let cameras_path = dir.join(CAMERAS);
    let arrays = read_camera_arrays(&cameras_path)?;
    let has = |name: &str| arrays.iter().any(|(n, _)| n == name);
    let (world_mats, normalization) = if has("world_mat_0") {
        let zero_based = cameras_by_keys(&cameras_path, &arrays, (0..).map(|k: usize| k.to_string()))?;
        // Both numberings in one file: they must be the same cameras, or which one a reader
        // takes decides the scene (PolGS reads the 1-based keys).
        if has("world_mat_01") {
            let one_based = cameras_by_keys(&cameras_path, &arrays, (1..).map(|k: usize| format!("{k:02}")))?;
            if one_based != zero_based {
                return Err(Error::format(
                    &cameras_path,
                    "holds 0-based (world_mat_0, ...) and 1-based (world_mat_01, ...) cameras that disagree: \
                     readers differ in which they take",
                ));
            }
        }
        zero_based
    } else if has("world_mat_01") {
        cameras_by_keys(&cameras_path, &arrays, (1..).map(|k: usize| format!("{k:02}")))?
    } else {
        return Err(Error::format(&cameras_path, "no world_mat_0 (0-based keys) or world_mat_01 (1-based keys)"));
    };
    let stokes_files = stokes_files(dir);
    if stokes_files.len() != world_mats.len() {
        return Err(Error::format(
            dir.join(STOKES_FOLDER),
            format!("{} Stokes archives for the {} cameras of {CAMERAS}", stokes_files.len(), world_mats.len()),
        ));
    }
    let views = world_mats
        .par_iter()
        .zip(&stokes_files)
        .enumerate()
        .map(|(i, (world_mat, path))| {
            let arrays = npy::read_npz::<f32>(path)?;
            let take = |name: &str| -> Result<crate::Image<f32>> {
                let array = arrays
                    .iter()
                    .find(|(n, _)| n == name)
                    .map(|(_, a)| a.clone())
                    .ok_or_else(|| Error::format(path, format!("no array {name}")))?;
                image_from_array(path, array)
            };
            let stokes = Stokes { s0: take("S0")?, s1: take("S1")?, s2: take("S2")? };
            stokes.validate().map_err(|e| e.in_file(path))?;
            let (w, h) = stokes.s0.size();
            let p: Matrix3x4<f64> = world_mat.fixed_view::<3, 4>(0, 0).into_owned();
            let camera = Camera::from_projection(&p, w as u32, h as u32).map_err(|e| e.in_file(&cameras_path))?;
            let stem = path.file_stem().expect("a file").to_string_lossy();
            let mut view = View::new(format!("{i:03}"), Split::Train, camera);
            view.projection = Some(*world_mat);
            view.stokes = Some(stokes);
            let masks = MASK_FOLDERS.map(|folder| dir.join(folder).join(format!("{stem}.png")));
            let mask = masks.iter().find(|m| m.exists()).ok_or_else(|| {
                Error::format(&masks[0], format!("no mask for {} (looked in mask/ and masks/)", path.display()))
            })?;
            let mask_image = png::read_png_u8(mask)?.channel(0);
            check_size(mask, mask_image.size(), path.display(), (w, h))?;
            view.mask = Some(mask_image);
            let preview = dir.join("image").join(format!("{stem}.png"));
            if preview.is_file() {
                view.preview = Some(read_sized(&preview, png::read_png_u8, path.display(), (w, h))?);
            }
            Ok(view)
        })
        .collect::<Result<Vec<View>>>()?;
    let mut scene = Scene::new();
    scene.views = views;
    scene.normalization = normalization;
    Ok(scene)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Image;
    use nalgebra::{Matrix3, Matrix4, Vector3};

    fn scene() -> Scene {
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
        scene
    }

    fn assert_same(back: &Scene, scene: &Scene) {
        assert_eq!(back.normalization, scene.normalization);
        assert_eq!(back.views.len(), scene.views.len());
        for (a, b) in back.views.iter().zip(&scene.views) {
            assert_eq!((&a.name, &a.stokes, &a.mask), (&b.name, &b.stokes, &b.mask));
            assert!((a.camera.k - b.camera.k).abs().max() < 1e-9 && (a.camera.t - b.camera.t).abs().max() < 1e-9);
        }
    }

    #[test]
    fn a_scene_reads_back_as_it_was_written() {
        let scene = scene();
        let dir = tempfile::tempdir().unwrap();
        write(&scene, dir.path()).unwrap();
        assert!(dir.path().join("mask/0001.png").is_file(), "the release's mask folder");
        assert_same(&read(dir.path()).unwrap(), &scene);
        // A damaged archive is named.
        std::fs::write(dir.path().join("images_stokes/0001.npz"), b"not a zip").unwrap();
        let err = read(dir.path()).unwrap_err().to_string();
        assert!(err.contains("0001.npz"), "{err}");
    }

    #[test]
    fn both_numberings_are_read_when_they_agree_and_refused_when_not() {
        let scene = scene();
        let dir = tempfile::tempdir().unwrap();
        write(&scene, dir.path()).unwrap();
        let cameras = dir.path().join(CAMERAS);
        let zero_based = npy::read_npz::<f64>(&cameras).unwrap();
        let one_based = |shift: f64| {
            zero_based.iter().map(move |(name, a)| {
                let (stem, k) = name.rsplit_once('_').unwrap();
                let mut a = a.clone();
                a.data[3] += shift;
                (format!("{stem}_{:02}", k.parse::<usize>().unwrap() + 1), a)
            })
        };
        npy::write_npz(&cameras, &zero_based.iter().cloned().chain(one_based(0.0)).collect::<Vec<_>>()).unwrap();
        assert_same(&read(dir.path()).unwrap(), &scene);
        npy::write_npz(&cameras, &zero_based.iter().cloned().chain(one_based(0.5)).collect::<Vec<_>>()).unwrap();
        let err = read(dir.path()).unwrap_err().to_string();
        assert!(err.contains("cameras.npz") && err.contains("disagree"), "{err}");
    }

    #[test]
    fn one_based_keys_and_a_masks_folder_read_the_same() {
        let scene = scene();
        let dir = tempfile::tempdir().unwrap();
        write(&scene, dir.path()).unwrap();
        // Renumber the cameras as world_mat_01, scale_mat_01, ... and the files from 0001.
        let arrays = npy::read_npz::<f64>(&dir.path().join(CAMERAS)).unwrap();
        let renamed: Vec<(String, npy::Array<f64>)> = arrays
            .into_iter()
            .map(|(name, a)| {
                let (stem, k) = name.rsplit_once('_').unwrap();
                (format!("{stem}_{:02}", k.parse::<usize>().unwrap() + 1), a)
            })
            .collect();
        npy::write_npz(&dir.path().join(CAMERAS), &renamed).unwrap();
        for i in (0..2).rev() {
            for (folder, ext) in [(STOKES_FOLDER, "npz"), ("mask", "png"), ("image", "png")] {
                let at = |k: usize| dir.path().join(folder).join(format!("{k:04}.{ext}"));
                std::fs::rename(at(i), at(i + 1)).unwrap();
            }
        }
        std::fs::rename(dir.path().join("mask"), dir.path().join("masks")).unwrap();
        assert_same(&read(dir.path()).unwrap(), &scene);
        std::fs::remove_file(dir.path().join("masks/0002.png")).unwrap();
        let err = read(dir.path()).unwrap_err().to_string();
        assert!(err.contains("mask/0002.png: no mask for") && err.contains("0002.npz"), "{err}");
    }
}
