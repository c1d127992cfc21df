//! Datasets from posed, masked capture sessions (`rmvp dataset build`), in stages that a build
//! can resume:
//!
//! 1. `views`: every view with a pose and a mask, lens distortion removed, a sparse training
//!    split spread over the viewing directions, the normalisation from the visual hull;
//! 2. `reference` (with a scan): a reference shape reconstructed from all views (the dense
//!    preset of `rmvp recon`; resumes from its checkpoint);
//! 3. `scan`: the laser scan (millimetres, any pose) aligned onto the reference by ICP with
//!    scale, its units checked where the world is metric;
//! 4. `ground-truth`: the aligned scan as the dataset's mesh; per view, normals and depth ray
//!    cast from it (the ground-truth silhouette is where the depth is positive);
//! 5. `environment` (with a panorama): the panorama turned into the world frame
//!    ([`crate::panorama`]);
//! 6. `layouts`: the NeRSP layout (what the official loader reads) and ours, each written
//!    beside its final place and moved there whole; the build's page (`report.html`).
//!
//! `build.json` (a [`BuildRecord`]) is rewritten after every stage and says `complete` last.
//!
//! ```text
//! DATASET/build.json        what was built from what, stage times, residuals
//! DATASET/nersp/            the NeRSP layout (training views in cameras.npz, every view in gt/)
//! DATASET/rmvp/             our layout
//! DATASET/report.html       the datasheet, the truth in 3D with the cameras, the views
//! DATASET/work/reference/   the reference reconstruction (checkpoint, mesh.ply)
//! DATASET/work/scan/        alignment.json, aligned.ply (the scan in the world frame)
//! ```

pub mod record;

pub use record::*;

use crate::ground_truth::set_ground_truth;
use crate::panorama::{read_panorama, to_world, world_to_panorama};
use crate::report::{write_dataset_report, DatasetObject};
use crate::{Error, Result};
#[cfg(test)]
use nalgebra::Rotation3;
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use rmvp_align::icp::{align, ALIGNED_MESH, ALIGNMENT_FILE};
use rmvp_align::IcpOptions;
use rmvp_calib::board::board_to_y_up;
use rmvp_calib::intrinsics::CameraCalibration;
use rmvp_calib::masks::MASKS_FOLDER;
use rmvp_calib::poses::charuco::BOARD_WORLD;
use rmvp_calib::poses::{PoseSet, POSES_FILE};
use rmvp_calib::scene::posed_scene;
use rmvp_calib::undistort::undistort_view;
use rmvp_dataset::layout::{write_scene, Layout};
use rmvp_dataset::progress::progress_bar;
use rmvp_dataset::session::SessionManifest;
use rmvp_dataset::{Camera, Image, Mesh, Scene, Split};
use rmvp_recon::options::RunControl;
use rmvp_recon::reconstruct::{reconstruct, MESH};
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The layouts every dataset holds, each in the folder named after it.
pub const DATASET_LAYOUTS: [Layout; 2] = [Layout::Nersp, Layout::Rmvp];
/// The reference reconstruction's folder.
pub const REFERENCE_FOLDER: &str = "work/reference";
/// The scan alignment's folder (`alignment.json`, `aligned.ply`).
pub const SCAN_FOLDER: &str = "work/scan";
/// A scan whose ICP scale is this far (relative) from its stated units' is refused.
pub const SCAN_SCALE_TOLERANCE: f64 = 0.05;
/// A scan whose median distance to the reference exceeds this share of the reference's size
/// (bounding-box diagonal) after alignment is refused.
pub const SCAN_MAX_MEDIAN_DISTANCE: f64 = 0.01;

/// `count` of `cameras` (name, camera) spread over the directions from which they see
/// `centre`: farthest-point sampling on the unit sphere, from the camera nearest the mean
/// direction. Names in capture order.
pub fn spread_views(cameras: &[(String, Camera)], centre: &Vector3<f64>, count: usize) -> Vec<String> {
    let directions: Vec<Vector3<f64>> = cameras.iter().map(|(_, c)| (c.center().coords - centre).normalize()).collect();
    let mean = directions.iter().sum::<Vector3<f64>>();
    let mut chosen = Vec::new();
    if let Some(first) =
        (0..directions.len()).max_by(|&a, &b| directions[a].dot(&mean).total_cmp(&directions[b].dot(&mean)))
    {
        chosen.push(first);
    }
    while chosen.len() < count.min(directions.len()) {
        let far = (0..directions.len())
            .filter(|i| !chosen.contains(i))
            .max_by(|&a, &b| {
                let gap = |i: usize| {
                    chosen.iter().map(|&c| directions[i].dot(&directions[c])).fold(f64::NEG_INFINITY, f64::max)
                };
                gap(b).total_cmp(&gap(a))
            })
            .expect("views left");
        chosen.push(far);
    }
    chosen.sort_unstable();
    chosen.into_iter().map(|i| cameras[i].0.clone()).collect()
}

