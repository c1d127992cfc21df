//! Capture sessions end to end: `rmvp capture` against `rmvp simulate-camera` (a GenICam GigE
//! Vision camera on a loopback address of its own, in its own process so that it can be
//! killed), opened by its address: serials repeat when a second suite runs beside this one.

use rmvp_capture::correction::subtract_dark;
use rmvp_capture::simulator::{SimulatedScene, SimulatorOptions};
use rmvp_capture::FrameProcessor;
use rmvp_dataset::layout::rmvp::read_stokes;
use rmvp_dataset::session::{PositioningMode, SessionManifest, StokesUnit};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// One rig at a time: each renders and streams at full speed on the machine's cores, and a
/// frame that waits behind another test's is a frame timing out.
static ONE_RIG: Mutex<()> = Mutex::new(());

/// A simulated camera process, killed when dropped, and the address it answers on.
struct SimulatedCameraProcess {
    child: Child,
    address: String,
}

impl SimulatedCameraProcess {
    fn start(serial: &str, views: usize, extra: &[&str]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_rmvp"))
            .args(["simulate-camera", "--serial", serial, "--views", &views.to_string()])
            .args(["--seed", &rmvp_testkit::test_seed().to_string()])
            .args(extra)
            .stderr(Stdio::piped())
            .spawn()
            .expect("rmvp runs");
        let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
        let ready = lines.next().expect("a line").unwrap();
        let address = ready.split("ready on ").nth(1).and_then(|rest| rest.split_whitespace().next());
        let address = address.unwrap_or_else(|| panic!("no address in {ready:?}")).to_string();
        // Keep draining its stderr so that it never blocks on a full pipe.
        std::thread::spawn(move || lines.for_each(drop));
        Self { child, address }
    }

    fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for SimulatedCameraProcess {
    fn drop(&mut self) {
        self.kill();
    }
}

/// What each test starts from: its turn ([`ONE_RIG`]), a simulated camera process
/// (extra `rmvp simulate-camera` arguments) and an empty session folder. Fields drop in order:
/// the camera stops before the folder goes and the turn is passed on.
struct Rig {
    dir: PathBuf,
    camera: SimulatedCameraProcess,
    _tmp: tempfile::TempDir,
    _turn: MutexGuard<'static, ()>,
}

impl Rig {
    fn new(serial: &str, views: usize, camera_args: &[&str]) -> Self {
        let turn = ONE_RIG.lock().unwrap_or_else(|e| e.into_inner());
        let tmp = tempfile::tempdir().unwrap();
        let camera = SimulatedCameraProcess::start(serial, views, camera_args);
        Self { dir: tmp.path().join("session"), camera, _tmp: tmp, _turn: turn }
    }
}

fn capture_command(camera: &SimulatedCameraProcess, dir: &Path, extra: &[&str]) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_rmvp"));
    command.args(["capture", "--camera", &camera.address, "--object", "spot", "-o", dir.to_str().unwrap()]);
    if !extra.contains(&"--views") {
        command.args(["--views", "6"]);
    }
    command.args(["--frame-timeout", "2"]).args(extra);
    command
}

fn run(mut command: Command) -> Output {
    command.output().expect("rmvp runs")
}

/// The Stokes images the session would hold without noise: the rendered truth through the
/// noise-free sensor, black level removed, and the same processing.
fn noise_free_capture(truth: &rmvp_dataset::Stokes, exposure_us: f64) -> rmvp_dataset::Stokes {
    let sensor = SimulatedScene::sensor(exposure_us, 0.0, 12).noise_free();
    let mut raw = sensor.digitize(&sensor.electrons(truth), 0, 0);
    let black = sensor.dark_frame(truth.s0.width(), truth.s0.height(), 0);
    subtract_dark(&mut raw, &black).unwrap();
    let processor = FrameProcessor { saturation_aware: true, ..FrameProcessor::default() };
    processor.process(&raw).unwrap().estimate.stokes
}

