//! The pipeline on its built-in example, end to end:
//!
//! 1. Simulate a capture: six views of the built-in "spot" rendered with polarization, and the
//!    raw 12-bit frames the sensor would send (with shot and read noise and a dark frame).
//! 2. Capture processing: every raw frame through decoding, demosaicing, dark subtraction and
//!    Stokes, AoP and DoP estimation.
//! 3. Dataset: the processed views with their cameras and masks as a NeRSP-layout scene, read
//!    back and validated.
//! 4. Report: the captured polarization against the rendered ground truth, as numbers
//!    ([`DemoReport`], `report.json`) and pictures (`contact_sheet.png`).
//! 5. Reconstruction: NeRSP (fast preset) on the captured dataset, evaluated against the true
//!    mesh and normals.

use crate::simulate::{simulate, SimulateOptions, DARK_FRAME, RAW_FOLDER, RAW_FORMAT};
use crate::Result;
use rmvp_align::{evaluate, SurfaceOptions};
use rmvp_capture::sensor::{SensorRecord, SENSOR_FILE};
use rmvp_capture::{FrameProcessor, RawFrame};
use rmvp_dataset::io::json::{read_json, write_json};
use rmvp_dataset::io::png;
use rmvp_dataset::layout::{read_scene, write_scene, Layout};
use rmvp_dataset::progress::progress_bar;
use rmvp_dataset::visualize::{aop_picture, contact_sheet, downsample, gray_ramp, preview, quantile};
use rmvp_dataset::{Image, Mesh, Scene, View};
use rmvp_recon::model::Preset;
use rmvp_recon::reconstruct::{reconstruct, Options as ReconOptions, MESH};
use serde::{Deserialize, Serialize};
use std::f32::consts::PI;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

/// What the demo runs; [`DemoOptions::default`] holds every default of `rmvp demo`.
#[derive(Clone, Debug, PartialEq)]
pub struct DemoOptions {
    /// Output folder.
    pub output: PathBuf,
    /// Image size of the simulated views (the raw frames are twice as large).
    pub size: (u32, u32),
    /// Samples per pixel of the simulation.
    pub spp: u32,
    /// Training iterations of the reconstruction (fast preset).
    pub recon_iterations: u32,
    /// Marching grid cells per axis of the reconstructed mesh.
    pub mesh_resolution: usize,
    /// Show progress bars.
    pub progress: bool,
}

impl Default for DemoOptions {
    fn default() -> Self {
        Self {
            output: PathBuf::from("demo-out"),
            size: (612, 512),
            spp: 16,
            recon_iterations: 1000,
            mesh_resolution: 192,
            progress: true,
        }
    }
}

/// Views the demo simulates.
pub const DEMO_VIEWS: usize = 6;
/// AoP is compared where the rendered light is at least this polarized.
pub const AOP_MIN_DOP: f32 = 0.05;
/// S0 is compared where the rendered S0 (green) is at least this bright.
pub const S0_MIN: f32 = 0.05;
/// AoP errors above this many degrees are white in the contact sheet.
pub const AOP_ERROR_MAP_MAX_DEG: f32 = 10.0;
/// The report's file name.
pub const REPORT_FILE: &str = "report.json";
/// The contact sheet's file name.
pub const CONTACT_SHEET: &str = "contact_sheet.png";

/// The simulation the demo made.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimulatedSummary {
    /// Views rendered.
    pub views: usize,
    /// Image size.
    pub size: [u32; 2],
    /// Samples per pixel.
    pub spp: u32,
    /// Where the simulated scene is, relative to the output folder.
    pub layout: String,
}

/// The dataset built from the processed frames.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DatasetSummary {
    /// Its folder, relative to the output folder.
    pub folder: String,
    /// Its layout.
    pub layout: String,
    /// Views it holds.
    pub views: usize,
    /// Whether it read back and validated.
    pub valid: bool,
}

/// Quantiles of an error over the pixels where it was measured.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ErrorQuantiles {
    /// Median.
    pub median: f32,
    /// 90th percentile.
    pub p90: f32,
    /// Pixels measured.
    pub pixels: usize,
}

