//! From the simulated camera to a published dataset, as a lab does it: a calibration session
//! (the board moved in front of the camera), a 24-view session of the object standing on the
//! board, the empty lab at the same turntable positions (background plates); then `rmvp
//! calibrate`, `rmvp poses` (ChArUco and COLMAP), `rmvp masks`, each against the simulated
//! truth; `rmvp dataset build` with a simulated laser scan and panorama, `publish`, `verify`;
//! and `rmvp recon` on the release's six-view split, judged by `rmvp eval` against the
//! release's ground truth and against the simulator's, beside the same run with the true poses
//! and masks. Failures of each step are refused by name, leaving the session as it was.

use nalgebra::Vector3;
use rmvp_align::normal_errors;
use rmvp_align::{surface_metrics, Similarity, SurfaceOptions};
use rmvp_calib::board::BoardOptions;
use rmvp_calib::intrinsics::CameraCalibration;
use rmvp_calib::lab::lab_environment;
use rmvp_calib::lab::LabOptions;
use rmvp_calib::normalization::visual_hull_sphere;
use rmvp_calib::poses::accuracy::pose_errors;
use rmvp_calib::poses::PoseSet;
use rmvp_calib::scene::posed_scene;
use rmvp_capture::simulator::{SimulatedScene, SimulatedSetup, SimulatorOptions};
use rmvp_dataset::io::png;
use rmvp_dataset::layout::{read_scene, write_scene, Layout};
use rmvp_dataset::{Camera, Mesh};
use rmvp_pipeline::build::{BuildRecord, Stage};
use rmvp_pipeline::ground_truth::mask_iou;
use rmvp_render::envmap::procedural_image;
use rmvp_render::EnvMap;
use std::path::Path;

#[path = "common/browser.rs"]
mod browser;
mod common;
use common::{fails, ok, s};

/// The lab's board: ChArUco, 10x8 squares of 30 mm (larger than `rmvp`'s default 8x6, so that
/// enough corners show around the object).
const BOARD: [&str; 2] = ["--squares", "10x8"];

fn lab_setup() -> LabOptions {
    LabOptions { board: BoardOptions { squares: [10, 8], ..BoardOptions::default() }, ..LabOptions::default() }
}

/// One simulated camera at a time: each renders and streams at full speed on the machine's
/// cores, and a frame that waits behind another test's is a frame timing out.
static ONE_CAMERA: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// A session from the in-process simulated camera.
fn capture(dir: &Path, views: usize, setup: &[&str]) {
    let _turn = ONE_CAMERA.lock().unwrap_or_else(|e| e.into_inner());
    let views = views.to_string();
    let seed = rmvp_testkit::test_seed().to_string();
    let mut args = vec!["capture", "--simulated", "--seed", &seed, "--object", "lab", "--mode", "turntable"];
    args.extend(["--dark", "4"]);
    args.extend(["--average", "4", "--views", &views, "-o", s(dir)]);
    args.extend_from_slice(setup);
    ok(&args);
}

