//! Helpers shared by the integration tests that run the `rmvp` binary.

use std::path::Path;
use std::process::{Command, Output};

/// Run `rmvp` with `args`.
pub fn rmvp(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rmvp")).args(args).output().expect("rmvp runs")
}

/// Run `rmvp` with `args`, assert it succeeds, return its standard output.
pub fn ok(args: &[&str]) -> String {
    let out = rmvp(args);
    assert!(out.status.success(), "rmvp {args:?} failed:\n{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap()
}

/// Run `rmvp` with `args`, assert it fails, return its standard error.
pub fn fails(args: &[&str]) -> String {
    let out = rmvp(args);
    assert!(!out.status.success(), "rmvp {args:?} should have failed");
    String::from_utf8(out.stderr).unwrap()
}

/// A path as the `&str` an argument list needs.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}
