//! A dataset in other tools' layouts (`rmvp dataset export`, `rmvp dataset import`):
//!
//! - `nerfstudio`: `transforms.json` (OpenGL camera-to-world, OpenCV intrinsics),
//!   `images/<view>.png` (S0 previews), `masks/<view>.png`;
//! - `colmap`: a text model `sparse/0/{cameras,images,points3D}.txt` (one `OPENCV` camera per
//!   view, no points) and `images/<view>.png`;
//! - `rmvp3d`: RMVP3D's original part ([`rmvp_dataset::layout::rmvp3d`]), read back by
//!   [`import_rmvp3d`] (and by every command that reads a scene);
//! - `pandora`: PANDORA's layout ([`rmvp_dataset::layout::pandora`]).
//!
//! Every view with Stokes is exported; cameras are the dataset's (lens distortion removed).

use crate::{Error, Result};
use rmvp_dataset::exchange::colmap::ColmapModel;
use rmvp_dataset::exchange::nerfstudio::Transforms;
use rmvp_dataset::io::png;
use rmvp_dataset::layout::{pandora, read_scene, rmvp3d};
use rmvp_dataset::visualize::preview;
use rmvp_dataset::{Camera, Scene, Split};
use std::path::Path;

/// A layout to export to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum ExportFormat {
    /// nerfstudio's `transforms.json`.
    Nerfstudio,
    /// A COLMAP text model.
    Colmap,
    /// RMVP3D's release layout.
    Rmvp3d,
    /// PANDORA's layout.
    Pandora,
}

/// Export the views of `scene` that have Stokes into `dir` (which must not exist or be empty).
pub fn export_scene(scene: &Scene, dir: &Path, format: ExportFormat) -> Result<()> {
    if dir.read_dir().is_ok_and(|mut d| d.next().is_some()) {
        return Err(Error::Folder { path: dir.to_path_buf(), why: "not empty; export into a new folder".into() });
    }
    let mut views = scene.clone();
    views.views.retain(|v| v.stokes.is_some());
    let write_pictures = |masks: bool| -> Result<()> {
        for view in &views.views {
            let stokes = view.stokes.as_ref().expect("kept above");
            let picture = view.preview.clone().unwrap_or_else(|| preview(&stokes.s0));
            png::write_png_u8(&dir.join("images").join(format!("{}.png", view.name)), &picture)?;
            if let (true, Some(mask)) = (masks, &view.mask) {
                png::write_png_u8(&dir.join("masks").join(format!("{}.png", view.name)), mask)?;
            }
        }
        Ok(())
    };
    match format {
        ExportFormat::Nerfstudio => {
            write_pictures(true)?;
            let cameras: Vec<(String, Option<String>, Camera)> = views
                .views
                .iter()
                .map(|v| {
                    let mask = v.mask.as_ref().map(|_| format!("masks/{}.png", v.name));
                    (format!("images/{}.png", v.name), mask, v.camera.clone())
                })
                .collect();
            let split = |split: Split| -> Vec<String> {
                views.views.iter().filter(|v| v.split == split).map(|v| format!("images/{}.png", v.name)).collect()
            };
            let (train, val) = (split(Split::Train), split(Split::Eval));
            Transforms::from_cameras(&cameras).with_split(train, val).write(&dir.join("transforms.json"))?;
        }
        ExportFormat::Colmap => {
            write_pictures(false)?;
            let cameras: Vec<(String, Camera)> =
                views.views.iter().map(|v| (format!("{}.png", v.name), v.camera.clone())).collect();
            let sparse = dir.join("sparse/0");
            std::fs::create_dir_all(&sparse).map_err(|e| rmvp_dataset::Error::io(&sparse, e))?;
            ColmapModel::from_cameras(&cameras).write_text(&sparse)?;
        }
        ExportFormat::Rmvp3d => rmvp3d::write(&views, dir)?,
        ExportFormat::Pandora => pandora::write(&views, dir)?,
    }
    Ok(())
}

/// An RMVP3D object folder as a scene (every view a training view: choose a split with
/// `rmvp dataset convert` or by name at reconstruction).
pub fn import_rmvp3d(dir: &Path) -> Result<Scene> {
    if rmvp_dataset::layout::Layout::detect(dir)? != rmvp_dataset::layout::Layout::Rmvp3d {
        let why = format!("not an RMVP3D object folder (no {}/NNNN.npz archives)", rmvp3d::STOKES_FOLDER);
        return Err(Error::Folder { path: dir.to_path_buf(), why });
    }
    Ok(read_scene(dir)?)
}
