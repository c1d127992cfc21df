//! Progress bars for long work (indicatif): one look for every stage, hidden where nobody
//! watches (tests, batch tasks).

use indicatif::{ProgressBar, ProgressStyle};

/// A progress bar over `total` items on standard error, labelled `what`; hidden when `show`
/// is false (every call on it then does nothing).
pub fn progress_bar(show: bool, total: u64, what: &str) -> ProgressBar {
    if !show {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(total);
    bar.set_style(
        ProgressStyle::with_template("{prefix:>10} [{bar:30}] {pos}/{len} {msg} ({elapsed}, eta {eta})")
            .expect("valid template")
            .progress_chars("=> "),
    );
    bar.set_prefix(what.to_string());
    bar
}
