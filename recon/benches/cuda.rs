//! Surface extraction on the GPU against the CPU engine: the SDF grid and the whole mesh (grid,
//! marching tetrahedra, vertex normals) timed on both, with the largest difference of the SDF
//! and the grid points whose sign differs. Fields: the fast and dense presets' initial spheres
//! made bumpy (every level on), and with `RMVP_BENCH_SCENE=DIR` the fast preset trained on that
//! scene for `RMVP_BENCH_ITERS` iterations (default 500). Run with
//! `cargo bench -p rmvp-recon --features cuda --bench cuda` on a machine with an NVIDIA GPU
//! (`RMVP_BENCH_RES=fast:256,dense:384,trained:512` grid cells per axis); writes
//! `bench/results/cuda.json`.

use rmvp_dataset::layout::read_scene;
use rmvp_dataset::rng::Rng;
use rmvp_recon::cuda::CudaSdf;
use rmvp_recon::data::{Frame, TrainingSet};
use rmvp_recon::extract::{extract_mesh, CpuSdf, SdfEvaluator};
use rmvp_recon::model::Model;
use rmvp_recon::presets::{self, Preset};
use rmvp_recon::train::Trainer;
use rmvp_testkit::results::{BenchResult, Table};
use std::time::Instant;

fn seconds(start: Instant) -> f64 {
    start.elapsed().as_secs_f64()
}

/// A field to extract: its model, parameters, level weights, frame and normals' step.
struct Subject {
    model: Model,
    params: Vec<f32>,
    level_weight: Vec<f32>,
    frame: Frame,
    fd_step: f32,
}

fn bumpy(preset: Preset) -> Subject {
    let model = Model::new(presets::model(preset));
    let mut params = model.init(1);
    let mut rng = Rng::for_pixel(2, 0, 0);
    for (i, p) in params.iter_mut().enumerate() {
        *p += (rng.next_f32() * 2.0 - 1.0) * if i < model.network_params() { 0.01 } else { 0.1 };
    }
    let level_weight = vec![1.0f32; model.field.levels()];
    let frame = Frame::new(nalgebra::Matrix4::identity()).expect("frame");
    Subject { model, params, level_weight, frame, fd_step: 1e-3 }
}

fn trained(scene: &str, iterations: u32) -> Subject {
    let scene = read_scene(std::path::Path::new(scene)).expect("scene");
    let config = presets::training(Preset::Fast, iterations);
    let set = TrainingSet::from_scene(&scene, config.margin).expect("training set");
    let mut trainer = Trainer::new(config, set);
    let start = Instant::now();
    while trainer.iteration < iterations {
        trainer.step();
    }
    println!("trained {iterations} iterations in {:.1} s", seconds(start));
    let level_weight = trainer.level_weight();
    let fd_step = trainer.output_fd_step(&level_weight);
    Subject { model: trainer.model, params: trainer.params, level_weight, frame: trainer.set.frame, fd_step }
}

fn main() {
    if !std::env::args().any(|a| a == "--bench") {
        return; // run by `cargo test --all-targets` (no `--bench`): measure only under `cargo bench`
    }
    let sizes = std::env::var("RMVP_BENCH_RES").unwrap_or_else(|_| "fast:256,dense:384,trained:512".into());
    let scene = std::env::var("RMVP_BENCH_SCENE").ok();
    let iterations = std::env::var("RMVP_BENCH_ITERS").ok().and_then(|s| s.parse().ok()).unwrap_or(500);
    let mut rows = Vec::new();
    let mut device = String::new();
    for entry in sizes.split(',') {
        let (name, n) = entry.split_once(':').expect("field:cells");
        let n: usize = n.parse().expect("cells per axis");
        let s = match (name, &scene) {
            ("dense", _) => bumpy(Preset::Dense),
            ("trained", Some(scene)) => trained(scene, iterations),
            ("trained", None) => continue,
            _ => bumpy(Preset::Fast),
        };
        let cpu = CpuSdf::new(&s.model, &s.params, &s.level_weight);
        let start = Instant::now();
        let gpu = CudaSdf::new(&s.model.field, &s.params, &s.level_weight).expect("a GPU");
        let setup = seconds(start);
        device = gpu.device().to_string();
        let start = Instant::now();
        let want = cpu.sdf_grid(n).expect("cpu");
        let cpu_grid = seconds(start);
        gpu.sdf_grid(n).expect("warm-up");
        let start = Instant::now();
        let got = gpu.sdf_grid(n).expect("gpu");
        let gpu_grid = seconds(start);
        let worst = want.iter().zip(&got).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
        let flipped = want.iter().zip(&got).filter(|(a, b)| (**a < 0.0) != (**b < 0.0)).count();
        let start = Instant::now();
        let cpu_mesh = extract_mesh(&cpu, n, &s.frame, s.fd_step).expect("cpu mesh");
        let cpu_mesh_s = seconds(start);
        let start = Instant::now();
        let gpu_mesh = extract_mesh(&gpu, n, &s.frame, s.fd_step).expect("gpu mesh");
        let gpu_mesh_s = seconds(start);
        rows.push(vec![
            name.to_string(),
            format!("{n}^3"),
            format!("{cpu_grid:.2}"),
            format!("{setup:.2}"),
            format!("{gpu_grid:.3}"),
            format!("{worst:.1e}"),
            flipped.to_string(),
            format!("{cpu_mesh_s:.2}"),
            format!("{gpu_mesh_s:.2}"),
            format!("{} / {}", cpu_mesh.positions.len(), gpu_mesh.positions.len()),
        ]);
    }
    let threads = rayon::current_num_threads();
    println!("cuda benchmark: {threads} CPU threads, GPU {device}");
    let mut table = Table::new(&[
        "field",
        "grid",
        "CPU grid s",
        "GPU set-up s",
        "GPU grid s",
        "largest difference",
        "signs differing",
        "CPU mesh s",
        "GPU mesh s",
        "vertices CPU / GPU",
    ]);
    for row in rows {
        println!("| {} |", row.join(" | "));
        table.row(row);
    }
    let mut result =
        BenchResult::now("Mesh extraction on a GPU", "cargo bench -p rmvp-recon --features cuda --bench cuda");
    result.machine.gpu = device.clone();
    if let Some(first) = table.rows.first() {
        let seconds = result.figure("gpu_grid_seconds", &first[4]);
        result.headline = format!("{} SDF grid in {seconds} s on the GPU", first[1]);
    }
    result.about = format!(
        "The SDF on the `(n + 1)^3` grid a mesh needs, on the CPU ({threads} threads) and on {device} (the kernel and \
         the download; the set-up is NVRTC's compile and the upload, once a process), and the whole mesh (the grid, \
         marching tetrahedra on the CPU, the vertex normals); the fields are the fast and dense presets' starts made \
         bumpy (every level on) and, with `RMVP_BENCH_SCENE`, the fast preset trained on a scene."
    );
    result.tables = vec![table];
    result.write("cuda");
}
