//! A whole reconstruction run in an output folder: training with checkpoints and a loss log
//! (resumable), then the mesh, normal maps, re-rendered Stokes and a comparison picture.

use crate::data::TrainingSet;
use crate::extract::{extract_mesh, CpuSdf, Device};
use crate::model::Preset;
use crate::output::{render_view, SurfaceGuide};
use crate::train::{StepReport, TrainConfig, Trainer};
use crate::volume::Sampling;
use crate::{Error, Result};
use rmvp_dataset::io::atomic::write_bytes_atomically;
use rmvp_dataset::io::{exr, png};
use rmvp_dataset::visualize::{aop_picture, contact_sheet, normal_picture, preview};
use rmvp_dataset::{Mesh, Scene, Split};
use std::io::Write;
use std::ops::ControlFlow;
use std::path::Path;

/// What the user chose; [`Options::default`] holds every default of `rmvp recon`.
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    /// Model preset.
    pub preset: Preset,
    /// Iterations (default: the preset's).
    pub iterations: Option<u32>,
    /// Use the photometric cue.
    pub photometric: bool,
    /// Use the geometric cue.
    pub geometric: bool,
    /// Continue from `checkpoint.bin` in the output folder.
    pub resume: bool,
    /// Marching grid cells per axis.
    pub mesh_resolution: usize,
    /// Where the mesh's SDF is evaluated (CPU engine or CUDA kernels).
    pub mesh_device: Device,
    /// Iterations between checkpoints.
    pub checkpoint_every: u32,
    /// Rays per batch (default: the preset's).
    pub batch_rays: Option<usize>,
    /// Samples per ray (default: the preset's).
    pub sampling: Option<Sampling>,
    /// Dilation of the masks that object rays are drawn from, pixels (default: the preset's).
    pub margin: Option<usize>,
    /// Learning rate of hash-grid level `l` relative to level 0, `decay^l` (default: the preset's).
    pub grid_level_decay: Option<f32>,
    /// Learn the specular lobe's polarization scale (default: the preset's;
    /// [`crate::model::Radiance::specular_polarization`]).
    pub learned_polarization: Option<bool>,
    /// Train on the views at 1/`downscale` of their size (the official code trains RMVP3D at 2,
    /// PANDORA at 4); outputs are written at the scene's size.
    pub downscale: u32,
    /// Random seed.
    pub seed: u64,
    /// Train at most this many iterations in this call, then checkpoint and return without
    /// results (time-boxed sessions; continue with `resume`).
    pub stop_after: Option<u32>,
    /// Write the per-view outputs (normal maps, Stokes, comparison) beside the mesh; off: the
    /// mesh alone (a dataset's reference shape).
    pub view_outputs: bool,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            preset: Preset::Fast,
            iterations: None,
            photometric: true,
            geometric: true,
            resume: false,
            mesh_resolution: 256,
            mesh_device: Device::Cpu,
            checkpoint_every: 500,
            batch_rays: None,
            sampling: None,
            margin: None,
            grid_level_decay: None,
            learned_polarization: None,
            downscale: 1,
            seed: 0,
            stop_after: None,
            view_outputs: true,
        }
    }
}

impl Options {
    /// Refuse options no training can run with, in words about their values: both cues off,
    /// zero iterations, an empty marching grid, zero rays per step.
    pub fn validate(&self) -> Result<()> {
        if !self.photometric && !self.geometric {
            return Err(Error::BothCuesOff);
        }
        let fault = if self.iterations == Some(0) {
            "the number of iterations must be at least 1"
        } else if self.mesh_resolution == 0 {
            "the mesh resolution (marching grid cells per axis) must be at least 1"
        } else if self.batch_rays == Some(0) {
            "the rays per iteration (batch) must be at least 1"
        } else if self.checkpoint_every == 0 {
            "the iterations between checkpoints must be at least 1"
        } else if self.downscale == 0 {
            "the training downscale factor must be at least 1"
        } else {
            return Ok(());
        };
        Err(Error::InvalidOption(fault.into()))
    }

    /// The training configuration these options give.
    pub fn config(&self) -> TrainConfig {
        let iterations = self.iterations.unwrap_or(self.preset.default_iterations());
        let mut config = TrainConfig::preset(self.preset, iterations);
        config.photometric = self.photometric;
        config.geometric = self.geometric;
        config.seed = self.seed;
        config.downscale = self.downscale;
        if let Some(b) = self.batch_rays {
            config.batch_rays = b;
        }
        if let Some(s) = self.sampling {
            config.sampling = s;
        }
        if let Some(m) = self.margin {
            config.margin = m;
        }
        if let Some(d) = self.grid_level_decay {
            config.adam.grid_level_decay = d;
        }
        if let Some(learned) = self.learned_polarization {
            config.model.learned_polarization = learned;
        }
        config
    }
}

/// Files of an output folder.
pub const CHECKPOINT: &str = "checkpoint.bin";
/// The loss log, one JSON object per iteration.
pub const LOG: &str = "log.jsonl";
/// The extracted surface, world frame.
pub const MESH: &str = "mesh.ply";