/// Whether poses put the world in millimetres (a board's frame, or a rig calibrated on one).
fn world_in_millimetres(poses: &PoseSet) -> bool {
    poses.world.contains(BOARD_WORLD)
}

/// The record to continue, or a new one; refuses a folder that holds something else.
fn start(options: &BuildOptions) -> Result<Option<BuildRecord>> {
    let out = &options.output;
    let folder = |why: String| Error::Folder { path: out.clone(), why };
    if out.join(BUILD_FILE).is_file() {
        let record = BuildRecord::read(out)?;
        if !options.resume {
            let done: Vec<String> = record.stages.iter().map(|s| s.name.to_string()).collect();
            return Err(if record.complete {
                folder("a complete dataset is here already; remove it or build into another folder".into())
            } else {
                Error::BuildUnfinished { path: out.clone(), done: done.join(", ") }
            });
        }
        let changed: Vec<String> =
            rmvp_dataset::io::json::differences(&record.options, options).into_iter().map(|(_, c)| c).collect();
        if !changed.is_empty() {
            return Err(Error::BuildOptionsChanged { path: out.clone(), changed: changed.join(", ") });
        }
        return Ok(Some(record));
    }
    if out.read_dir().is_ok_and(|mut d| d.next().is_some()) {
        return Err(folder(format!("not empty and has no {BUILD_FILE}: not a dataset build")));
    }
    Ok(None)
}

/// Build the dataset of `options` (or continue it) and return its record.
pub fn build_dataset(options: &BuildOptions) -> Result<BuildRecord> {
    let session = &options.session;
    if !session.join(rmvp_dataset::session::SESSION_FILE).is_file() {
        if let Ok(layout) = Layout::detect(session) {
            return Err(Error::SceneNotSession { path: session.clone(), layout: layout.name() });
        }
    }
    if !session.join(POSES_FILE).is_file() {
        return Err(Error::Unprepared { session: session.clone(), missing: "camera poses (poses.json)" });
    }
    if !session.join(MASKS_FOLDER).is_dir() {
        return Err(Error::Unprepared { session: session.clone(), missing: "object masks (masks/)" });
    }
    let previous = start(options)?;
    if let Some(record) = previous.as_ref().filter(|r| r.complete) {
        return Ok(record.clone());
    }
    // Inputs are checked before any work: a wrong panorama fails now, not after an hour.
    let panorama = options.panorama.as_ref().map(|p| read_panorama(&p.path).map(|image| (p, image))).transpose()?;
    if let Some(scan) = options.scan.as_ref().filter(|s| !s.path.is_file()) {
        return Err(Error::Scan { path: scan.path.clone(), why: "no such file".into() });
    }
    std::fs::create_dir_all(&options.output).map_err(|e| rmvp_dataset::Error::io(&options.output, e))?;

    let mut build = Build::views(options, previous)?;
    if let Some(scan) = &options.scan {
        build.reference()?;
        build.align(scan)?;
        build.ground_truth()?;
    }
    if let Some((input, panorama)) = &panorama {
        build.environment(input, panorama)?;
    }
    build.layouts()
}

/// A build under way: what each stage needs from those before it.
struct Build<'a> {
    options: &'a BuildOptions,
    record: BuildRecord,
    poses: PoseSet,
    scene: Scene,
}

