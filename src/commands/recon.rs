//! `rmvp recon SCENE -o DIR`: NeRSP reconstruction ([`rmvp_recon::reconstruct`]).

use super::progress;
use anyhow::{Context, Result};
use rmvp_dataset::io::json::read_json;
use rmvp_dataset::layout::read_scene;
use rmvp_recon::options::{ReconOptions, RunControl};
use rmvp_recon::reconstruct::{reconstruct, MESH_PARTS};
use rmvp_recon::unseen::UnseenParts;
use std::ops::ControlFlow;
use std::path::PathBuf;

/// Arguments of `rmvp recon`.
#[derive(clap::Args)]
pub struct Args {
    /// Scene folder (any layout) with Stokes images and masks.
    scene: PathBuf,
    /// Output folder: mesh.ply, mesh_parts.json, normals/, stokes/, comparison.png, residuals.png, residuals.json, log.jsonl, checkpoint.bin.
    #[arg(short, long)]
    output: PathBuf,
    /// The reconstruction's options.
    #[command(flatten)]
    options: ReconOptions,
    /// Continue from the output folder's checkpoint (with the options it was started with).
    #[arg(long)]
    resume: bool,
    /// Stop after this many iterations in this call (checkpointed; continue with --resume).
    #[arg(long)]
    stop_after: Option<u32>,
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let scene = read_scene(&args.scene)?;
    let options = args.options;
    let control = RunControl { resume: args.resume, stop_after: args.stop_after };
    let total = options.config().iterations;
    let bar = progress(total as u64, "recon");
    let trainer = reconstruct(&scene, &args.output, &options, control, |report, trainer| {
        bar.set_position(trainer.iteration as u64);
        if let Some(error) = report.normal_error_deg {
            bar.println(format!("iteration {}: normal error {error:.2} degrees against the truth", trainer.iteration));
        }
        match &report.event {
            Some(event) => bar.println(format!("iteration {}: {event}", report.iteration)),
            None if report.iteration % 10 == 0 => {
                let terms: Vec<String> =
                    report.losses.iter().map(|(term, value)| format!("{term} {value:.4}")).collect();
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
        let parts = args.output.join(MESH_PARTS);
        if let Some(line) = read_json::<UnseenParts>(&parts, "the mesh's parts")?.summary() {
            println!("{line}");
        }
        let page = rmvp_pipeline::report::write_recon_report(&args.output, Some(&scene))?;
        println!("{} iterations; results in {}, the page {}", trainer.iteration, args.output.display(), page.display());
    }
    Ok(())
}
