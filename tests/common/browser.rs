//! A report page opened in headless Chromium (Debian `chromium`, installed by
//! `scripts/install-system-deps.sh test`) with `#selftest` in its address: what its 3D views
//! drew, as the page's script writes it into `#selftest`.

use std::path::Path;
use std::process::Command;

/// The page's self-test after its scripts ran: `{"views": [{"id", "covered": [two
/// directions], "byError": {"covered", "warm"} or null}], "errors": [...]}`; `profile` is a
/// scratch folder for the browser.
pub fn selftest(page: &Path, profile: &Path) -> serde_json::Value {
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
    let dom = String::from_utf8_lossy(&out.stdout);
    let result = dom
        .split("<pre id=\"selftest\" hidden=\"\">")
        .nth(1)
        .and_then(|rest| rest.split("</pre>").next())
        .unwrap_or_else(|| panic!("no self-test in the page: {}", &dom[..dom.len().min(500)]));
    serde_json::from_str(result).unwrap()
}

/// The share of the canvas each view of a self-test covers, from its two directions.
pub fn covered(view: &serde_json::Value) -> Vec<f64> {
    view["covered"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect()
}
