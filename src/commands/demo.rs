//! `rmvp demo`: the pipeline on its built-in example ([`rmvp_pipeline::demo`]).

use anyhow::Result;
use rmvp_pipeline::demo::{run_demo, DemoOptions};
use std::path::PathBuf;

/// Arguments of `rmvp demo`.
#[derive(clap::Args)]
pub struct Args {
    /// Output folder.
    #[arg(short, long, default_value_os_t = DemoOptions::default().output)]
    output: PathBuf,
    /// Samples per pixel of the simulated camera's renderer.
    #[arg(long, default_value_t = DemoOptions::default().spp)]
    spp: u32,
    /// Training iterations of the reconstruction (fast preset).
    #[arg(long, default_value_t = DemoOptions::default().recon_iterations)]
    recon_iters: u32,
    /// Marching grid cells per axis of the reconstructed mesh.
    #[arg(long, default_value_t = DemoOptions::default().mesh_resolution)]
    mesh_res: usize,
    /// Reconstruct the mesh only: no normal maps or re-rendered Stokes of the views.
    #[arg(long)]
    mesh_only: bool,
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let options = DemoOptions {
        output: args.output,
        spp: args.spp,
        recon_iterations: args.recon_iters,
        mesh_resolution: args.mesh_res,
        view_outputs: !args.mesh_only,
        progress: true,
    };
    let report = run_demo(&options, &mut |line| println!("{line}"))?;
    let (aop, s0, recon) = (&report.aop_error_deg, &report.s0_rel_error, &report.reconstruction);
    println!(
        "captured vs rendered: AoP error median {:.2} deg (90% {:.2} deg) over {} pixels with DoP > 0.05; S0 error median {:.2}%",
        aop.median,
        aop.p90,
        aop.pixels,
        100.0 * s0.median
    );
    println!(
        "reconstruction ({:.0} s): Chamfer {:.4} (object radius 1), F-score {:.3}, normal MAE {:.2} deg over {} views",
        recon.seconds, recon.chamfer, recon.f_score, recon.normal_mae_deg, report.dataset.views
    );
    println!("wrote {}:", options.output.display());
    println!("  contact_sheet.png  per view: rendered S0 | captured S0 | captured AoP x DoP | AoP error");
    println!("  report.json        the figures above");
    println!("  session/           the capture session (raw frames, Stokes, AoP, DoP; poses.json, masks/)");
    println!("  simulated/         ground truth (NeRSP layout with gt/): noise-free Stokes, normals, mesh");
    println!("  dataset/           the dataset built from the session (nersp/, rmvp/, build.json)");
    println!("  release/           the dataset published: card, croissant.json, datacite.json, index/, SHA256SUMS");
    println!("  recon/             mesh.ply, mesh_parts.json, normals/, stokes/, comparison.png (input | rendered S0, AoP, normals), residuals.png, log.jsonl");
    Ok(())
}
