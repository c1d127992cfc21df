//! A batch on Slurm, through its own commands (no Slurm crate is maintained): a job array of
//! `rmvp batch task DIR INDEX` submitted with `sbatch --parsable`, a gather job after it
//! (`afterany`: one failed task must not leave it pending forever), states from `sacct
//! --parsable2` where accounting exists and `squeue` where it does not, a requeue of a task
//! warned by SIGUSR2, and resubmission of the failed indices.
//!
//! ```text
//! DIR/batch.sbatch      the array's script (every #SBATCH line at the top)
//! DIR/gather.sbatch     the gather job's script
//! DIR/submission.json   the jobs submitted so far and their indices ([`Submission`])
//! DIR/logs/%A_%a.log    one log per task, appended across requeues
//! ```

use super::plan::BatchPlan;
use super::signals::StopSignals;
use super::task::{run_task, task_state, TaskOutcome, TaskState};
use crate::{Error, Result};
use rmvp_dataset::io::json::{read_json, write_json};
use rmvp_dataset::progress::progress_bar;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The job array's script in a batch folder.
pub const SCRIPT_FILE: &str = "batch.sbatch";
/// The gather job's script.
pub const GATHER_SCRIPT_FILE: &str = "gather.sbatch";
/// The record of submitted jobs.
pub const SUBMISSION_FILE: &str = "submission.json";
/// The folder of the tasks' logs.
pub const LOGS_FOLDER: &str = "logs";
/// Seconds before its time limit that Slurm warns a task (SIGUSR2) to checkpoint and requeue.
pub const WARNING_SECONDS: u32 = 120;

/// Resources and limits of every task (`#SBATCH` options).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SlurmOptions {
    /// Partition (default: the cluster's).
    pub partition: Option<String>,
    /// Time limit per task, Slurm's format (`HH:MM:SS`, `D-HH`; default: the partition's).
    pub time: Option<String>,
    /// CPUs per task (the task's threads).
    pub cpus_per_task: usize,
    /// Memory per task, Slurm's format (`4G`; default: the cluster's per-CPU default).
    pub mem: Option<String>,
    /// Tasks running at once at most (default: as many as Slurm allows).
    pub max_running: Option<usize>,
    /// Account to charge (default: the user's).
    pub account: Option<String>,
}

impl Default for SlurmOptions {
    fn default() -> Self {
        Self { partition: None, time: None, cpus_per_task: 4, mem: None, max_running: None, account: None }
    }
}

/// One submission: an array over some task indices and its gather job.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ArrayJob {
    /// The array's job id.
    pub job_id: String,
    /// The gather job's id.
    pub gather_job_id: String,
    /// The task indices it runs.
    pub indices: Vec<usize>,
}

/// Every submission of a batch folder, oldest first (`submission.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Submission {
    /// The options of the scripts.
    pub options: SlurmOptions,
    /// The `rmvp` program the scripts run.
    pub program: PathBuf,
    /// The arrays submitted (the first, then resubmissions).
    pub arrays: Vec<ArrayJob>,
}

/// `s` quoted for a POSIX shell.
fn shell_quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

/// Indices as a Slurm array specification (`0-3,5,7-9`), with `%K` when limited.
pub fn array_spec(indices: &[usize], max_running: Option<usize>) -> String {
    let mut sorted = indices.to_vec();
    sorted.sort_unstable();
    sorted.dedup();
    let mut parts = Vec::new();
    let mut i = 0;
    while i < sorted.len() {
        let start = sorted[i];
        while i + 1 < sorted.len() && sorted[i + 1] == sorted[i] + 1 {
            i += 1;
        }
        parts.push(if sorted[i] == start { start.to_string() } else { format!("{start}-{}", sorted[i]) });
        i += 1;
    }
    let limit = max_running.map_or(String::new(), |k| format!("%{k}"));
    format!("{}{limit}", parts.join(","))
}