impl ErrorQuantiles {
    fn of(errors: &[f32]) -> Self {
        Self { median: quantile(errors, 0.5), p90: quantile(errors, 0.9), pixels: errors.len() }
    }
}

/// The reconstruction the demo ran, and its evaluation against the truth.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReconSummary {
    /// Its folder, relative to the output folder.
    pub folder: String,
    /// The preset.
    pub preset: Preset,
    /// Training iterations.
    pub iterations: u32,
    /// Wall time of the whole reconstruction stage, seconds.
    pub seconds: f64,
    /// Chamfer distance to the true mesh (scene units).
    pub chamfer: f64,
    /// F-score at 1 % of the true mesh's bounding-box diagonal.
    pub f_score: f64,
    /// Mean normal angular error over the views, degrees.
    pub normal_mae_deg: f64,
    /// The input-against-rendered picture, relative to the output folder.
    pub comparison: String,
}

/// Everything the demo measured (`report.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DemoReport {
    /// The simulation.
    pub simulated: SimulatedSummary,
    /// The raw frames and the sensor that made them.
    pub raw_frames: SensorRecord,
    /// The captured dataset.
    pub captured_dataset: DatasetSummary,
    /// Captured AoP against the rendered AoP, degrees (where DoP > [`AOP_MIN_DOP`]).
    pub aop_error_deg: ErrorQuantiles,
    /// Captured S0 against the rendered S0, relative (where S0 > [`S0_MIN`]).
    pub s0_rel_error: ErrorQuantiles,
    /// The contact sheet, relative to the output folder.
    pub contact_sheet: String,
    /// What each column of the contact sheet shows.
    pub contact_sheet_columns: Vec<String>,
    /// The reconstruction.
    pub reconstruction: ReconSummary,
}

impl DemoReport {
    /// Read a report written by [`DemoReport::write`].
    pub fn read(path: &Path) -> Result<Self> {
        Ok(read_json(path, "a demo report")?)
    }

    /// Write the report to `path` (JSON, atomically).
    pub fn write(&self, path: &Path) -> Result<()> {
        Ok(write_json(path, self)?)
    }
}

