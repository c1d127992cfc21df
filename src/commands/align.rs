//! `rmvp align --scan SCAN --to TARGET -o DIR`: a laser scan onto a reconstruction, by a
//! similarity (rotation, translation, uniform scale).

use anyhow::Result;
use rmvp_align::icp::AlignmentRecord;
use rmvp_align::{align, IcpOptions};
use rmvp_dataset::io::write_bytes_atomically;
use rmvp_dataset::Mesh;
use serde_json::json;
use std::path::PathBuf;

/// Arguments of `rmvp align`.
#[derive(clap::Args)]
pub struct Args {
    /// The scan (PLY/OBJ mesh or point cloud), in any units.
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
    #[arg(long, default_value_t = 50_000)]
    max_points: usize,
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let (scan, target) = (Mesh::read(&args.scan)?, Mesh::read(&args.to)?);
    let options = IcpOptions { coarse: !args.no_coarse, max_scan_points: args.max_points, ..IcpOptions::default() };
    let result = align(&scan, &target, &options)?;
    let t = &result.transform;
    let mut record = AlignmentRecord::from(t);
    record.inverse = Some(Box::new(AlignmentRecord::from(&t.inverse())));
    let report = json!({
        "scan": args.scan.display().to_string(),
        "target": args.to.display().to_string(),
        "scan_to_target": record,
        "rms_point_to_plane": result.rms,
        "median_distance": result.median_distance,
        "inlier_ratio": result.inlier_ratio,
    });
    write_bytes_atomically(&args.output.join("alignment.json"), serde_json::to_string_pretty(&report)?.as_bytes())?;
    let moved = |p: &[f32; 3], f: &dyn Fn(&nalgebra::Vector3<f64>) -> nalgebra::Vector3<f64>| {
        let q = f(&nalgebra::Vector3::from(p.map(|v| v as f64)));
        [q.x as f32, q.y as f32, q.z as f32]
    };
    let aligned = Mesh {
        positions: scan.positions.iter().map(|p| moved(p, &|v| t.apply(v))).collect(),
        normals: scan.normals.as_ref().map(|n| n.iter().map(|p| moved(p, &|v| t.r * v)).collect()),
        ..scan
    };
    aligned.write(&args.output.join("aligned.ply"))?;
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
    println!("wrote {}/alignment.json and aligned.ply", args.output.display());
    Ok(())
}
