//! One module per subcommand, and what they share: value parsers, progress bars, and hints
//! that turn a library error into the command to run next.

pub mod align;
pub mod batch;
pub mod board;
pub mod calibrate;
pub mod capture;
pub mod dataset;
pub mod demo;
pub mod demosaic;
pub mod eval;
pub mod masks;
pub mod poses;
pub mod recon;
pub mod report;
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

/// Two counts written `AxB` on the command line (an image size, a board's squares); the
/// defaults come from the libraries' values through it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Pair(pub u32, pub u32);

impl std::fmt::Display for Pair {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "{}x{}", self.0, self.1)
    }
}

impl std::str::FromStr for Pair {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        let (a, b) = text.split_once('x').ok_or_else(|| format!("{text:?}: expected two numbers as AxB, e.g. 8x6"))?;
        let number = |s: &str| s.parse::<u32>().map_err(|e| format!("{s:?}: {e}"));
        Ok(Pair(number(a)?, number(b)?))
    }
}

/// A visible progress bar over `len` items, labelled `what`.
pub fn progress(len: u64, what: &str) -> ProgressBar {
    rmvp_dataset::progress::progress_bar(true, len, what)
}

/// What the user can do next about `error`, in terms of this command line.
pub fn hint(error: &anyhow::Error) -> Option<&'static str> {
    use rmvp_capture::Error as Capture;
    use rmvp_pipeline::Error as Pipeline;
    if let Some(Pipeline::SlurmMissing { .. }) = error.chain().find_map(|e| e.downcast_ref::<Pipeline>()) {
        return Some(
            "hint: without Slurm, run the plan on this machine: rmvp batch run FILE -o DIR --local [--jobs N]",
        );
    }
    let too_large = |e: &&(dyn std::error::Error + 'static)| {
        matches!(e.downcast_ref::<rmvp_dataset::Error>(), Some(rmvp_dataset::Error::ImageTooLarge { .. }))
    };
    if error.chain().any(|e| too_large(&e)) {
        return Some("hint: --max-pixels N raises the limit for one command");
    }
    if let Some(Pipeline::SceneNotSession { .. }) = error.chain().find_map(|e| e.downcast_ref::<Pipeline>()) {
        return Some("hint: rmvp recon reconstructs a scene; rmvp dataset convert or export rewrites it");
    }
    if let Some(Pipeline::BuildUnfinished { .. }) = error.chain().find_map(|e| e.downcast_ref::<Pipeline>()) {
        return Some("hint: run the same command with --resume to continue the build");
    }
    let capture = error.chain().find_map(|e| e.downcast_ref::<Capture>())?;
    match capture {
        Capture::Session { .. } | Capture::DiskFull { .. } => {
            Some("hint: run the same command with --resume to continue the session")
        }
        Capture::SessionExists { .. } => Some("hint: pass --resume to continue it, or choose another folder"),
        Capture::OperatorGone => Some("hint: without an operator at the keyboard, use --mode timed or turntable"),
        _ => None,
    }
}
