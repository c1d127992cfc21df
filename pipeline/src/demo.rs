//! The pipeline on its built-in example, end to end, through the stages a lab runs:
//!
//! 1. Capture: the built-in "spot" on the simulated turntable, six views through the simulated
//!    GenICam camera (the BFS-U3-51S5PC-C's 2448x2048 polarized raw frames over GigE Vision on
//!    loopback) into a capture session ([`rmvp_capture::session::capture`]: dark frames,
//!    demosaicing, Stokes, AoP, DoP).
//! 2. Ground truth: the camera's own noise-free renderings and the object's geometry per view,
//!    in the NeRSP layout (`simulated/`).
//! 3. Poses and masks: the rig's cameras imported from that layout's `cameras.npz`
//!    ([`rmvp_calib::poses::pose_session`]), masks from the object's mesh
//!    ([`rmvp_calib::masks::make_masks`]).
//! 4. Dataset: `rmvp dataset build` on the posed, masked session ([`build_dataset`]),
//!    published as a release (`release/`: card, Croissant, DataCite and Zenodo metadata,
//!    checksums; [`crate::publish`]).
//! 5. Report: the dataset's polarization against the rendered ground truth, as numbers
//!    ([`DemoReport`], `report.json`) and pictures (`contact_sheet.png`).
//! 6. Reconstruction: NeRSP (fast preset) on the dataset, evaluated against the true mesh and
//!    normals.

use crate::build::{build_dataset, BuildOptions, BuildRecord, TrainViews, DATASET_LAYOUTS};
use crate::publish::metadata::{Creator, ReleaseInfo};
use crate::publish::{publish, PublishOptions};
use crate::report;
use crate::simulate::NORMALIZATION_MARGIN;
use crate::{Error, Result};
use rmvp_align::{evaluate, SurfaceOptions};
use rmvp_calib::masks::{make_masks, MaskMethod, MaskOptions, MASKS_FOLDER};
use rmvp_calib::poses::{pose_session, PoseRequest, POSES_FILE};
use rmvp_capture::camera::CameraDevice;
use rmvp_capture::session::positioning::Positioning;
use rmvp_capture::session::{capture, SessionOptions, SessionReport};
use rmvp_capture::simulator::{SimulatedCamera, SimulatedScene, SimulatorOptions};
use rmvp_dataset::io::atomic::write_bytes_atomically;
use rmvp_dataset::io::json::{read_json, write_json};
use rmvp_dataset::io::png;
use rmvp_dataset::layout::{nersp, read_scene, write_scene, Layout};
use rmvp_dataset::polarization;
use rmvp_dataset::progress::progress_bar;
use rmvp_dataset::session::{SessionManifest, StokesUnit};
use rmvp_dataset::visualize::{aop_picture, contact_sheet, downsample, gray_ramp, preview, quantile};
use rmvp_dataset::{Image, Mesh, Scene, Split, View};
use rmvp_recon::options::{ReconOptions, RunControl};
use rmvp_recon::presets::Preset;
use rmvp_recon::reconstruct::{reconstruct, MESH};
use rmvp_render::envmap::procedural_image;
use serde::{Deserialize, Serialize};
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

/// What the demo runs; [`DemoOptions::default`] holds every default of `rmvp demo`.
#[derive(Clone, Debug, PartialEq)]
pub struct DemoOptions {
    /// Output folder.
    pub output: PathBuf,
    /// Samples per pixel of the simulated camera's renderer.
    pub spp: u32,
    /// Training iterations of the reconstruction (fast preset; default: the preset's).
    pub recon_iterations: u32,
    /// Marching grid cells per axis of the reconstructed mesh.
    pub mesh_resolution: usize,
    /// Render the reconstruction's normal maps and Stokes in every view (off: the mesh only).
    pub view_outputs: bool,
    /// Show progress bars.
    pub progress: bool,
}

impl Default for DemoOptions {
    fn default() -> Self {
        Self {
            output: PathBuf::from("demo-out"),
            spp: 16,
            recon_iterations: Preset::Fast.default_iterations(),
            mesh_resolution: 192,
            view_outputs: true,
            progress: true,
        }
    }
}

