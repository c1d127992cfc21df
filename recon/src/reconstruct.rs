//! A whole reconstruction run in an output folder: training with checkpoints and a loss log
//! (resumable; with the normal error against the scene's ground truth where it has one), then the mesh, normal maps, re-rendered Stokes, a comparison picture and the
//! residuals of the model against its input.

use crate::checkpoint;
use crate::data::TrainingSet;
use crate::extract::{extract_mesh, CpuSdf, Device};
use crate::options::{ReconOptions, RunControl};
use crate::output::{render_view, SurfaceGuide};
use crate::residuals::view_residuals;
use crate::tracking::{tracked_at, NormalTrack};
use crate::train::{StepReport, Trainer};
use crate::unseen::unseen_parts;
use crate::{Error, Result};
use rmvp_dataset::io::atomic::write_bytes_atomically;
use rmvp_dataset::io::json::{read_json, write_json};
use rmvp_dataset::io::{exr, png};
use rmvp_dataset::visualize::{aop_picture, contact_sheet, normal_picture, preview};
use rmvp_dataset::{Image, Mesh, Scene, Split};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::ops::ControlFlow;
use std::path::Path;
use std::time::Instant;

/// Files of an output folder.
pub const CHECKPOINT: &str = "checkpoint.bin";
/// The loss log, one JSON object per iteration.
pub const LOG: &str = "log.jsonl";
/// The extracted surface, world frame.
pub const MESH: &str = "mesh.ply";
/// Per training view: input and rendered S0 and AoP, and the normals.
pub const COMPARISON: &str = "comparison.png";
/// Per training view: the residuals of S0, S1, S2 and the AoP ([`crate::residuals`]).
pub const RESIDUALS_PICTURE: &str = "residuals.png";
/// Per training view: the residuals' figures ([`crate::residuals::ViewResiduals`]).
pub const RESIDUALS: &str = "residuals.json";
/// The run's wall times ([`RunTimes`]).
pub const TIMES: &str = "times.json";
/// The mesh's connected parts and those that no training view sees
/// ([`crate::unseen::UnseenParts`]).
pub const MESH_PARTS: &str = "mesh_parts.json";

/// A run's wall times (its folder's [`TIMES`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RunTimes {
    /// Training, seconds, summed over the calls that trained the run (a stopped run continued).
    pub training_seconds: f64,
    /// The mesh and the view outputs, seconds (0 until the run finished).
    pub results_seconds: f64,
    /// Worker threads of the last call.
    pub threads: usize,
}

