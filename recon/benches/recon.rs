//! Training step time of each preset on the spot fixture (6 views, 128x128): milliseconds per
//! iteration, rays and samples per second, with 1 and 2 threads. Run with
//! `cargo bench -p rmvp-recon --bench recon` (`RMVP_BENCH_STEPS` steps per measurement,
//! `RMVP_BENCH_PRESETS=fast,dense,paper`).

use rmvp_dataset::layout::read_scene;
use rmvp_recon::data::TrainingSet;
use rmvp_recon::presets::{self, Preset};
use rmvp_recon::train::Trainer;
use std::time::Instant;

fn main() {
    if !std::env::args().any(|a| a == "--bench") {
        return; // run by `cargo test --all-targets` (no `--bench`): measure only under `cargo bench`
    }
    let scene = read_scene(&rmvp_testkit::fixture("spot_nersp")).expect("fixture");
    let steps: u32 = std::env::var("RMVP_BENCH_STEPS").ok().and_then(|s| s.parse().ok()).unwrap_or(20);
    let presets = std::env::var("RMVP_BENCH_PRESETS").unwrap_or_else(|_| "fast,paper".into());
    println!("recon benchmark: spot fixture, 6 views 128x128, median step over {steps} steps after warm-up");
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
                trainer.iteration = std::env::var("RMVP_BENCH_AT").ok().and_then(|s| s.parse().ok()).unwrap_or(trainer.config.diffuse_only);
                let warm = if preset == Preset::Paper { 1 } else { 3 };
                for _ in 0..warm {
                    trainer.step();
                }
                let mut times = Vec::new();
                let mut samples = 0;
                let n = if preset == Preset::Paper { steps.div_ceil(5) } else { steps };
                for _ in 0..n {
                    let start = Instant::now();
                    let r = trainer.step();
                    times.push(start.elapsed().as_secs_f64());
                    samples = r.samples;
                }
                times.sort_by(f64::total_cmp);
                let t = times[times.len() / 2];
                println!(
                    "{name:>5} {threads} thread(s): {:8.1} ms/step  {:9.0} rays/s  {:10.0} samples/s  (batch {} rays, {} samples, 7 field evaluations each)",
                    t * 1e3,
                    trainer.config.batch_rays as f64 / t,
                    samples as f64 / t,
                    trainer.config.batch_rays,
                    samples
                );
            });
        }
    }
}