/// Views the demo captures (all of them train, as NeRSP's sparse split does).
pub const DEMO_VIEWS: usize = 6;
/// The captured object's name.
pub const DEMO_OBJECT: &str = "spot";
/// Dark frames averaged at the start of the session (the simulated rig's lens cap).
pub const DEMO_DARK_FRAMES: usize = 4;
/// S0 is compared where the rendered S0 (green) is at least this bright.
pub const S0_MIN: f32 = 0.05;
/// AoP errors above this many degrees are white in the contact sheet.
pub const AOP_ERROR_MAP_MAX_DEG: f32 = 10.0;
/// The report's file name.
pub const REPORT_FILE: &str = "report.json";
/// The contact sheet's file name.
pub const CONTACT_SHEET: &str = "contact_sheet.png";
/// The capture session's folder.
pub const SESSION_FOLDER: &str = "session";
/// The ground truth's folder (NeRSP layout).
pub const TRUTH_FOLDER: &str = "simulated";
/// The dataset's folder.
pub const DATASET_FOLDER: &str = "dataset";
/// The reconstruction's folder.
pub const RECON_FOLDER: &str = "recon";
/// The release's folder.
pub const RELEASE_FOLDER: &str = "release";

/// Who publishes the demo's release and under what licence: the data is rendered from Keenan
/// Crane's public-domain "spot", so it is public domain too.
pub fn demo_release_info() -> ReleaseInfo {
    ReleaseInfo {
        title: Some("rmvp demo: spot on the simulated turntable".into()),
        license: Some("CC0-1.0".into()),
        description: Some(
            "The built-in example of rmvp: Keenan Crane's spot (public domain) on a simulated turntable, \
             captured through the simulated BFS-U3-51S5PC-C polarization camera, posed, masked and built \
             into a dataset with its ground truth."
                .into(),
        ),
        publisher: Some("rmvp".into()),
        creators: vec![Creator { name: "rmvp demo".into(), affiliation: None, orcid: None }],
        ..ReleaseInfo::default()
    }
}

/// The capture session the demo made.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CaptureSummary {
    /// Its folder, relative to the output folder.
    pub folder: String,
    /// The camera, as it named itself over GenICam.
    pub camera: String,
    /// The pixel format it streamed.
    pub pixel_format: String,
    /// Raw frame size.
    pub raw_size: [usize; 2],
    /// Views captured.
    pub views: usize,
    /// Dark frames averaged.
    pub dark_frames: usize,
    /// Frames the stream lost and the session grabbed again.
    pub dropped_frames: usize,
    /// Samples per pixel of the simulated camera's renderer.
    pub spp: u32,
    /// Processed Stokes per unit of rendered Stokes (exposure x gain): the session's Stokes are
    /// divided by it before they are compared with the ground truth.
    pub stokes_gain: f32,
}

/// The dataset built from the session.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DatasetSummary {
    /// Its folder, relative to the output folder.
    pub folder: String,
    /// The layouts in it.
    pub layouts: Vec<String>,
    /// Views it holds.
    pub views: usize,
    /// Its training views.
    pub train: Vec<String>,
    /// Whether its build record says complete.
    pub complete: bool,
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
    /// The input-against-rendered picture, relative to the output folder (none when the
    /// views were not rendered).
    pub comparison: Option<String>,
}

