//! From the simulated camera to posed, masked views, as a lab does it: a calibration session
//! (the board moved in front of the camera), a 24-view session of the object standing on the
//! board, the empty lab at the same turntable positions (background plates); then `rmvp
//! calibrate`, `rmvp poses` (ChArUco and COLMAP), `rmvp masks`, each against the simulated
//! truth, and NeRSP on six views with the estimated poses and masks against the same run with
//! the true ones. Failures of each step are refused by name, leaving the session as it was.

use rmvp_align::normal_errors;
use rmvp_calib::board::BoardSpec;
use rmvp_calib::intrinsics::CameraCalibration;
use rmvp_calib::lab::LabSetup;
use rmvp_calib::normalization::visual_hull_sphere;
use rmvp_calib::poses::accuracy::pose_errors;
use rmvp_calib::poses::PoseSet;
use rmvp_calib::scene::posed_scene;
use rmvp_capture::simulator::{SimulatedScene, SimulatedSetup, SimulatorConfig};
use rmvp_dataset::io::png;
use rmvp_dataset::{Camera, Scene};
use rmvp_recon::extract::extract_mesh;
use rmvp_recon::model::Preset;
use rmvp_recon::train::{TrainConfig, Trainer};
use std::path::Path;
use std::process::{Command, Output};

fn rmvp(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rmvp")).args(args).output().expect("rmvp runs")
}

