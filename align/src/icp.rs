//! Similarity alignment (rotation, translation and uniform scale) of a scan onto a target
//! surface: a coarse multistart over principal axes and rotations, then point-to-plane ICP
//! solving all 7 degrees of freedom by Gauss-Newton with robust (Geman-McClure) weights, a
//! shrinking correspondence distance and Levenberg damping for flat or symmetric shapes.
//! Optionally an eighth unknown: a uniform offset of the target's surface along its normals, as
//! a reconstruction grown by its masks' dilation carries (fitted only with the scale fixed: on a
//! rounded shape the two are nearly the same motion).
//!
//! Work happens in a normalised frame (target centroid at the origin, RMS radius 1) so that the
//! thresholds and the damping mean the same for millimetres and metres.

use crate::{Error, Result};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::{Matrix3, Matrix4, Rotation3, SMatrix, SVector, Vector3};
use rayon::prelude::*;
use rmvp_dataset::io::json::{read_json, write_json};
use rmvp_dataset::similarity::Similarity;
use rmvp_dataset::Mesh;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Settings of the alignment.
#[derive(Clone, Debug, PartialEq)]
pub struct IcpOptions {
    /// Run the coarse multistart (off: start from `initial`).
    pub coarse: bool,
    /// Starting guess when `coarse` is off.
    pub initial: Similarity,
    /// Keep the starting guess's scale (a rigid fit: the scan's scale in the target's frame is
    /// known, as from a scan in millimetres onto a metric reconstruction).
    pub fixed_scale: bool,
    /// Also fit how far the target's surface lies outside the scan's along its normals (the
    /// same everywhere), so that a uniformly grown or shrunk target does not pull the fit
    /// towards its better covered side. Only with `fixed_scale`.
    pub fit_offset: bool,
    /// Scan points used by the fine stage at most (random subsample).
    pub max_scan_points: usize,
    /// Points sampled on the target surface (at least its vertex count).
    pub target_samples: usize,
    /// Fine iterations.
    pub iterations: usize,
    /// Seed of the subsampling.
    pub seed: u64,
}

impl Default for IcpOptions {
    fn default() -> Self {
        Self {
            coarse: true,
            initial: Similarity::identity(),
            fixed_scale: false,
            fit_offset: false,
            max_scan_points: 50_000,
            target_samples: 200_000,
            iterations: 60,
            seed: 0,
        }
    }
}

/// The result of an alignment (`alignment.json`: the similarity both ways and the residuals).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "AlignmentRecord", into = "AlignmentRecord")]
pub struct Alignment {
    /// Scan to target.
    pub transform: Similarity,
    /// RMS point-to-plane residual of the inliers, in target units.
    pub rms: f64,
    /// Median absolute point-to-point distance of all scan points after alignment.
    pub median_distance: f64,
    /// Share of scan points within the final correspondence distance.
    pub inlier_ratio: f64,
    /// How far the target's surface lies outside the aligned scan's along its normals, in
    /// target units (fitted with [`IcpOptions::fit_offset`], otherwise 0); `rms` is measured
    /// from the target moved back by it.
    pub target_offset: f64,
}

/// The stored form of an [`Alignment`]: `x_target = s R x_scan + t`, and the inverse.
#[derive(Serialize, Deserialize)]
struct AlignmentRecord {
    scan_to_target: Similarity,
    target_to_scan: Similarity,
    rms_point_to_plane: f64,
    median_distance: f64,
    inlier_ratio: f64,
    #[serde(default)]
    target_offset: f64,
}

impl From<Alignment> for AlignmentRecord {
    fn from(a: Alignment) -> Self {
        Self {
            scan_to_target: a.transform,
            target_to_scan: a.transform.inverse(),
            rms_point_to_plane: a.rms,
            median_distance: a.median_distance,
            inlier_ratio: a.inlier_ratio,
            target_offset: a.target_offset,
        }
    }
}