/// The array indices a Slurm job id names: `123_4` -> [4]; `123_[0-3,7%2]` -> [0,1,2,3,7].
fn array_indices(job_id: &str) -> Vec<usize> {
    let Some((_, tail)) = job_id.split_once('_') else { return Vec::new() };
    let tail = tail.trim_start_matches('[').trim_end_matches(']');
    let tail = tail.split('%').next().unwrap_or_default();
    let mut indices = Vec::new();
    for part in tail.split(',') {
        match part.split_once('-') {
            Some((a, b)) => {
                if let (Ok(a), Ok(b)) = (a.parse::<usize>(), b.parse::<usize>()) {
                    indices.extend(a..=b);
                }
            }
            None => indices.extend(part.parse::<usize>().ok()),
        }
    }
    indices
}

/// The array's script: every `#SBATCH` line first (sbatch ignores those after a command).
pub fn batch_script(plan: &BatchPlan, dir: &Path, options: &SlurmOptions, program: &Path) -> String {
    let dir_text = dir.display().to_string();
    let mut lines = vec![
        "#!/bin/bash".to_string(),
        "#SBATCH --job-name=rmvp-batch".into(),
        format!("#SBATCH --array={}", array_spec(&(0..plan.tasks.len()).collect::<Vec<_>>(), options.max_running)),
        format!("#SBATCH --output={dir_text}/{LOGS_FOLDER}/%A_%a.log"),
        "#SBATCH --open-mode=append".into(),
        "#SBATCH --requeue".into(),
        format!("#SBATCH --signal=B:USR2@{WARNING_SECONDS}"),
        format!("#SBATCH --cpus-per-task={}", options.cpus_per_task.max(1)),
    ];
    let optional = [("partition", &options.partition), ("time", &options.time), ("mem", &options.mem)];
    for (name, value) in optional.into_iter().chain([("account", &options.account)]) {
        if let Some(value) = value {
            lines.push(format!("#SBATCH --{name}={value}"));
        }
    }
    lines.extend([
        String::new(),
        format!("# Written by rmvp for the plan {}: task i of the array is task i", plan.source.display()),
        "# of plan.json. Load what the cluster needs here (module load ...). rmvp runs in place of".into(),
        "# this shell (exec) so that Slurm's SIGUSR2 reaches it: it checkpoints and requeues the task.".into(),
        format!(
            "exec {} --threads \"${{SLURM_CPUS_PER_TASK:-1}}\" batch task {} \"$SLURM_ARRAY_TASK_ID\"",
            shell_quote(&program.display().to_string()),
            shell_quote(&dir_text)
        ),
    ]);
    lines.join("\n") + "\n"
}

/// The gather job's script.
pub fn gather_script(dir: &Path, options: &SlurmOptions, program: &Path) -> String {
    let dir_text = dir.display().to_string();
    let mut lines = vec![
        "#!/bin/bash".to_string(),
        "#SBATCH --job-name=rmvp-gather".into(),
        format!("#SBATCH --output={dir_text}/{LOGS_FOLDER}/gather_%j.log"),
        "#SBATCH --cpus-per-task=1".into(),
    ];
    for (name, value) in [("partition", &options.partition), ("account", &options.account)] {
        if let Some(value) = value {
            lines.push(format!("#SBATCH --{name}={value}"));
        }
    }
    lines.push(String::new());
    lines.push(format!("exec {} batch gather {}", shell_quote(&program.display().to_string()), shell_quote(&dir_text)));
    lines.join("\n") + "\n"
}

/// Run a Slurm command and return its standard output; a missing command and a failure are
/// errors naming it.
fn slurm_command(program: &str, args: &[String]) -> Result<String> {
    let output = Command::new(program).args(args).output().map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            Error::SlurmMissing { command: program.into() }
        } else {
            Error::Slurm { command: format!("{program} {}", args.join(" ")), why: e.to_string() }
        }
    })?;
    if !output.status.success() {
        let why = String::from_utf8_lossy(&output.stderr).trim().to_string();
        return Err(Error::Slurm { command: format!("{program} {}", args.join(" ")), why });
    }
    Ok(String::from_utf8_lossy(&output.stdout).into_owned())
}

