//! `rmvp recon SCENE -o DIR`: NeRSP reconstruction ([`rmvp_recon::reconstruct`]).

use super::progress;
use anyhow::{Context, Result};
use rmvp_dataset::layout::read_scene;
use rmvp_recon::extract::Device;
use rmvp_recon::model::Preset;
use rmvp_recon::reconstruct::{reconstruct, Options};
use std::ops::ControlFlow;
use std::path::PathBuf;

/// Arguments of `rmvp recon`.
#[derive(clap::Args)]
pub struct Args {
    /// Scene folder (any layout) with Stokes images and masks.
    scene: PathBuf,
    /// Output folder: mesh.ply, normals/, stokes/, comparison.png, log.jsonl, checkpoint.bin.
    #[arg(short, long)]
    output: PathBuf,
    /// Model preset: `fast` (hash grid, minutes on a CPU), `dense` (a finer grid, twice the
    /// rays, 4000 iterations: a dataset's reference shape) or `paper` (NeRSP's 8x256 MLP).
    #[arg(long, value_enum, default_value_t = Options::default().preset)]
    preset: Preset,
    /// Training iterations (default: the preset's; fast 3000, about 6 minutes on 2 cores).
    #[arg(long)]
    iters: Option<u32>,
    /// Photometric cue only (PANDORA-like ablation).
    #[arg(long)]
    no_geometric: bool,
    /// Geometric cue only (MVAS-like ablation).
    #[arg(long)]
    no_photometric: bool,
    /// Continue from the output folder's checkpoint.
    #[arg(long)]
    resume: bool,
    /// Marching grid cells per axis for the mesh.
    #[arg(long, default_value_t = Options::default().mesh_resolution)]
    mesh_res: usize,
    /// Where the mesh's SDF is evaluated: `cuda` runs it on the first NVIDIA GPU (needs its
    /// driver and NVRTC; training stays on the CPU).
    #[arg(long, value_enum, default_value_t = Options::default().mesh_device)]
    mesh_device: Device,
    /// Learn one scale of the specular lobe's degree of polarization for the object (a
    /// conductor's reflection is nearly unpolarized; NeRSP's fixed dielectric Fresnel is the
    /// default); the value learned is in log.jsonl (`polarization`) and printed at the end.
    #[arg(long)]
    learned_polarization: bool,
    /// Rays per iteration (default: the preset's; fast 256, paper 512).
    #[arg(long)]
    batch: Option<usize>,
    /// Write the mesh alone (no normal maps, Stokes or comparison).
    #[arg(long)]
    mesh_only: bool,
    /// Iterations between checkpoints.
    #[arg(long, default_value_t = Options::default().checkpoint_every)]
    checkpoint_every: u32,
    /// Train at 1/N of the views' size (Stokes and masks averaged over N x N blocks, the
    /// intrinsics scaled); the outputs are written at the scene's size. The official code trains
    /// RMVP3D at 2 (612x512), PANDORA at 4.
    #[arg(long, default_value_t = Options::default().downscale)]
    downscale: u32,
    /// Random seed.
    #[arg(long, default_value_t = Options::default().seed)]
    seed: u64,
    /// Stop after this many iterations in this session (checkpointed; continue with --resume).
    #[arg(long)]
    stop_after: Option<u32>,
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let scene = read_scene(&args.scene)?;
    let options = Options {
        preset: args.preset,
        iterations: args.iters,
        photometric: !args.no_photometric,
        geometric: !args.no_geometric,
        resume: args.resume,
        mesh_resolution: args.mesh_res,
        mesh_device: args.mesh_device,
        checkpoint_every: args.checkpoint_every.max(1),
        batch_rays: args.batch,
        learned_polarization: args.learned_polarization.then_some(true),
        downscale: args.downscale,
        seed: args.seed,
        stop_after: args.stop_after,
        view_outputs: !args.mesh_only,
        ..Options::default()
    };
    let total = options.config().iterations;
    let bar = progress(total as u64, "recon");
    let trainer = reconstruct(&scene, &args.output, &options, |report, trainer| {
        bar.set_position(trainer.iteration as u64);
        match &report.event {
            Some(event) => bar.println(format!("iteration {}: {event}", report.iteration)),
            None if report.iteration % 10 == 0 => {
                let terms: Vec<String> =
                    report.losses.iter().map(|(term, value)| format!("{} {value:.4}", term.name())).collect();
                bar.set_message(format!("loss {:.4} ({}) s {:.0}", report.loss, terms.join(" "), report.inv_s))
            }
            None => {}
        }
        ControlFlow::Continue(())
    })
    .with_context(|| format!("reconstructing {}", args.scene.display()))?;
    bar.finish();
    if let Some(scale) = trainer.model.radiance.learned_polarization(&trainer.params) {
        println!("specular polarization scale learned: {scale:.3} (1: a dielectric of index 1.5)");
    }
    if trainer.iteration < trainer.config.iterations {
        println!("stopped at iteration {} of {}; continue with --resume", trainer.iteration, trainer.config.iterations);
    } else {
        println!("{} iterations; results in {}", trainer.iteration, args.output.display());
    }
    Ok(())
}
