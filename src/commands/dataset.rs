//! `rmvp dataset ...`: scene folders. `info` summarises and validates, `convert` rewrites in
//! another layout, `render-normals` ray casts a mesh's ground-truth maps in every view.

use anyhow::Result;
use rmvp_dataset::layout::{convert_scene, read_scene, Layout};
use rmvp_dataset::summary::SceneSummary;
use rmvp_dataset::Mesh;
use rmvp_pipeline::build::{build_dataset, BuildOptions, TrainViews};
use rmvp_pipeline::ground_truth::write_ground_truth_maps;
use std::path::PathBuf;

/// The subcommands of `rmvp dataset`.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Build a dataset from a posed, masked capture session (NeRSP layout and ours).
    Build(BuildArgs),
    /// Summarise and validate a scene folder (NeRSP or rmvp layout).
    Info(InfoArgs),
    /// Convert a scene between the NeRSP and rmvp layouts, without loss.
    Convert(ConvertArgs),
    /// Ray cast a mesh's normal maps, masks and depths in every view of a scene.
    RenderNormals(RenderNormalsArgs),
}

/// Arguments of `rmvp dataset build`.
#[derive(clap::Args)]
pub struct BuildArgs {
    /// The capture session, posed (`rmvp poses`) and masked (`rmvp masks`).
    session: PathBuf,
    /// The dataset folder: `nersp/` and `rmvp/`.
    #[arg(short, long)]
    output: PathBuf,
    /// Training views: a count, spread over the viewing directions, or names (`000,007,013`).
    #[arg(long, value_parser = str::parse::<TrainViews>, default_value = "6")]
    train_views: TrainViews,
}

/// Arguments of `rmvp dataset info`.
#[derive(clap::Args)]
pub struct InfoArgs {
    /// Scene folder (NeRSP or rmvp layout).
    scene: PathBuf,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
}

/// Arguments of `rmvp dataset convert`.
#[derive(clap::Args)]
pub struct ConvertArgs {
    /// Scene folder to read (either layout).
    source: PathBuf,
    /// Folder to write; must not exist yet, or be empty.
    destination: PathBuf,
    /// Layout to write: `nersp` (the official NeRSP loader's) or `rmvp` (ours).
    #[arg(long, value_enum)]
    to: Layout,
}

/// Arguments of `rmvp dataset render-normals`.
#[derive(clap::Args)]
pub struct RenderNormalsArgs {
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

/// Run a `rmvp dataset` subcommand.
pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Build(args) => {
            let options = BuildOptions { session: args.session, output: args.output, train: args.train_views };
            let scene = build_dataset(&options)?;
            let train: Vec<&str> = scene.train_views().map(|v| v.name.as_str()).collect();
            println!(
                "{} views ({} training: {}) -> {}/nersp and rmvp",
                scene.views.len(),
                train.len(),
                train.join(" "),
                options.output.display()
            );
            Ok(())
        }
        Command::Info(args) => info(args),
        Command::Convert(args) => {
            let scene = convert_scene(&args.source, &args.destination, args.to)?;
            println!("{} views -> {} ({} layout)", scene.views.len(), args.destination.display(), args.to.name());
            Ok(())
        }
        Command::RenderNormals(args) => {
            let (mesh, scene) = (Mesh::read(&args.mesh)?, read_scene(&args.scene)?);
            write_ground_truth_maps(&mesh, &scene, &args.output, true)?;
            println!("{} views -> {}", scene.views.len(), args.output.display());
            Ok(())
        }
    }
}

fn info(args: InfoArgs) -> Result<()> {
    let s = SceneSummary::of_folder(&args.scene)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&s)?);
        return Ok(());
    }
    println!("scene   {} ({} layout), valid", args.scene.display(), s.layout);
    println!("views   {} ({} train, {} eval)", s.views.len(), s.train_views, s.views.len() - s.train_views);
    for v in &s.views {
        println!(
            "  {:<6} {:<5} {}x{}  f {:.1} px  centre ({:+.3}, {:+.3}, {:+.3})  mask {:>5.1}%  {}",
            v.name,
            v.split,
            v.size[0],
            v.size[1],
            v.focal_px[0],
            v.center[0],
            v.center[1],
            v.center[2],
            v.mask_fraction.map_or(f64::NAN, |f| 100.0 * f),
            v.contents.join(" ")
        );
    }
    if let Some(m) = &s.mesh {
        println!("mesh    {} vertices, {} triangles", m.vertices, m.triangles);
    }
    if let Some([w, h]) = s.env_map {
        println!("env map {w}x{h}");
    }
    for (k, v) in &s.metadata {
        if !v.is_object() {
            println!("meta    {k} = {v}");
        }
    }
    Ok(())
}
