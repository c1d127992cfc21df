//! A batch's results as one table: per dataset x variant, the mean and spread over seeds of
//! Chamfer distance, F-score and normal MAE (all views, training views, held-out views) and
//! minutes; failed and unfinished tasks listed. Written as `results.json`, `results.csv`,
//! `results.md` and a bar chart of normal MAE, `results.png`.

use super::chart::{bar_chart, Bar};
use super::plan::BatchPlan;
use super::task::{task_state, TaskResult, TaskState};
use crate::report::{write_batch_report, TaskRow};
use crate::Result;
use rmvp_dataset::io::json::write_json;
use rmvp_dataset::io::{png, write_bytes_atomically};
use rmvp_dataset::Split;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The results table files of a batch folder (`.json`, `.csv`, `.md`, `.png`).
pub const RESULTS_STEM: &str = "results";
/// The `format` of [`BatchTable`].
pub const TABLE_FORMAT: &str = "rmvp-batch-table";

/// A mean over seeds and its spread (sample standard deviation; 0 for one seed).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Stat {
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation.
    pub spread: f64,
}

impl Stat {
    /// Of some values (`None` when there are none).
    pub fn of(values: &[f64]) -> Option<Self> {
        if values.is_empty() {
            return None;
        }
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let spread = if values.len() > 1 {
            (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
        } else {
            0.0
        };
        Some(Self { mean, spread })
    }
}

/// One dataset x variant.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ResultRow {
    /// Dataset.
    pub dataset: String,
    /// Variant.
    pub variant: String,
    /// Seeds finished.
    pub seeds: usize,
    /// Seeds planned.
    pub planned: usize,
    /// Chamfer distance (the meshes' units).
    pub chamfer: Option<Stat>,
    /// F-score.
    pub fscore: Option<Stat>,
    /// Normal MAE over every view, degrees.
    pub normal_mae_deg: Option<Stat>,
    /// Over the training views.
    pub train_mae_deg: Option<Stat>,
    /// Over the held-out views.
    pub heldout_mae_deg: Option<Stat>,
    /// Training, outputs and evaluation, minutes.
    pub minutes: Option<Stat>,
}

/// A task that did not finish.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OpenTask {
    /// Index in the plan.
    pub index: usize,
    /// Id.
    pub id: String,
    /// `failed`, `partial` or `not-started`.
    pub state: String,
    /// The error of a failed task; the iteration of a partial one.
    pub detail: String,
}

/// The gathered results (`results.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BatchTable {
    /// [`TABLE_FORMAT`].
    pub format: String,
    /// Rows, dataset-major in plan order.
    pub rows: Vec<ResultRow>,
    /// Every finished task's result.
    pub results: Vec<TaskResult>,
    /// Tasks that failed or have not finished.
    pub open: Vec<OpenTask>,
}