/// Submit a script with `sbatch --parsable` and return the job id.
fn sbatch(args: Vec<String>) -> Result<String> {
    let out = slurm_command("sbatch", &args)?;
    // `--parsable` prints `jobid` or `jobid;cluster`.
    let id = out.trim().split(';').next().unwrap_or_default().to_string();
    if id.is_empty() || !id.chars().all(|c| c.is_ascii_digit()) {
        return Err(Error::Slurm { command: format!("sbatch {}", args.join(" ")), why: format!("printed {out:?}") });
    }
    Ok(id)
}

/// Submit the tasks of `indices` and a gather job after them; record it in `submission.json`.
fn submit_array(dir: &Path, submission: &mut Submission, indices: &[usize]) -> Result<ArrayJob> {
    let script = dir.join(SCRIPT_FILE).display().to_string();
    let array = format!("--array={}", array_spec(indices, submission.options.max_running));
    let job_id = sbatch(vec!["--parsable".into(), array, script])?;
    let gather = dir.join(GATHER_SCRIPT_FILE).display().to_string();
    let gather_job_id = sbatch(vec!["--parsable".into(), format!("--dependency=afterany:{job_id}"), gather])?;
    let job = ArrayJob { job_id, gather_job_id, indices: indices.to_vec() };
    submission.arrays.push(job.clone());
    write_json(&dir.join(SUBMISSION_FILE), submission)?;
    Ok(job)
}

/// Write the plan and both scripts into `dir` and submit every task not yet complete (none:
/// nothing is submitted, `None`). `program` is the `rmvp` the tasks run.
pub fn submit(plan: &BatchPlan, dir: &Path, options: &SlurmOptions, program: &Path) -> Result<Option<ArrayJob>> {
    let dir = &std::path::absolute(dir).map_err(|e| rmvp_dataset::Error::io(dir, e))?;
    // Earlier submissions count only for the same tasks: their indices name this plan's tasks.
    let same_tasks = BatchPlan::load(dir).is_ok_and(|previous| previous.tasks == plan.tasks);
    plan.save(dir)?;
    let logs = dir.join(LOGS_FOLDER);
    std::fs::create_dir_all(&logs).map_err(|e| rmvp_dataset::Error::io(&logs, e))?;
    let io = |path: PathBuf, text: String| {
        rmvp_dataset::io::write_bytes_atomically(&path, text.as_bytes()).map_err(Error::from)
    };
    io(dir.join(SCRIPT_FILE), batch_script(plan, dir, options, program))?;
    io(dir.join(GATHER_SCRIPT_FILE), gather_script(dir, options, program))?;
    let pending: Vec<usize> =
        (0..plan.tasks.len()).filter(|&i| !matches!(task_state(plan, dir, i), TaskState::Done(_))).collect();
    if pending.is_empty() {
        return Ok(None);
    }
    let earlier = read_json::<Submission>(&dir.join(SUBMISSION_FILE), "a batch submission").ok();
    let arrays = earlier.filter(|_| same_tasks).map(|s| s.arrays).unwrap_or_default();
    let mut submission = Submission { options: options.clone(), program: program.to_path_buf(), arrays };
    submit_array(dir, &mut submission, &pending).map(Some)
}

/// Read `submission.json` of a batch folder (`None`: never submitted to Slurm).
pub fn read_submission(dir: &Path) -> Result<Option<Submission>> {
    let path = dir.join(SUBMISSION_FILE);
    if !path.exists() {
        return Ok(None);
    }
    Ok(Some(read_json(&path, "a batch submission")?))
}

/// Where Slurm's states came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum StateSource {
    /// `sacct` (accounting: every job, finished ones too).
    Sacct,
    /// `squeue` (no accounting: pending and running jobs only).
    Squeue,
}