impl TryFrom<AlignmentRecord> for Alignment {
    type Error = String;

    fn try_from(rec: AlignmentRecord) -> std::result::Result<Self, String> {
        let round_trip = rec.target_to_scan.compose(&rec.scan_to_target).matrix() - Matrix4::identity();
        if round_trip.abs().max() > 1e-6 {
            return Err("target_to_scan is not the inverse of scan_to_target".into());
        }
        Ok(Self {
            transform: rec.scan_to_target,
            rms: rec.rms_point_to_plane,
            median_distance: rec.median_distance,
            inlier_ratio: rec.inlier_ratio,
            target_offset: rec.target_offset,
        })
    }
}

/// The file an alignment is stored in.
pub const ALIGNMENT_FILE: &str = "alignment.json";
/// The scan moved onto the target.
pub const ALIGNED_MESH: &str = "aligned.ply";

impl Alignment {
    /// Read an alignment written by [`Alignment::write`].
    pub fn read(path: &Path) -> Result<Self> {
        Ok(read_json(path, "an alignment")?)
    }

    /// Write to `path` (JSON, atomically).
    pub fn write(&self, path: &Path) -> Result<()> {
        Ok(write_json(path, self)?)
    }
}

/// Align the scan file `scan` onto the target file `target` and write `out/alignment.json` and
/// `out/aligned.ply` (the scan moved onto the target).
pub fn align_files(scan: &Path, target: &Path, out: &Path, options: &IcpOptions) -> Result<Alignment> {
    let (scan_mesh, target_mesh) = (Mesh::read(scan)?, Mesh::read(target)?);
    // Inputs that no similarity can be fitted to are refused (before ICP runs and before
    // anything is written) naming their file.
    let alignment = align(&scan_mesh, &target_mesh, options).map_err(|e| {
        let (path, why) = match e {
            Error::TooFewScanPoints { points } => (scan, format!("{points} points; alignment needs at least 10")),
            Error::Degenerate { which: "scan", why } => (scan, why),
            Error::Degenerate { which: "target", why } => (target, why),
            other => return other,
        };
        rmvp_dataset::Error::format(path, format!("{why}: nothing to align")).into()
    })?;
    let t = &alignment.transform;
    let finite = t.s.is_finite() && t.s > 0.0 && t.r.iter().chain(t.t.iter()).all(|v| v.is_finite());
    if !finite {
        let why = "ICP found no finite similarity (do the scan and the target overlap at all?)".into();
        return Err(Error::Degenerate { which: "alignment", why });
    }
    alignment.write(&out.join(ALIGNMENT_FILE))?;
    alignment.transform.apply_to_mesh(&scan_mesh).write(&out.join(ALIGNED_MESH))?;
    Ok(alignment)
}

/// A target: points with unit normals and a k-d tree over them.
struct Target {
    points: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    tree: ImmutableKdTree<f32, 3>,
}

impl Target {
    /// Nearest target point within `radius`: (index, squared distance).
    fn nearest_within(&self, p: &Vector3<f64>, radius: f64) -> Option<(usize, f64)> {
        nearest_within(&self.tree, p, radius)
    }
}

/// Nearest point of `tree` within `radius` of `p`: (index, squared distance). Bounded queries
/// stay cheap for points far from every point (misaligned starts, outliers), where an unbounded
/// nearest-neighbour search visits much of the tree (measured: 0.2 against 25 us).
fn nearest_within(tree: &ImmutableKdTree<f32, 3>, p: &Vector3<f64>, radius: f64) -> Option<(usize, f64)> {
    let q = [p.x as f32, p.y as f32, p.z as f32];
    let r2 = (radius * radius) as f32;
    let found = tree
        .query(&q)
        .nearest_n::<SquaredEuclidean<f32>>(std::num::NonZeroUsize::MIN)
        .within::<SquaredEuclidean<f32>>(r2)
        .execute();
    found.first().map(|hit| (hit.item as usize, hit.distance as f64))
}

