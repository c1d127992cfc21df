//! From a simulated lab to posed, masked views: the time of each stage on 24 views at
//! 1224x1024 (COLMAP's own steps from its logs), and the pose accuracy of the ChArUco and
//! COLMAP methods against the rendered truth as the views drop from 24 to 12 to 6.
//! Then the dataset stage on the object session: `rmvp dataset build` with a laser scan (the
//! true mesh in millimetres, moved) and a panorama, each stage's time from `build.json` (the
//! reference reconstruction apart: the dense preset, or `RMVP_BENCH_REFERENCE_ITERS`
//! iterations of it), then `publish` (with a tar archive) and `verify`; the reference and
//! the aligned scan against the true object.
//! `cargo bench --bench lab` (part of `./run bench`). The three sessions (calibration, object,
//! empty lab) are captured once through the simulated camera into `target/tmp/bench-lab` and
//! reused; delete that folder to capture them again. Writes `bench/results/lab.json` and
//! `bench/results/dataset.json`.

use nalgebra::Vector3;
use rmvp_align::icp::ALIGNED_MESH;
use rmvp_align::{surface_metrics, SurfaceOptions};
use rmvp_calib::board::BoardOptions;
use rmvp_calib::lab::LabOptions;
use rmvp_calib::poses::accuracy::pose_errors;
use rmvp_calib::poses::PoseSet;
use rmvp_capture::simulator::{SimulatedScene, SimulatedSetup, SimulatorOptions};
use rmvp_dataset::session::SessionManifest;
use rmvp_dataset::{Camera, Mesh};
use rmvp_pipeline::build::{REFERENCE_FOLDER, SCAN_FOLDER};
use rmvp_recon::reconstruct::MESH;
use rmvp_testkit::results::{BenchResult, Table};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

const VIEWS: usize = 24;
const BOARD: [&str; 2] = ["--squares", "10x8"];

fn rmvp(args: &[&str]) -> f64 {
    let start = Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_rmvp")).args(args).output().expect("rmvp runs");
    assert!(out.status.success(), "rmvp {args:?}:\n{}", String::from_utf8_lossy(&out.stderr));
    start.elapsed().as_secs_f64()
}

fn s(p: &Path) -> &str {
    p.to_str().expect("UTF-8 path")
}

/// Capture `dir` unless a complete session is there; the seconds it took, if captured.
fn session(dir: &Path, setup: &[&str]) -> Option<f64> {
    if SessionManifest::read(dir).is_ok_and(|m| m.complete && m.views.len() == VIEWS) {
        return None;
    }
    let _ = std::fs::remove_dir_all(dir);
    let views = VIEWS.to_string();
    let mut args = vec!["capture", "--simulated", "--object", "lab", "--mode", "turntable", "--dark", "4"];
    args.extend(["--average", "4", "--views", &views, "-o", s(dir)]);
    args.extend_from_slice(setup);
    Some(rmvp(&args))
}

/// A session of the views of `full` numbered `keep`, sharing its files (symbolic links).
fn subset(full: &Path, keep: &[usize], dir: &Path) -> PathBuf {
    let _ = std::fs::remove_dir_all(dir);
    std::fs::create_dir_all(dir).expect("bench folder");
    let mut manifest = SessionManifest::read(full).expect("session");
    manifest.views.retain(|v| keep.contains(&v.index));
    manifest.views_planned = manifest.views.len();
    manifest.write(dir).expect("manifest");
    let full = full.canonicalize().expect("session folder");
    for folder in ["views", "dark", "masks"] {
        std::os::unix::fs::symlink(full.join(folder), dir.join(folder)).expect("link");
    }
    dir.to_path_buf()
}

/// COLMAP's own time for each step, from the "Elapsed time" line of its logs.
fn colmap_steps(workspace: &Path) -> Vec<(String, f64)> {
    ["feature_extractor", "exhaustive_matcher", "mapper"]
        .iter()
        .filter_map(|step| {
            let log = std::fs::read_to_string(workspace.join(format!("{step}.log"))).ok()?;
            let line = log.lines().rev().find(|l| l.contains("Elapsed time"))?;
            let minutes: f64 = line.split(':').nth(1)?.split_whitespace().next()?.parse().ok()?;
            Some((step.to_string(), 60.0 * minutes))
        })
        .collect()
}

