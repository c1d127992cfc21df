//! Reconstruction of the Mitsuba spot fixture with the fast preset (reduced iterations and
//! batch, same model), the paper's ablation claim (both cues together beat each alone on the
//! normal error over the ground-truth views), and what weighting the geometric cue by the
//! AoP's reliability buys on a renderer whose polarization is not the model's.

use rmvp_align::normal_errors;
use rmvp_dataset::layout::read_scene;
use rmvp_recon::data::TrainingSet;
use rmvp_recon::extract::{extract_mesh, CpuSdf};
use rmvp_recon::presets::{self, Preset};
use rmvp_recon::train::Trainer;

/// The cues a run uses, and the reliability DoP of the geometric one (0: unweighted).
#[derive(Clone, Copy)]
struct Run {
    photometric: bool,
    geometric: bool,
    aop_reliability: f32,
}

fn train(run: Run) -> f64 {
    let Run { photometric, geometric, aop_reliability } = run;
    let scene = read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
    let mut config = presets::training(Preset::Fast, 400);
    config.batch_rays = 256;
    config.photometric = photometric;
    config.geometric = geometric;
    config.aop_reliability = aop_reliability;
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
    println!(
        "photometric {photometric} geometric {geometric} AoP reliability {aop_reliability}: normal MAE {:.2} deg",
        report.mean_mae_deg
    );
    report.mean_mae_deg
}

/// `train` in a pool of one thread: the runs train side by side, which keeps two cores busier
/// than one run on both (results do not depend on the thread count).
fn train_alone(run: Run) -> f64 {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    pool.install(|| train(run))
}

#[test]
fn full_model_beats_both_ablations_on_spot_and_the_aop_reliability_gains() {
    let runs = [(true, true, 0.0), (true, false, 0.0), (false, true, 0.0), (true, true, 0.05)]
        .map(|(photometric, geometric, aop_reliability)| Run { photometric, geometric, aop_reliability });
    let [full, photometric_only, geometric_only, weighted] = std::thread::scope(|scope| {
        runs.map(|run| scope.spawn(move || train_alone(run))).map(|run| run.join().unwrap())
    });
    // Holds the curvature weight's gain: with 5e-4 this test measures 11.53 degrees
    // (photometric only 12.30, geometric only 15.87); with the preset's 5e-3, 7.63 (7.75, 10.46).
    assert!(full < 9.5, "full model: {full:.2} deg (the curvature weight 5e-4 gave 11.5)");
    assert!(full < photometric_only, "full {full:.2} vs photometric only {photometric_only:.2}");
    assert!(full < geometric_only, "full {full:.2} vs geometric only {geometric_only:.2}");
    // Mitsuba's AoP strays from the normal's planes where its DoP is low; weighting each
    // view's tangent term by dop^2 / (dop^2 + 0.05^2) measures 6.98 here.
    assert!(weighted < 7.3, "AoP reliability 0.05: {weighted:.2} deg (unweighted {full:.2})");
}
