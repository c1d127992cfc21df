//! `rmvp report DIR [--scene SCENE]`: the page of a reconstruction, a built dataset, a release
//! or a batch ([`rmvp_pipeline::report`]), written again.

use anyhow::Result;
use rmvp_dataset::layout::read_scene;
use rmvp_pipeline::batch::gather;
use rmvp_pipeline::batch::plan::PLAN_FILE;
use rmvp_pipeline::build::{write_build_report, BUILD_FILE};
use rmvp_pipeline::publish::{write_release_report, CHECKSUMS};
use std::path::PathBuf;

/// Arguments of `rmvp report`.
#[derive(clap::Args)]
pub struct Args {
    /// A reconstruction's output folder (`rmvp recon -o DIR`), a built dataset (`rmvp dataset
    /// build`), a release (`rmvp dataset publish`; its line in SHA256SUMS follows the page) or
    /// a batch (`rmvp batch plan`; as `rmvp batch gather`): the page is DIR/report.html.
    dir: PathBuf,
    /// The scene reconstructed (a reconstruction's page): its cameras are drawn as frustums
    /// around the mesh, which is coloured by its distance to the scene's true surface.
    #[arg(long)]
    scene: Option<PathBuf>,
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let dir = &args.dir;
    let page = if dir.join(PLAN_FILE).is_file() {
        gather(dir)?;
        dir.join(rmvp_pipeline::report::PAGE)
    } else if dir.join(BUILD_FILE).is_file() {
        write_build_report(dir)?
    } else if dir.join(CHECKSUMS).is_file() {
        write_release_report(dir)?
    } else {
        let scene = args.scene.map(|dir| read_scene(&dir)).transpose()?;
        rmvp_pipeline::report::write_recon_report(dir, scene.as_ref())?
    };
    println!("{}", page.display());
    Ok(())
}
