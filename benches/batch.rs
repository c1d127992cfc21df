//! The batch layer's cost and a local batch's throughput: a plan of short reconstructions on the
//! two fixtures (2 datasets x 2 variants x 2 seeds, 20 iterations, 64-cell mesh grid, mesh only)
//! run with `--jobs 1` (all threads to one task) and `--jobs 2` (one thread each), then run
//! again complete (what skipping costs) and gathered.
//! `cargo bench --bench batch` (part of `./run bench`). Per-task overhead = (wall time of the
//! batch - the tasks' own training, output and evaluation seconds) / tasks: reading the scene,
//! the records, the thread pools.

use rmvp_pipeline::batch::{gather, run_local, BatchPlan, LocalOptions};
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
        println!(
            "| {jobs} | {} | {wall:.1} | {own:.1} | {overhead_ms:.0} | {:.2} |",
            (threads / jobs).max(1),
            plan.tasks.len() as f64 / wall * 60.0
        );
    }
    let dir = root.join("jobs1");
    let start = Instant::now();
    let summary = run_local(&plan, &dir, &LocalOptions { jobs: 1, threads: Some(threads), progress: false }, &stop)
        .expect("batch");
    let skip = start.elapsed().as_secs_f64();
    assert_eq!(summary.skipped.len(), plan.tasks.len());
    let start = Instant::now();
    gather(&dir).expect("gather");
    println!(
        "re-run of the complete plan: {:.1} ms per task; gather (table, CSV, Markdown, chart): {:.0} ms",
        skip * 1000.0 / plan.tasks.len() as f64,
        start.elapsed().as_secs_f64() * 1000.0
    );
}
