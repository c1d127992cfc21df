//! One module per subcommand.

pub mod convert;
pub mod demo;
pub mod demosaic;
pub mod info;
pub mod simulate;
pub mod stokes;

use indicatif::{ProgressBar, ProgressStyle};

/// A progress bar over `len` items, labelled `what`.
pub fn progress(len: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template("{prefix:>10} [{bar:30}] {pos}/{len} {msg} ({elapsed}, eta {eta})")
            .expect("valid template")
            .progress_chars("=> "),
    );
    bar.set_prefix(what.to_string());
    bar
}
