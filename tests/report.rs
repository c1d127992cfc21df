//! The page `rmvp recon` writes beside its results (`report.html`), opened offline in headless
//! Chromium: no error, the 3D view draws the mesh from two directions and colours it by its
//! distance to the truth, the plots, tables and pictures are there.

use rmvp_testkit::fixture;

mod common;
use common::{fails, ok, s};
#[path = "common/browser.rs"]
mod browser;

#[test]
fn a_reconstructions_page_shows_the_mesh_in_3d_its_losses_and_figures_offline() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("recon");
    let scene = fixture("spot_nersp");
    let stdout = ok(&["recon", s(&scene), "-o", s(&out), "--iters", "40", "--mesh-res", "64"]);
    let page = out.join("report.html");
    assert!(stdout.contains("report.html") && page.is_file(), "{stdout}");
    let html = std::fs::read_to_string(&page).unwrap();
    // Self-contained: nothing is fetched.
    for remote in ["http://", "https://", "src=\"//"] {
        assert!(!html.contains(remote), "the page fetches {remote}");
    }
    assert!(html.contains("<svg class=\"plot\"") && html.matches("<polyline").count() >= 5, "the loss plot");
    assert!(html.contains("<caption>Options</caption>") && html.contains("The model against its input"));
    assert!(html.contains("<caption>Times</caption>") && out.join("times.json").is_file());
    assert!(html.matches("src=\"data:image/png;base64,").count() >= 2, "comparison and residual pictures");

    // The normal error against the truth, measured at the run's last iteration, plotted.
    assert!(html.contains("aria-label=\"normal error against iteration\"") && html.contains("<circle"));

    let result = browser::selftest(&page, &tmp.path().join("profile"));
    assert_eq!(result["errors"], serde_json::json!([]), "{result}");
    // The spot (a blob after 40 iterations) covers part of the canvas from both directions;
    // coloured by its distance to the truth, most of it is far (the ramp's warm half: beyond
    // the F-score threshold).
    let view = &result["views"][0];
    assert!(browser::covered(view).iter().all(|&c| c > 0.02 && c < 0.9), "{result}");
    let blob_warm = view["byError"]["warm"].as_f64().unwrap();
    // The truth itself as the reconstruction: all of it cold.
    let truth = out.join("truth-as-mesh");
    std::fs::create_dir(&truth).unwrap();
    std::fs::copy(scene.join("gt/mesh.ply"), truth.join("mesh.ply")).unwrap();
    ok(&["report", s(&truth), "--scene", s(&scene)]);
    let result = browser::selftest(&truth.join("report.html"), &tmp.path().join("profile"));
    let truth_warm = result["views"][0]["byError"]["warm"].as_f64().unwrap();
    eprintln!("coloured by error, the share of warm pixels: the blob {blob_warm:.3}, the truth {truth_warm:.3}");
    assert!(blob_warm > 0.3 && truth_warm < 0.01, "warm share: the blob {blob_warm:.3}, the truth {truth_warm:.3}");

    // Again from the folder alone, with the scene's cameras.
    std::fs::remove_file(&page).unwrap();
    let again = ok(&["report", s(&out), "--scene", s(&scene)]);
    assert!(again.trim().ends_with("report.html") && page.is_file(), "{again}");
    assert!(std::fs::read_to_string(&page).unwrap().contains("\"frustums\":["));
    // The parts of the mesh that no training view sees are said on the page; a broken record
    // of them is named, once.
    let parts = out.join("mesh_parts.json");
    assert!(parts.is_file());
    let record = r#"{"parts": 2, "pixels": 900, "unseen": [{"seen": 1, "crossed": 40, "faces": 120}], "kept": false}"#;
    std::fs::write(&parts, record).unwrap();
    ok(&["report", s(&out)]);
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(html.contains("1 part of 2 (120 triangles) that no training view sees"), "the unseen part");
    std::fs::write(&parts, "{\"parts\": \"two\"}").unwrap();
    let error = fails(&["report", s(&out)]);
    assert_eq!(error.matches("mesh_parts.json").count(), 1, "{error}");
    std::fs::remove_file(&parts).unwrap();
    // A broken log is named, once.
    std::fs::write(out.join("log.jsonl"), "{\"iteration\": 0\n").unwrap();
    let error = fails(&["report", s(&out)]);
    assert_eq!(error.matches("log.jsonl").count(), 1, "{error}");
}
