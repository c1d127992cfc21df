//! `rmvp batch plan|run|task|status|gather|resubmit` ([`rmvp_pipeline::batch`]).

use anyhow::{bail, Result};
use clap::{ArgGroup, Subcommand};
use rmvp_pipeline::batch::gather::RESULTS_STEM;
use rmvp_pipeline::batch::slurm::{self, SUBMISSION_FILE};
use rmvp_pipeline::batch::{
    batch_status, gather, run_local, BatchPlan, LocalOptions, SlurmOptions, StopSignals, TaskOutcome, TaskState,
};
use std::path::{Path, PathBuf};

/// Subcommands of `rmvp batch`.
#[derive(Subcommand)]
pub enum Command {
    /// Print the tasks a plan file expands to (checking it: datasets, options).
    Plan {
        /// The plan (`batch.toml`).
        file: PathBuf,
    },
    /// Run a plan on this machine (--local) or submit it as a Slurm job array (--slurm); tasks
    /// already complete in the output folder are skipped.
    Run(RunArgs),
    /// Run task INDEX of a batch folder (what each Slurm array task runs).
    Task {
        /// The batch folder.
        dir: PathBuf,
        /// The task's index in plan.json.
        index: usize,
    },
    /// Where every task of a batch folder stands (its files, and Slurm's state when submitted).
    Status {
        /// The batch folder.
        dir: PathBuf,
    },
    /// Tabulate the results: results.json, .csv, .md and a bar chart, results.png.
    Gather {
        /// The batch folder.
        dir: PathBuf,
    },
    /// Submit again the tasks of a Slurm batch that failed (and only those).
    Resubmit {
        /// The batch folder.
        dir: PathBuf,
    },
}

/// Arguments of `rmvp batch run`.
#[derive(clap::Args)]
#[command(group(ArgGroup::new("where").required(true).args(["local", "slurm"])))]
pub struct RunArgs {
    /// The plan (`batch.toml`).
    file: PathBuf,
    /// The batch folder (plan.json, tasks/, results).
    #[arg(short, long)]
    output: PathBuf,
    /// Run here, --jobs tasks at a time.
    #[arg(long)]
    local: bool,
    /// Submit to Slurm (sbatch) as a job array and a gather job.
    #[arg(long)]
    slurm: bool,
    /// Tasks at a time with --local (the threads are split between them).
    #[arg(long, default_value_t = LocalOptions::default().jobs)]
    jobs: usize,
    /// Slurm partition.
    #[arg(long)]
    partition: Option<String>,
    /// Slurm time limit per task (HH:MM:SS or D-HH); a task warned 120 s before it checkpoints
    /// and requeues itself.
    #[arg(long)]
    time: Option<String>,
    /// CPUs per Slurm task (its threads).
    #[arg(long, default_value_t = SlurmOptions::default().cpus_per_task)]
    cpus_per_task: usize,
    /// Memory per Slurm task (e.g. 8G).
    #[arg(long)]
    mem: Option<String>,
    /// Slurm tasks running at once at most.
    #[arg(long)]
    max_running: Option<usize>,
    /// Slurm account.
    #[arg(long)]
    account: Option<String>,
}

/// Run the command.
pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Plan { file } => {
            let plan = BatchPlan::read(&file)?;
            println!(
                "{} tasks: {} datasets x {} variants x {} seeds",
                plan.tasks.len(),
                plan.datasets.len(),
                plan.variants.len(),
                plan.seeds.len()
            );
            for task in &plan.tasks {
                let options = serde_json::to_string(&task.variant)?;
                println!("{:>4}  {}  {}  seed {}  {options}", task.index, task.id, task.scene.display(), task.seed);
            }
            Ok(())
        }
        Command::Run(args) => run_plan(args),
        Command::Task { dir, index } => {
            let signals = StopSignals::register()?;
            match slurm::run_array_task(&dir, index, &signals)? {
                TaskOutcome::Done { result, skipped } => {
                    let how = if skipped { "already complete" } else { "done" };
                    println!("task {index} ({}): {how} in {:.1} min", result.task.id, result.minutes());
                    Ok(())
                }
                TaskOutcome::Stopped { iteration } if signals.preempted() => {
                    println!("task {index}: checkpointed at iteration {iteration}; requeued");
                    Ok(())
                }
                TaskOutcome::Stopped { iteration } => {
                    bail!("task {index}: stopped by a signal at iteration {iteration} (checkpointed; run it again to resume)")
                }
            }
        }
        Command::Status { dir } => status(&dir),
        Command::Gather { dir } => {
            let table = gather(&dir)?;
            print!("{}", table.markdown());
            println!("written: {0}.json {0}.csv {0}.md {0}.png in {1}", RESULTS_STEM, dir.display());
            Ok(())
        }
        Command::Resubmit { dir } => {
            match slurm::resubmit(&dir)? {
                Some(job) => println!(
                    "resubmitted {} task(s) as job {} (gather job {})",
                    job.indices.len(),
                    job.job_id,
                    job.gather_job_id
                ),
                None => println!("nothing to resubmit: every task is complete or still queued"),
            }
            Ok(())
        }
    }
}

