//! `rmvp convert SRC DST --to nersp|rmvp`.

use anyhow::{bail, Result};
use rmvp_dataset::layout::{read_scene, write_scene, Layout};
use std::path::PathBuf;

/// Arguments of `rmvp convert`.
#[derive(clap::Args)]
pub struct Args {
    /// Scene folder to read (either layout).
    source: PathBuf,
    /// Folder to write; must not exist yet, or be empty.
    destination: PathBuf,
    /// Layout to write: `nersp` (official NeRSP loader) or `rmvp` (our manifest layout).
    #[arg(long)]
    to: String,
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let layout = match args.to.as_str() {
        "nersp" => Layout::Nersp,
        "rmvp" => Layout::Canonical,
        other => bail!("unknown layout {other:?}: use nersp or rmvp"),
    };
    if args.destination.exists() && std::fs::read_dir(&args.destination)?.next().is_some() {
        bail!("{}: exists and is not empty; choose a new folder", args.destination.display());
    }
    let bar = super::progress(2, "convert");
    bar.set_message(format!("reading {}", args.source.display()));
    let scene = read_scene(&args.source)?;
    bar.inc(1);
    bar.set_message(format!("writing {}", args.destination.display()));
    write_scene(&scene, &args.destination, layout)?;
    bar.inc(1);
    bar.finish_with_message(format!(
        "{} views -> {} ({} layout)",
        scene.views.len(),
        args.destination.display(),
        layout.name()
    ));
    Ok(())
}