/// Train on `scene` into `out`, calling `on_step` after every iteration, then write the results.
/// The session ends early, checkpointed and without results (the returned trainer has not
/// finished; continue with `resume`), after `stop_after` iterations or when `on_step` returns
/// [`ControlFlow::Break`] (a signal, a time limit).
pub fn reconstruct(
    scene: &Scene,
    out: &Path,
    options: &Options,
    mut on_step: impl FnMut(&StepReport, &Trainer) -> ControlFlow<()>,
) -> Result<Trainer> {
    options.validate()?;
    // A mesh device that cannot run is said before training, not after it.
    check_device(options.mesh_device)?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let config = options.config();
    let set = if config.downscale > 1 {
        TrainingSet::from_scene(&scene.downscaled(config.downscale), config.margin)?
    } else {
        TrainingSet::from_scene(scene, config.margin)?
    };
    let checkpoint = out.join(CHECKPOINT);
    let log_path = out.join(LOG);
    let mut trainer = if options.resume && checkpoint.exists() {
        let t = Trainer::load_checkpoint(&checkpoint, set)?;
        if t.config != config {
            return Err(Error::CheckpointSettings { path: checkpoint });
        }
        t
    } else {
        Trainer::new(config, set)
    };
    // The log keeps exactly the iterations the checkpoint has seen.
    let kept: String = match rmvp_dataset::io::input::read_text(&log_path) {
        Ok(text) if trainer.iteration > 0 => {
            text.lines().take(trainer.iteration as usize).map(|l| format!("{l}\n")).collect()
        }
        _ => String::new(),
    };
    write_bytes_atomically(&log_path, kept.as_bytes())?;
    let mut log = std::fs::OpenOptions::new().append(true).open(&log_path).map_err(|e| Error::io(&log_path, e))?;
    let mut budget = options.stop_after.unwrap_or(u32::MAX);
    while trainer.iteration < trainer.config.iterations {
        if budget == 0 {
            log.sync_data().map_err(|e| Error::io(&log_path, e))?;
            trainer.save_checkpoint(&checkpoint)?;
            return Ok(trainer);
        }
        budget -= 1;
        let report = trainer.step();
        let line = serde_json::to_string(&report).expect("plain data");
        writeln!(log, "{line}").map_err(|e| Error::io(&log_path, e))?;
        if trainer.iteration.is_multiple_of(options.checkpoint_every) || trainer.iteration == trainer.config.iterations
        {
            log.sync_data().map_err(|e| Error::io(&log_path, e))?;
            trainer.save_checkpoint(&checkpoint)?;
        }
        if on_step(&report, &trainer).is_break() && trainer.iteration < trainer.config.iterations {
            log.sync_data().map_err(|e| Error::io(&log_path, e))?;
            trainer.save_checkpoint(&checkpoint)?;
            return Ok(trainer);
        }
    }
    if options.view_outputs {
        write_results(&trainer, scene, out, options.mesh_resolution, options.mesh_device)?;
    } else {
        write_mesh(&trainer, out, options.mesh_resolution, options.mesh_device)?;
    }
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

/// The extracted surface alone, `out/mesh.ply` (world frame), its SDF evaluated on `device`;
/// returns the mesh.
pub fn write_mesh(trainer: &Trainer, out: &Path, mesh_resolution: usize, device: Device) -> Result<Mesh> {
    let lw = trainer.level_weight();
    let (model, params, frame, fd_step) = (&trainer.model, &trainer.params, &trainer.set.frame, trainer.fd_step(&lw));
    let mesh = match device {
        Device::Cpu => extract_mesh(&CpuSdf::new(model, params, &lw), mesh_resolution, frame, fd_step)?,
        #[cfg(feature = "cuda")]
        Device::Cuda => {
            let gpu = crate::cuda::CudaSdf::new(&model.field, params, &lw)?;
            extract_mesh(&gpu, mesh_resolution, frame, fd_step)?
        }
        #[cfg(not(feature = "cuda"))]
        Device::Cuda => return Err(no_cuda_support()),
    };
    if mesh.faces.is_empty() {
        return Err(Error::NoSurface);
    }
    mesh.write(&out.join(MESH))?;
    Ok(mesh)
}

/// Mesh, normal maps (every view), re-rendered Stokes (training views) and `comparison.png`.
pub fn write_results(
    trainer: &Trainer,
    scene: &Scene,
    out: &Path,
    mesh_resolution: usize,
    mesh_device: Device,
) -> Result<()> {
    let mesh = write_mesh(trainer, out, mesh_resolution, mesh_device)?;
    let guide = SurfaceGuide::new(&mesh, &trainer.set.frame, mesh_resolution);
    let (normals_dir, stokes_dir) = (out.join("normals"), out.join("stokes"));
    for d in [&normals_dir, &stokes_dir] {
        std::fs::create_dir_all(d).map_err(|e| Error::io(d, e))?;
    }
    let mut tiles = Vec::new();
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
        }
    }
    if !tiles.is_empty() {
        png::write_png_u8(&out.join("comparison.png"), &contact_sheet(&tiles, 5))?;
    }
    Ok(())
}
