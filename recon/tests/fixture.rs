//! Reconstruction of the Mitsuba spot fixture with the fast preset (reduced iterations and
//! batch, same model), and the paper's ablation claim: both cues together beat each alone on
//! the normal error over the ground-truth views.

use rmvp_align::normal_errors;
use rmvp_dataset::layout::read_scene;
use rmvp_recon::data::TrainingSet;
use rmvp_recon::extract::{extract_mesh, CpuSdf};
use rmvp_recon::presets::{self, Preset};
use rmvp_recon::train::Trainer;

fn train(photometric: bool, geometric: bool) -> f64 {
    let scene = read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
    let mut config = presets::training(Preset::Fast, 400);
    config.batch_rays = 256;
    config.photometric = photometric;
    config.geometric = geometric;
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
    println!("photometric {photometric} geometric {geometric}: normal MAE {:.2} deg", report.mean_mae_deg);
    report.mean_mae_deg
}

/// `train` in a pool of one thread: the three runs train side by side, which keeps two
/// cores busier than one run on both (results do not depend on the thread count).
fn train_alone(photometric: bool, geometric: bool) -> f64 {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    pool.install(|| train(photometric, geometric))
}

#[test]
fn full_model_beats_both_ablations_on_spot() {
    let [full, photometric_only, geometric_only] = std::thread::scope(|scope| {
        [(true, true), (true, false), (false, true)]
            .map(|(p, g)| scope.spawn(move || train_alone(p, g)))
            .map(|run| run.join().unwrap())
    });
    // Holds the curvature weight's gain: with 5e-4 this test measures 11.53 degrees
    // (photometric only 12.30, geometric only 15.87); with the preset's 5e-3, 7.63 (7.75, 10.46).
    assert!(full < 9.5, "full model: {full:.2} deg (the curvature weight 5e-4 gave 11.5)");
    assert!(full < photometric_only, "full {full:.2} vs photometric only {photometric_only:.2}");
    assert!(full < geometric_only, "full {full:.2} vs geometric only {geometric_only:.2}");
}
