//! Poses from COLMAP (Debian's `colmap` 3.8, run as a program, headless and offline): CPU SIFT
//! on each view's S0 with the object painted out by its mask (features come from the board and
//! the table, not from the reflective object), exhaustive (or sequential) matching, and the
//! incremental mapper with the calibrated intrinsics fixed (`OPENCV` model), using only pairs
//! and registrations of at least [`MIN_VERIFIED_MATCHES`] inliers. The largest model
//! is kept; views it did not register are reported. Never the vocabulary-tree matcher, which
//! needs a downloaded file.

use super::{PoseMethod, PoseSet, ViewPose};
use crate::intrinsics::{CameraCalibration, Rejected};
use crate::pictures::{grey_picture, read_view_stokes};
use crate::{Error, Result};
use rayon::prelude::*;
use rmvp_dataset::camera::CameraRecord;
use rmvp_dataset::exchange::colmap::ColmapModel;
use rmvp_dataset::io::png;
use rmvp_dataset::session::SessionManifest;
use rmvp_dataset::Image;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Which image pairs COLMAP matches.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Matcher {
    /// Every pair (best for a few dozen views).
    #[default]
    Exhaustive,
    /// Each view with the next `overlap` in capture order (long sessions).
    Sequential,
}

/// How COLMAP is run; [`ColmapOptions::default`] holds `rmvp poses`' defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapOptions {
    /// The program.
    pub program: PathBuf,
    /// Pair selection.
    pub matcher: Matcher,
    /// Views each view is matched with (sequential matcher).
    pub overlap: usize,
    /// Views that must be registered.
    pub min_views: usize,
    /// Object masks (`<view>.png`, object 255): the object is painted out of feature extraction.
    pub masks: Option<PathBuf>,
    /// SIFT features per image at most (matching time grows with their square).
    pub max_features: usize,
}

impl Default for ColmapOptions {
    fn default() -> Self {
        Self {
            program: "colmap".into(),
            matcher: Matcher::Exhaustive,
            overlap: 10,
            min_views: 3,
            masks: None,
            max_features: 4096,
        }
    }
}

/// The fewest verified matches (inliers of a pair's two-view geometry) that the mapper uses a
/// pair of views by, and the fewest inliers it registers a view with (COLMAP's defaults: 15 and
/// 30). A board's repeating squares match across views 60, 90 and 180 degrees apart with 19-48
/// inliers that are mostly wrong, where most right pairs have hundreds; two views registered by
/// such a pair are posed tens of degrees off, consistently with each other. At 60 the mapper
/// leaves those pairs out, and a view that only weak pairs would pose is reported as not
/// registered instead (`docs/design.md`, COLMAP).
pub const MIN_VERIFIED_MATCHES: usize = 60;

/// What the world frame of COLMAP poses is.
pub const COLMAP_WORLD: &str = "COLMAP's model frame (arbitrary origin, orientation and scale)";

/// Run one COLMAP subcommand with `args`, its output in `workspace/<step>.log`.
fn run_colmap(options: &ColmapOptions, workspace: &Path, step: &str, args: &[String]) -> Result<()> {
    let log = workspace.join(format!("{step}.log"));
    let file = std::fs::File::create(&log).map_err(|e| rmvp_dataset::Error::io(&log, e))?;
    let status = Command::new(&options.program)
        .arg(step)
        .args(args)
        .stdout(file.try_clone().map_err(|e| rmvp_dataset::Error::io(&log, e))?)
        .stderr(file)
        .status()
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => Error::ColmapMissing { program: options.program.display().to_string() },
            _ => rmvp_dataset::Error::io(&options.program, e).into(),
        })?;
    if !status.success() {
        let text = std::fs::read_to_string(&log).unwrap_or_default();
        let tail: Vec<&str> = text.lines().rev().take(15).collect::<Vec<_>>().into_iter().rev().collect();
        return Err(Error::ColmapFailed {
            step: step.into(),
            status: status.to_string(),
            log: log.display().to_string(),
            tail: tail.join("\n"),
        });
    }
    Ok(())
}

fn arg(name: &str, value: impl std::fmt::Display) -> [String; 2] {
    [format!("--{name}"), value.to_string()]
}