/// Slurm's state of each task index of a submission (the latest array holding an index wins).
pub fn scheduler_states(submission: &Submission) -> Result<(StateSource, BTreeMap<usize, String>)> {
    let ids: Vec<&str> = submission.arrays.iter().map(|a| a.job_id.as_str()).collect();
    if ids.is_empty() {
        return Ok((StateSource::Squeue, BTreeMap::new()));
    }
    let jobs = ids.join(",");
    let sacct = slurm_command(
        "sacct",
        &["-X", "--parsable2", "--noheader", "--format=JobID,State", "-j", &jobs].map(String::from),
    );
    let (source, text) = match sacct {
        Ok(text) => (StateSource::Sacct, text),
        // No accounting storage (or no sacct): what is queued or running is all there is.
        Err(Error::Slurm { .. }) | Err(Error::SlurmMissing { .. }) => {
            let args = ["-h", "-r", "-t", "all", "-o", "%i|%T", "-j", &jobs].map(String::from);
            (StateSource::Squeue, slurm_command("squeue", &args)?)
        }
        Err(e) => return Err(e),
    };
    Ok((source, parse_states(&text, submission)))
}

/// Task states from `JOBID|STATE` lines (sacct `--parsable2`, squeue `-o %i|%T`) of the
/// submission's arrays; later arrays (resubmissions) override earlier ones.
fn parse_states(text: &str, submission: &Submission) -> BTreeMap<usize, String> {
    let mut states = BTreeMap::new();
    for array in &submission.arrays {
        for line in text.lines() {
            let mut fields = line.split('|');
            let (Some(job), Some(state)) = (fields.next(), fields.next()) else { continue };
            if job.split('_').next() != Some(array.job_id.as_str()) {
                continue;
            }
            // sacct says `CANCELLED by 0`; keep the word.
            let state = state.split_whitespace().next().unwrap_or_default().to_string();
            for index in array_indices(job) {
                states.insert(index, state.clone());
            }
        }
    }
    states
}

/// Whether a Slurm state means the task is still to run or running.
pub fn is_active(state: &str) -> bool {
    matches!(
        state,
        "PENDING"
            | "RUNNING"
            | "REQUEUED"
            | "REQUEUE_HOLD"
            | "REQUEUE_FED"
            | "CONFIGURING"
            | "COMPLETING"
            | "SUSPENDED"
            | "RESIZING"
            | "SIGNALING"
            | "STAGE_OUT"
    )
}

/// Submit again the tasks that failed: recorded failures, and tasks Slurm no longer runs that
/// left no result (killed, out of memory, timed out). `None`: nothing to resubmit.
pub fn resubmit(dir: &Path) -> Result<Option<ArrayJob>> {
    let plan = BatchPlan::load(dir)?;
    let Some(mut submission) = read_submission(dir)? else {
        let why = "was never submitted to Slurm; run the plan first".to_string();
        return Err(Error::Folder { path: dir.to_path_buf(), why });
    };
    let (_, states) = scheduler_states(&submission)?;
    let failed: Vec<usize> = (0..plan.tasks.len())
        .filter(|&i| match task_state(&plan, dir, i) {
            TaskState::Done(_) => false,
            TaskState::Failed(_) => !states.get(&i).is_some_and(|s| is_active(s)),
            _ => !states.get(&i).is_some_and(|s| is_active(s)),
        })
        .collect();
    if failed.is_empty() {
        return Ok(None);
    }
    submit_array(dir, &mut submission, &failed).map(Some)
}

/// `rmvp batch task DIR INDEX`, as a Slurm array task runs it: the task, and when SIGUSR2
/// stopped it, a requeue of this array task (`scontrol requeue`) after its checkpoint.
pub fn run_array_task(dir: &Path, index: usize, signals: &StopSignals) -> Result<TaskOutcome> {
    let plan = BatchPlan::load(dir)?;
    if index >= plan.tasks.len() {
        let why = format!("has {} tasks; there is no task {index}", plan.tasks.len());
        return Err(Error::Folder { path: dir.join(super::plan::PLAN_FILE), why });
    }
    // The task's log (Slurm's output file) gets a progress line every 5 % and 30 s of training.
    let progress = progress_bar(true, 0, &plan.tasks[index].id);
    let outcome = run_task(&plan, dir, index, &signals.any, |iteration, total| {
        progress.set_length(total.into());
        progress.set_position(iteration.into());
    });
    progress.abandon();
    let outcome = outcome?;
    if matches!(outcome, TaskOutcome::Stopped { .. }) && signals.preempted() {
        requeue_this_task()?;
    }
    Ok(outcome)
}

