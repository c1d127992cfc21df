//! The page `rmvp recon` writes beside its results (`report.html`), opened offline in headless
//! Chromium (Debian `chromium`, installed by `scripts/install-system-deps.sh test`): no error,
//! the 3D view draws the mesh from two directions, the plot, tables and pictures are there.

use rmvp_testkit::fixture;
use std::process::Command;

mod common;
use common::{fails, ok, s};

/// The page's DOM after its scripts ran, with `#selftest` in the address.
fn rendered_dom(page: &std::path::Path, profile: &std::path::Path) -> String {
    let chromium = ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|c| Command::new(c).arg("--version").output().is_ok_and(|o| o.status.success()))
        .expect("Chromium is needed for this test: run scripts/install-system-deps.sh test");
    let out = Command::new(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--enable-unsafe-swiftshader",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--virtual-time-budget=8000",
            "--dump-dom",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("file://{}#selftest", page.display()))
        .output()
        .unwrap();
    String::from_utf8_lossy(&out.stdout).into_owned()
}

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
    assert!(html.matches("src=\"data:image/png;base64,").count() >= 2, "comparison and residual pictures");

    let dom = rendered_dom(&page, &tmp.path().join("profile"));
    let selftest = dom
        .split("<pre id=\"selftest\" hidden=\"\">")
        .nth(1)
        .and_then(|rest| rest.split("</pre>").next())
        .unwrap_or_else(|| panic!("no self-test in the page: {}", &dom[..dom.len().min(500)]));
    let result: serde_json::Value = serde_json::from_str(selftest).unwrap();
    assert_eq!(result["errors"], serde_json::json!([]), "{result}");
    // The spot (a blob after 40 iterations) covers part of the canvas from both directions.
    let covered: Vec<f64> = result["covered"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    assert!(covered.len() == 2 && covered.iter().all(|&c| c > 0.02 && c < 0.9), "{result}");

    // Again from the folder alone, with the scene's cameras.
    std::fs::remove_file(&page).unwrap();
    let again = ok(&["report", s(&out), "--scene", s(&scene)]);
    assert!(again.trim().ends_with("report.html") && page.is_file(), "{again}");
    assert!(std::fs::read_to_string(&page).unwrap().contains("\"frustums\":["));
    // A broken log is named, once.
    std::fs::write(out.join("log.jsonl"), "{\"iteration\": 0\n").unwrap();
    let error = fails(&["report", s(&out)]);
    assert_eq!(error.matches("log.jsonl").count(), 1, "{error}");
}