/// Everything the demo measured (`report.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DemoReport {
    /// The capture session.
    pub capture: CaptureSummary,
    /// The ground truth's folder (NeRSP layout), relative to the output folder.
    pub ground_truth: String,
    /// The dataset.
    pub dataset: DatasetSummary,
    /// The dataset's release folder, relative to the output folder.
    #[serde(default)]
    pub release: String,
    /// The dataset's AoP against the rendered AoP, degrees (where DoP > [`AOP_MIN_DOP`](polarization::AOP_MIN_DOP)).
    pub aop_error_deg: ErrorQuantiles,
    /// The dataset's S0 against the rendered S0, relative (where S0 > [`S0_MIN`]).
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
    remove_previous_demo(out)?;
    let session = out.join(SESSION_FOLDER);
    announce(&format!(
        "1/6 capturing {DEMO_OBJECT} on the simulated turntable: {DEMO_VIEWS} views through the simulated GenICam camera ({} spp)",
        options.spp
    ));
    let config = SimulatorOptions { views: DEMO_VIEWS, spp: options.spp, ..SimulatorOptions::default() };
    let simulator = SimulatedCamera::start(&config)?;
    let captured = capture_session(&simulator, &session, options.progress)?;
    let manifest = SessionManifest::read(&session)?;

    announce("2/6 ground truth: the camera's noise-free renderings and the object's geometry (NeRSP layout)");
    let names: Vec<String> = manifest.views.iter().map(|v| v.name.clone()).collect();
    let truth = truth_scene(&simulator, &names);
    drop(simulator);
    let truth_dir = out.join(TRUTH_FOLDER);
    write_scene(&truth, &truth_dir, Layout::Nersp)?;

    announce("3/6 poses (the rig's cameras, imported) and masks (from the object's mesh)");
    let source = truth_dir.join(nersp::CAMERAS);
    pose_session(&session, &PoseRequest::Import { source, min_views: DEMO_VIEWS }, &session.join(POSES_FILE))?;
    let masks =
        MaskOptions { method: MaskMethod::Mesh, mesh: Some(truth_dir.join(nersp::GT_MESH)), ..MaskOptions::default() };
    make_masks(&session, &masks, &session.join(MASKS_FOLDER))?;

    announce("4/6 building the dataset from the posed, masked session (NeRSP and rmvp layouts), publishing it");
    let dataset_dir = out.join(DATASET_FOLDER);
    let record = build_dataset(&BuildOptions {
        session: session.clone(),
        output: dataset_dir.clone(),
        train: TrainViews::Count(DEMO_VIEWS),
        progress: options.progress,
        ..BuildOptions::default()
    })?;
    publish(&PublishOptions {
        datasets: vec![dataset_dir.clone()],
        output: out.join(RELEASE_FOLDER),
        info: demo_release_info(),
        archive: None,
        progress: options.progress,
    })?;
    let dataset = read_scene(&dataset_dir.join(Layout::Nersp.name()))?;

    announce("5/6 comparing the dataset's polarization with the rendered ground truth");
    let stokes_gain = stokes_gain(&session, &manifest)?;
    let comparison = compare_polarization(&truth, &dataset, stokes_gain);
    png::write_png_u8(&out.join(CONTACT_SHEET), &contact_sheet(&comparison.tiles, 4))?;

    announce(&format!("6/6 reconstructing the dataset (NeRSP, fast preset, {} iterations)", options.recon_iterations));
    let reconstruction = reconstruct_and_evaluate(dataset, &truth, &out.join(RECON_FOLDER), options)?;

    let report = DemoReport {
        capture: CaptureSummary {
            folder: SESSION_FOLDER.into(),
            camera: format!("{} {}", manifest.camera.identity.vendor, manifest.camera.identity.model),
            pixel_format: manifest.camera.pixel_format.clone(),
            raw_size: [manifest.camera.width, manifest.camera.height],
            views: captured.views_complete,
            dark_frames: manifest.settings.dark_frames,
            dropped_frames: captured.dropped_frames,
            spp: options.spp,
            stokes_gain,
        },
        ground_truth: TRUTH_FOLDER.into(),
        dataset: dataset_summary(&record),
        release: RELEASE_FOLDER.into(),
        aop_error_deg: ErrorQuantiles::of(&comparison.aop_errors_deg),
        s0_rel_error: ErrorQuantiles::of(&comparison.s0_rel_errors),
        contact_sheet: CONTACT_SHEET.into(),
        contact_sheet_columns: ["rendered S0", "captured S0", "captured AoP (hue) x DoP", "AoP error 0..10 deg"]
            .map(String::from)
            .to_vec(),
        reconstruction,
    };
    report.write(&out.join(REPORT_FILE))?;
    Ok(report)
}

/// The files and folders a demo writes into its output folder.
const DEMO_OUTPUTS: [&str; 7] =
    [SESSION_FOLDER, TRUTH_FOLDER, DATASET_FOLDER, RELEASE_FOLDER, RECON_FOLDER, REPORT_FILE, CONTACT_SHEET];

/// Remove what an earlier demo wrote into `out` (and nothing else), so that the demo runs again
/// from the start: a capture session or a dataset build would refuse a folder that is there.
fn remove_previous_demo(out: &Path) -> Result<()> {
    for path in DEMO_OUTPUTS.map(|name| out.join(name)) {
        let removed = if path.is_dir() { std::fs::remove_dir_all(&path) } else { std::fs::remove_file(&path) };
        match removed {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(rmvp_dataset::Error::io(&path, e).into()),
            _ => {}
        }
    }
    Ok(())
}