/// Sample the target surface (faces) with face normals, or take its vertices and normals.
fn target_from_mesh(mesh: &Mesh, samples: usize, seed: u64, normalize: &Similarity) -> Result<Target> {
    let (points, normals): (Vec<[f32; 3]>, Vec<[f32; 3]>) = if !mesh.faces.is_empty() {
        let count = samples.max(mesh.positions.len());
        let located = crate::sampling::sample_surface_with_faces(mesh, count, seed);
        located
            .into_iter()
            .map(|(p, face)| {
                let [a, b, c] = mesh.faces[face].map(|i| Vector3::from(mesh.positions[i as usize].map(|v| v as f64)));
                let n = (b - a).cross(&(c - a)).normalize();
                (p, [n.x as f32, n.y as f32, n.z as f32])
            })
            .unzip()
    } else if let Some(normals) = &mesh.normals {
        (mesh.positions.clone(), normals.clone())
    } else {
        return Err(Error::TargetWithoutSurface);
    };
    let points: Vec<[f32; 3]> = points
        .iter()
        .map(|p| {
            let q = normalize.apply(&Vector3::from(p.map(|v| v as f64)));
            [q.x as f32, q.y as f32, q.z as f32]
        })
        .collect();
    let tree = ImmutableKdTree::new_from_slice(&points)
        .map_err(|e| Error::BadMesh { which: "target", message: format!("k-d tree: {e:?}") })?;
    Ok(Target { points, normals, tree })
}

/// Why points cannot be aligned, if they cannot: fewer than 10, or all at one place or on one
/// line (no rotation or scale is determined).
fn degenerate(points: &[[f32; 3]]) -> Option<String> {
    let n = points.len();
    if n < 10 {
        return Some(format!("{n} points; alignment needs at least 10"));
    }
    let points: Vec<Vector3<f64>> = points.iter().map(|p| Vector3::from(p.map(|v| v as f64))).collect();
    let (c, _) = centroid_and_radius(&points);
    let cov = points.iter().map(|p| (p - c) * (p - c).transpose()).sum::<Matrix3<f64>>() / n as f64;
    let mut spread = cov.symmetric_eigen().eigenvalues.as_slice().to_vec();
    spread.sort_by(|a, b| b.total_cmp(a));
    let scale = c.norm_squared().max(spread[0]);
    if !spread[0].is_finite() || spread[0] <= 1e-12 * scale.max(f64::MIN_POSITIVE) {
        Some(format!("all {n} points coincide"))
    } else if spread[1] <= 1e-10 * spread[0] {
        Some(format!("all {n} points lie on one line"))
    } else {
        None
    }
}

/// Centroid and RMS radius.
fn centroid_and_radius(points: &[Vector3<f64>]) -> (Vector3<f64>, f64) {
    let c = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
    let r = (points.iter().map(|p| (p - c).norm_squared()).sum::<f64>() / points.len() as f64).sqrt();
    (c, r)
}

/// Principal axes (columns, descending variance) of centred points.
fn principal_axes(points: &[Vector3<f64>], c: &Vector3<f64>) -> Matrix3<f64> {
    let cov = points.iter().map(|p| (p - c) * (p - c).transpose()).sum::<Matrix3<f64>>();
    let eig = cov.symmetric_eigen();
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let mut axes = Matrix3::from_columns(&order.map(|k| eig.eigenvectors.column(k).into_owned()));
    if axes.determinant() < 0.0 {
        axes.set_column(2, &-axes.column(2));
    }
    axes
}

/// The unknowns of a refinement besides rotation and translation.
#[derive(Clone, Copy)]
struct Free {
    /// The scale.
    scale: bool,
    /// The target's offset along its normals.
    offset: bool,
}

/// Rotation and translation only.
const RIGID: Free = Free { scale: false, offset: false };