/// How a captured view differs from the truth: |S0 error| / sigma against the noise-free
/// capture (sigma: the S0 noise the sensor model injects, shot and read noise of the polarizer
/// samples), median and 90th percentile over object pixels, and the median AoP error
/// (degrees) against the rendered truth where it is polarized (DoP > 0.1).
fn residuals(view: &Path, truth: &rmvp_dataset::Stokes) -> (f64, f64, f64) {
    let measured = read_stokes(&view.join("view_stokes.exr")).unwrap();
    let reference = noise_free_capture(truth, 20_000.0);
    let sensor = SimulatedScene::sensor(20_000.0, 0.0, 12);
    let gain = sensor.stokes_gain() as f64;
    let (mut z, mut aop_errors) = (Vec::new(), Vec::new());
    let channels = truth.s0.channels();
    for i in 0..truth.s0.data().len() {
        let t0 = truth.s0.data()[i] as f64;
        if t0 < 0.05 {
            continue;
        }
        // Four samples of about t0/2 each: electrons e = t0/2 * exposure * full well; S0 is
        // half their sum, so its sigma is that of one sample.
        let electrons = 0.5 * t0 * sensor.exposure as f64 * sensor.full_well as f64;
        let sigma = (electrons + (sensor.read_noise as f64).powi(2)).sqrt() / sensor.full_well as f64;
        z.push((measured.s0.data()[i] as f64 - reference.s0.data()[i] as f64).abs() / sigma);
        if i % channels == 1 {
            let (t1, t2) = (truth.s1.data()[i] as f64, truth.s2.data()[i] as f64);
            if (t1 * t1 + t2 * t2).sqrt() / t0 > 0.1 {
                let (m1, m2) = (measured.s1.data()[i] as f64 / gain, measured.s2.data()[i] as f64 / gain);
                let d = 0.5 * (m2.atan2(m1) - t2.atan2(t1));
                let d =
                    (d + std::f64::consts::FRAC_PI_2).rem_euclid(std::f64::consts::PI) - std::f64::consts::FRAC_PI_2;
                aop_errors.push(d.abs().to_degrees());
            }
        }
    }
    assert!(z.len() > 10_000 && aop_errors.len() > 1_000, "{} object pixels, {} polarized", z.len(), aop_errors.len());
    let quantile = |v: &mut Vec<f64>, q: f64| {
        v.sort_by(f64::total_cmp);
        v[(q * v.len() as f64) as usize]
    };
    (quantile(&mut z, 0.5), quantile(&mut z, 0.9), quantile(&mut aop_errors, 0.5))
}

#[test]
fn a_six_view_session_matches_the_renderer_within_the_noise() {
    let rig = Rig::new("RMVPSESS01", 6, &[]);
    let dir = rig.dir.clone();
    // Dark frames (the simulated rig's lens cap) remove the black level.
    let out = run(capture_command(&rig.camera, &dir, &["--dark", "4"]));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let manifest = SessionManifest::read(&dir).unwrap();
    assert_eq!((manifest.dark.len(), manifest.dark[0].frames), (1, 4));
    assert!(manifest.complete);
    assert_eq!(manifest.views.len(), 6);
    assert_eq!(manifest.camera.identity.serial, "RMVPSESS01");
    assert_eq!(manifest.camera.pixel_format, "BayerRGPolarized12p");
    assert_eq!(manifest.camera.features["ExposureAuto"], "Off");
    assert_eq!(manifest.camera.features["ExposureTime"], "20000");
    manifest.verify(&dir).unwrap();

    let scene = SimulatedScene::new(&SimulatorOptions {
        views: 6,
        seed: rmvp_testkit::test_seed(),
        ..SimulatorOptions::default()
    })
    .unwrap();
    for view in &manifest.views {
        let truth = scene.render(view.index);
        let (z, z90, aop) = residuals(&dir.join("views").join(&view.name), &truth);
        // Gaussian noise has median |z| = 0.67 and 90th percentile 1.64 (demosaicing smooths
        // it a little).
        eprintln!("view {}: |S0 error| median {z:.2}, p90 {z90:.2} sigma; median AoP error {aop:.2} deg", view.index);
        assert!(z < 0.8 && z90 < 2.0, "view {}: |S0 error| median {z:.2}, p90 {z90:.2} sigma", view.index);
        assert!(aop < 6.0, "view {}: median AoP error {aop:.2} deg", view.index);
    }
    // The same check fails against the wrong pose.
    let (z, z90, _) = residuals(&dir.join("views/000"), &scene.render(1));
    eprintln!("against the wrong pose: |z| median {z:.2}, p90 {z90:.2}");
    assert!(z90 > 5.0, "a wrong pose gave |z| p90 {z90:.2}");
}

