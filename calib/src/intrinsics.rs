//! Intrinsic calibration from images of a board: OpenCV's `calibrateCamera` (Zhang's method,
//! the OpenCV distortion model with `k1`, `k2` estimated and `p1`, `p2`, `k3` zero unless asked:
//! measured on rendered boards, freeing the tangential terms made the principal point's
//! deviation three times larger for lenses that have none), with every image's corners in
//! rmvp's pixel convention, so that `K` is in it too. Images where the board is not found well
//! enough are left out and named; mixed sizes, too few images and views that cannot fix the
//! focal length (the board at one orientation throughout) are refused.

use crate::board::{Board, BoardOptions, Detection};
use crate::{Error, Result};
use nalgebra::{Matrix3, Vector3};
use opencv::calib3d;
use opencv::core::{self, Mat, Point2f, Point3f, Vector};
use opencv::prelude::*;
use rmvp_dataset::camera::{matrix_from_rows, matrix_rows};
use rmvp_dataset::io::json::{read_json, write_json};
use rmvp_dataset::visualize::hsv_to_rgb;
use rmvp_dataset::{Distortion, Image};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// How to calibrate; [`CalibrationOptions::default`] holds the defaults of `rmvp calibrate`.
#[derive(Clone, Debug, PartialEq)]
pub struct CalibrationOptions {
    /// Corners an image needs to take part.
    pub min_corners: usize,
    /// Images needed.
    pub min_images: usize,
    /// Estimate the tangential coefficients `p1`, `p2` too (off: zero). They trade off against
    /// the principal point; machine-vision lenses rarely need them.
    pub tangential: bool,
    /// Estimate `k3` too (off: zero, the usual choice for ordinary lenses).
    pub k3: bool,
    /// Below this spread of board orientations (degrees) the focal length is not determined.
    pub min_tilt_spread_deg: f64,
}

impl Default for CalibrationOptions {
    fn default() -> Self {
        Self { min_corners: 12, min_images: 4, tangential: false, k3: false, min_tilt_spread_deg: 3.0 }
    }
}

/// One image's part in a calibration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImageResidual {
    /// The image.
    pub name: String,
    /// Corners used.
    pub corners: usize,
    /// RMS reprojection error of its corners, pixels.
    pub rms_px: f64,
}

/// An image left out, and why.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Rejected {
    /// The image (or view).
    pub name: String,
    /// Why it was left out.
    pub reason: String,
}

/// A calibrated camera (`camera.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraCalibration {
    /// Intrinsics, row-major, rmvp pixel convention (pixel centres at +0.5).
    pub k: [[f64; 3]; 3],
    /// OpenCV distortion.
    pub distortion: Distortion,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Standard deviations of fx, fy, cx, cy (pixels) as the calibration estimates them.
    pub k_std_px: [f64; 4],
    /// RMS reprojection error over all corners, pixels.
    pub rms_px: f64,
    /// The images used.
    pub images: Vec<ImageResidual>,
    /// The images left out.
    pub rejected: Vec<Rejected>,
    /// The board.
    pub board: BoardOptions,
    /// What deserves a look before the calibration is trusted ([`error_clusters`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

impl CameraCalibration {
    /// The intrinsic matrix.
    pub fn k(&self) -> Matrix3<f64> {
        matrix_from_rows(&self.k)
    }

    /// Read `camera.json`.
    pub fn read(path: &Path) -> Result<Self> {
        Ok(read_json(path, "a camera calibration")?)
    }

    /// Write `camera.json` atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        Ok(write_json(path, self)?)
    }
}

/// What calibrating a set of images gives: the calibration and each used image's detection.
pub struct CalibrationRun {
    /// The camera.
    pub calibration: CameraCalibration,
    /// Detections of the images used, in [`CameraCalibration::images`] order.
    pub detections: Vec<Detection>,
}

