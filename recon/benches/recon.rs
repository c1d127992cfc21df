//! Training step time of each preset on the spot fixture (6 views, 128x128): milliseconds per
//! iteration, rays and samples per second, with 1 and 2 threads. Run with
//! `cargo bench -p rmvp-recon --bench recon` (`RMVP_BENCH_STEPS` steps per measurement,
//! `RMVP_BENCH_PRESETS=fast,dense,paper`). By default each preset's model is at its start, the
//! iteration set to `RMVP_BENCH_AT`; `RMVP_BENCH_CHECKPOINT=checkpoint.bin` measures instead
//! a trained model (a `rmvp recon` run's checkpoint of the spot fixture, its own options), once
//! as trained and once rendering every sample (`min_weight` 0); `RMVP_BENCH_SCENE=DIR` trains
//! on another scene instead of the fixture (the checkpoint's, for a model trained there);
//! `RMVP_BENCH_TANGENT_VIEWS=N` compares a surface point with at most N views (0: every one)
//! whatever the checkpoint's run did.

use rmvp_dataset::layout::read_scene;
use rmvp_recon::checkpoint;
use rmvp_recon::data::TrainingSet;
use rmvp_recon::presets::{self, Preset};
use rmvp_recon::train::Trainer;
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
                });
            }
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

/// One line of the table.
fn report(label: &str, threads: usize, ms: f64, rays: usize, samples: usize) {
    println!(
        "{label:>24} {threads} thread(s): {ms:8.1} ms/step  {:9.0} rays/s  {:10.0} samples/s  ({rays} rays, {samples} samples, {:.1} a ray)",
        rays as f64 / ms * 1e3,
        samples as f64 / ms * 1e3,
        samples as f64 / rays as f64
    );
}
