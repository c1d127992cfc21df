//! End-to-end tests: the `rmvp` binary as users run it.

use rmvp_align::{Alignment, Evaluation};
use rmvp_dataset::summary::SceneSummary;
use rmvp_pipeline::demo::DemoReport;
use rmvp_testkit::fixture;
use std::path::Path;

#[path = "common/browser.rs"]
mod browser;
mod common;
use common::{fails, ok, s};

#[test]
fn demo_captures_builds_a_dataset_and_reconstructs_it() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("demo");
    let args = ["demo", "-o", s(&out), "--spp", "8", "--recon-iters", "20", "--mesh-res", "48", "--mesh-only"];
    let stdout = ok(&args);
    assert!(stdout.contains("AoP error median"), "{stdout}");
    let report = DemoReport::read(&out.join("report.json")).unwrap();
    // Captured through the simulated GenICam camera: full-sensor polarized raw frames.
    assert_eq!((report.capture.views, report.capture.raw_size), (6, [2448, 2048]), "{report:?}");
    assert_eq!(report.capture.pixel_format, "BayerRGPolarized12p");
    assert!(report.capture.camera.contains("BFS-U3-51S5PC-C"), "{report:?}");
    // Noisy frames of an 8-spp rendering against the noise-free rendering: AoP within a few
    // degrees where the light is polarized, S0 within a few percent.
    assert!(report.aop_error_deg.median < 5.0 && report.aop_error_deg.pixels > 10_000, "{report:?}");
    assert!(report.s0_rel_error.median < 0.1, "{report:?}");
    let sheet = rmvp_dataset::io::png::read_png_u8(&out.join("contact_sheet.png")).unwrap();
    assert_eq!(sheet.size(), (4 * 248 + 4, 6 * 208 + 4));
    // The dataset came from the session through `rmvp dataset build`: posed, masked, complete,
    // in both layouts, its Stokes the session's own.
    assert!(report.dataset.complete && report.dataset.train.len() == 6, "{report:?}");
    let record = rmvp_pipeline::build::BuildRecord::read(&out.join("dataset")).unwrap();
    assert!(
        record.complete && record.stages.iter().any(|s| s.name == rmvp_pipeline::build::Stage::Layouts),
        "{record:?}"
    );
    for layout in ["nersp", "rmvp"] {
        let info = ok(&["dataset", "info", s(&out.join("dataset").join(layout))]);
        assert!(info.contains("6 (6 train, 0 eval)"), "{info}");
    }
    let session = out.join("session");
    let manifest = rmvp_dataset::session::SessionManifest::read(&session).unwrap();
    let stokes = rmvp_calib::pictures::read_view_stokes(&session, &manifest.views[3]).unwrap();
    let s0 = rmvp_dataset::io::npy::read_npy::<f32>(&out.join("dataset/nersp/s0/0003.npy")).unwrap();
    assert_eq!(stokes.s0.data(), &s0.data[..]);
    // The reconstruction stage ran and was evaluated (20 iterations: a coarse blob, not a shape).
    assert_eq!(report.reconstruction.iterations, 20);
    assert!(report.reconstruction.normal_mae_deg.is_finite(), "{report:?}");
    for file in ["mesh.ply", "log.jsonl", "checkpoint.bin", "evaluation.json", "report.html"] {
        assert!(out.join("recon").join(file).is_file(), "{file}");
    }
    // Training tracked its normal error against the truth; the dataset has its page too.
    let log = std::fs::read_to_string(out.join("recon/log.jsonl")).unwrap();
    assert!(log.lines().last().unwrap().contains("\"normal_error_deg\":"), "{log}");
    assert!(out.join("dataset/report.html").is_file());
    // The page stays small and opens offline: no error, the mesh drawn from two directions
    // and coloured by its distance to the truth.
    assert!(std::fs::metadata(out.join("recon/report.html")).unwrap().len() < 20 << 20);
    let result = browser::selftest(&out.join("recon/report.html"), &tmp.path().join("profile"));
    assert_eq!(result["errors"], serde_json::json!([]), "{result}");
    let view = &result["views"][0];
    assert!(
        browser::covered(view).iter().all(|&c| c > 0.02) && view["byError"]["covered"].as_f64() > Some(0.02),
        "{result}"
    );
    // --mesh-only: no view outputs (`rmvp recon`'s own test covers them).
    assert!(report.reconstruction.comparison.is_none() && !out.join("recon/normals").exists(), "{report:?}");
    // The dataset's release, as the field's tools read it.
    assert_eq!(report.release, "release");
    check_the_release(&out.join("release"));

    // One raw frame of the session through `rmvp demosaic`, with the session's dark frame,
    // gives the session's Stokes.
    let view = session.join("views/003");
    let again = tmp.path().join("again");
    ok(&[
        "demosaic",
        s(&view.join("raw/20000us_0.raw")),
        "--dark",
        s(&session.join("dark/dark_20000us.png")),
        "-o",
        s(&again),
    ]);
    let demosaiced = rmvp_dataset::layout::rmvp::read_stokes(&again.join("20000us_0_stokes.exr")).unwrap();
    let close = |a: &f32, b: &f32| (a - b).abs() <= 1e-5 * b.abs().max(1.0);
    assert!(demosaiced.s0.data().iter().zip(stokes.s0.data()).all(|(a, b)| close(a, b)));
    for suffix in ["000.png", "045.png", "090.png", "135.png", "aop.exr", "dop.exr", "aop.png", "dop.png", "s0.png"] {
        assert!(again.join(format!("20000us_0_{suffix}")).is_file(), "{suffix}");
    }

    // Run again into the same folder: the earlier demo's files are replaced, others are kept.
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    ok(&args);
    assert_eq!(std::fs::read_to_string(out.join("notes.txt")).unwrap(), "mine");
    assert_eq!(DemoReport::read(&out.join("report.json")).unwrap().dataset, report.dataset);
}

