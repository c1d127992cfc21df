//! The signals that stop a batch's training at the next iteration, with a checkpoint: SIGUSR2
//! (Slurm's warning before a time limit or a preemption, `--signal=B:USR2@120`), SIGTERM and
//! SIGINT (a second Ctrl-C ends the process at once).

use crate::Result;
use signal_hook::consts::{SIGINT, SIGTERM, SIGUSR2};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// Flags set by the stop signals (signal-hook's async-signal-safe handlers).
#[derive(Clone, Debug, Default)]
pub struct StopSignals {
    /// Set by SIGUSR2: save and ask the scheduler to run the task again.
    pub preempt: Arc<AtomicBool>,
    /// Set by SIGTERM or SIGINT: save and end.
    pub terminate: Arc<AtomicBool>,
    /// Set by any of them: what training loops watch.
    pub any: Arc<AtomicBool>,
}

impl StopSignals {
    /// Install the handlers for this process.
    pub fn register() -> Result<Self> {
        let flags = Self::default();
        let io = |e: std::io::Error| rmvp_dataset::Error::io("signal handlers", e);
        // A second SIGINT while the first is being handled ends the process.
        signal_hook::flag::register_conditional_shutdown(SIGINT, 130, flags.terminate.clone()).map_err(io)?;
        for (signal, flag) in [(SIGUSR2, &flags.preempt), (SIGTERM, &flags.terminate), (SIGINT, &flags.terminate)] {
            signal_hook::flag::register(signal, flag.clone()).map_err(io)?;
            signal_hook::flag::register(signal, flags.any.clone()).map_err(io)?;
        }
        Ok(flags)
    }

    /// Whether SIGUSR2 arrived.
    pub fn preempted(&self) -> bool {
        self.preempt.load(Ordering::Relaxed)
    }
}