#[test]
fn a_camera_killed_mid_session_leaves_a_partial_session_that_resume_completes() {
    let mut rig = Rig::new("RMVPKILL01", 6, &[]);
    let dir = rig.dir.clone();
    let session = capture_command(&rig.camera, &dir, &[]).stderr(Stdio::piped()).spawn().unwrap();
    let start = Instant::now();
    while SessionManifest::read(&dir).map_or(0, |m| m.views.len()) < 2 {
        assert!(start.elapsed() < Duration::from_secs(120), "no progress");
        std::thread::sleep(Duration::from_millis(20));
    }
    rig.camera.kill();
    let out = session.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(stderr.contains("RMVPKILL01"), "the error names the camera: {stderr}");
    assert!(stderr.contains("--resume"), "the error says how to continue: {stderr}");

    let partial = SessionManifest::read(&dir).unwrap();
    assert!(!partial.complete && (2..6).contains(&partial.views.len()), "{} views", partial.views.len());
    partial.verify(&dir).unwrap();
    let on_disk: Vec<String> = std::fs::read_dir(dir.join("views"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !n.ends_with(".partial"))
        .collect();
    assert!(on_disk.len() >= partial.views.len());

    // Without --resume the session is refused; with it, it completes and keeps what was there.
    rig.camera = SimulatedCameraProcess::start("RMVPKILL01", 6, &[]);
    let refused = run(capture_command(&rig.camera, &dir, &[]));
    assert!(String::from_utf8_lossy(&refused.stderr).contains("--resume"));
    let out = run(capture_command(&rig.camera, &dir, &["--resume"]));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let resumed = SessionManifest::read(&dir).unwrap();
    assert!(resumed.complete);
    assert_eq!(resumed.views.len(), 6);
    assert_eq!(resumed.views[..partial.views.len()], partial.views[..], "views captured before stay identical");
    assert_eq!(resumed.views.iter().map(|v| v.index).collect::<Vec<_>>(), (0..6).collect::<Vec<_>>());
    resumed.verify(&dir).unwrap();
    let mut names: Vec<String> = std::fs::read_dir(dir.join("views"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["000", "001", "002", "003", "004", "005"]);
}

#[test]
fn hdr_brackets_recover_highlights_the_long_exposure_clips() {
    let rig = Rig::new("RMVPHDR01", 2, &[]);
    let dir = rig.dir.clone();
    let args = ["--views", "2", "--hdr", "4000,120000", "--average", "2", "--dark", "2"];
    let out = run(capture_command(&rig.camera, &dir, &args));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let manifest = SessionManifest::read(&dir).unwrap();
    assert_eq!(manifest.views[0].frames, 4);
    assert_eq!(manifest.dark.len(), 2);
    let unit = &manifest.settings.stokes_unit;
    assert!(matches!(unit, StokesUnit::HdrFullScale { shortest_exposure_us: 4000.0, .. }), "{unit}");

    let truth = SimulatedScene::new(&SimulatorOptions {
        views: 2,
        seed: rmvp_testkit::test_seed(),
        ..SimulatorOptions::default()
    })
    .unwrap()
    .render(0);
    let measured = read_stokes(&dir.join("views/000/view_stokes.exr")).unwrap();
    // HDR Stokes are in units of the shortest exposure's full scale: compare with the noise-free
    // capture at 4 ms, which clips nowhere.
    let reference = noise_free_capture(&truth, 4000.0);
    // Stokes pixels whose 2x2 polarizer cell would be far beyond full scale (1.5x) at 120 ms:
    // predicted from the noise-free 4-ms frame (30 times less light).
    let short = SimulatedScene::sensor(4000.0, 0.0, 12).noise_free();
    let short_raw = short.digitize(&short.electrons(&truth), 0, 0);
    let (w, _) = truth.s0.size();
    let saturated = |x: usize, y: usize| {
        (2 * x..2 * x + 2).any(|sx| {
            (2 * y..2 * y + 2).any(|sy| {
                let v = short_raw.pixels.data()[sy * 2 * w + sx] as f64 - short.dark_offset as f64;
                30.0 * v > 1.5 * 4095.0
            })
        })
    };
    let (mut clipped, mut unclipped) = (Vec::new(), Vec::new());
    for (i, &t) in truth.s0.data().iter().enumerate() {
        if t < 0.05 {
            continue;
        }
        let r = reference.s0.data()[i] as f64;
        let error = (measured.s0.data()[i] as f64 - r).abs() / r;
        let pixel = i / 3;
        if saturated(pixel % w, pixel / w) {
            clipped.push(error);
        } else {
            unclipped.push(error);
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    assert!(clipped.len() > 500, "{} pixels clip at 120 ms", clipped.len());
    let (c, u) = (median(&mut clipped), median(&mut unclipped));
    eprintln!("HDR S0 relative error: median {u:.4} where 120 ms is fine, {c:.4} where it clips");
    // Where 120 ms clips, only the two 4-ms frames measure; elsewhere the long exposure
    // dominates. Merging clipped samples as if they were not would underestimate by far more.
    assert!(u < 0.02 && c < 0.04, "HDR S0 relative error: {u:.4} unclipped, {c:.4} clipped");

    // The same session as one written before sessions recorded their polarizer cell: format
    // `/2`, no cell, a view's S2 of the wrong sign. It is refused by name until `rmvp
    // reprocess` computes its views again from the raw frames (brackets, averages and dark
    // frames), which gives back this session's files to the byte.
    let manifest_path = dir.join("session.json");
    let mut old: serde_json::Value = serde_json::from_slice(&std::fs::read(&manifest_path).unwrap()).unwrap();
    old["format"] = "rmvp-capture-session/2".into();
    old.as_object_mut().unwrap().remove("polarizer_cell");
    std::fs::write(&manifest_path, serde_json::to_vec_pretty(&old).unwrap()).unwrap();
    let mut mirrored = measured.clone();
    mirrored.s2.data_mut().iter_mut().for_each(|v| *v = -*v);
    rmvp_dataset::layout::rmvp::write_stokes(&dir.join("views/000/view_stokes.exr"), &mirrored).unwrap();
    let err = SessionManifest::read(&dir).unwrap_err().to_string();
    assert!(err.contains("session.json") && err.contains("[90 45; 135 0]") && err.contains("rmvp reprocess"), "{err}");
    let out = run({
        let mut command = Command::new(env!("CARGO_BIN_EXE_rmvp"));
        command.args(["reprocess", dir.to_str().unwrap()]);
        command
    });
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let reprocessed = SessionManifest::read(&dir).unwrap();
    assert_eq!(reprocessed.format, "rmvp-capture-session/3");
    assert_eq!(reprocessed.views, manifest.views, "views computed again as they were captured");
    reprocessed.verify(&dir).unwrap();
}

#[test]
fn the_operator_presses_enter_between_views_and_a_closed_stdin_stops_cleanly() {
    let rig = Rig::new("RMVPENTER1", 3, &[]);
    let dir = rig.dir.clone();
    let mut command = capture_command(&rig.camera, &dir, &["--views", "3", "--mode", "interactive"]);
    let mut child = command.stdin(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    // Enter for two views, then the operator leaves (stdin closed).
    child.stdin.take().unwrap().write_all(b"\n\n").unwrap();
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(stderr.contains("view 1/3: place the camera and press Enter"), "{stderr}");
    assert!(stderr.contains("1 views done; last:") && stderr.contains("saturated, mean DoP"), "{stderr}");
    assert!(stderr.contains("standard input closed") && stderr.contains("2 of 3 views complete"), "{stderr}");
    let manifest = SessionManifest::read(&dir).unwrap();
    assert_eq!((manifest.views.len(), manifest.settings.positioning), (2, PositioningMode::Interactive));
    manifest.verify(&dir).unwrap();
}

#[test]
fn frames_lost_on_the_link_are_counted_and_grabbed_again() {
    // 0.08 % of the packets: about one frame in two loses one (a 12-bit frame is about 840 packets
    // of 9000 bytes), so the 18 or more frames of the session lose some.
    let rig = Rig::new("RMVPLOSS01", 2, &["--lost-packets", "0.0008", "--noise-free"]);
    let dir = rig.dir.clone();
    let out = run(capture_command(&rig.camera, &dir, &["--views", "2", "--average", "8"]));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let manifest = SessionManifest::read(&dir).unwrap();
    let dropped: usize = manifest.views.iter().map(|v| v.dropped_frames).sum();
    eprintln!("{dropped} frames dropped and grabbed again");
    assert!(dropped > 0, "no frame was lost at a 0.08 % packet loss");
    assert!(stderr.contains(&format!("{dropped} dropped frames grabbed again")), "{stderr}");
    // Every kept frame is complete: noise-free frames of one pose are identical.
    let raw = dir.join("views/001/raw");
    let first = std::fs::read(raw.join("20000us_0.raw")).unwrap();
    for k in 1..8 {
        assert!(std::fs::read(raw.join(format!("20000us_{k}.raw"))).unwrap() == first, "frame {k} differs");
    }
}

#[test]
fn a_camera_left_with_gamma_and_a_mirrored_readout_is_put_right_and_its_state_recorded() {
    let rig = Rig::new("RMVPLEFT01", 1, &["--left-with", "gamma,reverse-x,odd-offset,adc8", "--noise-free"]);
    let out = run(capture_command(&rig.camera, &rig.dir, &["--views", "1"]));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let features = SessionManifest::read(&rig.dir).unwrap().camera.features;
    for (feature, value) in [
        ("GammaEnable", "false"),
        ("ReverseX", "false"),
        ("ReverseY", "false"),
        ("OffsetX", "0"),
        ("AdcBitDepth", "Bit12"),
        ("AcquisitionFrameRateEnable", "false"),
        ("AcquisitionResultingFrameRate", "25"),
        ("DeviceLinkThroughputLimit", "380000000"),
        ("TLParamsLocked", "0"),
    ] {
        assert_eq!(features.get(feature).map(String::as_str), Some(value), "{feature}: {features:?}");
    }
    assert!(features["BlackLevel"].parse::<f64>().is_ok_and(|b| b > 0.0), "{features:?}");
    drop(rig);

    // Left mirrored with the readout locked, the camera cannot be put right: refused, nothing
    // captured.
    let rig = Rig::new("RMVPLOCK01", 1, &["--left-with", "reverse-x,locked-readout", "--noise-free"]);
    let out = run(capture_command(&rig.camera, &rig.dir, &["--views", "1"]));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(stderr.contains("ReverseX") && stderr.contains("locked") && stderr.contains("RMVPLOCK01"), "{stderr}");
    assert!(!rig.dir.join("session.json").exists(), "nothing written: {stderr}");
}

#[test]
fn sessions_run_against_real_flir_descriptions_as_against_our_own() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/genicam");
    let session = |serial: &str, camera_args: &[&str], capture_args: &[&str]| {
        let rig = Rig::new(serial, 2, &[&["--noise-free", "--left-with", "gamma,reverse-x"], camera_args].concat());
        let out = run(capture_command(&rig.camera, &rig.dir, &[&["--views", "2"], capture_args].concat()));
        assert!(out.status.success(), "{camera_args:?}: {}", String::from_utf8_lossy(&out.stderr));
        let manifest = SessionManifest::read(&rig.dir).unwrap();
        manifest.verify(&rig.dir).unwrap();
        let stokes = std::fs::read(rig.dir.join("views/001/view_stokes.exr")).unwrap();
        (manifest, stokes)
    };
    let (_, ours) = session("RMVPDESC00", &[], &[]);
    // The older firmware's description names a plain mono Blackfly S and no polarized format:
    // the sensor behind it is declared polarized.
    for (k, (file, capture_args)) in
        [("FLIR-BFS-PGE-23S6C.xml", &[][..]), ("PGR_BFS_U3_51S5M.xml", &["--polarized-sensor"][..])].iter().enumerate()
    {
        let description = root.join(file);
        let camera_args = ["--description", description.to_str().unwrap()];
        let (manifest, stokes) = session(&format!("RMVPDESC0{}", k + 1), &camera_args, capture_args);
        assert!(manifest.complete, "{file}");
        assert!(manifest.camera.identity.model.starts_with("Simulated BFS_"), "{file}: {:?}", manifest.camera.identity);
        let features = &manifest.camera.features;
        eprintln!("{file}: {} {features:?}", manifest.camera.pixel_format);
        for (feature, value) in [("GammaEnable", "false"), ("ReverseX", "false"), ("ExposureTime", "20000")] {
            assert_eq!(features.get(feature).map(String::as_str), Some(value), "{file}: {feature}");
        }
        // At 20 ms the camera runs at 50 frames a second, and the link carries 50 frames.
        let rate: f64 = features["AcquisitionResultingFrameRate"].parse().unwrap();
        assert!((rate - 50.0).abs() < 0.01, "{file}: {rate}");
        assert_eq!(features["DeviceLinkThroughputLimit"], "380000000", "{file}");
        assert!(stokes == ours, "{file}: the view's Stokes differ from the session against rmvp's own description");
    }
}

#[test]
fn cameras_lists_what_each_camera_supports() {
    let description = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/genicam/FLIR-BFS-PGE-23S6C.xml");
    let _rig = Rig::new("RMVPLIST01", 1, &["--noise-free", "--description", description.to_str().unwrap()]);
    let out = run({
        let mut command = Command::new(env!("CARGO_BIN_EXE_rmvp"));
        command.arg("cameras");
        command
    });
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("RMVPLIST01") && stdout.contains("Simulated BFS_PGE_23S6"), "{stdout}");
    assert!(
        stdout.contains("pixel formats rmvp reads: BayerRG8") && stdout.contains("BayerRGPolarized12p"),
        "{stdout}"
    );
    assert!(
        stdout.contains("polarizers: yes (it offers BayerRGPolarized") && stdout.contains("control: free"),
        "{stdout}"
    );
    for line in ["GammaEnable", "ReverseX", "AdcBitDepth", "AcquisitionResultingFrameRate", "DeviceLinkThroughputLimit"]
    {
        assert!(stdout.lines().any(|l| l.trim_start().starts_with(line)), "{line}: {stdout}");
    }
}

#[test]
fn a_camera_another_program_controls_is_refused_naming_it() {
    let rig = Rig::new("RMVPHELD01", 2, &["--noise-free"]);
    // The first session holds the camera while it waits for the operator.
    let holder_dir = rig.dir.with_file_name("holder");
    let mut holder = capture_command(&rig.camera, &holder_dir, &["--views", "2", "--mode", "interactive"])
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(holder.stderr.take().unwrap()).lines();
    while !lines.next().expect("the first session prompts for Enter").unwrap().contains("press Enter") {}
    std::thread::spawn(move || lines.for_each(drop));

    let out = run(capture_command(&rig.camera, &rig.dir, &["--views", "1"]));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(
        stderr.contains("RMVPHELD01") && stderr.contains("controlled by another application at 127.0.0.1:"),
        "{stderr}"
    );
    assert!(stderr.contains("close it") && !stderr.contains("write_register"), "{stderr}");
    assert!(!rig.dir.join("session.json").exists());
    let listed = run({
        let mut command = Command::new(env!("CARGO_BIN_EXE_rmvp"));
        command.arg("cameras");
        command
    });
    let stdout = String::from_utf8_lossy(&listed.stdout);
    let listed_at = stdout.split(&format!("at {}]", rig.camera.address)).nth(1).expect("the camera is listed");
    let entry: Vec<&str> = listed_at.lines().skip(1).take_while(|l| l.starts_with(' ')).collect();
    assert!(
        entry.iter().any(|l| l.contains("control: is controlled by another application at 127.0.0.1:")),
        "{stdout}"
    );

    // Once the first session ends (the operator leaves), the camera is free.
    drop(holder.stdin.take());
    holder.wait().unwrap();
    let out = run(capture_command(&rig.camera, &rig.dir, &["--views", "1"]));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

#[test]
fn two_simulated_sessions_at_once_both_complete() {
    let _turn = ONE_RIG.lock().unwrap_or_else(|e| e.into_inner());
    let tmp = tempfile::tempdir().unwrap();
    let dirs: Vec<PathBuf> = (0..2).map(|k| tmp.path().join(format!("session{k}"))).collect();
    let sessions: Vec<Child> = dirs
        .iter()
        .map(|dir| {
            Command::new(env!("CARGO_BIN_EXE_rmvp"))
                .args(["capture", "--simulated", "--object", "spot", "--views", "1", "-o", dir.to_str().unwrap()])
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    let mut serials = Vec::new();
    for (session, dir) in sessions.into_iter().zip(&dirs) {
        let out = session.wait_with_output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let manifest = SessionManifest::read(dir).unwrap();
        assert!(manifest.complete);
        manifest.verify(dir).unwrap();
        serials.push(manifest.camera.identity.serial);
    }
    assert_ne!(serials[0], serials[1], "each session filmed its own camera");
    assert!(serials.iter().all(|s| s.starts_with("RMVPSIM")), "{serials:?}");
}

#[test]
fn a_camera_without_polarizers_is_refused_unless_declared() {
    let description = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/genicam/FLIR-BFS-PGE-23S6C.xml");
    // A colour Blackfly S whose firmware implements only the Bayer formats.
    let camera_args = ["--noise-free", "--pixel-formats", "BayerRG8,BayerRG12p", "--description"];
    let rig = Rig::new("RMVPPLAIN1", 1, &[&camera_args[..], &[description.to_str().unwrap()]].concat());
    let out = run(capture_command(&rig.camera, &rig.dir, &["--views", "1"]));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    for part in ["has no polarizers", "BayerRG8, BayerRG12p", "BFS_PGE_23S6", "BFS-U3-51S5PC-C", "--polarized-sensor"] {
        assert!(stderr.contains(part), "{part}: {stderr}");
    }
    assert!(!rig.dir.join("views").exists(), "nothing captured");
    let out = run(capture_command(&rig.camera, &rig.dir, &["--views", "1", "--polarized-sensor"]));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let manifest = SessionManifest::read(&rig.dir).unwrap();
    assert!(manifest.settings.camera.polarized_sensor && manifest.camera.pixel_format == "BayerRG12p");
}
