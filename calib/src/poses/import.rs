//! Poses imported from another tool: a COLMAP model (a folder with `images.bin` or
//! `images.txt`; images matched to views by file stem; the models a default run writes,
//! SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL and OPENCV, their distortion kept in the
//! cameras for `dataset build` to undistort the views), an IDR/NeRSP `cameras.npz` (the i-th
//! `world_mat` is the session's i-th view) or a nerfstudio `transforms.json` (frames matched by
//! file stem). The world frame is the source's.

use super::{PoseMethod, PoseSet, ViewPose};
use crate::intrinsics::Rejected;
use crate::pictures::read_view_stokes;
use crate::Result;
use rmvp_dataset::camera::CameraRecord;
use rmvp_dataset::exchange::colmap::ColmapModel;
use rmvp_dataset::exchange::nerfstudio::Transforms;
use rmvp_dataset::layout::nersp;
use rmvp_dataset::session::SessionManifest;
use rmvp_dataset::{Camera, Error as DataError};
use std::path::Path;

fn stem(name: &str) -> String {
    Path::new(name).file_stem().map_or_else(|| name.to_string(), |s| s.to_string_lossy().into_owned())
}

/// Pose the session in `dir` with the cameras in `source`; at least `min_views` must be posed.
pub fn import_poses(dir: &Path, source: &Path, min_views: usize) -> Result<PoseSet> {
    let manifest = SessionManifest::read(dir)?;
    manifest.require_views(dir)?;
    let names: Vec<String> = manifest.views.iter().map(|v| v.name.clone()).collect();
    let extension = source.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    // Named cameras, each with its residual and point count (where the source has points).
    type Imported = (Vec<(String, Camera)>, Vec<(f64, usize)>, String);
    let view_size = || -> Result<(usize, usize)> {
        let first = manifest.views.first().ok_or_else(|| DataError::format(dir, "the session has no views"))?;
        Ok(read_view_stokes(dir, first)?.s0.size())
    };
    // Cameras named by file: their sizes must be the views', and no two may match one view.
    let check = |named: &[(String, Camera)], what: &str| -> Result<Vec<(String, Camera)>> {
        let size = view_size()?;
        if let Some((name, c)) = named.iter().find(|(_, c)| (c.width as usize, c.height as usize) != size) {
            return Err(DataError::format(
                source,
                format!(
                    "image {name} was {}x{} pixels in {what}, the session's views are {}x{}: pose the views at \
                     their size",
                    c.width, c.height, size.0, size.1
                ),
            )
            .into());
        }
        for (i, (name, _)) in named.iter().enumerate() {
            if let Some((other, _)) = named[..i].iter().find(|(n, _)| stem(n) == stem(name)) {
                let which = if other == name {
                    format!("two of its cameras are {name}")
                } else {
                    format!("{other} and {name}")
                };
                return Err(DataError::format(
                    source,
                    format!("{which}: both would pose view {}; keep one", stem(name)),
                )
                .into());
            }
        }
        Ok(named.iter().map(|(n, c)| (stem(n), c.clone())).collect())
    };
    // The world is named by the source's last two path components (`simulated/cameras.npz`,
    // `sparse/0`): poses.json travels into published datasheets, where the rest of a path of
    // the machine that imported it means nothing.
    let tail: Vec<_> = source.components().rev().take(2).collect();
    let source_name = tail.iter().rev().collect::<std::path::PathBuf>().display().to_string();
    let (cameras, residuals, world): Imported = if source.is_dir() {
        let model = ColmapModel::read(source)?;
        let cameras = check(&model.cameras(source)?, "COLMAP")?;
        let residuals = cameras.iter().enumerate().map(|(i, (_, c))| model.residual(i, c)).collect();
        (cameras, residuals, format!("the COLMAP model's ({source_name})"))
    } else if extension == "npz" {
        let (world_mats, _) = nersp::read_cameras(source)?;
        let size = view_size()?;
        let cameras = world_mats
            .iter()
            .zip(&names)
            .map(|(m, name)| {
                let p = m.fixed_view::<3, 4>(0, 0).into_owned();
                let camera =
                    Camera::from_projection(&p, size.0 as u32, size.1 as u32).map_err(|e| e.in_file(source))?;
                Ok((name.clone(), camera))
            })
            .collect::<Result<Vec<_>>>()?;
        let n = cameras.len();
        (cameras, vec![(f64::NAN, 0); n], format!("the world_mat frame of {source_name}"))
    } else {
        let cameras = check(&Transforms::read(source)?.cameras(source)?, "transforms.json")?;
        let n = cameras.len();
        (cameras, vec![(f64::NAN, 0); n], format!("the transforms' world ({source_name})"))
    };
    let (mut views, mut failed) = (Vec::new(), Vec::new());
    for name in &names {
        match cameras.iter().position(|(n, _)| n == name) {
            Some(i) => views.push(ViewPose {
                name: name.clone(),
                camera: CameraRecord::from(&cameras[i].1),
                residual_px: residuals[i].0.is_finite().then_some(residuals[i].0),
                points: residuals[i].1,
            }),
            None => failed.push(Rejected {
                name: name.clone(),
                reason: format!("not among the cameras of {}", source.display()),
            }),
        }
    }
    PoseSet { method: PoseMethod::Import, world, views, failed }.require(min_views)
}