#[test]
fn simulate_writes_both_layouts_and_raw_frames() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("sim");
    let simulate = |dir: &Path| {
        let args = [
            "--res",
            "64x48",
            "--spp",
            "2",
            "--views",
            "4",
            "--eval-views",
            "2",
            "--rig",
            "turntable",
            "--raw",
            "--seed",
            "5",
        ];
        ok(&[&["simulate", "-o", s(dir)][..], &args[..]].concat());
    };
    simulate(&out);
    let a = rmvp_dataset::layout::read_scene(&out.join("nersp")).unwrap();
    let b = rmvp_dataset::layout::read_scene(&out.join("rmvp")).unwrap();
    // Four training views on the turntable, two held out elsewhere with ground truth only.
    let splits: Vec<_> = a.views.iter().map(|v| v.split).collect();
    assert_eq!(splits, [&[rmvp_dataset::Split::Train; 4][..], &[rmvp_dataset::Split::Eval; 2]].concat());
    for held_out in &a.views[4..] {
        assert!(held_out.normals.is_some() && held_out.mask.is_some(), "view {}", held_out.name);
        assert!(a.views[..4].iter().all(|v| (v.camera.center() - held_out.camera.center()).norm() > 0.1));
    }
    // What both layouts hold is identical (NeRSP quantizes AoP to 16 bits and has no DoP).
    for (x, y) in a.views.iter().zip(&b.views) {
        assert!(
            x.stokes == y.stokes && x.mask == y.mask && x.normals == y.normals && x.depth == y.depth,
            "view {}",
            x.name
        );
        assert!(x.polarized == y.polarized && x.camera == y.camera, "view {}", x.name);
    }
    assert!(a.mesh == b.mesh && a.env_map == b.env_map && a.metadata == b.metadata);
    let v = &a.views[0];
    assert!(
        v.stokes.is_some() && v.mask.is_some() && v.normals.is_some() && v.depth.is_some() && v.polarized.is_some()
    );
    assert!(a.mesh.is_some() && a.env_map.is_some());
    assert_eq!(std::fs::metadata(out.join("raw/000.raw")).unwrap().len(), 128 * 96 * 3 / 2);
    assert!(out.join("contact_sheet.png").is_file());
    // Camera-frame normals: the world normals rotated by R.
    let cam_normals =
        rmvp_dataset::io::exr::read_exr(&out.join("camera_normals/001.exr"), &["N.X", "N.Y", "N.Z"]).unwrap();
    let (world, r) = (a.views[1].normals.as_ref().unwrap(), a.views[1].camera.r);
    for (c, w) in cam_normals.data().chunks_exact(3).zip(world.data().chunks_exact(3)).step_by(97) {
        let expected = [0, 1, 2].map(|i| (0..3).map(|j| r[(i, j)] * w[j] as f64).sum::<f64>());
        assert!((0..3).all(|k| (c[k] as f64 - expected[k]).abs() < 1e-5));
    }
    // Same seed, same bytes.
    let again = tmp.path().join("again");
    simulate(&again);
    assert_eq!(std::fs::read(out.join("raw/002.raw")).unwrap(), std::fs::read(again.join("raw/002.raw")).unwrap());
    assert_eq!(
        std::fs::read(out.join("nersp/s1/0001.npy")).unwrap(),
        std::fs::read(again.join("nersp/s1/0001.npy")).unwrap()
    );
    // A conductor renders too (no diffuse lobe: a mirror-like spot).
    ok(&[
        "simulate",
        "-o",
        s(&tmp.path().join("gold")),
        "--res",
        "32x24",
        "--spp",
        "1",
        "--views",
        "1",
        "--conductor",
        "0.25,3.0",
        "--layout",
        "rmvp",
    ]);
    let texture = tmp.path().join("t.png");
    rmvp_dataset::io::png::write_png_u8(&texture, &rmvp_dataset::Image::new(2, 2, 3)).unwrap();
    let err = fails(&["simulate", "-o", s(&again), "--texture", s(&texture)]);
    assert!(err.contains("texture coordinates"), "{err}");
    let err = fails(&["simulate", "-o", s(&again), "--res", "63x48"]);
    assert!(err.contains("even"), "{err}");
    let err = fails(&["simulate", "-o", s(&again), "--rig", "orbit"]);
    assert!(err.contains("invalid value 'orbit'") && err.contains("sphere, turntable"), "{err}");
}

