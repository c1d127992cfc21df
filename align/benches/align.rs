//! A 200k-point scan in millimetres onto a ~140k-vertex reconstruction: the Stanford bunny
//! (`RMVP_BENCH_MESH`) subdivided once and scaled to 200 mm is the reconstruction; the scan is
//! its surface sampled, 12 % cropped, with 0.3 mm noise and 1 % outliers, turned 20 degrees,
//! scaled by 1.04 and moved. Prints time and errors; with `RMVP_BENCH_EXPORT=DIR` writes
//! `scan.ply`, `target.ply` and `truth.json` for `bench/align_reference.py`.

use nalgebra::{Rotation3, Unit, Vector3};
use rmvp_align::sampling::sample_surface;
use rmvp_align::{align, IcpOptions, Similarity};
use rmvp_dataset::io::write_bytes_atomically;
use rmvp_dataset::rng::Rng;
use rmvp_dataset::Mesh;
use std::collections::HashMap;
use std::time::Instant;

/// Split every triangle into four (edge midpoints), without smoothing.
fn subdivide(mesh: &Mesh) -> Mesh {
    let mut positions = mesh.positions.clone();
    let mut midpoints = HashMap::new();
    let mut mid = |a: u32, b: u32| {
        *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
            let (p, q) = (positions[a as usize], positions[b as usize]);
            positions.push([0, 1, 2].map(|k| 0.5 * (p[k] + q[k])));
            positions.len() as u32 - 1
        })
    };
    let faces = mesh
        .faces
        .iter()
        .flat_map(|&[a, b, c]| {
            let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
            [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        })
        .collect();
    Mesh { positions, faces, ..Mesh::default() }
}

fn main() {
    if !std::env::args().any(|a| a == "--bench") {
        return; // run by `cargo test --all-targets` (no `--bench`): measure only under `cargo bench`
    }
    let path =
        std::env::var_os("RMVP_BENCH_MESH").expect("set RMVP_BENCH_MESH to a mesh (bench/align.sh uses the bunny)");
    let base = Mesh::read(std::path::Path::new(&path)).expect("readable mesh");
    let fine = subdivide(&base);
    let target = Mesh { positions: fine.positions.iter().map(|p| p.map(|v| v * 100.0)).collect(), ..fine };
    let truth = Similarity {
        r: *Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(0.2, 1.0, 0.3)), 20f64.to_radians()).matrix(),
        t: Vector3::new(15.0, -8.0, 25.0),
        s: 1.04,
    };
    // The scan: sampled target surface, cropped (largest 12 % of x), noisy, with outliers, then
    // moved by the inverse of the truth, so that aligning it onto the target must find `truth`.
    let mut rng = Rng::for_pixel(21, 0, 0);
    let mut points = sample_surface(&target, 230_000, 4);
    let mut xs: Vec<f32> = points.iter().map(|p| p[0]).collect();
    xs.sort_by(f32::total_cmp);
    let cut = xs[(xs.len() as f64 * 0.88) as usize];
    points.retain(|p| p[0] < cut);
    points.truncate(198_000);
    let (lo, hi) = target.bounds().unwrap();
    for _ in 0..2_000 {
        points.push([0, 1, 2].map(|k| lo[k] + rng.next_f32() * (hi[k] - lo[k])));
    }
    let inverse = truth.inverse();
    let scan_points: Vec<[f32; 3]> = points
        .iter()
        .map(|p| {
            let q = inverse.apply(&Vector3::from(p.map(|v| (v + 0.3 * rng.normal()) as f64)));
            [q.x as f32, q.y as f32, q.z as f32]
        })
        .collect();
    let scan = Mesh { positions: scan_points, ..Mesh::default() };
    println!(
        "align benchmark: scan {} points (mm), target {} vertices / {} triangles, {} threads",
        scan.positions.len(),
        target.positions.len(),
        target.faces.len(),
        rayon::current_num_threads()
    );
    let start = Instant::now();
    let found = align(&scan, &target, &IcpOptions::default()).unwrap();
    let seconds = start.elapsed().as_secs_f64();
    let error = found.transform.compose(&truth.inverse());
    println!(
        "  rmvp: {seconds:.2} s, rotation error {:.4} deg, scale error {:+.4} %, translation error {:.3} mm, inliers {:.1} %",
        error.angle_deg(),
        100.0 * (found.transform.s / truth.s - 1.0),
        (found.transform.t - truth.t).norm(),
        100.0 * found.inlier_ratio
    );
    println!("rust_align_seconds {seconds:.3}");
    println!(
        "row\trmvp (7-DoF point-to-plane, multistart)\t{seconds:.2} s\t{:.4} deg\t{:+.3} %\t{:.3} mm",
        error.angle_deg(),
        100.0 * (found.transform.s / truth.s - 1.0),
        (found.transform.t - truth.t).norm()
    );
    if let Some(dir) = std::env::var_os("RMVP_BENCH_EXPORT") {
        let dir = std::path::PathBuf::from(dir);
        scan.write(&dir.join("scan.ply")).unwrap();
        target.write(&dir.join("target.ply")).unwrap();
        let m = truth.matrix();
        let json = serde_json::json!({"matrix": (0..4).map(|i| (0..4).map(|j| m[(i, j)]).collect::<Vec<_>>()).collect::<Vec<_>>(), "scale": truth.s});
        write_bytes_atomically(&dir.join("truth.json"), json.to_string().as_bytes()).unwrap();
    }
}