/// Capture the simulated camera's turntable views into `dir`, as `rmvp capture --simulated
/// --dark 4` would.
fn capture_session(simulator: &SimulatedCamera, dir: &Path, progress: bool) -> Result<SessionReport> {
    let mut camera = CameraDevice::open(Some(&simulator.address.to_string()))?;
    let options = SessionOptions {
        object: DEMO_OBJECT.into(),
        views: DEMO_VIEWS,
        dir: dir.to_path_buf(),
        dark_frames: DEMO_DARK_FRAMES,
        positioning: Positioning::default_for(&camera),
        progress,
        ..SessionOptions::default()
    };
    Ok(capture(&mut camera, &options)?)
}

/// The ground truth of the simulated camera's views, named `names` (the session's): its
/// noise-free rendering, mask, depth and normals; the object's mesh and the environment.
fn truth_scene(simulator: &SimulatedCamera, names: &[String]) -> Scene {
    let simulated = simulator.scene();
    let subject = simulated.subject.clone().expect("the turntable holds an object");
    let mut scene = Scene::new();
    for (i, name) in names.iter().enumerate() {
        let maps = simulated.geometry(i);
        let mut view = View::new(name.clone(), Split::Train, simulated.cameras[i].clone());
        view.stokes = Some(simulator.rendered(i).as_ref().clone());
        (view.mask, view.depth, view.normals) = (Some(maps.mask), Some(maps.depth), Some(maps.normals));
        scene.views.push(view);
    }
    scene.normalization = nalgebra::Matrix4::new_scaling(NORMALIZATION_MARGIN * subject.radius() as f64);
    scene.mesh = Some(subject);
    scene.env_map = Some(procedural_image());
    scene
}

/// Processed Stokes per unit of rendered Stokes in the simulated camera's session `dir`.
fn stokes_gain(dir: &Path, manifest: &SessionManifest) -> Result<f32> {
    match &manifest.settings.stokes_unit {
        StokesUnit::FullScale { bits, exposure_us, gain_db } => {
            Ok(SimulatedScene::sensor(*exposure_us, *gain_db, *bits).stokes_gain())
        }
        other => Err(Error::Folder { path: dir.to_path_buf(), why: format!("Stokes in {other}, not one exposure's") }),
    }
}

/// The dataset's summary from its build record.
fn dataset_summary(record: &BuildRecord) -> DatasetSummary {
    DatasetSummary {
        folder: DATASET_FOLDER.into(),
        layouts: DATASET_LAYOUTS.map(|l| l.name().to_string()).to_vec(),
        views: record.views.len(),
        train: record.train.clone(),
        complete: record.complete,
    }
}

/// Reconstruct `dataset` into `dir` and evaluate the mesh against `truth`.
fn reconstruct_and_evaluate(
    mut dataset: Scene,
    truth: &Scene,
    dir: &Path,
    options: &DemoOptions,
) -> Result<ReconSummary> {
    let recon_options = ReconOptions {
        iters: Some(options.recon_iterations),
        mesh_res: options.mesh_resolution,
        mesh_only: !options.view_outputs,
        ..ReconOptions::default()
    };
    let bar = progress_bar(options.progress, options.recon_iterations as u64, "recon");
    // The truth's normals beside the dataset's views: training tracks its normal error.
    for view in &mut dataset.views {
        view.normals = truth.view(&view.name).and_then(|t| t.normals.clone());
    }
    let started = std::time::Instant::now();
    reconstruct(&dataset, dir, &recon_options, RunControl::default(), |_, trainer| {
        bar.set_position(trainer.iteration as u64);
        ControlFlow::Continue(())
    })?;
    bar.finish();
    let seconds = started.elapsed().as_secs_f64();
    let predicted = Mesh::read(&dir.join(MESH))?;
    let true_mesh = truth.mesh.as_ref().expect("the truth has its mesh");
    let evaluation = evaluate(&predicted, true_mesh, Some(truth), &SurfaceOptions::default())?;
    write_bytes_atomically(&dir.join(report::EVALUATION), evaluation.to_json().as_bytes())?;
    evaluation.write_error_maps(&dir.join(report::ERROR_MAPS))?;
    report::write_recon_report(dir, Some(truth))?;
    Ok(ReconSummary {
        folder: RECON_FOLDER.into(),
        preset: recon_options.preset,
        iterations: options.recon_iterations,
        seconds,
        chamfer: evaluation.surface.chamfer,
        f_score: evaluation.surface.fscore,
        normal_mae_deg: evaluation.normal_mae_deg.expect("a scene was given"),
        comparison: options.view_outputs.then(|| format!("{RECON_FOLDER}/comparison.png")),
    })
}

