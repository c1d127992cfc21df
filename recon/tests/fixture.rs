//! Reconstruction of the Mitsuba spot fixture with the fast preset (reduced iterations and
//! batch, same model): the paper's ablation claim (both cues together beat each alone on the
//! normal error over the ground-truth views), and what the preset's departures from NeRSP (the
//! diffuse lobe's Fresnel transmission, the azimuth-only tangent gradient) buy on a renderer
//! that is not the model.

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

fn train(run: Run) -> f64 {
    let scene = read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
    let mut config = presets::training(Preset::Fast, 400);
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
fn train_alone(run: Run) -> f64 {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    pool.install(|| train(run))
}

#[test]
fn full_model_beats_both_ablations_and_nersps_settings_on_spot() {
    let runs = [
        Run { name: "preset", change: |_| {} },
        Run { name: "photometric only", change: |c| c.geometric = false },
        Run { name: "geometric only", change: |c| c.photometric = false },
        Run {
            name: "NeRSP's diffuse lobe and tangent gradient",
            change: |c| {
                c.model.diffuse_transmission = false;
                c.tangent_azimuth_only = false;
            },
        },
    ];
    let [full, photometric_only, geometric_only, nersp] = std::thread::scope(|scope| {
        runs.map(|run| scope.spawn(move || train_alone(run))).map(|run| run.join().unwrap())
    });
    // Measured: the preset 7.15 degrees, photometric only 7.59, geometric only 13.34, with
    // NeRSP's normalised diffuse lobe and full tangent gradient (the preset before) 7.63.
    assert!(full < photometric_only, "full {full:.2} vs photometric only {photometric_only:.2}");
    assert!(full < geometric_only, "full {full:.2} vs geometric only {geometric_only:.2}");
    assert!(full < nersp, "full {full:.2} vs NeRSP's settings {nersp:.2}");
    assert!(full < 7.4, "full model: {full:.2} deg (NeRSP's settings gave 7.63)");
}