fn ok(args: &[&str]) -> String {
    let out = rmvp(args);
    assert!(out.status.success(), "rmvp {args:?} failed:\n{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap()
}

fn fails(args: &[&str]) -> String {
    let out = rmvp(args);
    assert!(!out.status.success(), "rmvp {args:?} should have failed");
    String::from_utf8(out.stderr).unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The lab's board: ChArUco, 10x8 squares of 30 mm (larger than `rmvp`'s default 8x6, so that
/// enough corners show around the object).
const BOARD: [&str; 2] = ["--squares", "10x8"];

fn lab_setup() -> LabSetup {
    LabSetup { board: BoardSpec { squares: [10, 8], ..BoardSpec::default() }, ..LabSetup::default() }
}

/// One simulated camera on the loopback address at a time: tests take turns.
static LOOPBACK: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// A session from the in-process simulated camera.
fn capture(dir: &Path, views: usize, setup: &[&str]) {
    let _turn = LOOPBACK.lock().unwrap_or_else(|e| e.into_inner());
    let views = views.to_string();
    let mut args = vec!["capture", "--simulated", "--object", "lab", "--mode", "turntable", "--dark", "4"];
    args.extend(["--average", "4", "--views", &views, "-o", s(dir)]);
    args.extend_from_slice(setup);
    ok(&args);
}

/// Train the fast preset on `scene` and return the mean normal error over `truth`'s views.
fn reconstruct(scene: &Scene, truth: &Scene, iterations: u32) -> f64 {
    let config = TrainConfig::preset(Preset::Fast, iterations);
    let set = rmvp_recon::data::TrainingSet::from_scene(scene, config.margin).unwrap();
    let mut trainer = Trainer::new(config, set);
    while trainer.iteration < trainer.config.iterations {
        trainer.step();
    }
    let lw = trainer.level_weight();
    let mesh = extract_mesh(&trainer.model, &trainer.params, &lw, 160, &trainer.set.frame, trainer.fd_step(&lw));
    normal_errors(&mesh, truth).unwrap().mean_mae_deg
}

#[test]
fn a_lab_session_becomes_posed_masked_views() {
    let tmp = tempfile::tempdir().unwrap();
    let (cal, lab, empty) = (tmp.path().join("cal"), tmp.path().join("lab"), tmp.path().join("empty"));
    capture(&cal, 24, &["--setup", "calibration", BOARD[0], BOARD[1]]);
    capture(&lab, 24, &["--setup", "lab", BOARD[0], BOARD[1]]);
    capture(&empty, 24, &["--setup", "lab", "--no-object", BOARD[0], BOARD[1]]);
    let truth = SimulatedScene::new(&SimulatorConfig {
        views: 24,
        setup: SimulatedSetup::Lab(lab_setup()),
        ..SimulatorConfig::default()
    })
    .unwrap();
    let cameras = &truth.cameras;

    // Intrinsics: the simulated camera's, from the calibration session.
    let camera_file = tmp.path().join("camera.json");
    ok(&["calibrate", s(&cal), "-o", s(&camera_file), BOARD[0], BOARD[1]]);
    let calibration = CameraCalibration::read(&camera_file).unwrap();
    let (k, want) = (calibration.k(), cameras[0].k);
    eprintln!("calibrated {k:.3}\nsimulated {want:.3}");
    assert!((k[(0, 0)] / want[(0, 0)] - 1.0).abs() < 0.005 && (k[(1, 1)] / want[(1, 1)] - 1.0).abs() < 0.005);
    assert!((k[(0, 2)] - want[(0, 2)]).abs() < 1.0 && (k[(1, 2)] - want[(1, 2)]).abs() < 1.0);
    assert!(tmp.path().join("camera_coverage.png").is_file());

    // Poses from the board: the world is the board frame, as the simulation's.
    let charuco_file = tmp.path().join("charuco.json");
    ok(&[
        "poses",
        s(&lab),
        "--method",
        "charuco",
        "--camera",
        s(&camera_file),
        "-o",
        s(&charuco_file),
        BOARD[0],
        BOARD[1],
    ]);
    let charuco = PoseSet::read(&charuco_file).unwrap();
    assert_eq!((charuco.views.len(), charuco.failed.len()), (24, 0));
    // Every camera is this far from the object.
    let distance = lab_setup().distance_mm;
    let found: Vec<Camera> = charuco.views.iter().map(|v| Camera::try_from(&v.camera).unwrap()).collect();
    let errors = pose_errors(&found, cameras, false);
    let (worst_deg, worst_rel) = (errors.max_rotation_deg(), errors.max_centre_distance() / distance);
    eprintln!("charuco poses: rotation error at most {worst_deg:.4} deg, centres within {:.4} %", 100.0 * worst_rel);
    assert!(worst_deg < 0.1 && worst_rel < 0.002, "{worst_deg} deg, {worst_rel}");

    // The posed session is the rig calibration of the empty lab (same turntable positions);
    // and its poses, exported as nerfstudio transforms, import back.
    let turntable_file = tmp.path().join("turntable.json");
    ok(&["poses", s(&empty), "--method", "turntable", "--rig", s(&lab), "-o", s(&turntable_file)]);
    let turntable = PoseSet::read(&turntable_file).unwrap();
    assert!(turntable.views.iter().zip(&charuco.views).all(|(a, b)| a.camera == b.camera && a.name == b.name));
    let transforms = tmp.path().join("transforms.json");
    let named: Vec<(String, Option<String>, Camera)> = charuco
        .views
        .iter()
        .map(|v| (format!("images/{}.png", v.name), None, Camera::try_from(&v.camera).unwrap()))
        .collect();
    rmvp_dataset::exchange::nerfstudio::Transforms::from_cameras(&named).write(&transforms).unwrap();
    let imported_file = tmp.path().join("imported.json");
    ok(&["poses", s(&lab), "--method", "import", "--from", s(&transforms), "-o", s(&imported_file)]);
    for (a, b) in PoseSet::read(&imported_file).unwrap().views.iter().zip(&charuco.views) {
        let (a, b) = (Camera::try_from(&a.camera).unwrap(), Camera::try_from(&b.camera).unwrap());
        assert!((a.r - b.r).abs().max() < 1e-9 && (a.t - b.t).abs().max() < 1e-6);
    }

    // Masks against the background plates: the object's alone, as rendered.
    let masks = tmp.path().join("masks");
    ok(&["masks", s(&lab), "--method", "difference", "--background", s(&empty), "-o", s(&masks)]);
    let ious: Vec<f64> = (0..24)
        .map(|v| {
            let (want, got) = (truth.geometry(v).mask, png::read_png_u8(&masks.join(format!("{v:03}.png"))).unwrap());
            let (mut inter, mut union) = (0usize, 0usize);
            for (a, b) in want.data().iter().zip(got.data()) {
                inter += usize::from(*a > 127 && *b > 127);
                union += usize::from(*a > 127 || *b > 127);
            }
            inter as f64 / union as f64
        })
        .collect();
    let mean_iou = ious.iter().sum::<f64>() / ious.len() as f64;
    let min_iou = ious.iter().copied().fold(1.0, f64::min);
    eprintln!("masks: IoU mean {mean_iou:.4}, lowest {min_iou:.4}");
    assert!(mean_iou > 0.98 && min_iou > 0.97, "IoU mean {mean_iou:.4}, lowest {min_iou:.4}");
    assert!(masks.join("contact_sheet.png").is_file() && lab.join("masks/005.png").is_file());

    // COLMAP, the object painted out by the session's masks: right up to a similarity.
    let colmap_file = tmp.path().join("colmap.json");
    ok(&[
        "poses",
        s(&lab),
        "--method",
        "colmap",
        "--camera",
        s(&camera_file),
        "--max-features",
        "2048",
        "-o",
        s(&colmap_file),
    ]);
    let colmap = PoseSet::read(&colmap_file).unwrap();
    assert_eq!(colmap.views.len(), 24, "{:?}", colmap.failed);
    // The same model imported from COLMAP's files gives the same cameras.
    ok(&["poses", s(&lab), "--method", "import", "--from", s(&lab.join("colmap/sparse/0")), "-o", s(&imported_file)]);
    assert_eq!(PoseSet::read(&imported_file).unwrap().views, colmap.views);
    let estimated: Vec<Camera> = colmap.views.iter().map(|v| Camera::try_from(&v.camera).unwrap()).collect();
    let errors = pose_errors(&estimated, cameras, true);
    let (worst_deg, worst_rel) = (errors.max_rotation_deg(), errors.max_centre_distance() / distance);
    eprintln!(
        "colmap poses after a similarity: rotation error at most {worst_deg:.4} deg, centres within {:.4} %",
        100.0 * worst_rel
    );
    assert!(worst_deg < 0.3 && worst_rel < 0.005, "{worst_deg} deg, {worst_rel}");

    // NeRSP on six views (both rings, all around) with the estimated poses and masks, and with
    // the true ones: the normal error over all 24 views differs by less than 1.5 degrees.
    let train: Vec<String> = ["000", "005", "008", "013", "016", "021"].map(String::from).to_vec();
    let estimated_scene = posed_scene(&lab, &charuco, Some(&masks), &train).unwrap();
    let mut true_scene = estimated_scene.clone();
    for (v, view) in true_scene.views.iter_mut().enumerate() {
        view.camera = cameras[v].clone();
        view.mask = Some(truth.geometry(v).mask);
    }
    let hull: Vec<_> = true_scene.views.iter().map(|v| (v.camera.clone(), v.mask.clone().unwrap())).collect();
    true_scene.normalization = visual_hull_sphere(&hull).unwrap().scale_mat();
    let mut ground_truth = true_scene.clone();
    for (v, view) in ground_truth.views.iter_mut().enumerate() {
        view.normals = Some(truth.geometry(v).normals);
    }
    // Side by side, one thread each: two cores stay busier than with one run on both (results
    // do not depend on the thread count).
    let alone = |scene: &Scene| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        pool.install(|| reconstruct(scene, &ground_truth, 400))
    };
    let (with_estimates, with_truth) = std::thread::scope(|scope| {
        let estimates = scope.spawn(|| alone(&estimated_scene));
        let truth = alone(&true_scene);
        (estimates.join().unwrap(), truth)
    });
    eprintln!("normal MAE over 24 views: {with_estimates:.2} deg with estimated poses and masks, {with_truth:.2} with the true ones");
    assert!((with_estimates - with_truth).abs() < 1.5, "{with_estimates:.2} vs {with_truth:.2}");
}

#[test]
fn each_step_refuses_bad_input_by_name_and_leaves_the_session_as_it_was() {
    let tmp = tempfile::tempdir().unwrap();
    // The object alone on the turntable: no board in any view.
    let plain = tmp.path().join("plain");
    capture(&plain, 3, &["--setup", "turntable"]);
    let manifest = std::fs::read(plain.join("session.json")).unwrap();
    let k = rmvp_render::rig::rig_intrinsics(1224, 1024);
    let calibration = CameraCalibration {
        k: rmvp_dataset::camera::matrix_rows(&k),
        distortion: rmvp_dataset::Distortion { k1: 0.0, k2: 0.0, p1: 0.0, p2: 0.0, k3: 0.0 },
        width: 1224,
        height: 1024,
        k_std_px: [0.0; 4],
        rms_px: 0.0,
        images: Vec::new(),
        rejected: Vec::new(),
        board: Default::default(),
    };
    let camera = tmp.path().join("camera.json");
    calibration.write(&camera).unwrap();
    let out = tmp.path().join("poses.json");
    let poses = |extra: &[&str]| {
        let mut args = vec!["poses", s(&plain), "-o", s(&out), "--camera", s(&camera)];
        args.extend_from_slice(extra);
        fails(&args)
    };

    // The board absent: every view named, with its reason.
    let err = poses(&["--method", "charuco"]);
    assert!(err.contains("0 view(s) posed, 3 needed") && err.contains("002 (0 board corners seen, 8 needed)"), "{err}");
    // COLMAP absent.
    let err = poses(&["--method", "colmap", "--colmap", "/nonexistent/colmap"]);
    assert!(err.contains("colmap program was not found (/nonexistent/colmap)") && err.contains("install"), "{err}");
    // COLMAP registering too few views: three views of a reflective object before an empty sky.
    let err = poses(&["--method", "colmap", "--min-views", "3"]);
    assert!(err.contains("not registered by COLMAP") || err.contains("colmap mapper failed"), "{err}");
    // A calibration of another image size.
    let small = CameraCalibration { width: 640, height: 512, ..calibration.clone() };
    small.write(&camera).unwrap();
    let err = poses(&["--method", "charuco"]);
    assert!(err.contains("the calibration is for (640, 512) pixels, the views are (1224, 1024)"), "{err}");
    // Masks: background plates without the views, a mesh without poses.
    let err = fails(&["masks", s(&plain), "--method", "difference", "--background", s(tmp.path()), "-o", s(&out)]);
    assert!(err.contains("session.json"), "{err}");
    let err = fails(&["masks", s(&plain), "--method", "mesh", "--mesh", s(&camera), "-o", s(&out)]);
    assert!(err.contains("camera.json") && err.contains("unknown mesh format"), "{err}");
    // Nothing of the session changed, and no poses were kept.
    assert_eq!(std::fs::read(plain.join("session.json")).unwrap(), manifest);
    assert!(!plain.join("poses.json").exists() && !out.exists());
    rmvp_dataset::session::SessionManifest::read(&plain).unwrap().verify(&plain).unwrap();

    // A damaged session file is named.
    std::fs::write(plain.join("session.json"), b"{ not json").unwrap();
    let err = fails(&["poses", s(&plain), "--method", "charuco", "--camera", s(&camera), "-o", s(&out)]);
    assert!(err.contains("session.json") && err.contains("not a session manifest"), "{err}");
}
