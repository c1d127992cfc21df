//! `build.json`: what a dataset was built from, how, and which stages are done
//! ([`BuildRecord`]), and the options a build records ([`BuildOptions`]); read by verify,
//! publish, the demo and the benches.

use crate::Result;
use rmvp_align::icp::Alignment;
use rmvp_dataset::io::json::{free_form, read_json, write_json};
use rmvp_recon::options::ReconOptions;
use rmvp_recon::presets::Preset;
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The record of a build, in the dataset folder.
pub const BUILD_FILE: &str = "build.json";
/// The `format` of [`BuildRecord`].
pub const BUILD_FORMAT: &str = "rmvp-build-2";

/// Which views train (recorded as the count or the list of names).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum TrainViews {
    /// This many, spread over the viewing directions (farthest-point sampling).
    Count(usize),
    /// These, by name.
    Names(Vec<String>),
}

impl std::fmt::Display for TrainViews {
    /// As the command line takes it: the count, or the names joined by commas.
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match self {
            TrainViews::Count(n) => write!(f, "{n}"),
            TrainViews::Names(names) => write!(f, "{}", names.join(",")),
        }
    }
}

impl std::str::FromStr for TrainViews {
    type Err = String;

    /// `6` (a count) or `000,007,013` (names).
    fn from_str(text: &str) -> std::result::Result<Self, String> {
        match text.parse::<usize>() {
            Ok(0) => Err("at least one training view".into()),
            Ok(n) if !text.contains(',') => Ok(TrainViews::Count(n)),
            _ => {
                Ok(TrainViews::Names(text.split(',').map(|s| s.trim().to_string()).filter(|s| !s.is_empty()).collect()))
            }
        }
    }
}

/// A unit of length a scan may be stored in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum LengthUnit {
    /// Millimetres (Creaform and most scanners).
    Mm,
    /// Centimetres.
    Cm,
    /// Metres.
    M,
    /// Inches.
    In,
}

impl LengthUnit {
    /// The unit's symbol.
    pub fn name(self) -> &'static str {
        match self {
            LengthUnit::Mm => "mm",
            LengthUnit::Cm => "cm",
            LengthUnit::M => "m",
            LengthUnit::In => "in",
        }
    }

    /// One unit in millimetres.
    pub fn millimetres(self) -> f64 {
        match self {
            LengthUnit::Mm => 1.0,
            LengthUnit::Cm => 10.0,
            LengthUnit::M => 1000.0,
            LengthUnit::In => 25.4,
        }
    }
}

/// A laser scan to align.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ScanInput {
    /// PLY, STL or OBJ, any pose.
    pub path: PathBuf,
    /// Its unit of length.
    pub units: LengthUnit,
}

/// A panorama to turn into the environment map.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PanoramaInput {
    /// EXR, HDR, PNG or JPEG, equirectangular.
    pub path: PathBuf,
    /// Turn about the up axis after the world's own rotation (the board frame's z up to the
    /// panorama's +Y up), degrees.
    pub yaw_deg: f64,
}

/// What to build; [`BuildOptions::default`] holds `rmvp dataset build`'s defaults.
/// All but `output`, `resume` and `progress` are recorded in `build.json`: a resumed build must
/// be asked the same.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BuildOptions {
    /// The posed, masked session.
    pub session: PathBuf,
    /// The dataset folder.
    #[serde(skip)]
    pub output: PathBuf,
    /// The training split (NeRSP: 6 sparse views).
    #[serde(deserialize_with = "free_form")]
    pub train: TrainViews,
    /// The camera calibration the poses used (`camera.json`), for the record.
    pub calibration: Option<PathBuf>,
    /// A laser scan: ground truth in the dataset.
    pub scan: Option<ScanInput>,
    /// A panorama: the environment map.
    pub panorama: Option<PanoramaInput>,
    /// The reference reconstruction from all views (with a scan).
    #[serde(deserialize_with = "rmvp_recon::options::deserialize_recorded")]
    pub reference: ReconOptions,
    /// Continue an unfinished build in `output`.
    #[serde(skip)]
    pub resume: bool,
    /// Show progress bars.
    #[serde(skip)]
    pub progress: bool,
}

impl Default for BuildOptions {
    fn default() -> Self {
        Self {
            session: PathBuf::from("session"),
            output: PathBuf::from("dataset"),
            train: TrainViews::Count(6),
            calibration: None,
            scan: None,
            panorama: None,
            reference: ReconOptions {
                preset: Preset::Dense,
                mesh_res: 384,
                mesh_only: true,
                checkpoint_every: 250,
                ..ReconOptions::default()
            },
            resume: false,
            progress: true,
        }
    }
}