/// Point-to-plane Gauss-Newton refinement of `start` (normalised frame: the similarity and the
/// target's offset along its normals) on `scan` points, solving for the `free` unknowns.
fn refine(
    target: &Target,
    scan: &[Vector3<f64>],
    start: (Similarity, f64),
    iterations: usize,
    (radius_start, radius_end): (f64, f64),
    free: Free,
) -> (Similarity, f64) {
    let (mut current, mut offset) = start;
    for it in 0..iterations {
        // Correspondence distance shrinks geometrically from radius_start to radius_end.
        let f = it as f64 / (iterations.max(2) - 1) as f64;
        let radius = radius_start * (radius_end / radius_start).powf(f);
        let pairs: Vec<(Vector3<f64>, Vector3<f64>, Vector3<f64>)> = scan
            .par_iter()
            .filter_map(|p| {
                let x = current.apply(p);
                let (k, _) = target.nearest_within(&x, radius)?;
                let q = Vector3::from(target.points[k].map(|v| v as f64));
                let n = Vector3::from(target.normals[k].map(|v| v as f64));
                Some((x, q, n))
            })
            .collect();
        if pairs.len() < 7 {
            break;
        }
        // Robust scale from the median absolute residual.
        let residual = |(x, q, n): &(Vector3<f64>, Vector3<f64>, Vector3<f64>)| n.dot(&(x - q)) + offset;
        let mut abs: Vec<f64> = pairs.iter().map(|pair| residual(pair).abs()).collect();
        let mid = abs.len() / 2;
        let mad = *abs.select_nth_unstable_by(mid, f64::total_cmp).1;
        let c2 = (3.0 * 1.4826 * mad).max(1e-9).powi(2);
        let (mut h, mut g) = (SMatrix::<f64, 8, 8>::zeros(), SVector::<f64, 8>::zeros());
        for pair in &pairs {
            let (x, _, n) = pair;
            let r = residual(pair);
            // Geman-McClure weight.
            let w = c2 * c2 / (c2 + r * r).powi(2);
            // d r / d(sigma, omega, tau, delta) for x -> (1 + sigma) x + omega x x + tau, the
            // target's surface moved out by delta along its normals.
            let j = SVector::<f64, 8>::from_column_slice(&[
                n.dot(x),
                x.y * n.z - x.z * n.y,
                x.z * n.x - x.x * n.z,
                x.x * n.y - x.y * n.x,
                n.x,
                n.y,
                n.z,
                1.0,
            ]);
            h += w * j * j.transpose();
            g += w * r * j;
        }
        // Pin the unknowns that are not free (sigma: 0, delta: 7) to their current values.
        for (k, pinned) in [(0, !free.scale), (7, !free.offset)] {
            if pinned {
                h.row_mut(k).fill(0.0);
                h.column_mut(k).fill(0.0);
                h[(k, k)] = 1.0;
                g[k] = 0.0;
            }
        }
        let damping = 1e-6 * h.trace() / 8.0 + 1e-12;
        let Some(step) = (h + SMatrix::<f64, 8, 8>::identity() * damping).cholesky().map(|c| c.solve(&-g)) else {
            break;
        };
        let rotation = Rotation3::new(Vector3::new(step[1], step[2], step[3]));
        let delta = Similarity { r: *rotation.matrix(), t: Vector3::new(step[4], step[5], step[6]), s: step[0].exp() };
        current = delta.compose(&current);
        offset += step[7];
        // Converged: well below the noise of any scan (normalised units, radius 1).
        if step.norm() < 1e-7 {
            break;
        }
    }
    (current, offset)
}