/// Calibrate from `images` (name, 8-bit picture) of `board`.
pub fn calibrate(
    images: &[(String, Image<u8>)],
    board: &Board,
    options: &CalibrationOptions,
) -> Result<CalibrationRun> {
    let Some((_, first)) = images.first() else {
        return Err(Error::TooFewImages { usable: 0, needed: options.min_images, rejected: "(no images)".into() });
    };
    let size = first.size();
    let odd: Vec<String> = images
        .iter()
        .filter(|(_, i)| i.size() != size)
        .map(|(n, i)| format!("{n} is {}x{}", i.width(), i.height()))
        .collect();
    if !odd.is_empty() {
        return Err(Error::MixedSizes(format!("{} is {}x{}; {}", images[0].0, size.0, size.1, odd.join(", "))));
    }
    let detections: Vec<Detection> = images.iter().map(|(_, image)| board.detect(image)).collect::<Result<_>>()?;
    let (mut used, mut rejected) = (Vec::new(), Vec::new());
    for ((name, _), detection) in images.iter().zip(detections) {
        if detection.len() < options.min_corners {
            let reason = format!("{} corners found, {} needed", detection.len(), options.min_corners);
            rejected.push(Rejected { name: name.clone(), reason });
        } else {
            used.push((name.clone(), detection));
        }
    }
    if used.len() < options.min_images {
        return Err(Error::TooFewImages {
            usable: used.len(),
            needed: options.min_images,
            rejected: rejected.iter().map(|r| format!("{} ({})", r.name, r.reason)).collect::<Vec<_>>().join(", "),
        });
    }
    let spread = tilt_spread_deg(&used, size)?;
    if spread < options.min_tilt_spread_deg {
        return Err(Error::Degenerate {
            images: used.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>().join(", "),
            spread_deg: spread,
        });
    }

    let object: Vector<Vector<Point3f>> = used
        .iter()
        .map(|(_, d)| d.points.iter().map(|p| Point3f::new(p.x as f32, p.y as f32, p.z as f32)).collect())
        .collect();
    let pixels: Vector<Vector<Point2f>> =
        used.iter().map(|(_, d)| d.pixels.iter().map(|p| Point2f::new(p.x as f32, p.y as f32)).collect()).collect();
    let mut camera = Mat::default();
    let mut coefficients = Mat::default();
    let (mut rvecs, mut tvecs) = (Vector::<Mat>::new(), Vector::<Mat>::new());
    let (mut std_in, mut std_ex, mut per_view) = (Mat::default(), Mat::default(), Mat::default());
    let mut flags = 0;
    if !options.k3 {
        flags |= calib3d::CALIB_FIX_K3;
    }
    if !options.tangential {
        flags |= calib3d::CALIB_ZERO_TANGENT_DIST;
    }
    let criteria = core::TermCriteria::new(core::TermCriteria_COUNT + core::TermCriteria_EPS, 100, 1e-12)?;
    let rms = calib3d::calibrate_camera_extended(
        &object,
        &pixels,
        core::Size::new(size.0 as i32, size.1 as i32),
        &mut camera,
        &mut coefficients,
        &mut rvecs,
        &mut tvecs,
        &mut std_in,
        &mut std_ex,
        &mut per_view,
        flags,
        criteria,
    )?;
    let k = Matrix3::from_fn(|i, j| *camera.at_2d::<f64>(i as i32, j as i32).expect("3x3"));
    let d: Vec<f64> = (0..5).map(|i| *coefficients.at::<f64>(i).expect("5 coefficients")).collect();
    let images: Vec<ImageResidual> = used
        .iter()
        .enumerate()
        .map(|(v, (name, detection))| ImageResidual {
            name: name.clone(),
            corners: detection.len(),
            rms_px: *per_view.at::<f64>(v as i32).expect("one error per view"),
        })
        .collect();
    let warnings = error_clusters(&images).into_iter().collect();
    let calibration = CameraCalibration {
        k: matrix_rows(&k),
        distortion: Distortion { k1: d[0], k2: d[1], p1: d[2], p2: d[3], k3: d[4] },
        width: size.0 as u32,
        height: size.1 as u32,
        k_std_px: [0, 1, 2, 3].map(|i| *std_in.at::<f64>(i).expect("intrinsic deviations")),
        rms_px: rms,
        images,
        rejected,
        board: board.spec().clone(),
        warnings,
    };
    Ok(CalibrationRun { calibration, detections: used.into_iter().map(|(_, d)| d).collect() })
}

/// Per-image errors this many times the others' at the widest gap between them make two
/// clusters (and the gap must be at least [`CLUSTER_GAP_PX`]).
pub const CLUSTER_RATIO: f64 = 2.0;
/// The least gap (pixels) between two clusters of per-image errors: below it, both are within
/// what corner detection alone scatters.
pub const CLUSTER_GAP_PX: f64 = 0.1;

