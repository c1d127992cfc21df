//! `rmvp eval --pred MESH --gt MESH [--scene SCENE] [--json]`.

use anyhow::Result;
use rmvp_align::{normal_errors, surface_metrics, SurfaceOptions};
use rmvp_dataset::io::png;
use rmvp_dataset::layout::read_scene;
use rmvp_dataset::visualize::gray_ramp;
use rmvp_dataset::Mesh;
use serde_json::json;
use std::path::PathBuf;

/// Arguments of `rmvp eval`.
#[derive(clap::Args)]
pub struct Args {
    /// Predicted mesh (PLY or OBJ), in the ground truth's frame and units.
    #[arg(long)]
    pred: PathBuf,
    /// Ground-truth mesh.
    #[arg(long)]
    gt: PathBuf,
    /// A scene with ground-truth normal maps (`gt/normal` or our layout): also report the normal
    /// angular error per view.
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Write the figures to stdout as JSON.
    #[arg(long)]
    json: bool,
    /// Samples per unit area of each surface (default: as many as --max-samples allows).
    #[arg(long)]
    density: Option<f64>,
    /// Samples per surface at most.
    #[arg(long, default_value_t = 200_000)]
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
    let (pred, gt) = (Mesh::read(&args.pred)?, Mesh::read(&args.gt)?);
    let options = SurfaceOptions {
        density: args.density.unwrap_or(f64::INFINITY),
        max_samples: args.max_samples,
        max_distance: args.max_distance,
        threshold: args.threshold,
        seed: 0,
    };
    let surface = surface_metrics(&pred, &gt, &options)?;
    let normals =
        args.scene.as_ref().map(|dir| read_scene(dir).and_then(|scene| normal_errors(&pred, &scene))).transpose()?;
    if let (Some(report), Some(dir)) = (&normals, &args.output) {
        for v in &report.views {
            png::write_png_u8(
                &dir.join(format!("{}_normal_error.png", v.view)),
                &gray_ramp(&v.error_map.map(|e| if e.is_nan() { 0.0 } else { e }), 0.0, 30.0),
            )?;
        }
    }
    if args.json {
        let mut out = serde_json::to_value(&surface)?;
        if let Some(report) = &normals {
            out["normal_mae_deg"] = json!(report.mean_mae_deg);
            out["normal_views"] = serde_json::to_value(&report.views)?;
        }
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    println!("accuracy      {:.6}  (predicted -> ground truth, mean)", surface.accuracy);
    println!("completeness  {:.6}  (ground truth -> predicted, mean)", surface.completeness);
    println!("chamfer       {:.6}", surface.chamfer);
    println!(
        "F-score       {:.4}  at {:.6} (precision {:.4}, recall {:.4}; {} + {} samples)",
        surface.fscore, surface.threshold, surface.precision, surface.recall, surface.samples[0], surface.samples[1]
    );
    if let Some(report) = &normals {
        for v in &report.views {
            println!("normal MAE    {:>7.3} deg  view {} ({} px)", v.mae_deg, v.view, v.pixels);
        }
        println!("normal_mae_deg {:.3}  (mean over {} views)", report.mean_mae_deg, report.views.len());
    }
    Ok(())
}
