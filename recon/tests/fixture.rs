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

/// NeuS's initial sphere in place of the preset's.
fn neus_start(config: &mut TrainConfig) {
    config.model.initial_radius = neus_initial_radius();
}

#[test]
fn full_model_beats_both_ablations_and_nersps_settings_on_spot() {
    // After 400 iterations the preset's small start (`ModelConfig::initial_radius`) has not
    // yet grown into the object (11.00 degrees, NeRSP's settings 10.32), so the cues are
    // compared from NeuS's start, where they have.
    let runs = [
        Run { name: "preset", change: neus_start },
        Run {
            name: "photometric only",
            change: |c| {
                neus_start(c);
                c.geometric = false;
            },
        },
        Run {
            name: "geometric only",
            change: |c| {
                neus_start(c);
                c.photometric = false;
            },
        },
        Run {
            name: "NeRSP's lobes and tangent gradient",
            change: |c| {
                neus_start(c);
                c.model.diffuse_transmission = false;
                c.model.specular_tilt = false;
                c.tangent_azimuth_only = false;
                c.tangent_robust_angle = 0.0;
            },
        },
    ];
    let [full, photometric_only, geometric_only, nersp] = std::thread::scope(|scope| {
        runs.map(|run| scope.spawn(move || train_alone(run, 400))).map(|run| run.join().unwrap())
    });
    // Measured: the preset from NeuS's start 6.89 degrees (7.21 with the plain tangent term),
    // photometric only 7.60, geometric only 14.30, with NeRSP's normalised diffuse lobe,
    // untilted specular lobe and plain tangent term with its full gradient 7.66.
    assert!(full < photometric_only, "full {full:.2} vs photometric only {photometric_only:.2}");
    assert!(full < geometric_only, "full {full:.2} vs geometric only {geometric_only:.2}");
    assert!(full < nersp, "full {full:.2} vs NeRSP's settings {nersp:.2}");
    assert!(full < 7.05, "full model: {full:.2} deg (the plain tangent term gave 7.21)");
}

#[test]
fn the_robust_tangent_term_on_curved_surfaces_and_the_tilted_lobe_each_gain_on_spot() {
    let runs = [
        Run { name: "preset", change: |_| {} },
        Run { name: "NeRSP's plain tangent term", change: |c| c.tangent_robust_angle = 0.0 },
        Run {
            name: "the plain tangent term, the specular lobe polarized about the normal",
            change: |c| {
                c.tangent_robust_angle = 0.0;
                c.model.specular_tilt = false;
            },
        },
    ];
    let [preset, plain, untilted] = std::thread::scope(|scope| {
        runs.map(|run| scope.spawn(move || train_alone(run, 1000))).map(|run| run.join().unwrap())
    });
    // Measured: the preset 4.57 degrees, with the plain tangent term 4.73, with the lobe about
    // the normal as well 4.88 (from NeuS's start 4.62, 4.78 and 4.92).
    assert!(preset < plain, "preset {preset:.2} vs the plain tangent term {plain:.2}");
    assert!(plain < untilted, "tilted {plain:.2} vs the lobe about the normal {untilted:.2}");
    assert!(preset < 4.70, "preset: {preset:.2} deg (the plain tangent term gave 4.78)");
}
