//! Batches of reconstructions and evaluations: datasets x variants x seeds from a plan file
//! ([`plan`]), each task in its own folder and resumable ([`task`]), run on this machine
//! ([`local`]) or as a Slurm job array through Slurm's own commands ([`slurm`]), watched
//! ([`status`]) and tabulated ([`gather`](mod@gather), with a [`chart`]). See `docs/batch.md`.
//!
//! ```text
//! DIR/plan.json          the expanded plan: task i of the array is tasks[i]
//! DIR/tasks/ID/          one task: `rmvp recon`'s folder, its evaluation, result.json last
//! DIR/results.{json,csv,md,png}   the gathered table and its chart
//! DIR/batch.sbatch gather.sbatch submission.json logs/   on Slurm
//! ```

pub mod chart;
pub mod gather;
pub mod local;
pub mod plan;
pub mod signals;
pub mod slurm;
pub mod status;
pub mod task;

pub use gather::{gather, BatchTable};
pub use local::{run_local, LocalOptions, LocalSummary};
pub use plan::{BatchPlan, Task, Variant};
pub use signals::StopSignals;
pub use slurm::{SlurmOptions, Submission};
pub use status::{batch_status, BatchStatus};
pub use task::{run_task, TaskOutcome, TaskResult, TaskState};
