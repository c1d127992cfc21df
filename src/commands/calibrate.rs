//! `rmvp calibrate SESSION|IMAGES... -o camera.json`: intrinsics from views of a board
//! ([`rmvp_calib::intrinsics`]).

use super::board::BoardArgs;
use anyhow::Result;
use rmvp_calib::intrinsics::{calibrate_files, coverage_path, CalibrationOptions};
use std::path::PathBuf;

/// Arguments of `rmvp calibrate`.
#[derive(clap::Args)]
pub struct Args {
    /// A capture session of the board (each view's S0) or pictures (PNG, JPEG, TIFF, EXR, HDR;
    /// 8-bit files taken as the sRGB pictures they are, the others as linear light).
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// The calibration file to write (JSON); its coverage picture goes beside it.
    #[arg(short, long)]
    output: PathBuf,
    /// The board.
    #[command(flatten)]
    board: BoardArgs,
    /// Corners an image needs to take part.
    #[arg(long, default_value_t = CalibrationOptions::default().min_corners)]
    min_corners: usize,
    /// Estimate the tangential distortion p1, p2 too.
    #[arg(long)]
    tangential: bool,
    /// Estimate the third radial coefficient k3 too.
    #[arg(long)]
    k3: bool,
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let options = CalibrationOptions {
        min_corners: args.min_corners,
        tangential: args.tangential,
        k3: args.k3,
        ..CalibrationOptions::default()
    };
    let run = calibrate_files(&args.inputs, &args.board.spec(), &options, &args.output)?;
    let c = &run.calibration;
    let k = c.k();
    println!(
        "{} images: fx {:.2} fy {:.2} cx {:.2} cy {:.2} px (deviations {:.2} {:.2} {:.2} {:.2}), RMS {:.3} px",
        c.images.len(),
        k[(0, 0)],
        k[(1, 1)],
        k[(0, 2)],
        k[(1, 2)],
        c.k_std_px[0],
        c.k_std_px[1],
        c.k_std_px[2],
        c.k_std_px[3],
        c.rms_px
    );
    let d = &c.distortion;
    println!("distortion k1 {:.5} k2 {:.5} p1 {:.5} p2 {:.5} k3 {:.5}", d.k1, d.k2, d.p1, d.p2, d.k3);
    for image in &c.images {
        println!("  {:<24} {:>4} corners  RMS {:.3} px", image.name, image.corners, image.rms_px);
    }
    for r in &c.rejected {
        println!("  {:<24} left out: {}", r.name, r.reason);
    }
    for warning in &c.warnings {
        eprintln!("warning: {warning}");
    }
    println!("wrote {} and {}", args.output.display(), coverage_path(&args.output).display());
    Ok(())
}
