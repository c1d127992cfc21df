//! A batch on this machine: `jobs` tasks at a time, the cores split between them (each job its
//! own thread pool), complete tasks skipped, failed ones recorded while the others go on.

use super::plan::BatchPlan;
use super::task::{run_task, TaskOutcome};
use crate::Result;
use indicatif::{MultiProgress, ProgressDrawTarget};
use rmvp_dataset::progress::progress_bar;
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

/// How a local batch runs.
#[derive(Clone, Debug, PartialEq)]
pub struct LocalOptions {
    /// Tasks at a time.
    pub jobs: usize,
    /// Threads in all (default: every core), split evenly between the jobs.
    pub threads: Option<usize>,
    /// Show progress bars.
    pub progress: bool,
}

impl Default for LocalOptions {
    fn default() -> Self {
        Self { jobs: 1, threads: None, progress: true }
    }
}

/// What a local run did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LocalSummary {
    /// Tasks finished in this run.
    pub finished: Vec<usize>,
    /// Tasks already complete (not run again).
    pub skipped: Vec<usize>,
    /// Tasks that failed, with their errors.
    pub failed: Vec<(usize, String)>,
    /// Tasks stopped by a signal (checkpointed: run the plan again to resume them).
    pub stopped: Vec<usize>,
}

/// Run every task of `plan` in batch folder `dir` (its `plan.json` written first). `stop` ends
/// the running tasks at their next iteration, checkpointed, and starts no new one.
pub fn run_local(plan: &BatchPlan, dir: &Path, options: &LocalOptions, stop: &AtomicBool) -> Result<LocalSummary> {
    plan.save(dir)?;
    let jobs = options.jobs.clamp(1, plan.tasks.len().max(1));
    let threads = options.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let per_job = (threads / jobs).max(1);
    let bars = MultiProgress::with_draw_target(if options.progress {
        ProgressDrawTarget::stderr()
    } else {
        ProgressDrawTarget::hidden()
    });
    let overall = bars.add(progress_bar(options.progress, plan.tasks.len() as u64, "tasks"));
    let next = AtomicUsize::new(0);
    let summary = Mutex::new(LocalSummary::default());
    let first_error = Mutex::new(None);
    std::thread::scope(|scope| {
        for _ in 0..jobs {
            scope.spawn(|| {
                let pool = match rayon::ThreadPoolBuilder::new().num_threads(per_job).build() {
                    Ok(pool) => pool,
                    Err(e) => {
                        let error = rmvp_dataset::Error::io("thread pool", std::io::Error::other(e.to_string()));
                        first_error.lock().expect("no panics while held").get_or_insert(error.into());
                        return;
                    }
                };
                loop {
                    let index = next.fetch_add(1, Ordering::Relaxed);
                    if index >= plan.tasks.len() || stop.load(Ordering::Relaxed) {
                        break;
                    }
                    let task = &plan.tasks[index];
                    let task_bar = bars.insert_after(&overall, progress_bar(options.progress, 1, &task.id));
                    let outcome = pool.install(|| {
                        run_task(plan, dir, index, stop, |iteration, total| {
                            task_bar.set_length(total as u64);
                            task_bar.set_position(iteration as u64);
                        })
                    });
                    task_bar.finish_and_clear();
                    bars.remove(&task_bar);
                    let mut summary = summary.lock().expect("no panics while held");
                    match outcome {
                        Ok(TaskOutcome::Done { skipped: true, .. }) => summary.skipped.push(index),
                        Ok(TaskOutcome::Done { result, .. }) => {
                            let mae = result.evaluation.as_ref().and_then(|e| e.normal_mae_deg);
                            let figures = mae.map_or(String::new(), |m| format!(", normal MAE {m:.2} deg"));
                            overall.println(format!("{}: done in {:.1} min{figures}", task.id, result.minutes()));
                            summary.finished.push(index);
                        }
                        Ok(TaskOutcome::Stopped { iteration }) => {
                            overall.println(format!("{}: stopped at iteration {iteration}", task.id));
                            summary.stopped.push(index);
                        }
                        Err(error) => {
                            overall.println(format!("{}: failed: {error}", task.id));
                            summary.failed.push((index, error.to_string()));
                        }
                    }
                    overall.inc(1);
                }
            });
        }
    });
    overall.finish_and_clear();
    if let Some(error) = first_error.into_inner().expect("no panics while held") {
        return Err(error);
    }
    let mut summary = summary.into_inner().expect("no panics while held");
    for list in [&mut summary.finished, &mut summary.skipped, &mut summary.stopped] {
        list.sort_unstable();
    }
    summary.failed.sort_unstable();
    Ok(summary)
}
