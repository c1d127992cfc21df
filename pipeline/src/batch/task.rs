//! One task of a batch: a reconstruction in its own folder, then its evaluation, with records
//! that say where it stands (done, failed, part-way, not started) so that a batch can be run
//! again, resumed after a preemption, or resubmitted.
//!
//! ```text
//! tasks/ID/task.json       the task it holds (a folder of another task is cleared first)
//! tasks/ID/checkpoint.bin  log.jsonl mesh.ply normals/ stokes/ comparison.png: `rmvp recon`'s
//! tasks/ID/sessions.json   runs so far and their training time (a preempted task's clock)
//! tasks/ID/normal_errors/  normal error maps per view (black 0 to white 30 degrees)
//! tasks/ID/evaluation.json the evaluation; report.html the task's page
//! tasks/ID/result.json     written last: the task, times, evaluation ([`TaskResult`])
//! tasks/ID/failed.json     instead, when it failed: the error ([`TaskFailure`])
//! ```

use super::plan::{BatchPlan, Task};
use crate::report;
use crate::{Error, Result};
use rmvp_align::{evaluate, Evaluation};
use rmvp_dataset::io::atomic::write_bytes_atomically;
use rmvp_dataset::io::json::{read_json, write_json};
use rmvp_dataset::layout::read_scene;
use rmvp_recon::options::RunControl;
use rmvp_recon::reconstruct::{reconstruct, LOG, MESH};
use serde::{Deserialize, Serialize};
use std::ops::ControlFlow;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// The task a task folder holds.
pub const TASK_FILE: &str = "task.json";
/// A finished task's record, written last.
pub const RESULT_FILE: &str = "result.json";
/// A failed task's record.
pub const FAILED_FILE: &str = "failed.json";
/// Runs so far and their training time.
pub const SESSIONS_FILE: &str = "sessions.json";
/// The `format` of [`TaskResult`].
pub const RESULT_FORMAT: &str = "rmvp-batch-result";

/// A finished task: what ran, how long, and how good.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TaskResult {
    /// [`RESULT_FORMAT`].
    pub format: String,
    /// The task.
    pub task: Task,
    /// Training iterations.
    pub iterations: u32,
    /// Runs it took (more than one when it was preempted and resumed).
    pub sessions: u32,
    /// Training time over all runs, seconds.
    pub train_seconds: f64,
    /// Mesh extraction and per-view outputs, seconds.
    pub output_seconds: f64,
    /// Evaluation, seconds.
    pub evaluation_seconds: f64,
    /// Against the dataset's ground truth (`None`: evaluation off).
    pub evaluation: Option<Evaluation>,
}

impl TaskResult {
    /// Training, outputs and evaluation, minutes.
    pub fn minutes(&self) -> f64 {
        (self.train_seconds + self.output_seconds + self.evaluation_seconds) / 60.0
    }
}

/// A failed task's record.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TaskFailure {
    /// The task's id.
    pub id: String,
    /// The error, as it was printed.
    pub error: String,
}

/// Runs of a task so far (kept across preemptions).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
struct Sessions {
    /// Runs that ended (stopped) before this one.
    runs: u32,
    /// Their training time, seconds.
    train_seconds: f64,
}

/// Where a task stands, from its folder.
#[derive(Clone, Debug, PartialEq)]
pub enum TaskState {
    /// Finished: its result.
    Done(Box<TaskResult>),
    /// Failed: its error.
    Failed(TaskFailure),
    /// Stopped or running, `iteration` of its training done (it resumes from its checkpoint).
    Partial {
        /// Iterations done.
        iteration: u32,
    },
    /// Nothing done (or its folder holds another task).
    NotStarted,
}

impl TaskState {
    /// One word: `done`, `failed`, `partial`, `not-started`.
    pub fn word(&self) -> &'static str {
        match self {
            TaskState::Done(_) => "done",
            TaskState::Failed(_) => "failed",
            TaskState::Partial { .. } => "partial",
            TaskState::NotStarted => "not-started",
        }
    }
}

/// Where task `index` of `plan` stands in batch folder `dir`.
pub fn task_state(plan: &BatchPlan, dir: &Path, index: usize) -> TaskState {
    let (task, folder) = (&plan.tasks[index], plan.task_dir(dir, index));
    let holds: Option<Task> = read_json(&folder.join(TASK_FILE), "a batch task").ok();
    if holds.as_ref() != Some(task) {
        return TaskState::NotStarted;
    }
    if let Ok(result) = read_json::<TaskResult>(&folder.join(RESULT_FILE), "a task result") {
        if &result.task == task {
            return TaskState::Done(Box::new(result));
        }
    }
    if let Ok(failure) = read_json::<TaskFailure>(&folder.join(FAILED_FILE), "a task failure") {
        return TaskState::Failed(failure);
    }
    let iteration = std::fs::read_to_string(folder.join(LOG)).map(|log| log.lines().count() as u32).unwrap_or(0);
    if iteration > 0 {
        TaskState::Partial { iteration }
    } else {
        TaskState::NotStarted
    }
}