#[test]
fn demosaic_reports_a_truncated_frame_by_name() {
    let tmp = tempfile::tempdir().unwrap();
    let raw = tmp.path().join("cut.raw");
    std::fs::write(&raw, vec![0u8; 1000]).unwrap();
    let err = fails(&["demosaic", s(&raw), "-o", s(&tmp.path().join("o"))]);
    assert!(err.contains("cut.raw") && err.contains("truncated"), "{err}");
    let err = fails(&["demosaic", s(&raw), "-o", "x", "--ccm", "1,0,0"]);
    assert!(err.contains("expected 9 comma-separated numbers"), "{err}");
    let err = fails(&["demosaic", s(&raw), "-o", "x", "--pixel-format", "RGB8"]);
    assert!(err.contains("unsupported pixel format"), "{err}");
    let err = fails(&["demosaic", s(&raw), "-o", "x", "--method", "nearest"]);
    assert!(err.contains("invalid value 'nearest'") && err.contains("edge-aware"), "{err}");
}

/// The demo's release read by MLCommons' `mlcroissant` (validated, its records loaded), its
/// card's front matter by PyYAML and its splits by `rmvp.read_release` (`tests/release_check.py`,
/// from the `.venv` that `./run test` makes), against rmvp's own reading; then tampered with.
fn check_the_release(release: &std::path::Path) {
    let venv = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(".venv/bin");
    let tool = |name: &str| {
        let path = venv.join(name);
        assert!(path.is_file(), "{}: missing; `./run test` installs it into .venv first", path.display());
        std::process::Command::new(path)
    };
    let validated = tool("mlcroissant").args(["validate", "--jsonld"]).arg(release.join("croissant.json")).output();
    let validated = validated.unwrap();
    let log = String::from_utf8_lossy(&validated.stderr);
    assert!(validated.status.success() && !log.contains("WARNING") && !log.contains("ERROR"), "{log}");
    let read = tool("python")
        .arg(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/release_check.py"))
        .arg(release)
        .output();
    let read = read.unwrap();
    assert!(read.status.success(), "{}", String::from_utf8_lossy(&read.stderr));
    let seen: serde_json::Value = serde_json::from_slice(&read.stdout).unwrap();

    // Every view's record is rmvp's reading of the view: camera to the last bit a JSON number
    // keeps, files that are the view's.
    let dir = release.join("spot/rmvp");
    let scene = rmvp_dataset::layout::read_scene(&dir).unwrap();
    let manifest = rmvp_dataset::layout::rmvp::read_manifest(&dir).unwrap();
    let views = seen["records"]["views"].as_array().unwrap();
    assert_eq!(views.len(), scene.views.len(), "{seen}");
    for (view, record) in scene.views.iter().zip(&manifest.views) {
        let found =
            views.iter().find(|r| r["view"] == view.name.as_str()).unwrap_or_else(|| panic!("{}: {seen}", view.name));
        assert_eq!(
            (found["object"].as_str(), found["split"].as_str()),
            (Some("spot"), Some(view.split.to_string().as_str()))
        );
        assert_eq!(
            (found["width"].as_u64(), found["height"].as_u64()),
            (Some(view.camera.width as u64), Some(view.camera.height as u64))
        );
        let (k, r, t) = (&view.camera.k, &view.camera.r, &view.camera.t);
        let mut expected =
            vec![("fx", k[(0, 0)]), ("fy", k[(1, 1)]), ("cx", k[(0, 2)]), ("cy", k[(1, 2)]), ("skew", k[(0, 1)])];
        for i in 0..3 {
            for j in 0..3 {
                expected.push((["r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33"][3 * i + j], r[(i, j)]));
            }
            expected.push((["t1", "t2", "t3"][i], t[i]));
        }
        for (name, value) in expected {
            let got = found[name].as_f64().unwrap_or(f64::NAN);
            assert!(
                (got - value).abs() <= 1e-12 * value.abs().max(1.0),
                "view {} {name}: {got} against {value}",
                view.name
            );
        }
        let stokes = format!("spot/rmvp/{}", record.files.stokes.as_ref().unwrap());
        assert_eq!(found["stokes"].as_str(), Some(stokes.as_str()));
        assert!(release.join(&stokes).is_file() && found["normal"].is_null(), "{found}");
    }
    let objects = &seen["records"]["objects"];
    assert_eq!(objects.as_array().map(Vec::len), Some(1), "{seen}");
    assert_eq!((objects[0]["object"].as_str(), objects[0]["views"].as_u64()), (Some("spot"), Some(6)));
    assert_eq!(objects[0]["build_record"].as_str(), Some("spot/build.json"));

    // The card's front matter says what the release's record says.
    let info = rmvp_pipeline::demo::demo_release_info();
    let card = &seen["front_matter"];
    assert_eq!(card["license"].as_str(), info.license.map(|l| l.to_lowercase()).as_deref(), "{card}");
    assert_eq!(card["pretty_name"].as_str(), info.title.as_deref(), "{card}");
    assert_eq!(card["size_categories"], serde_json::json!(["n<1K"]));
    let files = &card["configs"][0]["data_files"];
    assert_eq!((files[0]["split"].as_str(), files[1]["split"].as_str()), (Some("train"), Some("eval")), "{card}");
    for file in files.as_array().unwrap() {
        assert!(release.join(file["path"].as_str().unwrap()).is_file(), "{card}");
    }
    let names: Vec<&str> = scene.views.iter().map(|v| v.name.as_str()).collect();
    assert_eq!(seen["read_release"], serde_json::json!({"train": {"spot": names}, "eval": {"spot": []}}));

    // A file changed after publishing: verify names it, twice (SHA256SUMS and Croissant), and
    // so does read_release.
    let changed = release.join(stokes_of(&manifest, 2));
    let mut bytes = std::fs::read(&changed).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    std::fs::write(&changed, bytes).unwrap();
    let err = fails(&["dataset", "verify", s(release)]);
    let name = stokes_of(&manifest, 2);
    assert!(err.contains(&format!("croissant.json: {name}: sha256 differs")), "{err}");
    assert!(err.contains(&format!("{name}: checksum differs from SHA256SUMS")), "{err}");
    let script = format!(
        "import rmvp\ntry:\n    rmvp.read_release({:?})\nexcept rmvp.InputError as e:\n    print(e)",
        s(release)
    );
    let refused = tool("python").args(["-c", &script]).output().unwrap();
    assert!(String::from_utf8_lossy(&refused.stdout).contains(&name), "{}", String::from_utf8_lossy(&refused.stderr));
}

/// The release path of view `k`'s Stokes file.
fn stokes_of(manifest: &rmvp_dataset::layout::rmvp::SceneManifest, k: usize) -> String {
    format!("spot/rmvp/{}", manifest.views[k].files.stokes.as_ref().unwrap())
}

#[test]
fn demosaic_refuses_a_plain_sensor_format_unless_the_sensor_is_declared_polarized() {
    let tmp = tempfile::tempdir().unwrap();
    let raw = tmp.path().join("frame.raw");
    std::fs::write(&raw, (0..64u8).collect::<Vec<_>>()).unwrap();
    let size = ["--width", "8", "--height", "8"];
    for (format, cells) in [("BayerRG8", "colour filters"), ("Mono8", "plain pixels")] {
        let out = tmp.path().join(format);
        let err = fails(&[&["demosaic", s(&raw), "-o", s(&out), "--pixel-format", format][..], &size].concat());
        assert!(err.contains(format) && err.contains(cells) && err.contains("--polarized-sensor"), "{err}");
        assert!(!out.exists(), "{format}: nothing written");
        let declared =
            [&["demosaic", s(&raw), "-o", s(&out), "--pixel-format", format, "--polarized-sensor"][..], &size];
        let done = common::rmvp(&declared.concat());
        assert!(done.status.success(), "{format}: {}", String::from_utf8_lossy(&done.stderr));
        assert!(out.join("frame_000.png").exists(), "{format}");
    }
}

#[test]
fn check_finds_the_fixtures_aop_in_our_frame_and_a_mirrored_copy_mirrored() {
    let tmp = tempfile::tempdir().unwrap();
    for name in ["spot_nersp", "bunny_nersp"] {
        let scene = fixture(name);
        let out = common::rmvp(&["dataset", "check", s(&scene), "--json"]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let judged: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(judged["verdict"], "stored", "{judged}");
        let (stored, mirrored) = (judged["stored"].as_f64().unwrap(), judged["mirrored"].as_f64().unwrap());
        eprintln!("{name}: {stored:.3} as stored, {mirrored:.3} mirrored");
        assert!(stored > 0.25 && mirrored < 0.1, "{judged}");

        let flipped = tmp.path().join(name);
        ok(&["dataset", "convert", s(&scene), s(&flipped), "--layout", "nersp", "--mirror-aop"]);
        let err = fails(&["dataset", "check", s(&flipped)]);
        assert!(err.contains("mirrored") && err.contains("--mirror-aop"), "{err}");
        // Mirrored back, the copy is the fixture again as far as the check can tell.
        let back = tmp.path().join(format!("{name}_back"));
        ok(&["dataset", "convert", s(&flipped), s(&back), "--layout", "nersp", "--mirror-aop"]);
        assert!(ok(&["dataset", "check", s(&back)]).contains(&format!("{stored:.3} as stored")));
    }
}

#[test]
fn info_summarises_and_validates_both_layouts() {
    let spot = fixture("spot_nersp");
    let text = ok(&["info", s(&spot)]);
    assert!(
        text.contains("nersp layout") && text.contains("8 (6 train, 2 eval)") && text.contains("2930 vertices"),
        "{text}"
    );
    let summary: SceneSummary = serde_json::from_str(&ok(&["info", s(&spot), "--json"])).unwrap();
    assert_eq!(summary.views.len(), 8);
    assert_eq!(summary.views[0].contents, ["stokes", "mask", "aop", "polarizers", "preview", "normals"]);
    assert_eq!(summary.views[7].split, rmvp_dataset::Split::Eval);

    let err = fails(&["info", s(&spot.join("s0"))]);
    assert!(err.contains("not a scene"), "{err}");
    // `rmvp info` is `rmvp dataset info`.
    assert_eq!(ok(&["dataset", "info", s(&spot), "--json"]), ok(&["info", s(&spot), "--json"]));
}

#[test]
fn convert_round_trips_between_layouts() {
    let bunny = fixture("bunny_nersp");
    let tmp = tempfile::tempdir().unwrap();
    let (ours, back) = (tmp.path().join("ours"), tmp.path().join("back"));
    ok(&["dataset", "convert", s(&bunny), s(&ours), "--layout", "rmvp"]);
    assert!(ours.join("scene.json").is_file() && ours.join("views/000/stokes.exr").is_file());
    assert!(ok(&["info", s(&ours)]).contains("rmvp layout"));
    ok(&["convert", s(&ours), s(&back), "--to", "nersp"]); // the older spelling still works
    let a = rmvp_dataset::layout::read_scene(&bunny).unwrap();
    let b = rmvp_dataset::layout::read_scene(&back).unwrap();
    assert!(a == b, "scene changed through convert");
    let err = fails(&["convert", s(&bunny), s(&ours), "--to", "rmvp"]);
    assert!(err.contains("not empty"), "{err}");
    let err = fails(&["convert", s(&bunny), s(&tmp.path().join("x")), "--to", "canonical"]);
    assert!(err.contains("invalid value 'canonical'") && err.contains("nersp, rmvp"), "{err}");
}

#[test]
fn exports_give_the_same_cameras_and_rmvp3d_reads_back() {
    let spot = fixture("spot_nersp");
    let scene = rmvp_dataset::layout::read_scene(&spot).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let dir = |name: &str| tmp.path().join(name);
    for format in ["nerfstudio", "colmap", "rmvp3d", "pandora"] {
        ok(&["dataset", "export", s(&spot), "--format", format, "-o", s(&dir(format))]);
    }
    let with_stokes: Vec<&rmvp_dataset::View> = scene.views.iter().filter(|v| v.stokes.is_some()).collect();
    let same = |cameras: Vec<(String, rmvp_dataset::Camera)>| {
        assert_eq!(cameras.len(), with_stokes.len());
        for ((name, camera), view) in cameras.iter().zip(&with_stokes) {
            assert!(name.contains(&view.name), "{name} for {}", view.name);
            assert!((camera.k - view.camera.k).abs().max() < 1e-6, "{name}");
            assert!((camera.r - view.camera.r).abs().max() < 1e-9 && (camera.t - view.camera.t).abs().max() < 1e-9);
        }
    };
    let transforms = dir("nerfstudio").join("transforms.json");
    same(rmvp_dataset::exchange::nerfstudio::Transforms::read(&transforms).unwrap().cameras(&transforms).unwrap());
    assert!(dir("nerfstudio").join("masks/000.png").is_file());
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&transforms).unwrap()).unwrap();
    let train: Vec<String> = with_stokes
        .iter()
        .filter(|v| v.split == rmvp_dataset::Split::Train)
        .map(|v| format!("images/{}.png", v.name))
        .collect();
    assert_eq!(json["train_filenames"], serde_json::json!(train), "the dataset's split");
    assert!(json["fl_x"].is_number(), "one camera: intrinsics at the top level");
    let sparse = dir("colmap").join("sparse/0");
    same(rmvp_dataset::exchange::colmap::ColmapModel::read(&sparse).unwrap().cameras(&sparse).unwrap());
    assert!(dir("colmap").join("images/000.png").is_file());
    // RMVP3D (the release's mask/ folder) and PANDORA read back directly: the same cameras and
    // masks; RMVP3D's Stokes bit for bit.
    assert!(dir("rmvp3d").join("mask/0000.png").is_file());
    let pandora = rmvp_dataset::layout::read_scene(&dir("pandora")).unwrap();
    for (a, b) in pandora.views.iter().zip(&with_stokes) {
        assert_eq!(a.mask, b.mask, "view {}", b.name);
        assert!((a.camera.k - b.camera.k).abs().max() < 1e-9 && (a.camera.t - b.camera.t).abs().max() < 1e-12);
    }
    // RMVP3D back into our layout: the same Stokes, masks and cameras.
    ok(&["dataset", "import", s(&dir("rmvp3d")), "-o", s(&dir("back"))]);
    let back = rmvp_dataset::layout::read_scene(&dir("back")).unwrap();
    assert_eq!(back.normalization, scene.normalization);
    for (a, b) in back.views.iter().zip(&with_stokes) {
        assert_eq!((&a.stokes, &a.mask), (&b.stokes, &b.mask), "view {}", b.name);
    }
    let err = fails(&["dataset", "export", s(&spot), "--format", "blender", "-o", s(&dir("x"))]);
    assert!(err.contains("invalid value 'blender'") && err.contains("nerfstudio, colmap, rmvp3d, pandora"), "{err}");
    let err = fails(&["dataset", "export", s(&spot), "--format", "colmap", "-o", s(&dir("colmap"))]);
    assert!(err.contains("not empty"), "{err}");
}