/// Run the demo into `options.output`; `announce` hears a line as each stage starts.
pub fn run_demo(options: &DemoOptions, announce: &mut dyn FnMut(&str)) -> Result<DemoReport> {
    let out = &options.output;
    let (width, height) = options.size;
    announce(&format!(
        "1/5 simulating a capture of spot: {DEMO_VIEWS} views at {width}x{height}, {} spp, with raw sensor frames",
        options.spp
    ));
    let truth = simulate(&SimulateOptions {
        output: out.join("simulated"),
        views: DEMO_VIEWS,
        size: options.size,
        spp: options.spp,
        raw: true,
        layouts: vec![Layout::Nersp],
        progress: options.progress,
        ..SimulateOptions::default()
    })?;

    announce("2/5 processing the raw frames (decode, demosaic, dark frame, Stokes, AoP, DoP)");
    let raw_dir = out.join("simulated").join(RAW_FOLDER);
    let sensor = SensorRecord::read(&raw_dir.join(SENSOR_FILE))?;
    let captured = process_raw_capture(&truth, &raw_dir, &sensor, options.progress)?;

    announce("3/5 writing the captured dataset (NeRSP layout) and validating it");
    let dataset_dir = out.join("captured");
    write_scene(&captured, &dataset_dir, Layout::Nersp)?;
    let reread = read_scene(&dataset_dir)?;

    announce("4/5 comparing the captured polarization with the rendered ground truth");
    let comparison = compare_polarization(&truth, &reread);
    png::write_png_u8(&out.join(CONTACT_SHEET), &contact_sheet(&comparison.tiles, 4))?;

    announce(&format!(
        "5/5 reconstructing the captured dataset (NeRSP, fast preset, {} iterations)",
        options.recon_iterations
    ));
    let recon_dir = out.join("recon");
    let recon_options = ReconOptions {
        iterations: Some(options.recon_iterations),
        mesh_resolution: options.mesh_resolution,
        ..ReconOptions::default()
    };
    let bar = progress_bar(options.progress, options.recon_iterations as u64, "recon");
    let started = std::time::Instant::now();
    reconstruct(&reread, &recon_dir, &recon_options, |_, trainer| {
        bar.set_position(trainer.iteration as u64);
        ControlFlow::Continue(())
    })?;
    bar.finish();
    let seconds = started.elapsed().as_secs_f64();
    let predicted = Mesh::read(&recon_dir.join(MESH))?;
    let true_mesh = truth.mesh.as_ref().expect("simulations have their mesh");
    let evaluation = evaluate(&predicted, true_mesh, Some(&truth), &SurfaceOptions::default())?;

    let report = DemoReport {
        simulated: SimulatedSummary {
            views: truth.views.len(),
            size: [width, height],
            spp: options.spp,
            layout: "simulated/nersp".into(),
        },
        raw_frames: sensor,
        captured_dataset: DatasetSummary {
            folder: "captured".into(),
            layout: Layout::Nersp.name().into(),
            views: reread.views.len(),
            valid: true,
        },
        aop_error_deg: ErrorQuantiles::of(&comparison.aop_errors_deg),
        s0_rel_error: ErrorQuantiles::of(&comparison.s0_rel_errors),
        contact_sheet: CONTACT_SHEET.into(),
        contact_sheet_columns: ["rendered S0", "captured S0", "captured AoP (hue) x DoP", "AoP error 0..10 deg"]
            .map(String::from)
            .to_vec(),
        reconstruction: ReconSummary {
            folder: "recon".into(),
            preset: recon_options.preset,
            iterations: options.recon_iterations,
            seconds,
            chamfer: evaluation.surface.chamfer,
            f_score: evaluation.surface.fscore,
            normal_mae_deg: evaluation.normal_mae_deg.expect("a scene was given"),
            comparison: "recon/comparison.png".into(),
        },
    };
    report.write(&out.join(REPORT_FILE))?;
    Ok(report)
}

/// Process the raw frames of a simulated capture (`DIR/<view>.raw`, `DIR/dark.raw`, as
/// [`crate::simulate`] writes them) into a scene with `truth`'s cameras and masks, and Stokes,
/// AoP and DoP from the frames, in the rendered light's units.
pub fn process_raw_capture(truth: &Scene, dir: &Path, sensor: &SensorRecord, progress: bool) -> Result<Scene> {
    let (width, height) = (sensor.width, sensor.height);
    let processor = FrameProcessor {
        dark: Some(RawFrame::read(&dir.join(DARK_FRAME), RAW_FORMAT, width, height)?),
        ..Default::default()
    };
    let mut captured = Scene { mesh: None, env_map: None, ..truth.clone() };
    let bar = progress_bar(progress, truth.views.len() as u64, "process");
    let gain = 1.0 / sensor.stokes_gain;
    for view in &mut captured.views {
        let frame = RawFrame::read(&dir.join(format!("{}.raw", view.name)), RAW_FORMAT, width, height)?;
        let processed = processor.process(&frame)?;
        let mut stokes = processed.estimate.stokes;
        for image in [&mut stokes.s0, &mut stokes.s1, &mut stokes.s2] {
            image.data_mut().iter_mut().for_each(|v| *v *= gain);
        }
        *view = View {
            aop: Some(processed.aop),
            dop: Some(processed.dop),
            stokes: Some(stokes),
            polarized: None,
            preview: None,
            normals: None,
            depth: None,
            ..view.clone()
        };
        bar.inc(1);
    }
    bar.finish();
    Ok(captured)
}

/// Captured polarization against the rendered truth.
pub struct PolarizationComparison {
    /// AoP errors in degrees over object pixels with DoP > [`AOP_MIN_DOP`].
    pub aop_errors_deg: Vec<f32>,
    /// Relative S0 errors (green) over object pixels with S0 > [`S0_MIN`].
    pub s0_rel_errors: Vec<f32>,
    /// Per view: rendered S0, captured S0, captured AoP x DoP, AoP error (0 to
    /// [`AOP_ERROR_MAP_MAX_DEG`]), each at most 256 pixels wide.
    pub tiles: Vec<Image<u8>>,
}

