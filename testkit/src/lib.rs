//! Test support shared by the workspace's test suites: where the reference scenes rendered by
//! Mitsuba 3 are (`shared/fixtures` beside the checkout, or `$RMVP_FIXTURES`).

use std::path::{Path, PathBuf};

/// The fixtures folder: `$RMVP_FIXTURES`, else `shared/fixtures` beside the checkout.
pub fn fixtures_root() -> PathBuf {
    std::env::var_os("RMVP_FIXTURES")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/fixtures"))
}

/// One fixture scene by name (`spot_nersp`, `bunny_nersp`); panics with a clear message when
/// it is missing.
pub fn fixture(name: &str) -> PathBuf {
    let dir = fixtures_root().join(name);
    assert!(dir.is_dir(), "fixture {} missing; set RMVP_FIXTURES", dir.display());
    dir
}

/// Every fixture scene (folders with `cameras.npz`), sorted; at least the spot and the bunny.
pub fn fixture_scenes() -> Vec<PathBuf> {
    let root = fixtures_root();
    let mut scenes: Vec<PathBuf> = std::fs::read_dir(&root)
        .unwrap_or_else(|e| panic!("fixtures not found at {} ({e}); set RMVP_FIXTURES", root.display()))
        .map(|e| e.expect("readable folder").path())
        .filter(|p| p.join("cameras.npz").is_file())
        .collect();
    scenes.sort();
    assert!(scenes.len() >= 2, "expected the spot and bunny fixtures in {}", root.display());
    scenes
}
