//! `rmvp align --scan SCAN --to TARGET -o DIR`: a laser scan onto a reconstruction, by a
//! similarity (rotation, translation, uniform scale) ([`rmvp_align::align_files`]).

use anyhow::Result;
use rmvp_align::icp::{ALIGNED_MESH, ALIGNMENT_FILE};
use rmvp_align::{align_files, IcpOptions};
use std::path::PathBuf;

/// Arguments of `rmvp align`.
#[derive(clap::Args)]
pub struct Args {
    /// The scan (PLY/OBJ/STL mesh or point cloud), in any units.
    #[arg(long)]
    scan: PathBuf,
    /// The target: a mesh (or a point cloud with normals), e.g. a reconstruction.
    #[arg(long)]
    to: PathBuf,
    /// Output folder: `alignment.json` and `aligned.ply`.
    #[arg(short, long)]
    output: PathBuf,
    /// Skip the coarse multistart (the scan is already roughly in place).
    #[arg(long)]
    no_coarse: bool,
    /// Scan points used by the fine stage at most.
    #[arg(long, default_value_t = IcpOptions::default().max_scan_points)]
    max_points: usize,
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let options = IcpOptions { coarse: !args.no_coarse, max_scan_points: args.max_points, ..IcpOptions::default() };
    let result = align_files(&args.scan, &args.to, &args.output, &options)?;
    let t = &result.transform;
    println!(
        "scale {:.6}, rotation {:.3} deg, translation ({:.4}, {:.4}, {:.4})",
        t.s,
        t.angle_deg(),
        t.t.x,
        t.t.y,
        t.t.z
    );
    println!(
        "residuals: RMS point-to-plane {:.4}, median distance {:.4}, inliers {:.1} %",
        result.rms,
        result.median_distance,
        100.0 * result.inlier_ratio
    );
    println!("wrote {}/{ALIGNMENT_FILE} and {ALIGNED_MESH}", args.output.display());
    Ok(())
}