fn main() {
    if !std::env::args().any(|a| a == "--bench") {
        return; // built by `cargo test --all-targets`: measure only under `cargo bench`
    }
    let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("bench-lab");
    let (cal, lab, empty) = (root.join("cal"), root.join("lab"), root.join("empty"));
    println!("lab benchmark: {VIEWS} views at 1224x1024 per session, simulated camera, sessions in {}", root.display());
    let mut result = BenchResult::now("Calibration, poses and masks", "cargo bench --bench lab");
    let mut stages = Table::new(&["stage (24 views)", "seconds"]);
    let mut stage = |name: &str, seconds: f64| stages.row(vec![name.to_string(), format!("{seconds:.1}")]);
    for (dir, setup) in [
        (&cal, vec!["--setup", "calibration", BOARD[0], BOARD[1]]),
        (&lab, vec!["--setup", "lab", BOARD[0], BOARD[1]]),
        (&empty, vec!["--setup", "lab", "--no-object", BOARD[0], BOARD[1]]),
    ] {
        if let Some(seconds) = session(dir, &setup) {
            let name = dir.file_name().expect("named").to_string_lossy();
            println!("  capture {name:<6} {seconds:7.1} s (rendering, sensor, GenICam streaming, processing, writing)");
            stage(&format!("capture: the `{name}` session"), seconds);
        }
    }
    let camera = root.join("camera.json");
    let out = root.join("out");
    std::fs::create_dir_all(&out).expect("bench folder");
    println!("stage times ({VIEWS} views):");
    let t = rmvp(&["calibrate", s(&cal), "-o", s(&camera), BOARD[0], BOARD[1]]);
    println!("  calibrate (ChArUco, 24 images)          {t:7.1} s");
    stage("`rmvp calibrate` (ChArUco, 24 images)", t);
    let t = rmvp(&[
        "poses",
        s(&lab),
        "--method",
        "charuco",
        "--camera",
        s(&camera),
        "-o",
        s(&out.join("charuco.json")),
        BOARD[0],
        BOARD[1],
    ]);
    println!("  poses --method charuco                  {t:7.1} s");
    stage("`rmvp poses --method charuco`", t);
    let t = rmvp(&["masks", s(&lab), "--method", "grabcut", "--background", s(&empty), "-o", s(&out.join("grabcut"))]);
    println!("  masks --method grabcut                  {t:7.1} s");
    stage("`rmvp masks --method grabcut`", t);
    let t = rmvp(&["masks", s(&lab), "--method", "difference", "--background", s(&empty), "-o", s(&out.join("masks"))]);
    println!("  masks --method difference               {t:7.1} s");
    stage("`rmvp masks --method difference`", t);
    let t = rmvp(&[
        "poses",
        s(&lab),
        "--method",
        "colmap",
        "--camera",
        s(&camera),
        "--max-features",
        "2048",
        "-o",
        s(&out.join("colmap.json")),
    ]);
    println!("  poses --method colmap                   {t:7.1} s, of which COLMAP's own:");
    stage("`rmvp poses --method colmap` (2048 features an image, exhaustive matching)", t);
    for (step, seconds) in colmap_steps(&lab.join("colmap")) {
        println!("    colmap {step:<32} {seconds:7.1} s");
        stage(&format!("of which COLMAP's `{step}`"), seconds);
    }

    let truth = SimulatedScene::new(&SimulatorOptions {
        views: VIEWS,
        setup: SimulatedSetup::Lab(LabOptions {
            board: BoardOptions { squares: [10, 8], ..BoardOptions::default() },
            ..LabOptions::default()
        }),
        ..SimulatorOptions::default()
    })
    .expect("the simulated lab");
    let distance = LabOptions::default().distance_mm;
    println!("pose accuracy against the rendered truth (worst view; centres in % of the camera distance):");
    println!("  views  method    posed  rotation (deg)  centre (%)   time (s)");
    let mut accuracy =
        Table::new(&["views", "method", "posed", "rotation (deg)", "centre (% of the camera distance)", "seconds"]);
    // Both rings (views alternate between them), evenly around.
    for (count, keep) in [
        (24, (0..24).collect::<Vec<usize>>()),
        (12, (0..24).filter(|i| i % 4 < 2).collect()),
        (6, (0..24).filter(|i| i % 8 < 2).collect()),
    ] {
        let dir = subset(&lab, &keep, &root.join(format!("lab-{count}")));
        for method in ["charuco", "colmap"] {
            let file = out.join(format!("{method}-{count}.json"));
            let mut args = vec!["poses", s(&dir), "--method", method, "--camera", s(&camera), "-o", s(&file)];
            args.extend(if method == "charuco" { BOARD.to_vec() } else { vec!["--max-features", "2048"] });
            let start = Instant::now();
            let status = Command::new(env!("CARGO_BIN_EXE_rmvp")).args(&args).output().expect("rmvp runs");
            let seconds = start.elapsed().as_secs_f64();
            if !status.status.success() {
                let why = String::from_utf8_lossy(&status.stderr);
                let why = why.lines().next().unwrap_or("").to_string();
                println!("  {count:>5}  {method:<8}  failed: {why}");
                accuracy.row(vec![
                    count.to_string(),
                    method.into(),
                    format!("failed: {why}"),
                    "".into(),
                    "".into(),
                    "".into(),
                ]);
                continue;
            }
            let set = PoseSet::read(&file).expect("poses");
            let (found, reference): (Vec<Camera>, Vec<Camera>) = set
                .views
                .iter()
                .map(|v| {
                    let index: usize = v.name.parse().expect("numbered views");
                    (Camera::try_from(&v.camera).expect("camera"), truth.cameras[index].clone())
                })
                .unzip();
            let errors = pose_errors(&found, &reference, method == "colmap");
            let cells = vec![
                count.to_string(),
                method.to_string(),
                format!("{}/{count}", set.views.len()),
                format!("{:.3}", errors.max_rotation_deg()),
                format!("{:.3}", 100.0 * errors.max_centre_distance() / distance),
                format!("{seconds:.1}"),
            ];
            println!("  {}", cells.join("  "));
            if count == VIEWS {
                let rotation = result.figure(&format!("{method}_rotation"), &cells[3]);
                let centre = result.figure(&format!("{method}_centre"), &cells[4]);
                if method == "charuco" {
                    result.headline = format!("ChArUco poses {rotation} degrees, {centre} %");
                }
            }
            accuracy.row(cells);
        }
    }
    result.about = format!(
        "A simulated lab ([`calibration.md`](calibration.md)): three sessions of {VIEWS} views at 1224x1024 through \
         the simulated GenICam camera (the board alone, the object on the board on a textured table, the empty lab), \
         then each stage as the command line runs it. The second table: pose accuracy against the rendered truth as \
         the views drop (the worst view; COLMAP after a similarity fit, ChArUco as it is, since the board gives \
         metric poses)."
    );
    result.tables = vec![stages, accuracy];
    result.write("lab");
    dataset_stage(&root, &lab, &camera, &truth);
}

