//! `rmvp render-normals --mesh MESH --scene SCENE -o DIR`: ground-truth normal maps and masks of
//! a mesh in every view of a scene (what dataset building needs once a scan is aligned).

use anyhow::Result;
use rmvp_dataset::io::{exr, png};
use rmvp_dataset::layout::read_scene;
use rmvp_dataset::Mesh;
use rmvp_render::pbrdf::{Interface, Lobes};
use rmvp_render::{geometry_maps, Object};
use std::path::PathBuf;

/// Arguments of `rmvp render-normals`.
#[derive(clap::Args)]
pub struct Args {
    /// Mesh in the scene's world frame.
    #[arg(long)]
    mesh: PathBuf,
    /// Scene whose cameras to use (either layout).
    #[arg(long)]
    scene: PathBuf,
    /// Output folder: `<view>_normal.exr` (world frame, N.X N.Y N.Z), `<view>_normal.png`,
    /// `<view>_mask.png`, `<view>_depth.exr` (Z).
    #[arg(short, long)]
    output: PathBuf,
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let mesh = Mesh::read(&args.mesh)?;
    let scene = read_scene(&args.scene)?;
    let object = Object::new(&mesh, Interface::Dielectric(1.5), Lobes::Plastic)?;
    let bar = super::progress(scene.views.len() as u64, "normals");
    for view in &scene.views {
        let maps = geometry_maps(&object, &view.camera);
        let file = |suffix: &str| args.output.join(format!("{}_{suffix}", view.name));
        exr::write_exr(&file("normal.exr"), &maps.normals, &["N.X", "N.Y", "N.Z"])?;
        png::write_png_u8(&file("normal.png"), &maps.normals.map(|v| ((v * 0.5 + 0.5) * 255.0).round() as u8))?;
        png::write_png_u8(&file("mask.png"), &maps.mask)?;
        exr::write_exr(&file("depth.exr"), &maps.depth, &["Z"])?;
        bar.inc(1);
    }
    bar.finish_with_message(format!("{} views -> {}", scene.views.len(), args.output.display()));
    Ok(())
}
