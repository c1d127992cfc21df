//! Reconstruction of the Mitsuba spot fixture, a renderer that is not the model, with the fast
//! preset (reduced iterations and batch, same model): the normal error over the ground-truth
//! views after 400 iterations from NeuS's start. Comparisons of variants (the cues' ablations,
//! NeRSP's settings) are the quality bench's (`cargo bench --bench quality -- --sets mitsuba
//! --scenes spot --variants ...`, `docs/benchmarks.md`).

use rmvp_align::normal_errors;
use rmvp_dataset::layout::read_scene;
use rmvp_recon::data::TrainingSet;
use rmvp_recon::extract::{extract_mesh, CpuSdf};
use rmvp_recon::model::neus_initial_radius;
use rmvp_recon::presets::{self, Preset};
use rmvp_recon::tracking::NormalTrack;
use rmvp_recon::train::Trainer;

/// How far the normal error training tracks may be from the extracted mesh's, degrees: seeds
/// 0-3 differ by 0.03, 0.08, 0.02 and 0.03.
const TRACKED_BOUND: f64 = 0.5;

/// The normal MAE (degrees) over the spot's ground-truth views after `iterations` of the fast
/// preset from NeuS's start, with `seed`: the extracted mesh's, and the one training tracks on
/// the field ([`NormalTrack`]).
fn normal_mae(seed: u64, iterations: u32) -> (f64, f64) {
    let scene = read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
    let mut config = presets::training(Preset::Fast, iterations);
    config.batch_rays = 256;
    config.seed = seed;
    // The preset's smaller start has not grown into the object after 400 iterations.
    config.model.initial_radius = neus_initial_radius();
    let set = TrainingSet::from_scene(&scene, config.margin).unwrap();
    let mut trainer = Trainer::new(config, set);
    while trainer.iteration < trainer.config.iterations {
        trainer.step();
    }
    let lw = trainer.level_weight();
    let sdf = CpuSdf::new(&trainer.model, &trainer.params, &lw);
    let mesh = extract_mesh(&sdf, 128, &trainer.set.frame, trainer.output_fd_step(&lw)).unwrap();
    let mae = normal_errors(&mesh, &scene).unwrap().mean_mae_deg;
    let tracked = NormalTrack::new(&scene, &trainer.set.frame).unwrap().normal_error_deg(&trainer).unwrap();
    println!("seed {seed}: normal MAE {mae:.2} deg, tracked during training {tracked:.2}");
    (mae, tracked)
}

#[test]
fn the_fast_preset_reconstructs_the_spot_fixture() {
    // After 400 iterations a run's figure depends much on its seed: seeds 0-3 give 6.89, 7.50,
    // 10.88 and 8.58 degrees (a spread of 4.0; between machines about 0.1). The bound sits 5.6
    // above seed 0's figure and 1.6 above the worst seed's; the geometric cue alone gives 14.3
    // at seed 0.
    let (mae, tracked) = normal_mae(rmvp_testkit::test_seed(), 400);
    assert!(mae < 12.5, "normal MAE {mae:.2} deg");
    // The figure training tracks on 2048 pixels of the field follows the mesh's on every pixel.
    assert!((tracked - mae).abs() < TRACKED_BOUND, "tracked {tracked:.2} deg, evaluated {mae:.2}");
}