/// Gather the results of batch folder `dir` and write the table files.
pub fn gather(dir: &Path) -> Result<BatchTable> {
    let plan = BatchPlan::load(dir)?;
    let mut results = Vec::new();
    let mut open = Vec::new();
    for (index, task) in plan.tasks.iter().enumerate() {
        let (state, detail) = match task_state(&plan, dir, index) {
            TaskState::Done(result) => {
                results.push(*result);
                continue;
            }
            TaskState::Failed(failure) => ("failed", failure.error),
            TaskState::Partial { iteration } => ("partial", format!("iteration {iteration}")),
            TaskState::NotStarted => ("not-started", String::new()),
        };
        open.push(OpenTask { index, id: task.id.clone(), state: state.into(), detail });
    }
    let mut rows = Vec::new();
    for dataset in &plan.datasets {
        for variant in &plan.variants {
            let done: Vec<&TaskResult> = results
                .iter()
                .filter(|r| r.task.dataset == dataset.name && r.task.variant.name == variant.name)
                .collect();
            let stat = |f: &dyn Fn(&TaskResult) -> Option<f64>| {
                Stat::of(&done.iter().filter_map(|r| f(r)).collect::<Vec<_>>())
            };
            rows.push(ResultRow {
                dataset: dataset.name.clone(),
                variant: variant.name.clone(),
                seeds: done.len(),
                planned: plan.seeds.len(),
                chamfer: stat(&|r| r.evaluation.as_ref().map(|e| e.surface.chamfer)),
                fscore: stat(&|r| r.evaluation.as_ref().map(|e| e.surface.fscore)),
                normal_mae_deg: stat(&|r| r.evaluation.as_ref().and_then(|e| e.normal_mae_deg)),
                train_mae_deg: stat(&|r| r.evaluation.as_ref().and_then(|e| e.split_normal_mae_deg(Split::Train))),
                heldout_mae_deg: stat(&|r| r.evaluation.as_ref().and_then(|e| e.split_normal_mae_deg(Split::Eval))),
                minutes: stat(&|r| Some(r.minutes())),
            });
        }
    }
    let table = BatchTable { format: TABLE_FORMAT.into(), rows, results, open };
    write_json(&dir.join(format!("{RESULTS_STEM}.json")), &table)?;
    write_bytes_atomically(&dir.join(format!("{RESULTS_STEM}.csv")), table.csv().as_bytes())?;
    write_bytes_atomically(&dir.join(format!("{RESULTS_STEM}.md")), table.markdown().as_bytes())?;
    let groups: Vec<String> = plan.datasets.iter().map(|d| d.name.clone()).collect();
    let series: Vec<String> = plan.variants.iter().map(|v| v.name.clone()).collect();
    let bars: Vec<Vec<Option<Bar>>> = groups
        .iter()
        .map(|g| {
            table
                .rows
                .iter()
                .filter(|r| &r.dataset == g)
                .map(|r| r.normal_mae_deg.map(|s| Bar { mean: s.mean, spread: s.spread }))
                .collect()
        })
        .collect();
    let picture = bar_chart("normal MAE (deg), mean and spread over seeds", &groups, &series, &bars);
    let chart = dir.join(format!("{RESULTS_STEM}.png"));
    png::write_png_u8(&chart, &picture)?;
    let tasks: Vec<TaskRow> = table
        .results
        .iter()
        .map(|r| TaskRow {
            id: r.task.id.clone(),
            dataset: r.task.dataset.clone(),
            variant: r.task.variant.name.clone(),
            seed: r.task.seed,
            figures: r.evaluation.as_ref().map(|e| (e.surface.chamfer, e.surface.fscore, e.normal_mae_deg)),
            minutes: r.minutes(),
        })
        .collect();
    write_batch_report(dir, &tasks, &chart)?;
    Ok(table)
}

fn cell(stat: Option<Stat>, decimals: usize) -> String {
    match stat {
        Some(s) if s.spread > 0.0 => format!("{:.decimals$} ± {:.decimals$}", s.mean, s.spread),
        Some(s) => format!("{:.decimals$}", s.mean),
        None => "-".into(),
    }
}

impl BatchTable {
    /// One line per row: means and spreads in columns.
    pub fn csv(&self) -> String {
        let mut text = String::from(
            "dataset,variant,seeds,planned,chamfer_mean,chamfer_sd,fscore_mean,fscore_sd,normal_mae_mean,normal_mae_sd,\
             train_mae_mean,train_mae_sd,heldout_mae_mean,heldout_mae_sd,minutes_mean,minutes_sd\n",
        );
        for r in &self.rows {
            let pair = |s: Option<Stat>| s.map_or(",".into(), |s| format!("{},{}", s.mean, s.spread));
            text.push_str(&format!(
                "{},{},{},{},{},{},{},{},{},{}\n",
                r.dataset,
                r.variant,
                r.seeds,
                r.planned,
                pair(r.chamfer),
                pair(r.fscore),
                pair(r.normal_mae_deg),
                pair(r.train_mae_deg),
                pair(r.heldout_mae_deg),
                pair(r.minutes)
            ));
        }
        text
    }

    /// The table in Markdown (mean ± spread), then the tasks that did not finish.
    pub fn markdown(&self) -> String {
        let mut text = String::from(
            "| dataset | variant | seeds | Chamfer | F-score | normal MAE (deg) | train | held-out | minutes |\n\
             |---|---|---|---|---|---|---|---|---|\n",
        );
        for r in &self.rows {
            text.push_str(&format!(
                "| {} | {} | {}/{} | {} | {} | {} | {} | {} | {} |\n",
                r.dataset,
                r.variant,
                r.seeds,
                r.planned,
                cell(r.chamfer, 4),
                cell(r.fscore, 3),
                cell(r.normal_mae_deg, 2),
                cell(r.train_mae_deg, 2),
                cell(r.heldout_mae_deg, 2),
                cell(r.minutes, 1)
            ));
        }
        if !self.open.is_empty() {
            text.push_str("\nNot finished:\n\n");
            for t in &self.open {
                let detail = if t.detail.is_empty() { String::new() } else { format!(": {}", t.detail) };
                text.push_str(&format!("- task {} `{}` {}{detail}\n", t.index, t.id, t.state));
            }
        }
        text
    }
}
