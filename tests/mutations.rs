//! Mutated batch plans and training checkpoints through the mutation engine of `rmvp-testkit`
//! (each family in a child process under 2 GiB of address space, its peak memory measured, a
//! deadline): a mutated file is refused with an error that names it, or read; never a panic,
//! never more memory, never a hang. The dataset crate's readers have their own families.

use rmvp_dataset::layout::read_scene;
use rmvp_pipeline::batch::BatchPlan;
use rmvp_recon::data::TrainingSet;
use rmvp_recon::presets::{self, Preset};
use rmvp_recon::train::{TrainConfig, Trainer};
use rmvp_testkit::mutation::{no_fixup, outcome, run_family, Family};
use std::path::Path;
use std::sync::OnceLock;

/// A plan of the spot fixture: two variants, three seeds, evaluation settings.
fn plan_seed(_: &Path) -> Vec<u8> {
    let spot = rmvp_testkit::fixture("spot_nersp");
    format!(
        "datasets = [{:?}]\nseeds = [0, 1, 2]\n\n[[variant]]\nname = \"full\"\noptions = {{ iters = 1000, mesh_res = 128 }}\n\n\
         [[variant]]\nname = \"no-geometric\"\noptions = {{ no_geometric = true }}\n\n[evaluation]\nmax_samples = 20000\nthreshold = 0.01\n",
        spot.display().to_string()
    )
    .into_bytes()
}

/// A small model's run on the spot's training views: its set and configuration.
fn small_run() -> &'static (TrainingSet, TrainConfig) {
    static RUN: OnceLock<(TrainingSet, TrainConfig)> = OnceLock::new();
    RUN.get_or_init(|| {
        let mut scene = read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
        scene.views.retain(|v| v.split == rmvp_dataset::Split::Train);
        let mut config = presets::training(Preset::Fast, 10);
        config.model.grid = Some((4, 10, 4, 32));
        config.model.sdf_hidden = 16;
        config.model.color_hidden = 16;
        config.batch_rays = 64;
        (TrainingSet::from_scene(&scene, config.margin).unwrap(), config)
    })
}

fn checkpoint_seed(dir: &Path) -> Vec<u8> {
    let (set, config) = small_run();
    let mut trainer = Trainer::new(config.clone(), set.clone());
    trainer.step();
    let path = dir.join("seed.bin");
    rmvp_recon::checkpoint::save(&trainer, None, &path).unwrap();
    std::fs::read(path).unwrap()
}

fn families() -> Vec<Family> {
    vec![
        Family {
            name: "plan",
            file_name: "batch.toml",
            seed: plan_seed,
            read: |p| outcome(BatchPlan::read(p)),
            fixup: no_fixup,
        },
        Family {
            name: "checkpoint",
            file_name: "checkpoint.bin",
            seed: checkpoint_seed,
            read: |p| {
                let (set, config) = small_run();
                outcome(rmvp_recon::checkpoint::load(p, set.clone(), config, None))
            },
            fixup: no_fixup,
        },
    ]
}

#[test]
fn plan_family() {
    run_family(&families(), "plan");
}

#[test]
fn checkpoint_family() {
    run_family(&families(), "checkpoint");
}

#[test]
fn a_sparse_checkpoint_of_gigabytes_is_refused_from_its_header() {
    let peak = rmvp_testkit::limited_case("a_sparse_checkpoint_of_gigabytes_is_refused_from_its_header", || {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("checkpoint.bin");
        std::fs::write(&path, checkpoint_seed(dir.path())).unwrap();
        // A hole after the parameters: 1.5 GiB on disk, none of it stored.
        std::fs::OpenOptions::new().write(true).open(&path).unwrap().set_len(3 << 29).unwrap();
        let (set, config) = small_run();
        let err = rmvp_recon::checkpoint::load(&path, set.clone(), config, None).err().expect("refused").to_string();
        assert!(err.contains("checkpoint.bin") && err.contains("too long:"), "{err}");
    });
    assert!(peak < 256 << 20, "peak {} MiB", peak >> 20);
}