/// Symmetric truncated distance between a transformed scan sample and a target sample
/// (normalised frame): mean of `min(d, cap)` both ways. A shrunken or misplaced scan cannot
/// score well, since the target side measures coverage.
fn symmetric_score(
    target: &Target,
    target_sample: &[Vector3<f64>],
    scan: &[Vector3<f64>],
    transform: &Similarity,
) -> f64 {
    const CAP: f64 = 0.1;
    let moved: Vec<[f32; 3]> =
        scan.iter().map(|p| transform.apply(p)).map(|q| [q.x as f32, q.y as f32, q.z as f32]).collect();
    let Ok(tree) = ImmutableKdTree::<f32, 3>::new_from_slice(&moved) else { return f64::INFINITY };
    let forward: f64 = moved
        .iter()
        .map(|q| {
            let p = Vector3::new(q[0] as f64, q[1] as f64, q[2] as f64);
            target.nearest_within(&p, CAP).map_or(CAP, |(_, d2)| d2.sqrt())
        })
        .sum();
    let backward: f64 =
        target_sample.iter().map(|p| nearest_within(&tree, p, CAP).map_or(CAP, |(_, d2)| d2.sqrt())).sum();
    0.5 * (forward / moved.len() as f64 + backward / target_sample.len() as f64)
}

/// Align `scan` (points; a mesh's vertices) onto the surface of `target`.
pub fn align(scan: &Mesh, target: &Mesh, options: &IcpOptions) -> Result<Alignment> {
    if scan.positions.len() < 10 {
        return Err(Error::TooFewScanPoints { points: scan.positions.len() });
    }
    for (which, mesh) in [("scan", scan), ("target", target)] {
        if let Some(why) = degenerate(&mesh.positions) {
            return Err(Error::Degenerate { which, why });
        }
    }
    let target_vertices: Vec<Vector3<f64>> =
        target.positions.iter().map(|p| Vector3::from(p.map(|v| v as f64))).collect();
    let (tc, tr) = centroid_and_radius(&target_vertices);
    // Normalised frame: target centroid at the origin, target RMS radius 1.
    let normalize = Similarity { r: Matrix3::identity(), t: -tc / tr, s: 1.0 / tr };
    let tgt = target_from_mesh(target, options.target_samples, options.seed, &normalize)?;
    let mut rng = rmvp_dataset::rng::Rng::for_pixel(options.seed, 1, 0);
    let mut subsample = |n: usize| -> Vec<Vector3<f64>> {
        let take = n.min(scan.positions.len());
        (0..take)
            .map(|_| Vector3::from(scan.positions[rng.next_u32() as usize % scan.positions.len()].map(|v| v as f64)))
            .collect()
    };
    let fine_points = subsample(options.max_scan_points);
    let coarse_points = subsample(1_000);

    let start = if options.coarse {
        // Candidates: centroids and RMS radii matched, principal axes matched with every proper
        // sign flip, then each turned by the 24 rotations of the cube; scored by a short ICP.
        let (sc, sr) = centroid_and_radius(&fine_points);
        let (scan_axes, target_axes) = (principal_axes(&fine_points, &sc), principal_axes(&target_vertices, &tc));
        let flips = [[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]];
        let mut candidates = Vec::new();
        for flip in flips {
            let d = Matrix3::from_diagonal(&Vector3::from(flip));
            let r = target_axes * d * scan_axes.transpose();
            for turn in cube_rotations() {
                let r = turn * r;
                // scan -> normalised target frame: x -> (1/sr) r (x - sc)
                candidates.push(Similarity { r, t: -(r * sc) / sr, s: 1.0 / sr });
            }
        }
        let target_sample: Vec<Vector3<f64>> =
            (0..1_000).map(|k| Vector3::from(tgt.points[k * tgt.points.len() / 1_000].map(|v| v as f64))).collect();
        // Score every candidate as it stands, refine the best eight, keep the best of those.
        let score_all = |starts: &[Similarity], iterations: usize, radii: (f64, f64)| -> Vec<(Similarity, f64)> {
            let mut scored: Vec<(Similarity, f64)> = starts
                .par_iter()
                .map(|c| {
                    let (refined, _) = refine(&tgt, &coarse_points, (*c, 0.0), iterations, radii, RIGID);
                    (refined, symmetric_score(&tgt, &target_sample, &coarse_points, &refined))
                })
                .collect();
            scored.sort_by(|a, b| a.1.total_cmp(&b.1));
            scored
        };
        let first = score_all(&candidates, 0, (0.5, 0.3));
        let best: Vec<Similarity> = first.iter().take(8).map(|(s, _)| *s).collect();
        score_all(&best, 10, (0.3, 0.1))[0].0
    } else {
        normalize.compose(&options.initial)
    };
    // Coarse to fine: most iterations on a tenth of the points, the last third on all of them.
    let early = options.iterations * 2 / 3;
    let few = &fine_points[..fine_points.len().min(10_000)];
    let free = Free { scale: !options.fixed_scale, offset: options.fixed_scale && options.fit_offset };
    let fine = refine(&tgt, few, (start, 0.0), early, (0.2, 0.04), free);
    let (fine, offset) = refine(&tgt, &fine_points, fine, options.iterations - early, (0.04, 0.02), free);
    // Back to target units: scan -> normalised -> target.
    let transform = normalize.inverse().compose(&fine);
    // Statistics over all scan points, in target units; distances beyond half the target's
    // radius count as that much (the median needs no more).
    let final_radius = 0.02 * tr;
    let residuals: Vec<(f64, f64)> = scan
        .positions
        .par_iter()
        .map(|p| {
            let x = fine.apply(&Vector3::from(p.map(|v| v as f64)));
            match tgt.nearest_within(&x, 0.5) {
                Some((k, d2)) => {
                    let n = Vector3::from(tgt.normals[k].map(|v| v as f64));
                    let q = Vector3::from(tgt.points[k].map(|v| v as f64));
                    (d2.sqrt() * tr, (n.dot(&(x - q)) + offset) * tr)
                }
                None => (0.5 * tr, f64::INFINITY),
            }
        })
        .collect();
    let inliers: Vec<f64> = residuals.iter().filter(|(d, _)| *d <= final_radius).map(|(_, r)| *r).collect();
    let mut distances: Vec<f64> = residuals.iter().map(|(d, _)| *d).collect();
    let mid = distances.len() / 2;
    let median_distance = *distances.select_nth_unstable_by(mid, f64::total_cmp).1;
    Ok(Alignment {
        transform,
        rms: (inliers.iter().map(|r| r * r).sum::<f64>() / inliers.len().max(1) as f64).sqrt(),
        median_distance,
        inlier_ratio: inliers.len() as f64 / residuals.len() as f64,
        target_offset: offset * tr,
    })
}

