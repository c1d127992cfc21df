//! One module per subcommand.

pub mod align;
pub mod capture;
pub mod convert;
pub mod demo;
pub mod demosaic;
pub mod eval;
pub mod info;
pub mod recon;
pub mod render_normals;
pub mod simulate;
pub mod stokes;

use indicatif::ProgressBar;

/// Parse exactly `N` comma-separated numbers ("1.5,2" for `N = 2`).
pub fn parse_numbers<const N: usize>(text: &str) -> Result<[f32; N], String> {
    let values: Vec<f32> = text
        .split(',')
        .map(|v| v.trim().parse::<f32>().map_err(|e| format!("{v:?}: {e}")))
        .collect::<Result<_, _>>()?;
    values.try_into().map_err(|v: Vec<f32>| format!("expected {N} comma-separated numbers, got {}", v.len()))
}

/// A progress bar over `len` items, labelled `what`.
pub fn progress(len: u64, what: &str) -> ProgressBar {
    rmvp_capture::progress_bar(true, len, what)
}