impl<'a> Build<'a> {
    /// Stage [`Stage::Views`]: the session's posed, masked views, split into training and
    /// evaluation views and undistorted; the record started (or `previous` continued).
    fn views(options: &'a BuildOptions, previous: Option<BuildRecord>) -> Result<Self> {
        let clock = Instant::now();
        let session = &options.session;
        let manifest = SessionManifest::read(session)?;
        manifest.require_views(session)?;
        let poses = PoseSet::read(&session.join(POSES_FILE))?;
        let cameras: Vec<(String, Camera)> =
            poses.views.iter().filter_map(|v| Some((v.name.clone(), Camera::try_from(&v.camera).ok()?))).collect();
        // The split needs the object's centre: a first scene (all views evaluation) gives it.
        let mut scene = posed_scene(session, &poses, None, &[])?;
        let centre = scene.normalization.fixed_view::<3, 1>(0, 3).into_owned();
        let train = match &options.train {
            TrainViews::Count(n) => spread_views(&cameras, &centre, *n),
            TrainViews::Names(names) => names.clone(),
        };
        for view in &mut scene.views {
            view.split = if train.contains(&view.name) { Split::Train } else { Split::Eval };
        }
        let missing: Vec<&String> = train.iter().filter(|t| scene.view(t).is_none()).collect();
        if !missing.is_empty() {
            return Err(Error::Folder {
                path: session.clone(),
                why: format!("training views {missing:?} are not posed and masked views of the session"),
            });
        }
        scene.views = scene.views.par_iter().map(undistort_view).collect();
        // Training views first, as the layouts number them.
        scene.views.sort_by_key(|v| v.split != Split::Train);
        scene.metadata.insert("train".into(), serde_json::to_value(&train).expect("plain"));
        let residuals: Vec<f64> = poses.views.iter().filter_map(|v| v.residual_px).collect();
        let calibration = options
            .calibration
            .as_ref()
            .map(|path| -> Result<CalibrationSummary> {
                let c = CameraCalibration::read(path)?;
                Ok(CalibrationSummary { rms_px: c.rms_px, k_std_px: c.k_std_px, images: c.images.len() })
            })
            .transpose()?;
        let first = &scene.views[0].camera;
        let mut record = previous.unwrap_or_else(|| BuildRecord {
            format: BUILD_FORMAT.into(),
            options: options.clone(),
            object: manifest.object.clone(),
            camera: serde_json::to_value(&manifest.camera).expect("plain"),
            settings: serde_json::to_value(&manifest.settings).expect("plain"),
            views: Vec::new(),
            train: Vec::new(),
            size: [first.width, first.height],
            poses: PoseSummary {
                method: serde_json::to_value(poses.method).expect("plain"),
                world: poses.world.clone(),
                residual_px_mean: (!residuals.is_empty())
                    .then(|| residuals.iter().sum::<f64>() / residuals.len() as f64),
                residual_px_max: residuals.iter().copied().reduce(f64::max),
                failed: poses.failed.iter().map(|f| f.name.clone()).collect(),
            },
            calibration,
            reference: None,
            scan: None,
            environment: None,
            stages: Vec::new(),
            complete: false,
        });
        record.views = scene.views.iter().map(|v| v.name.clone()).collect();
        record.train = train;
        let mut build = Build { options, record, poses, scene };
        build.finish(Stage::Views, clock)?;
        Ok(build)
    }

    /// Stage [`Stage::Reference`]: the reference shape from all views (resumed from its
    /// checkpoint when the build is).
    fn reference(&mut self) -> Result<()> {
        if self.record.done(Stage::Reference) {
            return Ok(());
        }
        let (clock, options) = (Instant::now(), self.options);
        let mut everything = self.scene.clone();
        for view in &mut everything.views {
            view.split = Split::Train;
        }
        let control = RunControl { resume: options.resume, stop_after: None };
        let iterations = options.reference.iterations();
        let bar = progress_bar(options.progress, iterations as u64, "reference");
        let folder = options.output.join(REFERENCE_FOLDER);
        reconstruct(&everything, &folder, &options.reference, control, |report, _| {
            bar.set_position(report.iteration as u64 + 1);
            ControlFlow::Continue(())
        })?;
        bar.finish();
        self.record.reference = Some(ReferenceSummary {
            preset: options.reference.preset,
            iterations,
            views: everything.views.len(),
            mesh_resolution: options.reference.mesh_res,
        });
        self.finish(Stage::Reference, clock)
    }

    /// Stage [`Stage::Scan`]: the scan aligned onto the reference shape.
    fn align(&mut self, scan: &ScanInput) -> Result<()> {
        if self.record.done(Stage::Scan) {
            return Ok(());
        }
        let clock = Instant::now();
        let reference = Mesh::read(&self.options.output.join(REFERENCE_FOLDER).join(MESH))?;
        let folder = self.options.output.join(SCAN_FOLDER);
        self.record.scan = Some(align_scan(scan, &reference, world_in_millimetres(&self.poses), &folder)?);
        self.finish(Stage::Scan, clock)
    }