/// What one run of a task ended with.
#[derive(Clone, Debug, PartialEq)]
pub enum TaskOutcome {
    /// Finished now, or before (then nothing ran).
    Done {
        /// Its result.
        result: Box<TaskResult>,
        /// Whether it was already complete.
        skipped: bool,
    },
    /// Stopped by `stop`, checkpointed at `iteration`: running it again resumes there.
    Stopped {
        /// Iterations done.
        iteration: u32,
    },
}

/// Run task `index` of `plan` in batch folder `dir`: skip it when its result is complete,
/// resume it from its checkpoint when it was stopped, clear its folder when it holds another
/// task. `stop` (a signal) ends training at the next iteration with a checkpoint; `on_step`
/// sees (iteration, total). A failure is recorded in `failed.json` and returned.
pub fn run_task(
    plan: &BatchPlan,
    dir: &Path,
    index: usize,
    stop: &AtomicBool,
    mut on_step: impl FnMut(u32, u32),
) -> Result<TaskOutcome> {
    let (task, folder) = (&plan.tasks[index], plan.task_dir(dir, index));
    if let TaskState::Done(result) = task_state(plan, dir, index) {
        return Ok(TaskOutcome::Done { result, skipped: true });
    }
    let holds: Option<Task> = read_json(&folder.join(TASK_FILE), "a batch task").ok();
    if holds.is_some_and(|held| &held != task) {
        std::fs::remove_dir_all(&folder).map_err(|e| rmvp_dataset::Error::io(&folder, e))?;
    }
    std::fs::create_dir_all(&folder).map_err(|e| rmvp_dataset::Error::io(&folder, e))?;
    write_json(&folder.join(TASK_FILE), task)?;
    let failed = folder.join(FAILED_FILE);
    if failed.exists() {
        std::fs::remove_file(&failed).map_err(|e| rmvp_dataset::Error::io(&failed, e))?;
    }
    let outcome = run_reconstruction(plan, task, &folder, stop, &mut on_step);
    if let Err(error) = &outcome {
        write_json(&failed, &TaskFailure { id: task.id.clone(), error: error.to_string() })?;
    }
    outcome
}

fn run_reconstruction(
    plan: &BatchPlan,
    task: &Task,
    folder: &Path,
    stop: &AtomicBool,
    on_step: &mut impl FnMut(u32, u32),
) -> Result<TaskOutcome> {
    let scene = read_scene(&task.scene)?;
    let sessions_path = folder.join(SESSIONS_FILE);
    let earlier: Sessions = read_json(&sessions_path, "task sessions").unwrap_or_default();
    let options = task.variant.recon_options(task.seed);
    let total = options.iterations();
    let started = Instant::now();
    let mut trained = 0.0;
    // A task started again continues from its checkpoint.
    let control = RunControl { resume: true, stop_after: None };
    let trainer = reconstruct(&scene, folder, &options, control, |_, trainer| {
        trained = started.elapsed().as_secs_f64();
        on_step(trainer.iteration, total);
        if stop.load(Ordering::Relaxed) {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    })?;
    if trainer.iteration < trainer.config.iterations {
        let sessions = Sessions { runs: earlier.runs + 1, train_seconds: earlier.train_seconds + trained };
        write_json(&sessions_path, &sessions)?;
        return Ok(TaskOutcome::Stopped { iteration: trainer.iteration });
    }
    let output_seconds = started.elapsed().as_secs_f64() - trained;
    let clock = Instant::now();
    let evaluation = if plan.evaluation.enabled {
        let truth = scene.mesh.as_ref().ok_or_else(|| Error::Folder {
            path: task.scene.clone(),
            why: "no ground-truth mesh to evaluate against".into(),
        })?;
        let predicted = rmvp_align::surface::read_surface(&folder.join(MESH))?;
        let evaluation = evaluate(&predicted, truth, Some(&scene), &plan.evaluation.surface_options())?;
        evaluation.write_error_maps(&folder.join(report::ERROR_MAPS))?;
        write_bytes_atomically(&folder.join(report::EVALUATION), evaluation.to_json().as_bytes())?;
        Some(evaluation)
    } else {
        None
    };
    report::write_recon_report(folder, Some(&scene))?;
    let result = TaskResult {
        format: RESULT_FORMAT.into(),
        task: task.clone(),
        iterations: trainer.iteration,
        sessions: earlier.runs + 1,
        train_seconds: earlier.train_seconds + trained,
        output_seconds,
        evaluation_seconds: clock.elapsed().as_secs_f64(),
        evaluation,
    };
    write_json(&folder.join(RESULT_FILE), &result)?;
    Ok(TaskOutcome::Done { result: Box::new(result), skipped: false })
}
