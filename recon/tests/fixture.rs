//! Reconstruction of the Mitsuba spot fixture with the fast preset (reduced iterations and
//! batch, same model): the paper's ablation claim (both cues together beat each alone on the
//! normal error over the ground-truth views), and what the preset's departures from NeRSP (the
//! diffuse lobe's Fresnel transmission, the azimuth-only tangent gradient, the specular lobe
//! polarized about its lit half vectors, the robust tangent term on curved surfaces) buy on a
//! renderer that is not the model.

use rmvp_align::normal_errors;
use rmvp_dataset::layout::read_scene;
use rmvp_recon::data::TrainingSet;
use rmvp_recon::extract::{extract_mesh, CpuSdf};
use rmvp_recon::model::neus_initial_radius;
use rmvp_recon::presets::{self, Preset};
use rmvp_recon::train::{TrainConfig, Trainer};

/// One run: the preset's configuration changed by `change`.
#[derive(Clone, Copy)]
struct Run {
    name: &'static str,
    change: fn(&mut TrainConfig),
}

/// The sphere the SDF starts from.
#[derive(Clone, Copy)]
enum Start {
    /// The preset's (`ModelConfig::initial_radius`).
    Preset,
    /// NeuS's, in place of the preset's.
    Neus,
}

fn train(run: Run, start: Start, iterations: u32) -> f64 {
    let scene = read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
    let mut config = presets::training(Preset::Fast, iterations);
    config.batch_rays = 256;
    if let Start::Neus = start {
        config.model.initial_radius = neus_initial_radius();
    }
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
fn train_alone(run: Run, start: Start, iterations: u32) -> f64 {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    pool.install(|| train(run, start, iterations))
}

#[test]
fn full_model_beats_both_ablations_nersps_settings_and_the_plain_tangent_term_on_spot() {
    // After 400 iterations the preset's small start (`ModelConfig::initial_radius`) has not
    // yet grown into the object (11.00 degrees, NeRSP's settings 10.32), so the cues are
    // compared from NeuS's start, where they have.
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
                c.tangent_robust_angle = 0.0;
            },
        },
        Run { name: "NeRSP's plain tangent term", change: |c| c.tangent_robust_angle = 0.0 },
    ];
    let [full, photometric_only, geometric_only, nersp, plain] = std::thread::scope(|scope| {
        runs.map(|run| scope.spawn(move || train_alone(run, Start::Neus, 400))).map(|run| run.join().unwrap())
    });
    // Measured: the preset from NeuS's start 6.89 degrees, photometric only 7.60, geometric
    // only 14.30, with NeRSP's normalised diffuse lobe, untilted specular lobe and plain tangent
    // term with its full gradient 7.66, with the plain tangent term alone 7.21.
    assert!(full < photometric_only, "full {full:.2} vs photometric only {photometric_only:.2}");
    assert!(full < geometric_only, "full {full:.2} vs geometric only {geometric_only:.2}");
    assert!(full < nersp, "full {full:.2} vs NeRSP's settings {nersp:.2}");
    assert!(full < plain, "full {full:.2} vs the plain tangent term {plain:.2}");
    assert!(full < 7.05, "full model: {full:.2} deg (the plain tangent term gave 7.21)");
}

#[test]
fn the_tilted_lobe_gains_on_spot_from_the_presets_start() {
    // The tilt is read from the specular network, which takes longer to fit than the cues:
    // after 400 iterations from NeuS's start the lobe about the normal still does better
    // (7.07 against 7.21 with the plain tangent term), after 1000 from the preset's start
    // the tilted one does.
    let runs = [
        Run { name: "preset", change: |_| {} },
        Run { name: "the specular lobe polarized about the normal", change: |c| c.model.specular_tilt = false },
    ];
    let [preset, untilted] = std::thread::scope(|scope| {
        runs.map(|run| scope.spawn(move || train_alone(run, Start::Preset, 1000))).map(|run| run.join().unwrap())
    });
    // Measured: the preset 4.57 degrees, the lobe about the normal 4.66 (with the plain tangent
    // term: 4.73 tilted, 4.88 about the normal).
    assert!(preset < untilted, "tilted {preset:.2} vs the lobe about the normal {untilted:.2}");
    assert!(preset < 4.70, "preset: {preset:.2} deg (the plain tangent term gave 4.73)");
}
