//! The CUDA kernels against the CPU engine: the same SDF (grid and points) for a bumpy field
//! of the fast preset, and `rmvp recon`'s mesh through them, where a GPU is present; a clear
//! refusal before any training where none is; a refusal of fields the kernels do not cover on
//! any machine.
#![cfg(feature = "cuda")]

use rmvp_dataset::layout::read_scene;
use rmvp_dataset::rng::Rng;
use rmvp_dataset::Mesh;
use rmvp_recon::cuda::CudaSdf;
use rmvp_recon::extract::{CpuSdf, Device, SdfEvaluator};
use rmvp_recon::model::Model;
use rmvp_recon::options::{ReconOptions, RunControl};
use rmvp_recon::presets::{self, Preset};
use rmvp_recon::reconstruct::{reconstruct, CHECKPOINT, MESH};
use rmvp_recon::Error;
use std::ops::ControlFlow;

/// What a machine without a usable GPU is told.
fn no_gpu_here(why: &str) -> bool {
    why.contains("no CUDA driver") || why.contains("NVRTC") || why.contains("no usable GPU")
}

/// The preset's initial sphere made bumpy: every parameter moved, the grid's far from zero.
fn bumpy(preset: Preset) -> (Model, Vec<f32>) {
    let model = Model::new(presets::model(preset));
    let mut params = model.init(3);
    let mut rng = Rng::for_pixel(5, 0, 0);
    for (i, p) in params.iter_mut().enumerate() {
        let amplitude = if i < model.network_params() { 0.02 } else { 0.2 };
        *p += (rng.next_f32() * 2.0 - 1.0) * amplitude;
    }
    (model, params)
}

#[test]
fn cuda_sdf_matches_the_cpu_engine_or_says_why_not() {
    let (model, params) = bumpy(Preset::Fast);
    // The finest level still fading in, the one below half on: as during training.
    let mut level_weight = vec![1.0f32; model.field.levels()];
    let last = level_weight.len() - 1;
    (level_weight[last], level_weight[last - 1]) = (0.0, 0.5);
    let cpu = CpuSdf::new(&model, &params, &level_weight);
    let gpu = match CudaSdf::new(&model.field, &params, &level_weight) {
        Ok(gpu) => gpu,
        Err(Error::Cuda(why)) => {
            // A machine without the driver, NVRTC or a GPU: said so, nothing else went wrong.
            assert!(no_gpu_here(&why), "{why}");
            return;
        }
        Err(e) => panic!("{e}"),
    };
    let n = 64;
    let (want, got) = (cpu.sdf_grid(n).unwrap(), gpu.sdf_grid(n).unwrap());
    assert_eq!(got.len(), (n + 1).pow(3));
    let worst = want.iter().zip(&got).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
    assert!(worst < 1e-5, "grid: largest difference {worst}");
    let crossings = want.iter().filter(|v| **v < 0.0).count();
    assert!(crossings > 1000 && crossings < want.len() / 2, "a surface inside: {crossings} negative of {}", want.len());
    let mut rng = Rng::for_pixel(9, 0, 0);
    let points: Vec<f32> = (0..3 * 10_000).map(|_| rng.next_f32() * 2.2 - 1.1).collect();
    let (want, got) = (cpu.sdf(&points).unwrap(), gpu.sdf(&points).unwrap());
    let worst = want.iter().zip(&got).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
    assert!(worst < 1e-5, "points: largest difference {worst} ({})", gpu.device());
}

#[test]
fn the_paper_preset_is_refused_by_name() {
    let model = Model::new(presets::model(Preset::Paper));
    let params = model.init(0);
    match CudaSdf::new(&model.field, &params, &[]) {
        Err(Error::Cuda(why)) => assert!(why.contains("paper preset"), "{why}"),
        Err(e) => panic!("{e}"),
        Ok(_) => panic!("the paper preset's MLP field was accepted"),
    }
}

#[test]
fn a_cuda_mesh_is_written_or_refused_before_training() {
    let scene = read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
    let out = tempfile::tempdir().unwrap();
    let options = ReconOptions {
        iters: Some(2),
        mesh_res: 48,
        mesh_device: Device::Cuda,
        mesh_only: true,
        ..ReconOptions::default()
    };
    match reconstruct(&scene, out.path(), &options, RunControl::default(), |_, _| ControlFlow::Continue(())) {
        Ok(_) => {
            let mesh = Mesh::read(&out.path().join(MESH)).unwrap();
            assert!(mesh.faces.len() > 1000, "{} faces", mesh.faces.len());
        }
        Err(Error::Cuda(why)) => {
            assert!(no_gpu_here(&why), "{why}");
            assert!(!out.path().join(CHECKPOINT).exists(), "trained before saying that the mesh cannot be made");
        }
        Err(e) => panic!("{e}"),
    }
}