#[test]
fn a_lab_session_becomes_posed_masked_views() {
    let tmp = tempfile::tempdir().unwrap();
    let (cal, lab, empty) = (tmp.path().join("cal"), tmp.path().join("lab"), tmp.path().join("empty"));
    capture(&cal, 24, &["--setup", "calibration", BOARD[0], BOARD[1]]);
    capture(&lab, 24, &["--setup", "lab", BOARD[0], BOARD[1]]);
    capture(&empty, 24, &["--setup", "lab", "--no-object", BOARD[0], BOARD[1]]);
    let truth = SimulatedScene::new(&SimulatorOptions {
        views: 24,
        setup: SimulatedSetup::Lab(lab_setup()),
        seed: rmvp_testkit::test_seed(),
        ..SimulatorOptions::default()
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
    let charuco_poses = || {
        let args = ["poses", s(&lab), "--method", "charuco", "--camera", s(&camera_file), "-o", s(&charuco_file)];
        ok(&[&args[..], &BOARD[..]].concat())
    };
    charuco_poses();
    let charuco = PoseSet::read(&charuco_file).unwrap();
    assert_eq!((charuco.views.len(), charuco.failed.len()), (24, 0));
    // Every camera is this far from the object.
    let distance = lab_setup().distance_mm;
    let found: Vec<Camera> = charuco.views.iter().map(|v| Camera::try_from(&v.camera).unwrap()).collect();
    let errors = pose_errors(&found, cameras, false);
    let (worst_deg, worst_rel) = (errors.max_rotation_deg(), errors.max_centre_distance() / distance);
    // A focal length off by some share puts each board that share too far or too near, so the
    // centres are judged beyond what the calibration's focal error explains (up to 0.23 % at
    // seed 2, within the calibration's own bound above).
    let focal_error = (k[(0, 0)] / want[(0, 0)] - 1.0).abs().max((k[(1, 1)] / want[(1, 1)] - 1.0).abs());
    eprintln!(
        "charuco poses: rotation error at most {worst_deg:.4} deg, centres within {:.4} % (focal length {:.4} % off)",
        100.0 * worst_rel,
        100.0 * focal_error
    );
    // Seeds 0-2 (`bench/test-margins.sh --lab`): at most 0.094, 0.076 and 0.109 degrees; 0.14,
    // 0.12 and 0.28 % with the focal length 0.004, 0.015 and 0.23 % off (docs/design.md, test bounds).
    assert!(worst_deg < 0.15 && worst_rel < 0.0025 + focal_error, "{worst_deg} deg, {worst_rel}, focal {focal_error}");

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
            mask_iou(&want, &got)
        })
        .collect();
    let mean_iou = ious.iter().sum::<f64>() / ious.len() as f64;
    let min_iou = ious.iter().copied().fold(1.0, f64::min);
    eprintln!("masks: IoU mean {mean_iou:.4}, lowest {min_iou:.4}");
    assert!(mean_iou > 0.98 && min_iou > 0.97, "IoU mean {mean_iou:.4}, lowest {min_iou:.4}");
    assert!(masks.join("contact_sheet.png").is_file() && lab.join("masks/005.png").is_file());

    // COLMAP, the object painted out by the session's masks: right up to a similarity. Each view
    // matched with the next three in turntable order (up to 45 degrees on): fewer pairs than
    // exhaustive matching, and none of the pairs 60 degrees and more apart that the board's
    // repeating squares match wrongly.
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
        "--matcher",
        "sequential",
        "--overlap",
        "3",
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
    // COLMAP 3.8's matching differs from run to run, even on one thread, so a failure here
    // names what it needs to be understood: each view's error, the mapper's initial pair and
    // the order it registered the others in.
    if !(worst_deg < 0.3 && worst_rel < 0.005) {
        let per_view: Vec<String> = (colmap.views.iter().zip(&errors.rotation_deg).zip(&errors.centre_distance))
            .map(|((v, deg), d)| format!("{} {deg:.2} deg {:.2} %", v.name, 100.0 * d / distance))
            .collect();
        let log =
            std::fs::read_to_string(lab.join(rmvp_calib::poses::COLMAP_FOLDER).join("mapper.log")).unwrap_or_default();
        let steps: Vec<&str> =
            log.lines().filter(|l| l.starts_with("Initializing") || l.starts_with("Registering")).collect();
        panic!("{worst_deg} deg, {worst_rel}\nper view: {}\nmapper: {}", per_view.join("; "), steps.join("; "));
    }

    // The release: the session posed by the board again (COLMAP's frame has no millimetres),
    // a laser scan of the object (the true mesh's vertices with 0.02 mm of noise, a metrology
    // scanner's accuracy, its normals recomputed, turned and moved; a midpoint subdivision would
    // put new vertices on the flat facets, 0.76 deg (median) off the true shading normals alone)
    // and the simulator's environment as a panorama; built, published, verified.
    charuco_poses();
    let subject = truth.subject.clone().unwrap();
    let scan_file = tmp.path().join("scan.ply");
    let placement =
        Similarity { r: rotation(&Vector3::new(0.3, -1.0, 0.5), 2.1), t: Vector3::new(-250.0, 80.0, 1200.0), s: 1.0 };
    let scan = placement.apply_to_mesh(&noisy(&Mesh { normals: None, ..subject.clone() }, 0.02));
    // First in metres while said to be millimetres: refused after the reference shape, and the
    // unfinished build says so.
    Similarity { s: 0.001, ..placement }.apply_to_mesh(&subject).write(&scan_file).unwrap();
    let pano = tmp.path().join("studio.exr");
    rmvp_dataset::io::exr::write_exr(&pano, &procedural_image(), &["R", "G", "B"]).unwrap();
    let dataset = tmp.path().join("dataset");
    let train = "000,005,008,013,016,021";
    let build = |extra: &[&str], run: fn(&[&str]) -> String| {
        let mut args = vec!["dataset", "build", s(&lab), "-o", s(&dataset), "--train-views", train];
        args.extend(["--camera", s(&camera_file), "--scan", s(&scan_file), "--env", s(&pano)]);
        args.extend(["--reference-preset", "fast", "--reference-iters", "300", "--reference-mesh-res", "192"]);
        args.extend_from_slice(extra);
        run(&args)
    };
    let err = build(&[], fails);
    assert!(err.contains("scan.ply") && err.contains("wrong units"), "{err}");
    let record = BuildRecord::read(&dataset).unwrap();
    assert!(!record.complete && record.stages.iter().any(|s| s.name == Stage::Reference), "{record:?}");
    assert!(!dataset.join("nersp").exists() && !dataset.join("rmvp").exists());
    let err = build(&[], fails);
    assert!(err.contains("unfinished build") && err.contains("--resume"), "{err}");
    // The right scan, resumed: the reference is not trained again.
    scan.write(&scan_file).unwrap();
    eprintln!("{}", build(&["--resume"], ok));
    let record = BuildRecord::read(&dataset).unwrap();
    assert!(record.complete);
    let log = std::fs::read_to_string(dataset.join("work/reference/log.jsonl")).unwrap();
    assert_eq!(log.lines().count(), 300);
    let aligned = record.scan.as_ref().unwrap();
    eprintln!(
        "scan aligned: scale {:.5}, median distance {:.4} mm, masks IoU mean {:.4}, lowest {:.4}",
        aligned.alignment.transform.s, aligned.alignment.median_distance, aligned.mask_iou_mean, aligned.mask_iou_min.0
    );
    let release = tmp.path().join("release");
    // Who publishes it and under what licence is said, or nothing is written.
    let publish = ["dataset", "publish", s(&dataset), "-o", s(&release)];
    let err = fails(&[&publish[..], &["--creator", "Lab, Simulated; rmvp"]].concat());
    assert!(err.contains("licence") && err.contains("--license") && !release.exists(), "{err}");
    let err = fails(&[&publish[..], &["--license", "CC-BY-4.0"]].concat());
    assert!(err.contains("creators") && err.contains("--creator") && !release.exists(), "{err}");
    ok(&[&publish[..], &["--archive", "tar", "--license", "CC-BY-4.0", "--creator", "Lab, Simulated; rmvp"]].concat());
    let verified = ok(&["dataset", "verify", s(&release)]);
    assert!(verified.contains("verified (1 object(s): lab; ") && verified.contains("24 views"), "{verified}");
    // The objects' table names the scan and the ground-truth mesh it became.
    let objects: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(release.join("index/objects.json")).unwrap()).unwrap();
    assert_eq!(objects[0]["scan"], "scan.ply", "{objects}");
    assert!(release.join(objects[0]["mesh"].as_str().unwrap()).is_file(), "{objects}");
    let datasheet = std::fs::read_to_string(release.join("README.md")).unwrap();
    assert!(datasheet.contains("CC-BY-4.0") && datasheet.contains("charuco") && datasheet.contains("scan.ply"));
    assert!(tmp.path().join("release.tar").is_file() && release.join("lab/contact/normals.png").is_file());
    // The pages of the build and of the release: the datasheet, the true surface in 3D with
    // the cameras (drawn from two directions in a browser), every view, the checksums.
    let html = std::fs::read_to_string(release.join("report.html")).unwrap();
    assert!(html.contains("CC-BY-4.0") && html.contains("<table>") && html.contains("<code>SHA256SUMS</code>"));
    assert_eq!(html.matches("<figcaption>view ").count(), 24, "a picture of every view");
    assert_eq!(html.matches("(training)</figcaption>").count(), 6);
    let result = browser::selftest(&release.join("report.html"), &tmp.path().join("profile"));
    assert!(result["errors"] == serde_json::json!([]) && result["views"].as_array().unwrap().len() == 1, "{result}");
    assert!(browser::covered(&result["views"][0]).iter().all(|&c| c > 0.02 && c < 0.9), "{result}");
    // The release's build record names its inputs without this machine's paths.
    let released = std::fs::read_to_string(release.join("lab/build.json")).unwrap();
    assert!(released.contains("\"scan.ply\"") && !released.contains(s(tmp.path())), "{released}");
    let built = std::fs::read_to_string(dataset.join("report.html")).unwrap();
    assert!(built.contains("| reference |") || built.contains("<td>reference</td>"), "the build's stages");

    // The release's ground truth against the simulator's: the mesh within 0.3 % of the object's
    // size, the normals within 1.5 degrees (median), the environment map as the renderer's.
    // Seeds 0 and 1 gave 0.12 and 0.17 %, 0.91 and 1.01 degrees: the scan's alignment onto the
    // reference reconstruction varies with the session's noise (docs/design.md, test bounds).
    let published = read_scene(&release.join("lab/nersp")).unwrap();
    let gt_mesh = published.mesh.clone().unwrap();
    let size = 2.0 * lab_setup().object_radius_mm;
    let chamfer = surface_metrics(&gt_mesh, &subject, &SurfaceOptions::default()).unwrap().chamfer;
    let mut angles = Vec::new();
    for view in &published.views {
        let v: usize = view.name.parse().unwrap();
        let want = truth.geometry(v).normals;
        let got = view.normals.as_ref().unwrap();
        for (a, b) in got.data().chunks_exact(3).zip(want.data().chunks_exact(3)) {
            let dot: f32 = a.iter().zip(b).map(|(x, y)| x * y).sum();
            if a.iter().any(|&x| x != 0.0) && b.iter().any(|&x| x != 0.0) {
                angles.push(dot.clamp(-1.0, 1.0).acos().to_degrees());
            }
        }
    }
    angles.sort_by(f32::total_cmp);
    let median = angles[angles.len() / 2];
    eprintln!(
        "release ground truth: Chamfer {chamfer:.4} mm ({:.3} % of the size), normals median {median:.3} deg",
        100.0 * chamfer / size
    );
    assert!(chamfer < 0.003 * size && median < 1.5, "Chamfer {chamfer} mm, median {median} deg");
    let env = published.env_map.as_ref().unwrap();
    let want = lab_environment(EnvMap::procedural()).world_image(env.width(), env.height());
    let worst = env.data().iter().zip(want.data()).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
    assert!(worst < 1e-5, "environment map differs by {worst}");

    // A damaged file in the release is named.
    let victim = release.join("lab/nersp/s0/0003.npy");
    let original = std::fs::read(&victim).unwrap();
    let mut damaged = original.clone();
    *damaged.last_mut().unwrap() ^= 1;
    std::fs::write(&victim, &damaged).unwrap();
    let err = fails(&["dataset", "verify", s(&release)]);
    assert!(err.contains("lab/nersp/s0/0003.npy: checksum differs"), "{err}");
    std::fs::write(&victim, &original).unwrap();

    // `rmvp recon` on the release's six-view split (its undistorted views, the build's
    // normalisation) beside the same command on the session's six views with the true poses
    // and masks (one thread each, 1000 iterations); `rmvp eval` against the release's ground
    // truth. Over all 24 views, the two reconstructions' normal errors (against the
    // simulator's true normals) differ by less than 5 degrees, and the release's ground truth
    // judges the first as the simulator's does, within 1.5 degrees.
    let train: Vec<String> = train.split(',').map(String::from).collect();
    let mut true_scene = posed_scene(&lab, &charuco, Some(&masks), &train).unwrap();
    for (v, view) in true_scene.views.iter_mut().enumerate() {
        view.camera = cameras[v].clone();
        view.mask = Some(truth.geometry(v).mask);
    }
    let hull: Vec<_> = true_scene.views.iter().map(|v| (v.camera.clone(), v.mask.clone().unwrap())).collect();
    true_scene.normalization = visual_hull_sphere(&hull).unwrap().scale_mat();
    let true_dir = tmp.path().join("true-poses");
    write_scene(&true_scene, &true_dir, Layout::Rmvp).unwrap();
    let mut ground_truth = true_scene.clone();
    for (v, view) in ground_truth.views.iter_mut().enumerate() {
        view.normals = Some(truth.geometry(v).normals);
    }
    let recon = |scene: &Path, out: &Path| {
        let args = ["--threads", "1", "recon", s(scene), "-o", s(out), "--iters", "1000", "--mesh-res", "160"];
        ok(&[&args[..], &["--mesh-only", "--seed", &rmvp_testkit::test_seed().to_string()]].concat());
        Mesh::read(&out.join("mesh.ply")).unwrap()
    };
    let (from_release, from_truth) = (tmp.path().join("recon-release"), tmp.path().join("recon-true"));
    let published_dir = release.join("lab/nersp");
    let (release_mesh, true_mesh) = std::thread::scope(|scope| {
        let release_run = scope.spawn(|| recon(&published_dir, &from_release));
        let true_run = recon(&true_dir, &from_truth);
        (release_run.join().unwrap(), true_run)
    });
    let pred = from_release.join("mesh.ply");
    let gt = published_dir.join("gt/mesh.ply");
    let evaluated = ok(&["eval", "--pred", s(&pred), "--gt", s(&gt), "--scene", s(&published_dir), "--json"]);
    let evaluated: serde_json::Value = serde_json::from_str(&evaluated).unwrap();
    assert_eq!(evaluated["normal_views"].as_array().unwrap().len(), 24, "{evaluated}");
    let judged = evaluated["normal_mae_deg"].as_f64().unwrap();
    let from_release = normal_errors(&release_mesh, &ground_truth).unwrap().mean_mae_deg;
    let with_truth = normal_errors(&true_mesh, &ground_truth).unwrap().mean_mae_deg;
    eprintln!(
        "normal MAE over 24 views: {from_release:.2} deg from the release, {with_truth:.2} with the true poses and \
         masks; the release's own ground truth gives the first {judged:.2} (Chamfer {:.3} mm)",
        evaluated["chamfer"].as_f64().unwrap()
    );
    // Seeds 0-4: 3.49-5.86 degrees from the release, 3.02-4.18 with the truth, 0.18-2.74 apart
    // (2.08 at seed 0), so 5; the release's ground truth judged the first within 0.13-0.86 of
    // the simulator's (docs/design.md, test bounds).
    assert!((from_release - with_truth).abs() < 5.0, "{from_release:.2} vs {with_truth:.2}");
    assert!((judged - from_release).abs() < 1.5, "{judged:.2} vs {from_release:.2}");
}