#[test]
fn stokes_command_reproduces_the_fixture_azimuth_map() {
    let spot = fixture("spot_nersp");
    let tmp = tempfile::tempdir().unwrap();
    let images: Vec<String> =
        ["000", "045", "090", "135"].iter().map(|a| format!("{}/polarized/0002_{a}.png", spot.display())).collect();
    let mut args = vec!["stokes"];
    args.extend(images.iter().map(String::as_str));
    args.extend(["-o", s(tmp.path()), "--stem", "v2"]);
    ok(&args);
    let aop = rmvp_dataset::io::exr::read_exr(&tmp.path().join("v2_aop.exr"), &["AoP"]).unwrap();
    let stored = rmvp_dataset::io::png::read_png_u16(&spot.join("input_azimuth_maps/0002.png")).unwrap();
    let dop = rmvp_dataset::io::exr::read_exr(&tmp.path().join("v2_dop.exr"), &["DoP"]).unwrap();
    // From 16-bit quantized polarizer images the AoP is good where the light is polarized.
    let mut errors: Vec<f32> = (0..aop.data().len())
        .filter(|&k| dop.data()[k] > 0.05 && stored.data()[4 * k + 3] > 0)
        .map(|k| {
            let d = (aop.data()[k] - rmvp_dataset::polarization::aop_from_u16(stored.data()[4 * k]))
                .rem_euclid(std::f32::consts::PI);
            d.min(std::f32::consts::PI - d).to_degrees()
        })
        .collect();
    errors.sort_by(f32::total_cmp);
    assert!(errors.len() > 1000);
    assert!(
        errors[errors.len() / 2] < 0.05 && errors[errors.len() * 99 / 100] < 1.0,
        "median {} p99 {}",
        errors[errors.len() / 2],
        errors[errors.len() * 99 / 100]
    );
}

