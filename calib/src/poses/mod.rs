//! Camera poses of a capture session's views, in rmvp's conventions (OpenCV cameras,
//! `x_cam = R x_world + t`, pixel centres at +0.5): from a board under the object
//! ([`charuco`]), from COLMAP ([`colmap`]), from the turntable positions the session recorded
//! and a rig calibration ([`turntable`]), or imported from another tool's files ([`import`]).
//! Every method gives a [`PoseSet`]: each posed view with its residual, and the views that
//! failed with the reason. [`accuracy`] compares poses with reference poses.

pub mod accuracy;
pub mod charuco;
pub mod colmap;
pub mod import;
pub mod turntable;

use crate::intrinsics::Rejected;
use crate::{Error, Result};
use rmvp_dataset::camera::CameraRecord;
use rmvp_dataset::io::json::{read_json, write_json};
use rmvp_dataset::Camera;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The file a session's poses are kept in (in the session folder, for the steps after).
pub const POSES_FILE: &str = "poses.json";

/// How the poses were found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum PoseMethod {
    /// A ChArUco board under the object: world = board frame (z up, millimetres).
    Charuco,
    /// COLMAP structure from motion with the calibrated intrinsics fixed: world = COLMAP's
    /// (arbitrary scale).
    Colmap,
    /// Turntable positions recorded in the session and a rig calibration (poses of a session
    /// captured at the same positions).
    Turntable,
    /// Another tool's cameras (COLMAP model, IDR/NeRSP `cameras.npz`, nerfstudio
    /// `transforms.json`).
    Import,
}

/// One posed view.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewPose {
    /// The view's name in the session.
    pub name: String,
    /// Its camera.
    pub camera: CameraRecord,
    /// RMS reprojection error of the points that posed it, pixels (when the method has any).
    pub residual_px: Option<f64>,
    /// Points that posed it (board corners, COLMAP points).
    pub points: usize,
}

/// The poses of a session (`poses.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseSet {
    /// How they were found.
    pub method: PoseMethod,
    /// What the world frame is.
    pub world: String,
    /// Posed views, in session order.
    pub views: Vec<ViewPose>,
    /// Views that could not be posed, and why.
    pub failed: Vec<Rejected>,
}

impl PoseSet {
    /// Read `poses.json`.
    pub fn read(path: &Path) -> Result<Self> {
        let set: PoseSet = read_json(path, "a pose set")?;
        for view in &set.views {
            Camera::try_from(&view.camera)
                .map_err(|e| rmvp_dataset::Error::format(path, format!("view {}: {e}", view.name)))?;
        }
        Ok(set)
    }

    /// Write to `path` atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        Ok(write_json(path, self)?)
    }

    /// The camera of view `name`.
    pub fn camera(&self, name: &str) -> Option<Camera> {
        self.views.iter().find(|v| v.name == name).and_then(|v| Camera::try_from(&v.camera).ok())
    }

    /// Refuse a set with fewer than `min` posed views, naming the failures.
    pub fn require(self, min: usize) -> Result<Self> {
        if self.views.len() < min {
            return Err(Error::TooFewViews {
                posed: self.views.len(),
                needed: min,
                failed: self.failed.iter().map(|r| format!("{} ({})", r.name, r.reason)).collect::<Vec<_>>().join(", "),
            });
        }
        Ok(self)
    }
}

/// What `rmvp poses` is asked to do: a method with its inputs.
pub enum PoseRequest {
    /// [`charuco::charuco_poses`].
    Charuco {
        /// Intrinsics.
        calibration: crate::intrinsics::CameraCalibration,
        /// The board under the object.
        board: crate::board::BoardOptions,
        /// Strictness.
        options: charuco::CharucoOptions,
    },
    /// [`colmap::colmap_poses`] (workspace: `SESSION/colmap`).
    Colmap {
        /// Intrinsics (fixed).
        calibration: crate::intrinsics::CameraCalibration,
        /// How COLMAP runs.
        options: colmap::ColmapOptions,
    },
    /// [`turntable::turntable_poses`].
    Turntable {
        /// The posed rig session.
        rig: std::path::PathBuf,
        /// Views that must be posed.
        min_views: usize,
    },
    /// [`import::import_poses`].
    Import {
        /// COLMAP model folder, `cameras.npz` or `transforms.json`.
        source: std::path::PathBuf,
        /// Views that must be posed.
        min_views: usize,
    },
}

/// The COLMAP workspace of a session.
pub const COLMAP_FOLDER: &str = "colmap";

/// Pose the session in `dir` as `request` says, and keep the poses in the session
/// (`SESSION/poses.json`) and in `output` (when another file).
pub fn pose_session(dir: &Path, request: &PoseRequest, output: &Path) -> Result<PoseSet> {
    let set = match request {
        PoseRequest::Charuco { calibration, board, options } => {
            charuco::charuco_poses(dir, calibration, &crate::board::Board::new(board)?, options)?
        }
        PoseRequest::Colmap { calibration, options } => {
            colmap::colmap_poses(dir, calibration, &dir.join(COLMAP_FOLDER), options)?
        }
        PoseRequest::Turntable { rig, min_views } => turntable::turntable_poses(dir, rig, *min_views)?,
        PoseRequest::Import { source, min_views } => import::import_poses(dir, source, *min_views)?,
    };
    set.write(&dir.join(POSES_FILE))?;
    if output != dir.join(POSES_FILE) {
        set.write(output)?;
    }
    Ok(set)
}
