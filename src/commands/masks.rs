//! `rmvp masks SESSION --method threshold|difference|grabcut|mesh|folder -o DIR`
//! ([`rmvp_calib::masks`]).

use anyhow::Result;
use rmvp_calib::masks::{make_masks, MaskMethod, MaskOptions, MASKS_SHEET};
use std::path::PathBuf;

/// Arguments of `rmvp masks`.
#[derive(clap::Args)]
pub struct Args {
    /// The capture session.
    session: PathBuf,
    /// How to make the masks.
    #[arg(long, value_enum, default_value_t = MaskOptions::default().method)]
    method: MaskMethod,
    /// Folder for the masks (`<view>.png`), `masks.json` and `contact_sheet.png` (they are also
    /// kept in the session's `masks/`).
    #[arg(short, long)]
    output: PathBuf,
    /// threshold: S0 level as a fraction of its 99.5th percentile (default: Otsu's threshold).
    #[arg(long)]
    threshold: Option<f64>,
    /// difference: relative colour difference that counts as the object.
    #[arg(long, default_value_t = MaskOptions::default().difference)]
    difference: f64,
    /// difference, grabcut: background plates (the empty rig, same view names).
    #[arg(long)]
    background: Option<PathBuf>,
    /// Opening radius (removes specks), pixels.
    #[arg(long, default_value_t = MaskOptions::default().open_px)]
    open: u32,
    /// Closing radius (fills cracks and thin gaps), pixels.
    #[arg(long, default_value_t = MaskOptions::default().close_px)]
    close: u32,
    /// grabcut: width of the undecided band around the first guess, pixels.
    #[arg(long, default_value_t = MaskOptions::default().band_px)]
    band: u32,
    /// mesh: a mesh in the session's pose frame (the session needs `poses.json`).
    #[arg(long, required_if_eq("method", "mesh"))]
    mesh: Option<PathBuf>,
    /// folder: the hand-made masks (`<view>.png`, `.jpg` or `.tif`; white is the object).
    #[arg(long = "from", required_if_eq("method", "folder"))]
    folder: Option<PathBuf>,
    /// Hand-made masks (`<view>.png`, `.jpg` or `.tif`) that replace those of their views.
    #[arg(long)]
    corrections: Option<PathBuf>,
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let options = MaskOptions {
        method: args.method,
        threshold: args.threshold,
        difference: args.difference,
        band_px: args.band,
        open_px: args.open,
        close_px: args.close,
        background: args.background,
        mesh: args.mesh,
        folder: args.folder,
        corrections: args.corrections,
        ..MaskOptions::default()
    };
    let report = make_masks(&args.session, &options, &args.output)?;
    for v in &report.views {
        let corrected = if v.corrected { "  (hand-made correction)" } else { "" };
        println!("  {:<8} {:>6.2} % of the image{corrected}", v.name, 100.0 * v.area_fraction);
    }
    println!("wrote {} masks to {} (review {MASKS_SHEET})", report.views.len(), args.output.display());
    Ok(())
}