#[test]
fn eval_and_render_normals_on_a_fixture() {
    let spot = fixture("spot_nersp");
    let gt = spot.join("gt/mesh.ply");
    let tmp = tempfile::tempdir().unwrap();
    let json: Evaluation = serde_json::from_str(&ok(&[
        "eval",
        s(&spot),
        "--pred",
        s(&gt),
        "--gt",
        s(&gt),
        "--json",
        "--max-samples",
        "20000",
        "-o",
        s(tmp.path()),
    ]))
    .unwrap();
    assert!(json.surface.chamfer < 1e-6, "{json:?}");
    assert_eq!(json.surface.fscore, 1.0);
    assert!(json.normal_mae_deg.unwrap() < 3.0, "{json:?}");
    assert_eq!(json.normal_views.len(), 8);
    assert!(tmp.path().join("006_normal_error.png").is_file());
    let text = ok(&["eval", "--pred", s(&gt), "--gt", s(&gt), "--max-samples", "1000"]);
    assert!(text.contains("chamfer") && text.contains("F-score"), "{text}");

    let out = tmp.path().join("normals");
    ok(&["dataset", "render-normals", s(&spot), "--mesh", s(&gt), "-o", s(&out)]);
    let ours = rmvp_dataset::io::exr::read_exr(&out.join("007_normal.exr"), &["N.X", "N.Y", "N.Z"]).unwrap();
    let theirs = rmvp_dataset::io::exr::read_exr(&spot.join("gt/normal/007.exr"), &["N.X", "N.Y", "N.Z"]).unwrap();
    let mut errors: Vec<f64> = ours
        .data()
        .chunks_exact(3)
        .zip(theirs.data().chunks_exact(3))
        .filter(|(a, b)| a.iter().any(|v| *v != 0.0) && b.iter().any(|v| *v != 0.0))
        .map(|(a, b)| ((a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) as f64).clamp(-1.0, 1.0).acos().to_degrees())
        .collect();
    errors.sort_by(f64::total_cmp);
    assert!(errors.len() > 1000 && errors[errors.len() / 2] < 1.0, "median {}", errors[errors.len() / 2]);
    assert!(out.join("007_mask.png").is_file() && out.join("007_depth.exr").is_file());
    let err = fails(&["eval", "--pred", s(&spot.join("nope.ply")), "--gt", s(&gt)]);
    assert!(err.contains("nope.ply"), "{err}");
}