/// How the views were posed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseSummary {
    /// Method (`charuco`, `colmap`, ...).
    #[serde(deserialize_with = "free_form")]
    pub method: serde_json::Value,
    /// The world frame.
    pub world: String,
    /// Mean RMS reprojection error of the posing points over the views, pixels.
    pub residual_px_mean: Option<f64>,
    /// Largest of them.
    pub residual_px_max: Option<f64>,
    /// Views the method could not pose.
    pub failed: Vec<String>,
}

/// The camera calibration's figures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CalibrationSummary {
    /// RMS reprojection error over all corners, pixels.
    pub rms_px: f64,
    /// Standard deviations of fx, fy, cx, cy, pixels.
    pub k_std_px: [f64; 4],
    /// Board images used.
    pub images: usize,
}

/// The reference reconstruction.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceSummary {
    /// Preset.
    pub preset: Preset,
    /// Iterations.
    pub iterations: u32,
    /// Views it trained on (all).
    pub views: usize,
    /// Marching grid cells per axis.
    pub mesh_resolution: usize,
}

/// The scan and its alignment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ScanSummary {
    /// The scan file.
    pub file: PathBuf,
    /// Its units.
    pub units: LengthUnit,
    /// Scan to world (`x_world = s R x_scan + t`), RMS and median residuals in world units.
    pub alignment: Alignment,
    /// The scale its units give in a millimetre world (`None`: the world's scale is arbitrary
    /// and the units were not checked). When known, the alignment is rigid at this scale.
    pub expected_scale: Option<f64>,
    /// The scale that a fit with a free scale found (the units' check; it differs from the
    /// expected one by the reference's own error of size).
    #[serde(default)]
    pub free_scale: f64,
    /// Median scan-to-reference distance over the reference's bounding-box diagonal.
    pub median_distance_relative: f64,
    /// Captured masks against the scan's silhouettes: mean IoU over the views.
    pub mask_iou_mean: f64,
    /// The lowest IoU and its view.
    pub mask_iou_min: (f64, String),
}

/// The environment map.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EnvironmentSummary {
    /// The panorama file.
    pub file: PathBuf,
    /// Map size.
    pub size: [usize; 2],
    /// World to panorama frame, rows.
    pub world_to_panorama: [[f64; 3]; 3],
    /// The mapping of `env.exr`.
    pub convention: String,
}

/// One finished stage.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StageRecord {
    /// The stage.
    pub name: Stage,
    /// Wall time, seconds (of the run that finished it).
    pub seconds: f64,
}

/// `build.json`: what a dataset was built from, how, and which stages are done.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BuildRecord {
    /// [`BUILD_FORMAT`].
    pub format: String,
    /// What was asked (the recorded [`BuildOptions`]).
    pub options: BuildOptions,
    /// The object's name (the session's).
    pub object: String,
    /// The camera (identity, pixel format, size) as the session recorded it.
    #[serde(deserialize_with = "free_form")]
    pub camera: serde_json::Value,
    /// Acquisition settings as the session recorded them.
    #[serde(deserialize_with = "free_form")]
    pub settings: serde_json::Value,
    /// Views in the dataset.
    pub views: Vec<String>,
    /// The training split.
    pub train: Vec<String>,
    /// Image size.
    pub size: [u32; 2],
    /// Poses.
    pub poses: PoseSummary,
    /// Calibration.
    pub calibration: Option<CalibrationSummary>,
    /// Reference reconstruction.
    pub reference: Option<ReferenceSummary>,
    /// Scan.
    pub scan: Option<ScanSummary>,
    /// Environment map.
    pub environment: Option<EnvironmentSummary>,
    /// Finished stages, in order.
    pub stages: Vec<StageRecord>,
    /// All stages done and both layouts in place.
    pub complete: bool,
}

impl BuildRecord {
    /// Read `DATASET/build.json`.
    pub fn read(dataset: &Path) -> Result<Self> {
        let path = dataset.join(BUILD_FILE);
        let record: Self = read_json(&path, "a dataset build record")?;
        // View names become file names in exports and contact sheets.
        for name in record.views.iter().chain(&record.train) {
            rmvp_dataset::io::input::file_name(name)
                .map_err(|why| rmvp_dataset::Error::format(&path, format!("view {why}")))?;
        }
        Ok(record)
    }

    /// Write `DATASET/build.json` (atomically).
    pub(crate) fn write(&self, dataset: &Path) -> Result<()> {
        Ok(write_json(&dataset.join(BUILD_FILE), self)?)
    }

    pub(super) fn done(&self, stage: Stage) -> bool {
        self.stages.iter().any(|s| s.name == stage)
    }

