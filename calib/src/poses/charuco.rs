//! Poses from a ChArUco board under the object: every view's board corners and the calibrated
//! intrinsics give the camera in the board frame (OpenCV `solvePnP`, Levenberg-Marquardt),
//! world = board frame (z up, millimetres). Views where too few corners are seen, or only
//! corners on one line, are left out by name.

use super::{PoseMethod, PoseSet, ViewPose};
use crate::board::Board;
use crate::intrinsics::{CameraCalibration, Rejected};
use crate::pictures::{grey_picture, read_view_stokes};
use crate::{Error, Result};
use nalgebra::{Matrix3, Rotation3, Vector3};
use opencv::calib3d;
use opencv::core::{Mat, Point2f, Point3f, Vector};
use opencv::prelude::*;
use rayon::prelude::*;
use rmvp_dataset::camera::CameraRecord;
use rmvp_dataset::session::SessionManifest;
use rmvp_dataset::Camera;
use std::path::Path;

/// How strict the board poses are; [`CharucoOptions::default`] holds `rmvp poses`' defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct CharucoOptions {
    /// Corners a view needs.
    pub min_corners: usize,
    /// Views that must be posed.
    pub min_views: usize,
}

impl Default for CharucoOptions {
    fn default() -> Self {
        Self { min_corners: 8, min_views: 3 }
    }
}

/// What the world frame of board poses is.
pub const BOARD_WORLD: &str =
    "board frame: origin at the board's lower-left corner, x and y along its sides, z up, millimetres";

/// The camera that sees the board points `points` (board frame) at `pixels`, with the
/// calibrated intrinsics; and the RMS reprojection error.
pub fn board_pose(
    calibration: &CameraCalibration,
    points: &[nalgebra::Point3<f64>],
    pixels: &[nalgebra::Point2<f64>],
) -> Result<(Camera, f64)> {
    let object: Vector<Point3f> = points.iter().map(|p| Point3f::new(p.x as f32, p.y as f32, p.z as f32)).collect();
    let image: Vector<Point2f> = pixels.iter().map(|p| Point2f::new(p.x as f32, p.y as f32)).collect();
    let k = Mat::from_slice_2d(&calibration.k)?;
    let d = &calibration.distortion;
    let values = [d.k1, d.k2, d.p1, d.p2, d.k3];
    let coefficients = Mat::from_slice(&values)?;
    let (mut rvec, mut tvec) = (Mat::default(), Mat::default());
    calib3d::solve_pnp(&object, &image, &k, &coefficients, &mut rvec, &mut tvec, false, calib3d::SOLVEPNP_ITERATIVE)?;
    calib3d::solve_pnp_refine_lm_def(&object, &image, &k, &coefficients, &mut rvec, &mut tvec)?;
    let v =
        |m: &Mat| -> Result<Vector3<f64>> { Ok(Vector3::new(*m.at::<f64>(0)?, *m.at::<f64>(1)?, *m.at::<f64>(2)?)) };
    let rotation: Matrix3<f64> = *Rotation3::new(v(&rvec)?).matrix();
    let mut camera = Camera::new(calibration.k(), rotation, v(&tvec)?, calibration.width, calibration.height);
    camera.distortion = Some(calibration.distortion);
    let squared: f64 =
        points.iter().zip(pixels).map(|(p, q)| camera.project(p).map_or(1e6, |r| (r - q).norm_squared())).sum();
    Ok((camera, (squared / points.len().max(1) as f64).sqrt()))
}

/// Pose every view of the session in `dir` by the board `board`.
pub fn charuco_poses(
    dir: &Path,
    calibration: &CameraCalibration,
    board: &Board,
    options: &CharucoOptions,
) -> Result<PoseSet> {
    let manifest = SessionManifest::read(dir)?;
    manifest.require_views(dir)?;
    let pictures: Vec<_> = manifest
        .views
        .par_iter()
        .map(|view| Ok(grey_picture(&read_view_stokes(dir, view)?.s0)))
        .collect::<Result<_>>()?;
    let outcomes: Vec<std::result::Result<ViewPose, Rejected>> = manifest
        .views
        .iter()
        .zip(&pictures)
        .map(|(view, picture)| {
            let size = (picture.width() as u32, picture.height() as u32);
            if size != (calibration.width, calibration.height) {
                return Err(Error::SizeMismatch { calibrated: (calibration.width, calibration.height), views: size });
            }
            let found = board.detect(picture)?;
            let reject = |reason: String| Ok(Err(Rejected { name: view.name.clone(), reason }));
            if found.len() < options.min_corners {
                return reject(format!("{} board corners seen, {} needed", found.len(), options.min_corners));
            }
            if board.collinear(&found.ids)? {
                return reject(format!("the {} board corners seen lie on one line", found.len()));
            }
            let (camera, residual) = board_pose(calibration, &found.points, &found.pixels)?;
            Ok(Ok(ViewPose {
                name: view.name.clone(),
                camera: CameraRecord::from(&camera),
                residual_px: Some(residual),
                points: found.len(),
            }))
        })
        .collect::<Result<_>>()?;
    let (mut views, mut failed) = (Vec::new(), Vec::new());
    for outcome in outcomes {
        match outcome {
            Ok(pose) => views.push(pose),
            Err(rejected) => failed.push(rejected),
        }
    }
    PoseSet { method: PoseMethod::Charuco, world: BOARD_WORLD.into(), views, failed }.require(options.min_views)
}
