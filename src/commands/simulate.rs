//! `rmvp simulate`: a synthetic polarized capture of a mesh ([`rmvp_pipeline::simulate`]).

use anyhow::Result;
use rmvp_dataset::layout::Layout;
use rmvp_pipeline::simulate::{simulate, SimulateOptions, BUILT_IN_MESH};
use rmvp_render::pbrdf::Interface;
use rmvp_render::rig::RigKind;
use std::path::PathBuf;

/// Arguments of `rmvp simulate`.
#[derive(clap::Args)]
pub struct Args {
    /// Output folder: one scene folder per layout (`nersp/`, `rmvp/`), `camera_normals/`,
    /// `contact_sheet.png`, and with `--raw` the sensor frames in `raw/`.
    #[arg(short, long)]
    output: PathBuf,
    /// Mesh to render (PLY, OBJ or STL); default: the built-in "spot".
    #[arg(long)]
    mesh: Option<PathBuf>,
    /// Number of views.
    #[arg(long, default_value_t = SimulateOptions::default().views)]
    views: usize,
    /// Held-out views (ground truth only, for evaluation): random directions on the sphere,
    /// drawn with another seed than the training views.
    #[arg(long, default_value_t = SimulateOptions::default().eval_views)]
    eval_views: usize,
    /// Camera layout: sparse random views on a sphere, or the lab turntable's two rings.
    #[arg(long, value_enum, default_value_t = SimulateOptions::default().rig)]
    rig: RigKind,
    /// A JSON pose list instead of a rig: `[{"r": [[..]], "t": [..]}` or `{"eye": [..],
    /// "target": [..]}`, each optionally with its own `"k"`.
    #[arg(long, conflicts_with_all = ["rig", "views"])]
    poses: Option<PathBuf>,
    /// Image size WIDTHxHEIGHT (even; the rig's intrinsics are scaled to it).
    #[arg(long, default_value_t = super::Pair(SimulateOptions::default().size.0, SimulateOptions::default().size.1))]
    res: super::Pair,
    /// Samples per pixel.
    #[arg(long, default_value_t = SimulateOptions::default().spp)]
    spp: u32,
    /// Albedo texture for meshes with texture coordinates: PNG (sRGB) or EXR (linear RGB).
    #[arg(long)]
    texture: Option<PathBuf>,
    /// Lat-long environment map (EXR, top row +Y); default: a built-in studio environment.
    #[arg(long)]
    env: Option<PathBuf>,
    /// Also write the raw sensor frames the polarization camera would send.
    #[arg(long)]
    raw: bool,
    /// Seed of every random choice (views, samples, noise).
    #[arg(long, default_value_t = SimulateOptions::default().seed)]
    seed: u64,
    /// Relative refractive index of the dielectric surface.
    #[arg(long, default_value_t = rmvp_render::pbrdf::Interface::DEFAULT_ETA)]
    eta: f32,
    /// Render a conductor of complex index N + iK instead ("N,K", e.g. gold at 600 nm "0.25,3.0").
    #[arg(long, value_parser = super::parse_numbers::<2>, conflicts_with = "eta")]
    conductor: Option<[f32; 2]>,
    /// Layouts to write (repeat for several).
    #[arg(long, value_enum, default_values_t = SimulateOptions::default().layouts)]
    layout: Vec<Layout>,
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let options = SimulateOptions {
        output: args.output,
        mesh: args.mesh,
        views: args.views,
        eval_views: args.eval_views,
        rig: args.rig,
        poses: args.poses,
        size: (args.res.0, args.res.1),
        spp: args.spp,
        env: args.env,
        texture: args.texture,
        interface: match args.conductor {
            Some([n, k]) => Interface::Conductor(n, k),
            None => Interface::Dielectric(args.eta),
        },
        raw: args.raw,
        seed: args.seed,
        layouts: args.layout,
        progress: true,
    };
    let scene = simulate(&options)?;
    let (w, h) = options.size;
    let mesh = options.mesh.as_ref().map_or(BUILT_IN_MESH.to_string(), |p| p.display().to_string());
    println!(
        "rendered {} views of {mesh} at {w}x{h}, {} spp -> {}",
        scene.views.len(),
        options.spp,
        options.output.display()
    );
    println!("  contact_sheet.png: per view S0 | AoP (hue) x DoP | normals");
    Ok(())
}