/// Pose the session in `dir` with COLMAP in the folder `workspace` (created; its logs stay
/// there), intrinsics fixed to `calibration`.
pub fn colmap_poses(
    dir: &Path,
    calibration: &CameraCalibration,
    workspace: &Path,
    options: &ColmapOptions,
) -> Result<PoseSet> {
    let manifest = SessionManifest::read(dir)?;
    manifest.require_views(dir)?;
    let (images, masks, sparse) = (workspace.join("images"), workspace.join("masks"), workspace.join("sparse"));
    if workspace.exists() {
        std::fs::remove_dir_all(workspace).map_err(|e| rmvp_dataset::Error::io(workspace, e))?;
    }
    for folder in [&images, &sparse] {
        std::fs::create_dir_all(folder).map_err(|e| rmvp_dataset::Error::io(folder, e))?;
    }
    manifest.views.par_iter().try_for_each(|view| -> Result<()> {
        let picture = grey_picture(&read_view_stokes(dir, view)?.s0);
        let size = (picture.width() as u32, picture.height() as u32);
        if size != (calibration.width, calibration.height) {
            return Err(Error::SizeMismatch { calibrated: (calibration.width, calibration.height), views: size });
        }
        png::write_png_u8(&images.join(format!("{}.png", view.name)), &picture)?;
        if let Some(folder) = &options.masks {
            let mask = png::read_png_u8(&folder.join(format!("{}.png", view.name)))?;
            // COLMAP extracts no features where its mask is 0: zero on the object.
            let background: Image<u8> = mask.channel(0).map(|m| if m > 127 { 0 } else { 255 });
            png::write_png_u8(&masks.join(format!("{}.png.png", view.name)), &background)?;
        }
        Ok(())
    })?;
    let database = workspace.join("database.db");
    let k = calibration.k();
    let d = &calibration.distortion;
    let params = format!("{},{},{},{},{},{},{},{}", k[(0, 0)], k[(1, 1)], k[(0, 2)], k[(1, 2)], d.k1, d.k2, d.p1, d.p2);
    let mut extract: Vec<String> = [
        arg("database_path", database.display()),
        arg("image_path", images.display()),
        arg("ImageReader.single_camera", 1),
        arg("ImageReader.camera_model", "OPENCV"),
        arg("ImageReader.camera_params", &params),
        arg("SiftExtraction.use_gpu", 0),
        arg("SiftExtraction.max_num_features", options.max_features),
    ]
    .concat();
    if options.masks.is_some() {
        extract.extend(arg("ImageReader.mask_path", masks.display()));
    }
    run_colmap(options, workspace, "feature_extractor", &extract)?;
    let (matcher, mut matching) = match options.matcher {
        Matcher::Exhaustive => ("exhaustive_matcher", Vec::new()),
        Matcher::Sequential => (
            "sequential_matcher",
            [arg("SequentialMatching.overlap", options.overlap), arg("SequentialMatching.loop_detection", 0)].concat(),
        ),
    };
    matching.extend([arg("database_path", database.display()), arg("SiftMatching.use_gpu", 0)].concat());
    run_colmap(options, workspace, matcher, &matching)?;
    let mapping = [
        arg("database_path", database.display()),
        arg("image_path", images.display()),
        arg("output_path", sparse.display()),
        arg("Mapper.ba_refine_focal_length", 0),
        arg("Mapper.ba_refine_principal_point", 0),
        arg("Mapper.ba_refine_extra_params", 0),
        arg("Mapper.min_num_matches", MIN_VERIFIED_MATCHES),
        arg("Mapper.abs_pose_min_num_inliers", MIN_VERIFIED_MATCHES),
    ]
    .concat();
    run_colmap(options, workspace, "mapper", &mapping)?;

    // The largest of the models the mapper wrote (sparse/0, sparse/1, ...).
    let mut best: Option<ColmapModel> = None;
    if let Ok(entries) = std::fs::read_dir(&sparse) {
        for entry in entries.flatten().filter(|e| e.path().is_dir()) {
            let model = ColmapModel::read(&entry.path())?;
            if best.as_ref().is_none_or(|b| model.images.len() > b.images.len()) {
                best = Some(model);
            }
        }
    }
    let model = best.unwrap_or_default();
    let cameras = model.cameras(&sparse)?;
    let (mut views, mut failed) = (Vec::new(), Vec::new());
    for view in &manifest.views {
        let file = format!("{}.png", view.name);
        match cameras.iter().position(|(name, _)| *name == file) {
            Some(i) => {
                let (residual, points) = model.residual(i, &cameras[i].1);
                views.push(ViewPose {
                    name: view.name.clone(),
                    camera: CameraRecord::from(&cameras[i].1),
                    residual_px: residual.is_finite().then_some(residual),
                    points,
                });
            }
            None => failed.push(Rejected { name: view.name.clone(), reason: "not registered by COLMAP".into() }),
        }
    }
    PoseSet { method: PoseMethod::Colmap, world: COLMAP_WORLD.into(), views, failed }.require(options.min_views)
}