/// Ask Slurm to run this array task again (its checkpoint is written).
fn requeue_this_task() -> Result<()> {
    let var = |name: &str| std::env::var(name).ok();
    let job = match (var("SLURM_ARRAY_JOB_ID"), var("SLURM_ARRAY_TASK_ID"), var("SLURM_JOB_ID")) {
        (Some(array), Some(task), _) => format!("{array}_{task}"),
        (_, _, Some(job)) => job,
        _ => return Err(Error::Slurm { command: "scontrol requeue".into(), why: "not inside a Slurm job".into() }),
    };
    slurm_command("scontrol", &["requeue".to_string(), job]).map(|_| ())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn array_specs_and_job_ids_round_trip() {
        assert_eq!(array_spec(&[0, 1, 2, 3], Some(2)), "0-3%2");
        assert_eq!(array_spec(&[9, 5, 1, 2, 3, 7, 8], None), "1-3,5,7-9");
        assert_eq!(array_indices("123_4"), vec![4]);
        assert_eq!(array_indices("123_[1-3,5,7-9%2]"), vec![1, 2, 3, 5, 7, 8, 9]);
        assert_eq!(array_indices("123"), Vec::<usize>::new());
    }

    #[test]
    fn states_from_sacct_lines_later_arrays_winning() {
        let job = |id: &str, indices: Vec<usize>| ArrayJob { job_id: id.into(), gather_job_id: "0".into(), indices };
        let submission = Submission {
            options: SlurmOptions::default(),
            program: "/opt/rmvp".into(),
            arrays: vec![job("123", vec![0, 1, 2, 3]), job("130", vec![2, 3])],
        };
        // `sacct -X --parsable2 --noheader --format=JobID,State` as Slurm 22.05 prints it.
        let text = "123_0|COMPLETED\n123_1|CANCELLED by 0\n123_2|FAILED\n123_3|FAILED\n1230_1|RUNNING\n\
                    130_2|RUNNING\n130_[3%1]|PENDING\n131|PENDING\n";
        let states = parse_states(text, &submission);
        let words: Vec<(usize, &str)> = states.iter().map(|(i, s)| (*i, s.as_str())).collect();
        assert_eq!(words, [(0, "COMPLETED"), (1, "CANCELLED"), (2, "RUNNING"), (3, "PENDING")]);
        assert!(is_active("RUNNING") && !is_active("FAILED") && !is_active("CANCELLED"));
    }

    #[test]
    fn scripts_put_every_sbatch_line_first() {
        let plan = BatchPlan {
            format: super::super::plan::PLAN_FORMAT.into(),
            source: "/plans/batch.toml".into(),
            datasets: Vec::new(),
            variants: Vec::new(),
            seeds: vec![0],
            evaluation: Default::default(),
            tasks: Vec::new(),
        };
        let options = SlurmOptions {
            partition: Some("gpu".into()),
            time: Some("02:00:00".into()),
            cpus_per_task: 8,
            mem: Some("16G".into()),
            max_running: Some(4),
            account: Some("lab".into()),
        };
        let script = batch_script(&plan, Path::new("/runs/it's"), &options, Path::new("/opt/rmvp"));
        let lines: Vec<&str> = script.lines().collect();
        let first_command = lines.iter().position(|l| !l.starts_with('#') && !l.is_empty()).unwrap();
        assert!(lines[first_command..].iter().all(|l| !l.starts_with("#SBATCH")), "{script}");
        for expected in [
            "#SBATCH --output=/runs/it's/logs/%A_%a.log",
            "#SBATCH --open-mode=append",
            "#SBATCH --requeue",
            "#SBATCH --signal=B:USR2@120",
            "#SBATCH --cpus-per-task=8",
            "#SBATCH --partition=gpu",
            "#SBATCH --time=02:00:00",
            "#SBATCH --mem=16G",
            "#SBATCH --account=lab",
        ] {
            assert!(lines.contains(&expected), "{expected} missing:\n{script}");
        }
        assert!(script.contains(r"batch task '/runs/it'\''s' "), "{script}");
        assert!(lines[first_command].starts_with("exec '/opt/rmvp' --threads"), "{script}");
    }
}