/// A warning when the per-image errors split into two clusters: sorted, their widest gap (by
/// ratio) puts the images above it at [`CLUSTER_RATIO`] times or more the error of those below
/// and at least [`CLUSTER_GAP_PX`] further. One camera, one focus and a rigid board give errors
/// of one population; two clusters mean a second camera or zoom, a refocused lens, a board that
/// bent or moved during an exposure, or a wrong detection.
pub fn error_clusters(images: &[ImageResidual]) -> Option<String> {
    let mut sorted: Vec<&ImageResidual> = images.iter().collect();
    sorted.sort_by(|a, b| a.rms_px.total_cmp(&b.rms_px));
    let (split, ratio) = (1..sorted.len())
        .map(|k| (k, sorted[k].rms_px / sorted[k - 1].rms_px.max(1e-12)))
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    let (low, high) = sorted.split_at(split);
    let (low_max, high_min) = (low[low.len() - 1].rms_px, high[0].rms_px);
    if ratio < CLUSTER_RATIO || high_min - low_max < CLUSTER_GAP_PX {
        return None;
    }
    let names: Vec<&str> = high.iter().map(|i| i.name.as_str()).collect();
    Some(format!(
        "the per-image errors fall into two groups: {} at {high_min:.3}-{:.3} px against {:.3}-{low_max:.3} px for \
         the other {}: another camera, zoom or focus, a board that bent or moved, or a wrong detection?",
        names.join(", "),
        high[high.len() - 1].rms_px,
        low[0].rms_px,
        low.len()
    ))
}

/// The largest angle (degrees) between the board's vanishing lines of two images: zero when
/// the board has one orientation in all of them, whatever the camera's intrinsics (a plane's
/// vanishing line `H^-T (0, 0, 1)` depends on its normal alone).
fn tilt_spread_deg(used: &[(String, Detection)], size: (usize, usize)) -> Result<f64> {
    let (cx, cy, scale) = (size.0 as f64 / 2.0, size.1 as f64 / 2.0, size.0 as f64);
    let mut lines = Vec::new();
    for (_, d) in used {
        let board: Vector<Point2f> = d.points.iter().map(|p| Point2f::new(p.x as f32, p.y as f32)).collect();
        let image: Vector<Point2f> =
            d.pixels.iter().map(|p| Point2f::new(((p.x - cx) / scale) as f32, ((p.y - cy) / scale) as f32)).collect();
        let h = calib3d::find_homography(&board, &image, &mut core::no_array(), 0, 3.0)?;
        if h.empty() {
            continue;
        }
        let h = Matrix3::from_fn(|i, j| *h.at_2d::<f64>(i as i32, j as i32).expect("3x3"));
        if let Some(inverse) = h.try_inverse() {
            let line: Vector3<f64> = inverse.row(2).transpose();
            lines.push(line.normalize());
        }
    }
    let mut spread = 0f64;
    for (i, a) in lines.iter().enumerate() {
        for b in &lines[i + 1..] {
            spread = spread.max(a.dot(b).abs().min(1.0).acos().to_degrees());
        }
    }
    Ok(spread)
}

/// A picture of where the corners of every image fell (one colour per image) over the frame,
/// at most 800 pixels wide: gaps show where the calibration has not looked.
pub fn coverage_picture(width: u32, height: u32, detections: &[Detection]) -> Image<u8> {
    let factor = (width as f64 / 800.0).max(1.0);
    let (w, h) = ((width as f64 / factor).round() as usize, (height as f64 / factor).round() as usize);
    let mut picture = Image::from_vec(w, h, 3, vec![24u8; w * h * 3]).expect("sized");
    for (k, detection) in detections.iter().enumerate() {
        let colour = hsv_to_rgb(k as f32 / detections.len().max(1) as f32, 0.8, 1.0);
        for p in &detection.pixels {
            let (x, y) = ((p.x / factor) as isize, (p.y / factor) as isize);
            for (dx, dy) in (-1..=1).flat_map(|dx| (-1..=1).map(move |dy| (dx, dy))) {
                let (u, v) = (x + dx, y + dy);
                if (0..w as isize).contains(&u) && (0..h as isize).contains(&v) {
                    picture.pixel_mut(u as usize, v as usize).copy_from_slice(&colour);
                }
            }
        }
    }
    picture
}

/// The coverage picture written beside a calibration file: `camera.json` -> `camera_coverage.png`.
pub fn coverage_path(calibration: &Path) -> std::path::PathBuf {
    let stem = calibration.file_stem().map_or_else(|| "camera".into(), |s| s.to_string_lossy().into_owned());
    calibration.with_file_name(format!("{stem}_coverage.png"))
}

/// Calibrate from a capture session (its views' S0) or image files and write the calibration
/// to `output` (JSON) with its coverage picture beside it ([`coverage_path`]).
pub fn calibrate_files(
    inputs: &[std::path::PathBuf],
    board: &BoardOptions,
    options: &CalibrationOptions,
    output: &Path,
) -> Result<CalibrationRun> {
    let pictures = crate::pictures::read_pictures(inputs)?;
    let run = calibrate(&pictures, &Board::new(board)?, options)?;
    let c = &run.calibration;
    run.calibration.write(output)?;
    rmvp_dataset::io::png::write_png_u8(&coverage_path(output), &coverage_picture(c.width, c.height, &run.detections))?;
    Ok(run)
}