#[test]
fn align_recovers_a_moved_scaled_copy() {
    let spot = fixture("spot_nersp").join("gt/mesh.ply");
    let mesh = rmvp_dataset::Mesh::read(&spot).unwrap();
    // The scan: the mesh turned 30 degrees about y, scaled by 1.1 and moved.
    let (c, s_) = (30f32.to_radians().cos(), 30f32.to_radians().sin());
    let moved = rmvp_dataset::Mesh {
        positions: mesh
            .positions
            .iter()
            .map(|p| [1.1 * (c * p[0] + s_ * p[2]) + 0.3, 1.1 * p[1] - 0.2, 1.1 * (-s_ * p[0] + c * p[2]) + 0.1])
            .collect(),
        normals: None,
        ..mesh
    };
    let tmp = tempfile::tempdir().unwrap();
    let scan = tmp.path().join("scan.ply");
    moved.write(&scan).unwrap();
    let out = tmp.path().join("aligned");
    let text = ok(&["align", "--scan", s(&scan), "--to", s(&spot), "-o", s(&out)]);
    assert!(text.contains("rotation 30.0"), "{text}");
    let alignment = Alignment::read(&out.join("alignment.json")).unwrap();
    assert!((alignment.transform.s - 1.0 / 1.1).abs() < 1e-3, "{alignment:?}");
    assert!((alignment.transform.inverse().s - 1.1).abs() < 1e-3);
    // The aligned scan lies on the target: Chamfer about zero.
    let eval: Evaluation = serde_json::from_str(&ok(&[
        "eval",
        "--pred",
        s(&out.join("aligned.ply")),
        "--gt",
        s(&spot),
        "--json",
        "--max-samples",
        "20000",
    ]))
    .unwrap();
    assert!(eval.surface.chamfer < 1e-3, "{eval:?}");
}

