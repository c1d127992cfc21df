//! Training step time of each preset on the spot fixture (6 views, 128x128): milliseconds per
//! iteration, rays and samples per second, with 1 and 2 threads. Run with
//! `cargo bench -p rmvp-recon --bench recon` (`RMVP_BENCH_STEPS` steps per measurement,
//! `RMVP_BENCH_PRESETS=fast,dense,paper`). By default each preset's model is at its start, the
//! iteration set to `RMVP_BENCH_AT`; `RMVP_BENCH_CHECKPOINT=checkpoint.bin` measures instead
//! a trained model (a `rmvp recon` run's checkpoint of the spot fixture, its own options), once
//! as trained and once rendering every sample (`min_weight` 0); `RMVP_BENCH_SCENE=DIR` trains
//! on another scene instead of the fixture (the checkpoint's, for a model trained there);
//! `RMVP_BENCH_TANGENT_VIEWS=N` compares a surface point with at most N views (0: every one)
//! whatever the checkpoint's run did. With a checkpoint it writes its preset's rows into
//! `bench/results/recon-step.json` (keeping the other preset's).

use rmvp_dataset::layout::read_scene;
use rmvp_recon::checkpoint;
use rmvp_recon::data::TrainingSet;
use rmvp_recon::presets::{self, Preset};
use rmvp_recon::train::Trainer;
use rmvp_testkit::results::{BenchResult, Table};
use std::time::Instant;

fn main() {
    if !std::env::args().any(|a| a == "--bench") {
        return; // run by `cargo test --all-targets` (no `--bench`): measure only under `cargo bench`
    }
    let scene_dir = std::env::var_os("RMVP_BENCH_SCENE")
        .map_or_else(|| rmvp_testkit::fixture("spot_nersp"), std::path::PathBuf::from);
    let scene = read_scene(&scene_dir).expect("scene");
    let steps: u32 = std::env::var("RMVP_BENCH_STEPS").ok().and_then(|s| s.parse().ok()).unwrap_or(20);
    let presets = std::env::var("RMVP_BENCH_PRESETS").unwrap_or_else(|_| "fast,paper".into());
    println!(
        "recon benchmark: {} ({} views), median step over {steps} steps after warm-up",
        scene_dir.display(),
        scene.views.len()
    );
    if let Some(path) = std::env::var_os("RMVP_BENCH_CHECKPOINT") {
        let path = std::path::PathBuf::from(path);
        let recorded = checkpoint::recorded_config(&path).expect("checkpoint");
        let tangent_views: Option<usize> =
            std::env::var("RMVP_BENCH_TANGENT_VIEWS").ok().map(|s| s.parse().expect("N"));
        let preset = [Preset::Fast, Preset::Dense, Preset::Paper]
            .into_iter()
            .find(|&p| presets::model(p) == recorded.model)
            .map_or("other".to_string(), |p| serde_json::to_value(p).expect("a name").as_str().expect("a name").into());
        let mut rows = Vec::new();
        for min_weight in [None, Some(0.0)] {
            for threads in [1, 2] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
                pool.install(|| {
                    let mut config = recorded.clone();
                    if let Some(w) = min_weight {
                        config.sampling.min_weight = w;
                    }
                    config.tangent_views = tangent_views.unwrap_or(config.tangent_views);
                    let set = TrainingSet::from_scene(&scene, config.margin).expect("training set");
                    let mut trainer = checkpoint::load(&path, set, &recorded, None).expect("checkpoint");
                    trainer.config = config;
                    trainer.refresh_occupancy();
                    let (ms, rays, samples) = measure(&mut trainer, 2, steps, true);
                    let label = if min_weight.is_some() { "every sample" } else { "as trained" };
                    report(&format!("trained, {label}"), threads, ms, rays, samples);
                    let samples_label = if min_weight.is_some() { "every" } else { "weighted" };
                    rows.push(vec![
                        preset.clone(),
                        samples_label.to_string(),
                        threads.to_string(),
                        format!("{ms:.1}"),
                        format!("{:.0}", rays as f64 / ms * 1e3),
                        format!("{:.1}", samples as f64 / rays as f64),
                    ]);
                });
            }
        }
        if tangent_views.is_none() {
            write_results(&preset, rows, &scene_dir, scene.views.len());
        }
        return;
    }
    for name in presets.split(',') {
        let preset = match name {
            "paper" => Preset::Paper,
            "dense" => Preset::Dense,
            _ => Preset::Fast,
        };
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
            pool.install(|| {
                let config = presets::training(preset, 3_000);
                let set = TrainingSet::from_scene(&scene, config.margin).expect("training set");
                let mut trainer = Trainer::new(config, set);
                // Past the diffuse-only warm-up, so that every loss and network runs.
                trainer.iteration = std::env::var("RMVP_BENCH_AT")
                    .ok()
                    .and_then(|s| s.parse().ok())
                    .unwrap_or(trainer.config.diffuse_only);
                let (warm, n) = if preset == Preset::Paper { (1, steps.div_ceil(5)) } else { (3, steps) };
                let (ms, rays, samples) = measure(&mut trainer, warm, n, false);
                report(name, threads, ms, rays, samples);
            });
        }
    }
}

