//! The batch layer's cost and a local batch's throughput: a plan of short reconstructions on the
//! two fixtures (2 datasets x 2 variants x 2 seeds, 20 iterations, 64-cell mesh grid, mesh only)
//! run with `--jobs 1` (all threads to one task) and `--jobs 2` (one thread each), then run
//! again complete (what skipping costs) and gathered.
//! `cargo bench --bench batch` (part of `./run bench`). Per-task overhead = (wall time of the
//! batch - the tasks' own training, output and evaluation seconds) / tasks: reading the scene,
//! the records, the thread pools. Writes `bench/results/batch.json`.

use rmvp_pipeline::batch::{gather, run_local, BatchPlan, LocalOptions};
use rmvp_testkit::results::{BenchResult, Table};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

const PLAN: &str = r#"datasets = ["FIXTURES/*_nersp"]
seeds = [0, 1]

[evaluation]
max_samples = 20000

[[variant]]
name = "full"
options = { iters = 20, mesh_res = 64, mesh_only = true }

[[variant]]
name = "no-geometric"
options = { no_geometric = true, iters = 20, mesh_res = 64, mesh_only = true }
"#;

fn main() {
    if !std::env::args().any(|a| a == "--bench") {
        return; // run by `cargo test --all-targets` (no `--bench`): measure only under `cargo bench`
    }
    let root = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("bench-batch");
    let _ = std::fs::remove_dir_all(&root);
    std::fs::create_dir_all(&root).expect("bench folder");
    let plan_file = root.join("batch.toml");
    let fixtures = rmvp_testkit::fixtures_root();
    std::fs::write(&plan_file, PLAN.replace("FIXTURES", fixtures.to_str().expect("UTF-8 path"))).expect("plan");
    let plan = BatchPlan::read(&plan_file).expect("plan");
    let threads = std::thread::available_parallelism().map_or(2, |n| n.get());
    let stop = AtomicBool::new(false);
    println!("{} tasks, {threads} threads", plan.tasks.len());
    println!("| jobs | threads per task | wall s | tasks' own s | overhead per task ms | tasks per minute |");
    println!("|---|---|---|---|---|---|");
    let mut result = BenchResult::now("Batches", "cargo bench --bench batch");
    let mut runs =
        Table::new(&["jobs", "threads a task", "wall s", "tasks' own s", "overhead a task, ms", "tasks a minute"]);
    let mut overheads = Vec::new();
    for jobs in [1, 2] {
        let dir = root.join(format!("jobs{jobs}"));
        let options = LocalOptions { jobs, threads: Some(threads), progress: false };
        let start = Instant::now();
        let summary = run_local(&plan, &dir, &options, &stop).expect("batch");
        let wall = start.elapsed().as_secs_f64();
        assert_eq!(summary.finished.len(), plan.tasks.len(), "{summary:?}");
        let table = gather(&dir).expect("gather");
        let own: f64 = table.results.iter().map(|r| r.minutes() * 60.0).sum();
        // With several jobs the tasks' own times overlap: the overhead is what the wall time
        // holds beyond their sum divided among the jobs.
        let overhead_ms = (wall - own / jobs as f64) / plan.tasks.len() as f64 * 1000.0;
        let cells = [
            jobs.to_string(),
            (threads / jobs).max(1).to_string(),
            format!("{wall:.1}"),
            format!("{own:.1}"),
            format!("{overhead_ms:.0}"),
            format!("{:.1}", plan.tasks.len() as f64 / wall * 60.0),
        ];
        println!("| {} |", cells.join(" | "));
        runs.row(cells.to_vec());
        overheads.push(overhead_ms);
    }
    let dir = root.join("jobs1");
    let start = Instant::now();
    let summary = run_local(&plan, &dir, &LocalOptions { jobs: 1, threads: Some(threads), progress: false }, &stop)
        .expect("batch");
    let skip = start.elapsed().as_secs_f64();
    assert_eq!(summary.skipped.len(), plan.tasks.len());
    let start = Instant::now();
    gather(&dir).expect("gather");
    let (skip_ms, gather_ms) = (skip * 1000.0 / plan.tasks.len() as f64, start.elapsed().as_secs_f64() * 1000.0);
    println!("re-run of the complete plan: {skip_ms:.1} ms per task; gather (table, CSV, Markdown, chart): {gather_ms:.0} ms");
    let (least, most) = overheads.iter().fold((f64::INFINITY, 0f64), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    let overhead = result.figure("overhead_ms", format!("{least:.0}-{most:.0}"));
    result.headline = format!("{overhead} ms overhead a task");
    result.about = format!(
        "A local batch of {} short reconstructions of the two fixtures (2 datasets x 2 variants x 2 seeds; 20 \
         iterations, mesh only, evaluation on 20,000 samples) with `--jobs 1` (every thread to one task) and \
         `--jobs 2` (half each). Overhead: the wall time beyond the tasks' own training, output and evaluation. \
         Running the complete plan again skips every task in {skip_ms:.1} ms a task; gathering the results (table, \
         CSV, Markdown, chart) takes {gather_ms:.0} ms.",
        plan.tasks.len()
    );
    result.tables = vec![runs];
    result.write("batch");
}