/// Compare the captured views' Stokes with the truth's, view by view (same names, same order).
pub fn compare_polarization(truth: &Scene, captured: &Scene) -> PolarizationComparison {
    let (mut aop_errors_deg, mut s0_rel_errors, mut tiles) = (Vec::new(), Vec::new(), Vec::new());
    for (t, c) in truth.views.iter().zip(&captured.views) {
        let (Some(ts), Some(cs), Some(mask)) = (&t.stokes, &c.stokes, &t.mask) else { continue };
        let ((taop, tdop), (caop, cdop)) = (ts.aop_dop(), cs.aop_dop());
        let mut error_map = Image::new(mask.width(), mask.height(), 1);
        for k in 0..mask.data().len() {
            if mask.data()[k] == 0 {
                continue;
            }
            if tdop.data()[k] > AOP_MIN_DOP {
                let e = aop_difference_deg(caop.data()[k], taop.data()[k]);
                aop_errors_deg.push(e);
                error_map.data_mut()[k] = e;
            }
            let (a, b) = (cs.s0.data()[3 * k + 1], ts.s0.data()[3 * k + 1]);
            if b > S0_MIN {
                s0_rel_errors.push((a - b).abs() / b);
            }
        }
        let factor = mask.width().div_ceil(256);
        tiles.extend(
            [
                preview(&ts.s0),
                preview(&cs.s0),
                aop_picture(&caop, &cdop, Some(mask)),
                gray_ramp(&error_map, 0.0, AOP_ERROR_MAP_MAX_DEG),
            ]
            .map(|tile| downsample(&tile, factor)),
        );
    }
    PolarizationComparison { aop_errors_deg, s0_rel_errors, tiles }
}

/// Smallest angle between two AoPs, in degrees (AoP is periodic in 180 degrees).
pub fn aop_difference_deg(a: f32, b: f32) -> f32 {
    let d = (a - b).rem_euclid(PI);
    d.min(PI - d).to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aop_differences_wrap_at_180_degrees() {
        assert!((aop_difference_deg(0.01, PI - 0.01) - 0.02f32.to_degrees()).abs() < 1e-3);
        assert!((aop_difference_deg(0.5, 0.2) - 0.3f32.to_degrees()).abs() < 1e-3);
    }

    #[test]
    fn reports_read_back_what_they_wrote() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(REPORT_FILE);
        let report = DemoReport {
            simulated: SimulatedSummary { views: 6, size: [612, 512], spp: 16, layout: "simulated/nersp".into() },
            raw_frames: SensorRecord::new(Default::default(), RAW_FORMAT, 1224, 1024),
            captured_dataset: DatasetSummary {
                folder: "captured".into(),
                layout: "nersp".into(),
                views: 6,
                valid: true,
            },
            aop_error_deg: ErrorQuantiles { median: 2.6, p90: 7.5, pixels: 1234 },
            s0_rel_error: ErrorQuantiles { median: 0.01, p90: 0.03, pixels: 2345 },
            contact_sheet: CONTACT_SHEET.into(),
            contact_sheet_columns: vec!["a".into(), "b".into()],
            reconstruction: ReconSummary {
                folder: "recon".into(),
                preset: Preset::Fast,
                iterations: 1000,
                seconds: 490.5,
                chamfer: 0.0132,
                f_score: 0.908,
                normal_mae_deg: 5.8,
                comparison: "recon/comparison.png".into(),
            },
        };
        report.write(&path).unwrap();
        assert_eq!(DemoReport::read(&path).unwrap(), report);
        std::fs::write(&path, "{}").unwrap();
        let err = DemoReport::read(&path).unwrap_err().to_string();
        assert!(err.contains(REPORT_FILE) && err.contains("not a demo report"), "{err}");
    }
}
