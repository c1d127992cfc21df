//! Progress of long work (indicatif): one look for every stage. On a terminal, a bar; where
//! standard error is not a terminal (a log file, nohup, Slurm), plain lines at a steady pace
//! instead: one at every 5 % and at least every 30 s, and one at the end, each with the count,
//! the rate, the time spent and the time left. Hidden where nobody watches (tests, batch tasks)
//! and everywhere after [`set_quiet`].

use indicatif::{HumanDuration, ProgressBar, ProgressStyle, WeakProgressBar};
use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Longest time between two progress lines in a log.
pub const LOG_INTERVAL: Duration = Duration::from_secs(30);
/// A progress line in a log at every this many percent.
pub const LOG_STEP_PERCENT: u64 = 5;

static QUIET: AtomicBool = AtomicBool::new(false);

/// Silence every progress bar and progress line of this process (`rmvp --quiet`).
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, Ordering::Relaxed);
}

/// Whether [`set_quiet`] silenced this process.
pub fn is_quiet() -> bool {
    QUIET.load(Ordering::Relaxed)
}

/// A progress bar over `total` items on standard error, labelled `what` (plain lines where
/// standard error is not a terminal); hidden when `show` is false or after [`set_quiet`]
/// (every call on it then does nothing).
pub fn progress_bar(show: bool, total: u64, what: &str) -> ProgressBar {
    if !show || QUIET.load(Ordering::Relaxed) {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(total);
    bar.set_style(
        ProgressStyle::with_template("{prefix:>10} [{bar:30}] {pos}/{len} {msg} ({elapsed}, eta {eta})")
            .expect("valid template")
            .progress_chars("=> "),
    );
    bar.set_prefix(what.to_string());
    if !std::io::stderr().is_terminal() {
        log_lines(bar.downgrade(), what.to_string());
    }
    bar
}

/// Print `bar`'s progress as plain lines on standard error until it finishes or is dropped.
fn log_lines(bar: WeakProgressBar, what: String) {
    std::thread::spawn(move || {
        let (mut printed_at, mut printed_permille) = (Instant::now(), 0);
        loop {
            std::thread::sleep(Duration::from_millis(200));
            let Some(bar) = bar.upgrade() else { return };
            let (position, total, finished) = (bar.position(), bar.length().unwrap_or(0), bar.is_finished());
            let permille = (position * 1000).checked_div(total).unwrap_or(0);
            let step = |permille: u64| permille / (LOG_STEP_PERCENT * 10);
            // A step reached less than half a step after a timed line waits for the next one.
            let step_due =
                step(permille) > step(printed_permille) && permille >= printed_permille + LOG_STEP_PERCENT * 5;
            if finished || step_due || printed_at.elapsed() >= LOG_INTERVAL {
                eprintln!("{}", line(&what, &bar));
                (printed_at, printed_permille) = (Instant::now(), permille);
            }
            if finished {
                return;
            }
        }
    });
}

/// `what: position/total (percent %), rate/s, elapsed, left` and the bar's message.
fn line(what: &str, bar: &ProgressBar) -> String {
    let (position, total) = (bar.position(), bar.length().unwrap_or(0));
    let percent = (position * 100).checked_div(total).unwrap_or(0);
    let mut text = format!(
        "{what}: {position}/{total} ({percent} %), {:.1}/s, {} elapsed",
        bar.per_sec(),
        HumanDuration(bar.elapsed())
    );
    if !bar.is_finished() && position > 0 {
        text += &format!(", {} left", HumanDuration(bar.eta()));
    }
    let message = bar.message();
    if !message.is_empty() {
        text += &format!(" ({message})");
    }
    text
}
