//! Where every task of a batch stands: its folder's records (done, failed, part-way, not
//! started) beside Slurm's state of its array task when the batch was submitted.

use super::plan::BatchPlan;
use super::slurm::{read_submission, scheduler_states, StateSource};
use super::task::{task_state, TaskState};
use crate::Result;
use std::path::Path;

/// One task's standing.
#[derive(Clone, Debug, PartialEq)]
pub struct TaskStatus {
    /// Index in the plan.
    pub index: usize,
    /// Id.
    pub id: String,
    /// From its folder.
    pub state: TaskState,
    /// Slurm's state (`PENDING`, `RUNNING`, `FAILED`, ...), when known.
    pub scheduler: Option<String>,
}

/// A batch's standing.
#[derive(Clone, Debug, PartialEq)]
pub struct BatchStatus {
    /// Every task, in plan order.
    pub tasks: Vec<TaskStatus>,
    /// Where Slurm's states came from (`None`: not submitted, or Slurm unreachable).
    pub source: Option<StateSource>,
    /// Why Slurm's states are missing, for a submitted batch.
    pub scheduler_error: Option<String>,
}

/// The standing of batch folder `dir`.
pub fn batch_status(dir: &Path) -> Result<BatchStatus> {
    let plan = BatchPlan::load(dir)?;
    let (mut source, mut states, mut scheduler_error) = (None, Default::default(), None);
    if let Some(submission) = read_submission(dir)? {
        match scheduler_states(&submission) {
            Ok((from, found)) => (source, states) = (Some(from), found),
            Err(e) => scheduler_error = Some(e.to_string()),
        }
    }
    let tasks = (0..plan.tasks.len())
        .map(|index| TaskStatus {
            index,
            id: plan.tasks[index].id.clone(),
            state: task_state(&plan, dir, index),
            scheduler: states.get(&index).cloned(),
        })
        .collect();
    Ok(BatchStatus { tasks, source, scheduler_error })
}