    /// Stage [`Stage::GroundTruth`]: mesh, normals and depth of every view from the aligned
    /// scan, and how well the captured masks agree with its silhouettes.
    fn ground_truth(&mut self) -> Result<()> {
        let clock = Instant::now();
        let aligned = Mesh::read(&self.options.output.join(SCAN_FOLDER).join(ALIGNED_MESH))?;
        let ious = set_ground_truth(&mut self.scene, &aligned)?;
        let summary = self.record.scan.as_mut().expect("the scan stage is done");
        summary.mask_iou_mean = ious.iter().map(|(iou, _)| iou).sum::<f64>() / ious.len().max(1) as f64;
        summary.mask_iou_min = ious.iter().cloned().min_by(|a, b| a.0.total_cmp(&b.0)).unwrap_or((1.0, String::new()));
        self.scene.metadata.insert("scan_alignment".into(), serde_json::to_value(&*summary).expect("plain"));
        self.finish(Stage::GroundTruth, clock)
    }

    /// Stage [`Stage::Environment`]: the panorama turned into the world frame.
    fn environment(&mut self, input: &PanoramaInput, panorama: &Image<f32>) -> Result<()> {
        let clock = Instant::now();
        let base = if world_in_millimetres(&self.poses) { board_to_y_up() } else { Matrix3::identity() };
        let rotation = world_to_panorama(&base, input.yaw_deg);
        self.scene.env_map = Some(to_world(panorama, &rotation)?);
        let summary = EnvironmentSummary {
            file: input.path.clone(),
            size: [panorama.width(), panorama.height()],
            world_to_panorama: [0, 1, 2].map(|r| [0, 1, 2].map(|c| rotation[(r, c)])),
            convention: ENV_CONVENTION.into(),
        };
        self.scene.metadata.insert("environment".into(), serde_json::to_value(&summary).expect("plain"));
        self.record.environment = Some(summary);
        self.finish(Stage::Environment, clock)
    }

    /// Stage [`Stage::Layouts`]: both layouts, each written aside and moved into place whole;
    /// the build complete.
    fn layouts(mut self) -> Result<BuildRecord> {
        let clock = Instant::now();
        let out = &self.options.output;
        for layout in DATASET_LAYOUTS {
            let (final_dir, partial) = (out.join(layout.name()), out.join(format!("{}.partial", layout.name())));
            for dir in [&final_dir, &partial] {
                if dir.exists() {
                    std::fs::remove_dir_all(dir).map_err(|e| rmvp_dataset::Error::io(dir, e))?;
                }
            }
            write_scene(&self.scene, &partial, layout)?;
            std::fs::rename(&partial, &final_dir).map_err(|e| rmvp_dataset::Error::io(&final_dir, e))?;
        }
        self.record.complete = true;
        write_build_page(&self.options.output, &self.record, &self.scene)?;
        self.finish(Stage::Layouts, clock)?;
        Ok(self.record)
    }

    /// Record `stage` as finished (its time, that of this run) in `build.json`.
    fn finish(&mut self, stage: Stage, clock: Instant) -> Result<()> {
        let seconds = clock.elapsed().as_secs_f64();
        match self.record.stages.iter_mut().find(|s| s.name == stage) {
            Some(done) => done.seconds = seconds,
            None => self.record.stages.push(StageRecord { name: stage, seconds }),
        }
        self.record.write(&self.options.output)
    }
}

/// Write a complete build's page again (`rmvp report DATASET`); returns its path.
pub fn write_build_report(dataset: &Path) -> Result<PathBuf> {
    let record = BuildRecord::read(dataset)?;
    if !record.complete {
        return Err(Error::Folder { path: dataset.to_path_buf(), why: "an unfinished build has no page yet".into() });
    }
    let scene = rmvp_dataset::layout::read_scene(&dataset.join(Layout::Rmvp.name()))?;
    write_build_page(dataset, &record, &scene)
}

/// The page of the build in `dataset` (`report.html`): its record's datasheet and stage times,
/// its truth in 3D with the cameras, its views.
fn write_build_page(dataset: &Path, record: &BuildRecord, scene: &Scene) -> Result<PathBuf> {
    let mut sheet = format!(
        "Built with rmvp {} (`rmvp dataset build`): {} views, {} for training ({}), {}x{}.\n\n{}\n\
         | stage | seconds |\n| --- | --- |\n",
        env!("CARGO_PKG_VERSION"),
        record.views.len(),
        record.train.len(),
        record.train.join(", "),
        record.size[0],
        record.size[1],
        record.datasheet_section()
    );
    for stage in &record.stages {
        sheet += &format!("| {} | {:.1} |\n", stage.name, stage.seconds);
    }
    let object = DatasetObject { name: &record.object, scene };
    write_dataset_report(dataset, &record.object, &sheet, &[object], None)
}