#[test]
fn recon_resumes_where_it_stopped_and_reports_bad_input() {
    let tmp = tempfile::tempdir().unwrap();
    let fixture = rmvp_testkit::fixture("spot_nersp");
    let (straight, stopped) = (tmp.path().join("straight"), tmp.path().join("stopped"));
    let recon = |dir: &Path, extra: &[&str]| {
        let mut args = vec!["recon", s(&fixture), "-o", s(dir), "--iters", "6", "--batch", "32", "--mesh-res", "32"];
        args.extend_from_slice(extra);
        ok(&args)
    };
    assert!(recon(&straight, &[]).contains("6 iterations"));
    assert!(recon(&stopped, &["--stop-after", "4"]).contains("stopped at iteration 4 of 6"));
    assert!(!stopped.join("mesh.ply").exists());
    assert!(recon(&stopped, &["--resume"]).contains("6 iterations"));
    // Bit for bit: the same loss log and the same mesh as the uninterrupted run.
    let log = std::fs::read_to_string(straight.join("log.jsonl")).unwrap();
    assert_eq!(log.lines().count(), 6);
    assert_eq!(log, std::fs::read_to_string(stopped.join("log.jsonl")).unwrap());
    assert_eq!(std::fs::read(straight.join("mesh.ply")).unwrap(), std::fs::read(stopped.join("mesh.ply")).unwrap());
    for file in ["comparison.png", "residuals.png", "normals/006.png", "normals/006.exr", "stokes/000_s2.exr"] {
        assert!(stopped.join(file).is_file(), "{file}");
    }
    // The residuals' figures: one record per training view, over pixels the surface covers.
    let residuals: Vec<serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(stopped.join("residuals.json")).unwrap()).unwrap();
    let views: Vec<&str> = residuals.iter().map(|r| r["view"].as_str().unwrap()).collect();
    assert_eq!(views, ["000", "001", "002", "003", "004", "005"]);
    assert!(residuals.iter().all(|r| r["pixels"].as_u64().unwrap() > 0), "{residuals:?}");

    // The learned polarization scale: logged at every step, printed at the end, and moved by
    // training from its start at 1 (the dielectric).
    let learned = tmp.path().join("learned");
    let printed = recon(&learned, &["--learned-polarization", "--mesh-only"]);
    let scales: Vec<f64> = std::fs::read_to_string(learned.join("log.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["polarization"].as_f64().unwrap())
        .collect();
    assert_eq!(scales.len(), 6);
    assert_eq!(scales[0], 1.0);
    assert!(scales[5] < 1.0 && scales[5] > 0.9, "{scales:?}");
    assert!(printed.contains("specular polarization scale learned"), "{printed}");
    assert!(!log.contains("polarization"), "the default model learns no scale");

    let err = fails(&["recon", s(&tmp.path().join("missing")), "-o", s(&tmp.path().join("x"))]);
    assert!(err.contains("missing"), "{err}");
}

#[test]
fn recon_trains_at_a_downscale_and_writes_outputs_at_full_size() {
    let tmp = tempfile::tempdir().unwrap();
    let fixture = rmvp_testkit::fixture("spot_nersp");
    let out = tmp.path().join("half");
    let args = ["recon", s(&fixture), "-o", s(&out), "--iters", "4", "--batch", "32", "--mesh-res", "24"];
    ok(&[&args[..], &["--downscale", "2"]].concat());
    let full = rmvp_dataset::io::png::read_png_u8(&fixture.join("image/0000.png")).unwrap().size();
    for file in ["normals/000.png", "normals/006.png"] {
        let size = rmvp_dataset::io::png::read_png_u8(&out.join(file)).unwrap().size();
        assert_eq!(size, full, "{file} at the scene's size");
    }
    // The factor is part of the run: resuming at another one is refused.
    let err = fails(&[&args[..], &["--downscale", "1", "--resume"]].concat());
    assert!(err.contains("checkpoint"), "{err}");
    let err = fails(&[&args[..], &["--downscale", "0"]].concat());
    assert!(err.contains("the training downscale factor must be at least 1"), "{err}");
}

#[test]
fn recon_refuses_a_start_without_a_surface_and_names_the_radius_that_has_one() {
    let tmp = tempfile::tempdir().unwrap();
    let fixture = rmvp_testkit::fixture("spot_nersp");
    let out = tmp.path().join("paper");
    let args = ["recon", s(&fixture), "-o", s(&out), "--preset", "paper", "--iters", "1", "--batch", "32"];
    let err = fails(&[&args[..], &["--initial-radius", "0.2"]].concat());
    let (_, least) = err.split_once("a radius of at least ").expect(&err);
    let least = least.split_whitespace().next().unwrap();
    assert!(err.contains("0.2 leaves this network's start without a surface"), "{err}");
    assert!(!out.exists(), "refused before anything is written");
    // The radius it names trains.
    ok(&[&args[..], &["--initial-radius", least, "--mesh-res", "24", "--mesh-only"]].concat());
    assert_eq!(std::fs::read_to_string(out.join("log.jsonl")).unwrap().lines().count(), 1);
}

#[test]
fn recon_writes_progress_lines_into_a_log_during_training_and_none_when_quiet() {
    let tmp = tempfile::tempdir().unwrap();
    let spot = rmvp_testkit::fixture("spot_nersp");
    let run = |extra: &[&str]| {
        let out = tmp.path().join(format!("out{}", extra.len()));
        let log = std::fs::File::create(tmp.path().join("stderr.log")).unwrap();
        let mut args = vec!["recon", s(&spot), "-o", s(&out), "--iters", "80", "--batch", "32", "--mesh-only"];
        args.extend(["--mesh-res", "24"]);
        args.extend_from_slice(extra);
        let status = std::process::Command::new(env!("CARGO_BIN_EXE_rmvp")).args(&args).stderr(log).status().unwrap();
        assert!(status.success());
        std::fs::read_to_string(tmp.path().join("stderr.log")).unwrap()
    };
    // Standard error into a file: plain lines (no bar), several while it trains.
    let log = run(&[]);
    let during: Vec<&str> = log
        .lines()
        .filter(|l| {
            l.starts_with("recon: ") && !l.starts_with("recon: 80/80") && l.contains("/80 (") && l.contains("/s")
        })
        .collect();
    assert!(during.len() >= 3, "{log}");
    assert!(!log.contains('\r') && !log.contains("=>"), "{log}");
    assert!(!run(&["--quiet"]).contains("recon: "));
}

#[test]
fn the_cli_reference_in_docs_is_the_one_the_definitions_give() {
    let generated = ok(&["cli-reference"]);
    let committed = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/cli.md")).unwrap();
    assert!(
        generated == committed,
        "docs/cli.md is out of date: regenerate it with `cargo run --release -- cli-reference > docs/cli.md`"
    );
}

#[test]
fn a_folder_of_the_wrong_kind_is_told_what_it_is_and_what_to_run() {
    let spot = rmvp_testkit::fixture("spot_nersp");
    let tmp = tempfile::tempdir().unwrap();
    let err = fails(&["calibrate", s(&spot), "-o", s(&tmp.path().join("camera.json"))]);
    assert!(err.contains("is a folder but not a capture session") && !err.contains("PNG"), "{err}");
    let err = fails(&["dataset", "build", s(&spot), "-o", s(&tmp.path().join("dataset"))]);
    assert!(err.contains("a scene in the nersp layout, not a capture session") && err.contains("rmvp recon"), "{err}");
}

#[test]
fn the_board_page_warns_when_it_does_not_fit_the_paper() {
    let tmp = tempfile::tempdir().unwrap();
    let page = tmp.path().join("board.png");
    let board = |extra: &[&str]| {
        let mut args = vec!["board", "-o", s(&page), "--dpi", "60"];
        args.extend_from_slice(extra);
        let out = common::rmvp(&args);
        assert!(out.status.success());
        String::from_utf8(out.stderr).unwrap()
    };
    assert!(!board(&[]).contains("warning"), "the lab's 8x6 board of 30 mm fits A4");
    for paper in ["a4", "letter"] {
        let err = board(&["--squares", "10x8", "--paper", paper]);
        assert!(err.contains("the page is 320 x 260 mm and does not fit"), "{err}");
    }
    assert!(!board(&["--squares", "10x8", "--paper", "a3"]).contains("warning"));
}
