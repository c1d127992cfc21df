//! `rmvp eval [SCENE] --pred MESH --gt MESH [--json]` ([`rmvp_align::evaluate`]).

use anyhow::Result;
use rmvp_align::surface::read_surface;
use rmvp_align::{evaluate, SurfaceOptions};
use rmvp_dataset::layout::read_scene;
use rmvp_dataset::Split;
use std::path::PathBuf;

/// Arguments of `rmvp eval`.
#[derive(clap::Args)]
pub struct Args {
    /// Predicted mesh (PLY, OBJ or STL), in the ground truth's frame and units.
    #[arg(long)]
    pred: PathBuf,
    /// Ground-truth mesh.
    #[arg(long)]
    gt: PathBuf,
    /// A scene with ground-truth normal maps (`gt/normal` or our layout): also report the normal
    /// angular error per view.
    scene: Option<PathBuf>,
    /// The scene, as a flag (older spelling).
    #[arg(long = "scene", hide = true, conflicts_with = "scene")]
    scene_flag: Option<PathBuf>,
    /// Write the figures to stdout as JSON.
    #[arg(long)]
    json: bool,
    /// Samples per unit area of each surface (default: as many as --max-samples allows).
    #[arg(long)]
    density: Option<f64>,
    /// Samples per surface at most.
    #[arg(long, default_value_t = SurfaceOptions::default().max_samples)]
    max_samples: usize,
    /// Cap distances at this value in the means (DTU: 20 mm).
    #[arg(long)]
    max_distance: Option<f64>,
    /// F-score threshold (default: 1 % of the ground truth's bounding-box diagonal).
    #[arg(long)]
    threshold: Option<f64>,
    /// Folder for normal error maps (`<view>_normal_error.png`, black 0 to white 30 degrees).
    #[arg(short, long)]
    output: Option<PathBuf>,
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let (pred, gt) = (read_surface(&args.pred)?, read_surface(&args.gt)?);
    let defaults = SurfaceOptions::default();
    let options = SurfaceOptions {
        density: args.density.unwrap_or(defaults.density),
        max_samples: args.max_samples,
        max_distance: args.max_distance,
        threshold: args.threshold,
        ..defaults
    };
    let scene = args.scene.or(args.scene_flag).map(|dir| read_scene(&dir)).transpose()?;
    let evaluation = evaluate(&pred, &gt, scene.as_ref(), &options)?;
    if let Some(dir) = &args.output {
        evaluation.write_error_maps(dir)?;
    }
    if args.json {
        println!("{}", evaluation.to_json());
        return Ok(());
    }
    let surface = &evaluation.surface;
    println!("accuracy      {:.6}  (predicted -> ground truth, mean)", surface.accuracy);
    println!("completeness  {:.6}  (ground truth -> predicted, mean)", surface.completeness);
    println!("chamfer       {:.6}", surface.chamfer);
    println!(
        "F-score       {:.4}  at {:.6} (precision {:.4}, recall {:.4}; {} + {} samples)",
        surface.fscore, surface.threshold, surface.precision, surface.recall, surface.samples[0], surface.samples[1]
    );
    for v in &evaluation.normal_views {
        println!("normal MAE    {:>7.3} deg  view {} ({}, {} px)", v.mae_deg, v.view, v.split, v.pixels);
    }
    if let Some(mae) = evaluation.normal_mae_deg {
        println!("normal_mae_deg {mae:.3}  (mean over {} views)", evaluation.normal_views.len());
    }
    for split in [Split::Train, Split::Eval] {
        if let Some(mae) = evaluation.split_normal_mae_deg(split) {
            println!("normal MAE    {mae:>7.3} deg  mean over the {split} views");
        }
    }
    for line in evaluation.breakdown.iter().flat_map(|b| b.lines()) {
        println!("normal MAE {line}");
    }
    Ok(())
}