/// The mapping of a dataset's environment map (see [`crate::panorama`]).
pub const ENV_CONVENTION: &str = "lat-long, linear RGB; texel (i, j) of W x H holds the radiance arriving from the \
world direction (sin t sin p, cos t, -sin t cos p), p = 2 pi (i + 0.5) / W, t = pi (j + 0.5) / H (Mitsuba 3's \
envmap mapping of world directions)";

/// Align `scan` onto `reference` (world frame) by ICP with scale, check it (its units where
/// the world is in millimetres, `world_mm`, then refit rigidly at the scale they give; its
/// fit always), and write `dir/alignment.json` and
/// `dir/aligned.ply`. The masks' IoU fields are left for the ground-truth stage.
pub fn align_scan(scan: &ScanInput, reference: &Mesh, world_mm: bool, dir: &Path) -> Result<ScanSummary> {
    let refuse = |why: String| Error::Scan { path: scan.path.clone(), why };
    let mesh = Mesh::read(&scan.path)?;
    let mut alignment = align(&mesh, reference, &IcpOptions::default())?;
    let (lo, hi) = reference.bounds().ok_or_else(|| refuse("the reference reconstruction is empty".into()))?;
    let size = Vector3::from(hi).cast::<f64>().metric_distance(&Vector3::from(lo).cast::<f64>());
    let relative = alignment.median_distance / size;
    if relative > SCAN_MAX_MEDIAN_DISTANCE {
        return Err(refuse(format!(
            "does not fit the reference shape: after alignment its points lie {:.4} (median, {:.2} % of the \
             object's size) from it, {:.0} % within reach; another object, or a damaged scan",
            alignment.median_distance,
            100.0 * relative,
            100.0 * alignment.inlier_ratio
        )));
    }
    let expected_scale = world_mm.then(|| scan.units.millimetres());
    if let Some(expected) = expected_scale {
        let ratio = alignment.transform.s / expected;
        if (ratio - 1.0).abs() > SCAN_SCALE_TOLERANCE {
            return Err(refuse(format!(
                "aligning it needs a scale of {:.4}, where {} in this millimetre world give {expected}: \
                 wrong units? (the scan's unit of length: mm, cm, m or in)",
                alignment.transform.s,
                scan.units.name()
            )));
        }
    }
    let free_scale = alignment.transform.s;
    if let Some(expected) = expected_scale {
        // Units known in a metric world: the scale is known too, and the reference's own error
        // of size (tenths of a percent) must not pass into the ground truth. Refit rigidly at
        // that scale, from the free fit's pose about the scan's centroid, with the reference's
        // growth along its normals as an unknown: its masks' dilation grows it by a fraction of
        // a pixel all round, and its unseen underside would leave the grown top pulling the
        // scan up (docs/datasets.md).
        let n = mesh.positions.len().max(1) as f64;
        let centroid = mesh.positions.iter().map(|p| Vector3::from(p.map(|v| v as f64))).sum::<Vector3<f64>>() / n;
        let initial = alignment.transform.rescaled_about(expected, &centroid);
        let rigid = IcpOptions { coarse: false, initial, fixed_scale: true, fit_offset: true, ..IcpOptions::default() };
        alignment = align(&mesh, reference, &rigid)?;
    }
    let relative = alignment.median_distance / size;
    std::fs::create_dir_all(dir).map_err(|e| rmvp_dataset::Error::io(dir, e))?;
    alignment.transform.apply_to_mesh(&mesh).write(&dir.join(ALIGNED_MESH))?;
    alignment.write(&dir.join(ALIGNMENT_FILE))?;
    Ok(ScanSummary {
        file: scan.path.clone(),
        units: scan.units,
        alignment,
        expected_scale,
        free_scale,
        median_distance_relative: relative,
        mask_iou_mean: 0.0,
        mask_iou_min: (0.0, String::new()),
    })
}