/// The median milliseconds of `n` steps after `warm` steps, and the rays and samples of the
/// last; with `restore`, each step starts from the same parameters (a trained model stays as
/// trained).
fn measure(trainer: &mut Trainer, warm: u32, n: u32, restore: bool) -> (f64, usize, usize) {
    let start_params = trainer.params.clone();
    for _ in 0..warm {
        trainer.step();
    }
    let (mut times, mut rays, mut samples) = (Vec::new(), 0, 0);
    for _ in 0..n {
        if restore {
            trainer.params.clone_from(&start_params);
        }
        let start = Instant::now();
        let report = trainer.step();
        (rays, samples) = (report.rays, report.samples);
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], rays, samples)
}

/// The columns of the results' table.
const COLUMNS: [&str; 6] = ["preset", "samples", "threads", "ms a step", "rays/s", "samples a ray"];

/// Write `bench/results/recon-step.json`: `rows` of `preset` (trained on `scene`, of `views`
/// views) in place of that preset's earlier rows, the other presets' kept.
fn write_results(preset: &str, rows: Vec<Vec<String>>, scene: &std::path::Path, views: usize) {
    let command = "RMVP_BENCH_CHECKPOINT=CHECKPOINT cargo bench -p rmvp-recon --bench recon";
    let mut result = BenchResult::now("A training step", command);
    let earlier =
        BenchResult::read("recon-step").and_then(|r| r.tables.into_iter().next()).filter(|t| t.columns == COLUMNS);
    let mut table = Table::new(&COLUMNS);
    for row in earlier.map_or(Vec::new(), |t| t.rows).into_iter().filter(|r| r[0] != preset).chain(rows) {
        table.row(row);
    }
    table.rows.sort_by_key(|r| (r[0] != "fast", r[1] != "weighted", r[2].clone()));
    let ms = |p: &str| table.rows.iter().find(|r| r[0] == p && r[1] == "weighted" && r[2] == "2").map(|r| r[3].clone());
    let figures: Vec<String> = ["fast", "dense"]
        .iter()
        .filter_map(|&p| ms(p).map(|m| format!("{p} {}", result.figure(&format!("{p}_ms"), format!("{m} ms")))))
        .collect();
    result.headline = format!("a trained model's step on 2 threads: {}", figures.join(", "));
    result.about = format!(
        "The median step of a trained model (a `rmvp recon` checkpoint, its own options), nothing else running: \
         each preset's last run of the bench, here {preset} on `{}` ({views} views; `RMVP_BENCH_SCENE`, the spot \
         fixture by default). Samples rendered: those that carry weight (the default) or every one.",
        scene.file_name().map_or(String::new(), |n| n.to_string_lossy().into_owned())
    );
    result.tables = vec![table];
    result.write("recon-step");
}

/// One line of the table.
fn report(label: &str, threads: usize, ms: f64, rays: usize, samples: usize) {
    println!(
        "{label:>24} {threads} thread(s): {ms:8.1} ms/step  {:9.0} rays/s  {:10.0} samples/s  ({rays} rays, {samples} samples, {:.1} a ray)",
        rays as f64 / ms * 1e3,
        samples as f64 / ms * 1e3,
        samples as f64 / rays as f64
    );
}