/// Captured polarization against the rendered truth.
pub struct PolarizationComparison {
    /// AoP errors in degrees over object pixels with DoP > [`AOP_MIN_DOP`](polarization::AOP_MIN_DOP).
    pub aop_errors_deg: Vec<f32>,
    /// Relative S0 errors (green) over object pixels with S0 > [`S0_MIN`].
    pub s0_rel_errors: Vec<f32>,
    /// Per view: rendered S0, captured S0, captured AoP x DoP, AoP error (0 to
    /// [`AOP_ERROR_MAP_MAX_DEG`]), each at most 256 pixels wide.
    pub tiles: Vec<Image<u8>>,
}

/// Compare the captured views' Stokes, divided by `stokes_gain`, with the truth's, view by view
/// (same order).
pub fn compare_polarization(truth: &Scene, captured: &Scene, stokes_gain: f32) -> PolarizationComparison {
    let (mut aop_errors_deg, mut s0_rel_errors, mut tiles) = (Vec::new(), Vec::new(), Vec::new());
    for (t, c) in truth.views.iter().zip(&captured.views) {
        let (Some(ts), Some(cs), Some(mask)) = (&t.stokes, &c.stokes, &t.mask) else { continue };
        let ((taop, tdop), (caop, cdop)) = (ts.aop_dop(), cs.aop_dop());
        let mut error_map = Image::new(mask.width(), mask.height(), 1);
        for k in 0..mask.data().len() {
            if mask.data()[k] == 0 {
                continue;
            }
            if tdop.data()[k] > polarization::AOP_MIN_DOP {
                let e = polarization::aop_difference_deg(caop.data()[k], taop.data()[k]);
                aop_errors_deg.push(e);
                error_map.data_mut()[k] = e;
            }
            let (a, b) = (cs.s0.data()[3 * k + 1] / stokes_gain, ts.s0.data()[3 * k + 1]);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reports_read_back_what_they_wrote() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(REPORT_FILE);
        let report = DemoReport {
            capture: CaptureSummary {
                folder: SESSION_FOLDER.into(),
                camera: "rmvp Simulated BFS-U3-51S5PC-C".into(),
                pixel_format: "BayerRGPolarized12p".into(),
                raw_size: [2448, 2048],
                views: 6,
                dark_frames: 4,
                dropped_frames: 0,
                spp: 16,
                stokes_gain: 0.5,
            },
            ground_truth: TRUTH_FOLDER.into(),
            dataset: DatasetSummary {
                folder: DATASET_FOLDER.into(),
                layouts: vec!["nersp".into(), "rmvp".into()],
                views: 6,
                train: vec!["000".into(), "001".into()],
                complete: true,
            },
            release: RELEASE_FOLDER.into(),
            aop_error_deg: ErrorQuantiles { median: 2.6, p90: 7.5, pixels: 1234 },
            s0_rel_error: ErrorQuantiles { median: 0.01, p90: 0.03, pixels: 2345 },
            contact_sheet: CONTACT_SHEET.into(),
            contact_sheet_columns: vec!["a".into(), "b".into()],
            reconstruction: ReconSummary {
                folder: RECON_FOLDER.into(),
                preset: Preset::Fast,
                iterations: 1000,
                seconds: 490.5,
                chamfer: 0.0132,
                f_score: 0.908,
                normal_mae_deg: 5.8,
                comparison: Some("recon/comparison.png".into()),
            },
        };
        report.write(&path).unwrap();
        assert_eq!(DemoReport::read(&path).unwrap(), report);
        std::fs::write(&path, "{}").unwrap();
        let err = DemoReport::read(&path).unwrap_err().to_string();
        assert!(err.contains(REPORT_FILE) && err.contains("not a demo report"), "{err}");
    }
}