/// The folder of a built dataset in `layout`.
pub fn layout_folder(dataset: &Path, layout: Layout) -> PathBuf {
    dataset.join(layout.name())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rmvp_align::Similarity;
    use rmvp_render::shapes::torus_knot;

    /// `mesh` moved by a rotation about (1, 2, 3), a translation and `scale`.
    fn placement(scale: f64) -> Similarity {
        let r = Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(Vector3::new(1.0, 2.0, 3.0)), 2.0);
        Similarity { r: r.into_inner(), t: Vector3::new(30.0, -12.0, 7.0) * scale, s: scale }
    }

    fn moved(mesh: &Mesh, scale: f64) -> Mesh {
        placement(scale).apply_to_mesh(mesh)
    }

    fn write_scan(dir: &Path, mesh: &Mesh) -> PathBuf {
        let path = dir.join("scan.ply");
        mesh.write(&path).unwrap();
        path
    }

    #[test]
    fn scans_are_aligned_in_their_units_and_refused_in_others_or_when_they_do_not_fit() {
        let dir = tempfile::tempdir().unwrap();
        // The reference in a millimetre world: the spot 70 mm in radius.
        let reference = Similarity::scaling(70.0).apply_to_mesh(&rmvp_render::default_mesh());
        // A scan in metres, elsewhere and turned.
        let metres = write_scan(dir.path(), &moved(&reference, 0.001));
        let scan = ScanInput { path: metres.clone(), units: LengthUnit::M };
        let summary = align_scan(&scan, &reference, true, &dir.path().join("ok")).unwrap();
        assert!((summary.alignment.transform.s / 1000.0 - 1.0).abs() < 1e-3, "{:?}", summary.alignment);
        // Point-to-point distance to a sampled target: its spacing, about 0.1 % of the size.
        assert!(summary.median_distance_relative < 2e-3, "{}", summary.median_distance_relative);
        assert!(dir.path().join("ok").join(ALIGNED_MESH).is_file());
        // A reference 0.5 % too large (a reconstruction's error of size): the free fit follows
        // it, the ground truth keeps the scan's own millimetres, rigidly placed on it.
        let inflated = Similarity::scaling(1.005).apply_to_mesh(&reference);
        let summary = align_scan(&scan, &inflated, true, &dir.path().join("inflated")).unwrap();
        assert!((summary.free_scale / 1005.0 - 1.0).abs() < 1e-3, "{}", summary.free_scale);
        let got = &summary.alignment.transform;
        assert!((got.s - 1000.0).abs() < 1e-9, "{}", got.s);
        // Reference -> scan -> world: the identity when the scan is placed exactly.
        let error = got.compose(&placement(0.001));
        let angle = error.angle_deg();
        let worst = reference
            .positions
            .iter()
            .map(|q| Vector3::from(q.map(|v| v as f64)))
            .map(|q| (error.apply(&q) - q).norm())
            .fold(0.0, f64::max);
        eprintln!(
            "rigid fit on a 0.5 % large reference: rotation off by {angle:.4} deg, vertices within {worst:.3} mm"
        );
        assert!(angle < 0.1 && worst < 0.5, "{angle} deg, {worst} mm");
        // The same file said to be in millimetres: refused, naming it and the scale.
        let wrong = ScanInput { path: metres, units: LengthUnit::Mm };
        let err = align_scan(&wrong, &reference, true, &dir.path().join("wrong")).unwrap_err();
        assert!(matches!(err, Error::Scan { .. }) && err.to_string().contains("scan.ply"), "{err}");
        assert!(err.to_string().contains("wrong units"), "{err}");
        assert!(!dir.path().join("wrong").exists());
        // In a world of arbitrary scale the units are not checked.
        assert!(align_scan(&wrong, &reference, false, &dir.path().join("free")).is_ok());
        // Another object: refused for its distance.
        let knot = Similarity::scaling(70.0).apply_to_mesh(&torus_knot(2, 3, 0.3, 120, 16));
        let other = ScanInput { path: write_scan(dir.path(), &knot), units: LengthUnit::Mm };
        let err = align_scan(&other, &reference, true, &dir.path().join("other")).unwrap_err();
        assert!(err.to_string().contains("does not fit"), "{err}");
    }

    #[test]
    fn split_and_units_read_as_the_command_line_and_the_record_give_them() {
        assert_eq!("6".parse::<TrainViews>(), Ok(TrainViews::Count(6)));
        assert_eq!("000,007".parse::<TrainViews>(), Ok(TrainViews::Names(vec!["000".into(), "007".into()])));
        assert!("0".parse::<TrainViews>().is_err());
        for unit in [LengthUnit::Mm, LengthUnit::Cm, LengthUnit::M, LengthUnit::In] {
            let named: LengthUnit = serde_json::from_value(unit.name().into()).unwrap();
            assert_eq!(named, unit);
        }
        assert!(serde_json::from_value::<LengthUnit>("ft".into()).is_err());
    }
}
