//! Reconstruction of the Mitsuba spot fixture with the fast preset (reduced iterations and
//! batch, same model): the paper's ablation claim (both cues together beat each alone on the
//! normal error over the ground-truth views), and what the preset's departures from NeRSP (the
//! diffuse lobe's Fresnel transmission, the azimuth-only tangent gradient, the specular lobe
//! polarized about its lit half vectors) buy on a renderer that is not the model.

use rmvp_align::normal_errors;
use rmvp_dataset::layout::read_scene;
use rmvp_recon::data::TrainingSet;
use rmvp_recon::extract::{extract_mesh, CpuSdf};
use rmvp_recon::presets::{self, Preset};
use rmvp_recon::train::{TrainConfig, Trainer};

/// One run: the preset's configuration changed by `change`.
#[derive(Clone, Copy)]
struct Run {
    name: &'static str,
    change: fn(&mut TrainConfig),
}

fn train(run: Run, iterations: u32) -> f64 {
    let scene = read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
    let mut config = presets::training(Preset::Fast, iterations);
    config.batch_rays = 256;
    (run.change)(&mut config);
    let set = TrainingSet::from_scene(&scene, config.margin).unwrap();
    let mut trainer = Trainer::new(config, set);
    while trainer.iteration < trainer.config.iterations {
        trainer.step();
    }
    let lw = trainer.level_weight();
    let mesh =
        extract_mesh(&CpuSdf::new(&trainer.model, &trainer.params, &lw), 128, &trainer.set.frame, trainer.fd_step(&lw))
            .unwrap();
    let report = normal_errors(&mesh, &scene).unwrap();
    println!("{}: normal MAE {:.2} deg", run.name, report.mean_mae_deg);
    report.mean_mae_deg
}

/// `train` in a pool of one thread: the runs train side by side, which keeps two cores busier
/// than one run on both (results do not depend on the thread count).
fn train_alone(run: Run, iterations: u32) -> f64 {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    pool.install(|| train(run, iterations))
}

#[test]
fn full_model_beats_both_ablations_and_nersps_settings_on_spot() {
    let runs = [
        Run { name: "preset", change: |_| {} },
        Run { name: "photometric only", change: |c| c.geometric = false },
        Run { name: "geometric only", change: |c| c.photometric = false },
        Run {
            name: "NeRSP's lobes and tangent gradient",
            change: |c| {
                c.model.diffuse_transmission = false;
                c.model.specular_tilt = false;
                c.tangent_azimuth_only = false;
            },
        },
    ];
    let [full, photometric_only, geometric_only, nersp] = std::thread::scope(|scope| {
        runs.map(|run| scope.spawn(move || train_alone(run, 400))).map(|run| run.join().unwrap())
    });
    // Measured: the preset 7.21 degrees, photometric only 7.60, geometric only 13.34, with
    // NeRSP's normalised diffuse lobe, untilted specular lobe and full tangent gradient 7.66.
    // (After 400 iterations the specular lobe has yet to fit its light: untilted, the preset
    // gives 7.07; the tilt's gain shows from 1000, below.)
    assert!(full < photometric_only, "full {full:.2} vs photometric only {photometric_only:.2}");
    assert!(full < geometric_only, "full {full:.2} vs geometric only {geometric_only:.2}");
    assert!(full < nersp, "full {full:.2} vs NeRSP's settings {nersp:.2}");
    assert!(full < 7.4, "full model: {full:.2} deg (NeRSP's settings gave 7.66)");
}

#[test]
fn the_lobe_polarized_about_its_lit_half_vectors_beats_the_lobe_about_the_normal_on_spot() {
    let runs = [
        Run { name: "preset", change: |_| {} },
        Run { name: "the specular lobe polarized about the normal", change: |c| c.model.specular_tilt = false },
    ];
    let [tilted, untilted] = std::thread::scope(|scope| {
        runs.map(|run| scope.spawn(move || train_alone(run, 1000))).map(|run| run.join().unwrap())
    });
    // Measured: the preset 4.78 degrees, the lobe about the normal (the preset before) 4.92; after
    // 3000 iterations of the bench (docs/benchmarks.md) 4.59 against 5.08.
    assert!(tilted < untilted, "tilted {tilted:.2} vs about the normal {untilted:.2}");
    assert!(tilted < 4.86, "preset: {tilted:.2} deg (the lobe about the normal gave 4.92)");
}