/// The 24 rotations mapping the cube onto itself.
fn cube_rotations() -> Vec<Matrix3<f64>> {
    let axes: [Vector3<f64>; 6] =
        [Vector3::x(), Vector3::y(), Vector3::z(), -Vector3::x(), -Vector3::y(), -Vector3::z()];
    let mut out = Vec::with_capacity(24);
    for a in &axes {
        for b in &axes {
            if a.dot(b).abs() < 0.5 {
                out.push(Matrix3::from_columns(&[*a, *b, a.cross(b)]));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn similarity_algebra() {
        let a = Similarity {
            r: *Rotation3::new(Vector3::new(0.1, -0.4, 0.3)).matrix(),
            t: Vector3::new(1.0, 2.0, -3.0),
            s: 1.7,
        };
        let p = Vector3::new(0.3, -0.2, 0.9);
        assert!((a.inverse().apply(&a.apply(&p)) - p).norm() < 1e-12);
        assert!((a.compose(&a.inverse()).matrix() - Matrix4::identity()).norm() < 1e-12);
        let m = a.matrix();
        assert!(((m * p.push(1.0)).xyz() - a.apply(&p)).norm() < 1e-12);
        assert_eq!(cube_rotations().len(), 24);
        let text = serde_json::to_string(&a).unwrap();
        assert_eq!(serde_json::from_str::<Similarity>(&text).unwrap(), a);
        assert!(cube_rotations().iter().all(|r| (r.determinant() - 1.0).abs() < 1e-12));
    }
}