/// `mesh` with Gaussian noise of `sigma` on every coordinate.
fn noisy(mesh: &Mesh, sigma: f64) -> Mesh {
    let mut rng = rmvp_dataset::rng::Rng::for_pixel(7 + rmvp_testkit::test_seed(), 0, 0);
    let positions = mesh.positions.iter().map(|p| p.map(|v| v + (sigma * rng.normal() as f64) as f32)).collect();
    Mesh { positions, ..mesh.clone() }
}

/// The rotation by `angle` radians about `axis`.
fn rotation(axis: &Vector3<f64>, angle: f64) -> nalgebra::Matrix3<f64> {
    nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(*axis), angle).into_inner()
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
        warnings: Vec::new(),
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

    // A dataset of a session not posed.
    let err = fails(&["dataset", "build", s(&plain), "-o", s(&tmp.path().join("dataset"))]);
    assert!(err.contains("no camera poses (poses.json)") && err.contains("plain"), "{err}");

    // A damaged session file is named.
    std::fs::write(plain.join("session.json"), b"{ not json").unwrap();
    let err = fails(&["poses", s(&plain), "--method", "charuco", "--camera", s(&camera), "-o", s(&out)]);
    assert!(err.contains("session.json") && err.contains("not a session manifest"), "{err}");
}
