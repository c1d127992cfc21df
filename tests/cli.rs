//! End-to-end tests: the `rmvp` binary as users run it.

use std::path::{Path, PathBuf};
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

fn fixture(name: &str) -> PathBuf {
    let root = std::env::var_os("RMVP_FIXTURES")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/fixtures"));
    let dir = root.join(name);
    assert!(dir.is_dir(), "fixture {} missing; set RMVP_FIXTURES", dir.display());
    dir
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn demo_recovers_the_known_polarization_and_demosaic_reproduces_it() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("demo");
    let stdout = ok(&["demo", "-o", s(&out)]);
    assert!(stdout.contains("AoP error"), "{stdout}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert!(report["aop_error_deg"]["median"].as_f64().unwrap() < 0.1, "{report}");
    assert!(report["aop_error_deg"]["p95"].as_f64().unwrap() < 0.5, "{report}");
    assert!(report["dop_abs_error"]["p95"].as_f64().unwrap() < 0.002, "{report}");
    assert!(report["s0_rel_error"]["p95"].as_f64().unwrap() < 0.005, "{report}");
    assert!(report["aop_error_deg"]["pixels"].as_u64().unwrap() > 100_000);
    let sheet = rmvp_dataset::io::png::read_png_u8(&out.join("contact_sheet.png")).unwrap();
    assert_eq!(sheet.size(), (2 * 306 + 12, 3 * 256 + 16));

    // The raw frame the demo wrote goes through `rmvp demosaic` to the same Stokes.
    let again = tmp.path().join("again");
    ok(&["demosaic", s(&out.join("frame.raw")), "-o", s(&again)]);
    let read = |p: PathBuf| rmvp_dataset::layout::canonical::read_stokes(&p).unwrap();
    assert_eq!(read(again.join("frame_stokes.exr")), read(out.join("frame_stokes.exr")));
    for suffix in ["000.png", "045.png", "090.png", "135.png", "aop.exr", "dop.exr", "aop.png", "dop.png", "s0.png"] {
        assert!(again.join(format!("frame_{suffix}")).is_file(), "{suffix}");
    }
}

#[test]
fn demosaic_reports_a_truncated_frame_by_name() {
    let tmp = tempfile::tempdir().unwrap();
    let raw = tmp.path().join("cut.raw");
    std::fs::write(&raw, vec![0u8; 1000]).unwrap();
    let err = fails(&["demosaic", s(&raw), "-o", s(&tmp.path().join("o"))]);
    assert!(err.contains("cut.raw") && err.contains("truncated"), "{err}");
    let err = fails(&["demosaic", s(&raw), "-o", "x", "--pixel-format", "RGB8"]);
    assert!(err.contains("unsupported pixel format"), "{err}");
}

#[test]
fn info_summarises_and_validates_both_layouts() {
    let spot = fixture("spot_nersp");
    let text = ok(&["info", s(&spot)]);
    assert!(
        text.contains("nersp layout") && text.contains("8 (6 train, 2 eval)") && text.contains("2930 vertices"),
        "{text}"
    );
    let json: serde_json::Value = serde_json::from_str(&ok(&["info", s(&spot), "--json"])).unwrap();
    assert_eq!(json["views"].as_array().unwrap().len(), 8);
    assert_eq!(
        json["views"][0]["contents"],
        serde_json::json!(["stokes", "mask", "aop", "polarizers", "preview", "normals"])
    );
    assert_eq!(json["views"][7]["split"], "eval");

    let err = fails(&["info", s(&spot.join("s0"))]);
    assert!(err.contains("not a scene"), "{err}");
}

#[test]
fn convert_round_trips_between_layouts() {
    let bunny = fixture("bunny_nersp");
    let tmp = tempfile::tempdir().unwrap();
    let (ours, back) = (tmp.path().join("ours"), tmp.path().join("back"));
    ok(&["convert", s(&bunny), s(&ours), "--to", "rmvp"]);
    assert!(ours.join("scene.json").is_file() && ours.join("views/000/stokes.exr").is_file());
    assert!(ok(&["info", s(&ours)]).contains("rmvp layout"));
    ok(&["convert", s(&ours), s(&back), "--to", "nersp"]);
    let a = rmvp_dataset::layout::read_scene(&bunny).unwrap();
    let b = rmvp_dataset::layout::read_scene(&back).unwrap();
    assert_eq!(a, b);
    let err = fails(&["convert", s(&bunny), s(&ours), "--to", "rmvp"]);
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