fn run_plan(args: RunArgs) -> Result<()> {
    let plan = BatchPlan::read(&args.file)?;
    if args.slurm {
        let options = SlurmOptions {
            partition: args.partition,
            time: args.time,
            cpus_per_task: args.cpus_per_task,
            mem: args.mem,
            max_running: args.max_running,
            account: args.account,
        };
        let program = std::env::current_exe()?;
        match slurm::submit(&plan, &args.output, &options, &program)? {
            Some(job) => {
                println!(
                    "submitted {} of {} task(s) as array job {} and gather job {} (recorded in {})",
                    job.indices.len(),
                    plan.tasks.len(),
                    job.job_id,
                    job.gather_job_id,
                    args.output.join(SUBMISSION_FILE).display()
                );
                println!("watch with: rmvp batch status {}", args.output.display());
            }
            None => println!("every task is complete; tabulate with: rmvp batch gather {}", args.output.display()),
        }
        return Ok(());
    }
    let signals = StopSignals::register()?;
    let options = LocalOptions { jobs: args.jobs.max(1), threads: Some(rayon::current_num_threads()), progress: true };
    let summary = run_local(&plan, &args.output, &options, &signals.any)?;
    let table = gather(&args.output)?;
    print!("{}", table.markdown());
    println!(
        "{} finished, {} already complete, {} failed, {} stopped; results in {}",
        summary.finished.len(),
        summary.skipped.len(),
        summary.failed.len(),
        summary.stopped.len(),
        args.output.join(RESULTS_STEM).with_extension("md").display()
    );
    if !summary.stopped.is_empty() {
        bail!("stopped by a signal; run the same command again to resume");
    }
    if !summary.failed.is_empty() {
        let ids: Vec<&str> = summary.failed.iter().map(|(i, _)| plan.tasks[*i].id.as_str()).collect();
        bail!("{} task(s) failed: {}", ids.len(), ids.join(", "));
    }
    Ok(())
}

fn status(dir: &Path) -> Result<()> {
    let status = batch_status(dir)?;
    let mut counts = std::collections::BTreeMap::new();
    for task in &status.tasks {
        *counts.entry(task.state.word()).or_insert(0) += 1;
        let detail = match &task.state {
            TaskState::Done(result) => {
                let mae = result.evaluation.as_ref().and_then(|e| e.normal_mae_deg);
                format!(
                    "{:.1} min{}",
                    result.minutes(),
                    mae.map_or(String::new(), |m| format!(", normal MAE {m:.2} deg"))
                )
            }
            TaskState::Failed(failure) => failure.error.clone(),
            TaskState::Partial { iteration } => format!("iteration {iteration}"),
            TaskState::NotStarted => String::new(),
        };
        let scheduler = task.scheduler.as_deref().unwrap_or("-");
        println!("{:>4}  {:<32} {:<12} {:<12} {detail}", task.index, task.id, task.state.word(), scheduler);
    }
    let summary: Vec<String> = counts.iter().map(|(word, n)| format!("{n} {word}")).collect();
    println!("{} task(s): {}", status.tasks.len(), summary.join(", "));
    match (status.source, status.scheduler_error) {
        (Some(source), _) => println!("Slurm states from {source:?}"),
        (None, Some(error)) => println!("Slurm states unavailable: {error}"),
        (None, None) => {}
    }
    Ok(())
}