/// Train on `scene` into `out`, calling `on_step` after every iteration, then write the results.
/// The call ends early, checkpointed and without results (the returned trainer has not
/// finished; continue with `resume`), after `control.stop_after` iterations or when `on_step`
/// returns [`ControlFlow::Break`] (a signal, a time limit). The checkpoint records `options`;
/// resuming with options that train differently is refused, naming them.
pub fn reconstruct(
    scene: &Scene,
    out: &Path,
    options: &ReconOptions,
    control: RunControl,
    mut on_step: impl FnMut(&StepReport, &Trainer) -> ControlFlow<()>,
) -> Result<Trainer> {
    options.validate()?;
    // A mesh device that cannot run is said before training, not after it.
    check_device(options.mesh_device)?;
    let config = options.config();
    let set = if config.downscale > 1 {
        TrainingSet::from_scene(&scene.downscaled(config.downscale), config.margin)?
    } else {
        TrainingSet::from_scene(scene, config.margin)?
    };
    let checkpoint = out.join(CHECKPOINT);
    let log_path = out.join(LOG);
    let mut trainer = if control.resume && checkpoint.exists() {
        checkpoint::load(&checkpoint, set, &config, Some(options))?
    } else {
        let trainer = Trainer::new(config, set);
        if let Some(least) = trainer.model.start_without_surface(&trainer.params) {
            return Err(Error::InvalidOption(format!(
                "an initial sphere of radius {} leaves this network's start without a surface \
                 (its SDF is positive at the centre): a radius of at least {:.2} starts with one",
                trainer.config.model.initial_radius,
                (least * 100.0).floor() / 100.0 + 0.01
            )));
        }
        trainer
    };
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    // The log keeps exactly the iterations the checkpoint has seen.
    let kept: String = match rmvp_dataset::io::input::read_text(&log_path) {
        Ok(text) if trainer.iteration > 0 => {
            text.lines().take(trainer.iteration as usize).map(|l| format!("{l}\n")).collect()
        }
        _ => String::new(),
    };
    write_bytes_atomically(&log_path, kept.as_bytes())?;
    let mut log = std::fs::OpenOptions::new().append(true).open(&log_path).map_err(|e| Error::io(&log_path, e))?;
    let track = NormalTrack::new(scene, &trainer.set.frame);
    // Times of earlier calls count where this one continues them.
    let earlier = match trainer.iteration {
        0 => RunTimes::default(),
        _ => read_json::<RunTimes>(&out.join(TIMES), "a run's times").unwrap_or_default(),
    };
    let started = Instant::now();
    let times = |results_seconds: f64| RunTimes {
        training_seconds: earlier.training_seconds + started.elapsed().as_secs_f64() - results_seconds,
        results_seconds,
        threads: rayon::current_num_threads(),
    };
    let mut budget = control.stop_after.unwrap_or(u32::MAX);
    while trainer.iteration < trainer.config.iterations {
        if budget == 0 {
            log.sync_data().map_err(|e| Error::io(&log_path, e))?;
            checkpoint::save(&trainer, Some(options), &checkpoint)?;
            write_json(&out.join(TIMES), &times(0.0))?;
            return Ok(trainer);
        }
        budget -= 1;
        let mut report = trainer.step();
        if let Some(track) = track.as_ref().filter(|_| tracked_at(trainer.iteration, trainer.config.iterations)) {
            report.normal_error_deg = track.normal_error_deg(&trainer);
        }
        let line = serde_json::to_string(&report).expect("plain data");
        writeln!(log, "{line}").map_err(|e| Error::io(&log_path, e))?;
        if trainer.iteration.is_multiple_of(options.checkpoint_every) || trainer.iteration == trainer.config.iterations
        {
            log.sync_data().map_err(|e| Error::io(&log_path, e))?;
            checkpoint::save(&trainer, Some(options), &checkpoint)?;
        }
        if on_step(&report, &trainer).is_break() && trainer.iteration < trainer.config.iterations {
            log.sync_data().map_err(|e| Error::io(&log_path, e))?;
            checkpoint::save(&trainer, Some(options), &checkpoint)?;
            write_json(&out.join(TIMES), &times(0.0))?;
            return Ok(trainer);
        }
    }
    let trained = started.elapsed().as_secs_f64();
    if options.mesh_only {
        write_mesh(&trainer, out, options)?;
    } else {
        write_results(&trainer, scene, out, options)?;
    }
    write_json(&out.join(TIMES), &times(started.elapsed().as_secs_f64() - trained))?;
    Ok(trainer)
}

/// Whether `device` can evaluate the mesh's SDF here.
pub fn check_device(device: Device) -> Result<()> {
    match device {
        Device::Cpu => Ok(()),
        #[cfg(feature = "cuda")]
        Device::Cuda => crate::cuda::probe().map(drop),
        #[cfg(not(feature = "cuda"))]
        Device::Cuda => Err(no_cuda_support()),
    }
}

#[cfg(not(feature = "cuda"))]
fn no_cuda_support() -> Error {
    Error::Cuda("this build has no CUDA support (rmvp-recon's `cuda` feature)".into())
}