    /// The record as a release publishes it: each input file named by its file name alone, not
    /// by its path on the machine that built it.
    pub fn for_release(&self) -> Self {
        let name = |path: &Path| PathBuf::from(path.file_name().unwrap_or_default());
        let mut record = self.clone();
        let options = &mut record.options;
        options.session = name(&options.session);
        options.calibration = options.calibration.as_deref().map(name);
        if let Some(scan) = options.scan.as_mut() {
            scan.path = name(&scan.path);
        }
        if let Some(panorama) = options.panorama.as_mut() {
            panorama.path = name(&panorama.path);
        }
        if let Some(scan) = record.scan.as_mut() {
            scan.file = name(&scan.file);
        }
        if let Some(environment) = record.environment.as_mut() {
            environment.file = name(&environment.file);
        }
        record
    }

    /// The object's part of a datasheet (Markdown): camera, settings, calibration, poses, the
    /// ground truth's alignment and the environment map, as recorded.
    pub fn datasheet_section(&self) -> String {
        let mut s = String::new();
        let camera = &self.camera;
        let identity = &camera["identity"];
        let _ = writeln!(
            s,
            "- Camera: {} {} (serial {}, {}), {} at {}x{} sensor pixels.",
            identity["vendor"].as_str().unwrap_or("?"),
            identity["model"].as_str().unwrap_or("?"),
            identity["serial"].as_str().unwrap_or("?"),
            identity["protocol"].as_str().unwrap_or("?"),
            camera["pixel_format"].as_str().unwrap_or("?"),
            camera["width"],
            camera["height"],
        );
        let settings = &self.settings;
        let _ = writeln!(
            s,
            "- Settings: exposure(s) {} us, gain {} dB, {} frame(s) averaged, {} dark frame(s).",
            settings["exposures_us"], settings["camera"]["gain_db"], settings["average"], settings["dark_frames"]
        );
        match &self.calibration {
            Some(c) => {
                let _ = writeln!(
                    s,
                    "- Calibration: RMS reprojection error {:.3} px over {} board images; std of fx, fy, cx, cy \
                 {:.2}, {:.2}, {:.2}, {:.2} px.",
                    c.rms_px, c.images, c.k_std_px[0], c.k_std_px[1], c.k_std_px[2], c.k_std_px[3]
                );
            }
            None => {
                let _ = writeln!(s, "- Calibration: not recorded with this build.");
            }
        }
        let p = &self.poses;
        let _ = writeln!(
            s,
            "- Poses: {} ({}); reprojection RMS per view mean {} px, worst {} px; {} view(s) not posed.",
            p.method.as_str().unwrap_or("?"),
            p.world,
            p.residual_px_mean.map_or("-".into(), |r| format!("{r:.3}")),
            p.residual_px_max.map_or("-".into(), |r| format!("{r:.3}")),
            p.failed.len()
        );
        if let (Some(scan), Some(reference)) = (&self.scan, &self.reference) {
            let a = &scan.alignment;
            let fit = match scan.expected_scale {
                Some(_) => format!(
                    "rigidly at its units' scale (a free scale would be {:.5}; the reference's surface lies {:+.4} \
                 outside the scan's, fitted as one offset along its normals)",
                    scan.free_scale, a.target_offset
                ),
                None => "with scale".to_string(),
            };
            let _ = writeln!(
                s,
                "- Ground truth: laser scan `{}` ({:?}) aligned by ICP {fit} onto a reference reconstruction \
             from all {} views ({:?} preset, {} iterations): scale {:.5}, RMS point-to-plane {:.4}, median \
             distance {:.4} world units ({:.3} % of the object's size), {:.1} % inliers; captured masks \
             against the scan's silhouettes: IoU mean {:.4}, lowest {:.4} (view {}).",
                scan.file.file_name().unwrap_or_default().to_string_lossy(),
                scan.units,
                reference.views,
                reference.preset,
                reference.iterations,
                a.transform.s,
                a.rms,
                a.median_distance,
                100.0 * scan.median_distance_relative,
                100.0 * a.inlier_ratio,
                scan.mask_iou_mean,
                scan.mask_iou_min.0,
                scan.mask_iou_min.1
            );
        }
        if let Some(env) = &self.environment {
            let _ = writeln!(
                s,
                "- Environment map: panorama `{}` ({}x{}) turned into the world frame.",
                env.file.file_name().unwrap_or_default().to_string_lossy(),
                env.size[0],
                env.size[1]
            );
        }
        s
    }
}

/// The stages of a build, in order; each finished one is kept in `build.json`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Stage {
    /// The posed, masked views, split and undistorted.
    Views,
    /// The reference shape from all views (with a scan).
    Reference,
    /// The scan aligned onto the reference.
    Scan,
    /// Ground truth (mesh, normals, depth) from the aligned scan: seconds, done again on resume.
    GroundTruth,
    /// The environment map from the panorama: done again on resume.
    Environment,
    /// Both layouts, each written aside and moved into place whole.
    Layouts,
}

impl std::fmt::Display for Stage {
    /// The stage's name in `build.json`.
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        self.serialize(f)
    }
}
