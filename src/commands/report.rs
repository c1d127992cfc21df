//! `rmvp report DIR [--scene SCENE]`: the page of a reconstruction ([`rmvp_pipeline::report`]).

use anyhow::Result;
use rmvp_dataset::layout::read_scene;
use std::path::PathBuf;

/// Arguments of `rmvp report`.
#[derive(clap::Args)]
pub struct Args {
    /// A reconstruction's output folder (`rmvp recon -o DIR`): the page is DIR/report.html.
    dir: PathBuf,
    /// The scene reconstructed: its cameras are drawn as frustums around the mesh.
    #[arg(long)]
    scene: Option<PathBuf>,
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let scene = args.scene.map(|dir| read_scene(&dir)).transpose()?;
    let page = rmvp_pipeline::report::write_recon_report(&args.dir, scene.as_ref())?;
    println!("{}", page.display());
    Ok(())
}