/// The extracted surface alone, `out/mesh.ply` (world frame), at `options.mesh_res` with its
/// SDF evaluated on `options.mesh_device`, without the parts no training view sees unless
/// `options.keep_unseen_parts` ([`crate::unseen`]; which they were is `out/`[`MESH_PARTS`]);
/// returns the mesh.
pub fn write_mesh(trainer: &Trainer, out: &Path, options: &ReconOptions) -> Result<Mesh> {
    let lw = trainer.level_weight();
    let (model, params, frame, fd_step) =
        (&trainer.model, &trainer.params, &trainer.set.frame, trainer.output_fd_step(&lw));
    let n = options.mesh_res;
    let mesh = match options.mesh_device {
        Device::Cpu => extract_mesh(&CpuSdf::new(model, params, &lw), n, frame, fd_step)?,
        #[cfg(feature = "cuda")]
        Device::Cuda => {
            let gpu = crate::cuda::CudaSdf::new(&model.field, params, &lw)?;
            extract_mesh(&gpu, n, frame, fd_step)?
        }
        #[cfg(not(feature = "cuda"))]
        Device::Cuda => return Err(no_cuda_support()),
    };
    if mesh.faces.is_empty() {
        return Err(Error::NoSurface);
    }
    let (mesh, parts) = unseen_parts(mesh, &trainer.set, options.keep_unseen_parts);
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    write_json(&out.join(MESH_PARTS), &parts)?;
    mesh.write(&out.join(MESH))?;
    Ok(mesh)
}

/// 255 where both masks are set (one channel; the first channel of each is read).
fn both_set(a: &Image<u8>, b: &Image<u8>) -> Image<u8> {
    let data = a
        .data()
        .chunks_exact(a.channels())
        .zip(b.data().chunks_exact(b.channels()))
        .map(|(x, y)| if x[0] != 0 && y[0] != 0 { 255 } else { 0 })
        .collect();
    Image::from_vec(a.width(), a.height(), 1, data).expect("equal sizes")
}

/// Mesh, normal maps (every view), re-rendered Stokes (training views), [`COMPARISON`] and the
/// residuals ([`RESIDUALS_PICTURE`], [`RESIDUALS`]).
pub fn write_results(trainer: &Trainer, scene: &Scene, out: &Path, options: &ReconOptions) -> Result<()> {
    let mesh = write_mesh(trainer, out, options)?;
    let guide = SurfaceGuide::new(&mesh, &trainer.set.frame, options.mesh_res);
    let (normals_dir, stokes_dir) = (out.join("normals"), out.join("stokes"));
    for d in [&normals_dir, &stokes_dir] {
        std::fs::create_dir_all(d).map_err(|e| Error::io(d, e))?;
    }
    let (mut tiles, mut residual_tiles, mut residuals) = (Vec::new(), Vec::new(), Vec::new());
    for view in &scene.views {
        let train = view.split == Split::Train;
        let r = render_view(trainer, &view.camera, &guide, train);
        exr::write_exr(&normals_dir.join(format!("{}.exr", view.name)), &r.normals, &["N.X", "N.Y", "N.Z"])?;
        png::write_png_u8(&normals_dir.join(format!("{}.png", view.name)), &normal_picture(&r.normals))?;
        let Some(stokes) = &r.stokes else { continue };
        for (name, img) in [("s0", &stokes.s0), ("s1", &stokes.s1), ("s2", &stokes.s2)] {
            exr::write_exr(&stokes_dir.join(format!("{}_{name}.exr", view.name)), img, &["R", "G", "B"])?;
        }
        if let Some(input) = &view.stokes {
            let mask = view.mask.as_ref();
            let (aop_in, dop_in) = input.aop_dop();
            let (aop_out, dop_out) = stokes.aop_dop();
            tiles.extend([
                preview(&input.s0),
                preview(&stokes.s0),
                aop_picture(&aop_in, &dop_in, mask),
                aop_picture(&aop_out, &dop_out, Some(&r.mask)),
                normal_picture(&r.normals),
            ]);
            let compared = match mask {
                Some(m) => both_set(m, &r.mask),
                None => r.mask.clone(),
            };
            let (figures, pictures) = view_residuals(&view.name, input, stokes, &compared);
            residuals.push(figures);
            residual_tiles.extend(pictures);
        }
    }
    if !tiles.is_empty() {
        png::write_png_u8(&out.join(COMPARISON), &contact_sheet(&tiles, 5))?;
        png::write_png_u8(&out.join(RESIDUALS_PICTURE), &contact_sheet(&residual_tiles, 4))?;
        write_json(&out.join(RESIDUALS), &residuals)?;
    }
    Ok(())
}