/// `rmvp dataset build`, `publish` and `verify` on the object session, timed.
fn dataset_stage(root: &Path, lab: &Path, camera: &Path, truth: &SimulatedScene) {
    let out = root.join("out");
    rmvp(&[
        "poses",
        s(lab),
        "--method",
        "charuco",
        "--camera",
        s(camera),
        "-o",
        s(&out.join("charuco.json")),
        BOARD[0],
        BOARD[1],
    ]);
    let scan = out.join("scan.ply");
    let subject = truth.subject.clone().expect("the lab has a subject");
    let turn = nalgebra::Rotation3::from_euler_angles(0.4, -1.1, 2.0).into_inner();
    let placement = rmvp_align::Similarity { r: turn, t: nalgebra::Vector3::new(-250.0, 80.0, 1200.0), s: 1.0 };
    placement.apply_to_mesh(&subject).write(&scan).expect("scan");
    let pano = out.join("studio.exr");
    rmvp_dataset::io::exr::write_exr(&pano, &rmvp_render::envmap::procedural_image(), &["R", "G", "B"])
        .expect("panorama");
    let (dataset, release) = (out.join("dataset"), out.join("release"));
    for dir in [&dataset, &release] {
        let _ = std::fs::remove_dir_all(dir);
    }
    let _ = std::fs::remove_file(out.join("release.tar"));
    let iterations = std::env::var("RMVP_BENCH_REFERENCE_ITERS").ok();
    let mut args = vec!["dataset", "build", s(lab), "-o", s(&dataset), "--camera", s(camera)];
    args.extend(["--scan", s(&scan), "--env", s(&pano)]);
    if let Some(n) = &iterations {
        args.extend(["--reference-iters", n.as_str()]);
    }
    let total = rmvp(&args);
    let record = rmvp_pipeline::build::BuildRecord::read(&dataset).expect("build record");
    let reference = record.reference.as_ref().expect("reference");
    let command = match &iterations {
        Some(n) => format!("RMVP_BENCH_REFERENCE_ITERS={n} cargo bench --bench lab"),
        None => "cargo bench --bench lab".to_string(),
    };
    let mut result = BenchResult::now("The dataset stage", &command);
    let mut stages = Table::new(&[&format!("stage ({VIEWS} views at 1224x1024)"), "seconds"]);
    let mut stage = |name: &str, seconds: f64| stages.row(vec![name.to_string(), format!("{seconds:.1}")]);
    println!(
        "dataset stage ({VIEWS} views, reference: {:?} preset, {} iterations, mesh at {}^3):",
        reference.preset, reference.iterations, reference.mesh_resolution
    );
    for s in &record.stages {
        println!("  build {:<13}                    {:7.1} s", s.name.to_string(), s.seconds);
        stage(&format!("build: {}", s.name), s.seconds);
    }
    println!("  build in all                            {total:7.1} s");
    stage("`dataset build` in all", total);
    let t = rmvp(&[
        "dataset",
        "publish",
        s(&dataset),
        "-o",
        s(&release),
        "--archive",
        "tar",
        "--license",
        "CC-BY-4.0",
        "--creator",
        "Lab, Simulated; rmvp",
    ]);
    println!("  publish (copy, contact sheets, SHA-256, tar) {t:7.1} s");
    stage("`dataset publish` (copy, contact sheets, SHA-256, tar)", t);
    let t = rmvp(&["dataset", "verify", s(&release)]);
    println!("  verify                                  {t:7.1} s");
    stage("`dataset verify`", t);
    let scan = record.scan.as_ref().expect("scan");
    println!(
        "  scan aligned: scale {:.5}, median distance {:.4} mm; masks against its silhouettes: IoU mean {:.4}",
        scan.alignment.transform.s, scan.alignment.median_distance, scan.mask_iou_mean
    );
    // The reference and the ground truth against the true object (the board's frame, mm): the
    // scan's placement undone by the alignment is the identity when the fit is exact.
    let chamfer = |path: PathBuf| {
        let mesh = Mesh::read(&path).expect("mesh");
        surface_metrics(&mesh, &subject, &SurfaceOptions::default()).expect("metrics").chamfer
    };
    let off = scan.alignment.transform.compose(&placement);
    let centre = subject.positions.iter().map(|p| Vector3::from(p.map(|v| v as f64))).sum::<Vector3<f64>>()
        / subject.positions.len() as f64;
    let (reference_mm, truth_mm) =
        (chamfer(dataset.join(REFERENCE_FOLDER).join(MESH)), chamfer(dataset.join(SCAN_FOLDER).join(ALIGNED_MESH)));
    let (rotation, centre_mm) = (off.angle_deg(), (off.apply(&centre) - centre).norm());
    println!(
        "  against the true object: reference Chamfer {reference_mm:.3} mm; ground truth Chamfer {truth_mm:.3} mm, \
         rotation off by {rotation:.3} deg, centre off by {centre_mm:.3} mm"
    );
    let truth_chamfer = result.figure("scan_chamfer_mm", format!("{truth_mm:.3}"));
    result.headline = format!("release mesh {truth_chamfer} mm from the truth");
    result.about = format!(
        "`rmvp dataset build` on the lab bench's {VIEWS}-view object session at 1224x1024 with a scan (the true mesh \
         in millimetres, moved) and a panorama, the reference by the {:?} preset ({} iterations, mesh at {}^3), then \
         `publish` and `verify`. Against the true object: the reference {reference_mm:.3} mm Chamfer; the scan fitted \
         on it {truth_mm:.3} mm Chamfer, rotation {rotation:.3} degrees, centre {centre_mm:.3} mm off; the captured \
         masks against the scan's silhouettes IoU {:.3}. `tests/lab.rs` runs it with a small reference, asserting \
         with margins.",
        reference.preset, reference.iterations, reference.mesh_resolution, scan.mask_iou_mean
    );
    result.tables = vec![stages];
    result.write("dataset");
}
