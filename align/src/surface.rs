//! Surface metrics between a predicted and a ground-truth mesh, DTU-style: accuracy (mean
//! distance from predicted-surface samples to the ground truth), completeness (the reverse),
//! Chamfer = their mean, and precision / recall / F-score at a distance threshold. Distances
//! are exact point-to-triangle distances (parry3d).

use crate::sampling::{sample_surface, surface_area};
use crate::{Error, Result};
use parry3d::math::Vector;
use parry3d::query::PointQuery;
use parry3d::shape::TriMesh;
use rayon::prelude::*;
use rmvp_dataset::Mesh;
use serde::{Deserialize, Serialize};

/// How the metrics are computed.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceOptions {
    /// Sample points per unit area of each surface (DTU: points per mm^2 for mm meshes).
    pub density: f64,
    /// At most this many samples per surface (the density is lowered to fit).
    pub max_samples: usize,
    /// Distances above this are capped in the means (DTU: 20 mm); `None` caps nothing.
    pub max_distance: Option<f64>,
    /// F-score threshold; `None`: 1 % of the ground truth's bounding-box diagonal.
    pub threshold: Option<f64>,
    /// Seed of the sampling.
    pub seed: u64,
}

impl Default for SurfaceOptions {
    fn default() -> Self {
        Self { density: f64::INFINITY, max_samples: 200_000, max_distance: None, threshold: None, seed: 0 }
    }
}

/// The metrics, in the meshes' units.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SurfaceMetrics {
    /// Mean distance from predicted samples to the ground truth.
    pub accuracy: f64,
    /// Mean distance from ground-truth samples to the prediction.
    pub completeness: f64,
    /// `(accuracy + completeness) / 2`.
    pub chamfer: f64,
    /// Share of predicted samples within `threshold` of the ground truth.
    pub precision: f64,
    /// Share of ground-truth samples within `threshold` of the prediction.
    pub recall: f64,
    /// Harmonic mean of precision and recall.
    pub fscore: f64,
    /// The F-score threshold used.
    pub threshold: f64,
    /// Samples on the predicted and the ground-truth surface.
    pub samples: [usize; 2],
}

/// Read a mesh to evaluate: one without triangles is refused naming its file.
pub fn read_surface(path: &std::path::Path) -> Result<Mesh> {
    let mesh = Mesh::read(path)?;
    if mesh.faces.is_empty() {
        return Err(rmvp_dataset::Error::format(path, "has no triangles: a surface is needed to evaluate").into());
    }
    Ok(mesh)
}

fn trimesh(mesh: &Mesh, which: &'static str) -> Result<TriMesh> {
    mesh.validate()?;
    let vertices = mesh.positions.iter().map(|p| Vector::new(p[0], p[1], p[2])).collect();
    TriMesh::new(vertices, mesh.faces.clone()).map_err(|e| {
        let message = match e {
            parry3d::shape::TriMeshBuilderError::EmptyIndices => "has no triangles".to_string(),
            other => format!("cannot be used for distance queries ({other:?})"),
        };
        Error::BadMesh { which, message }
    })
}

fn sample_count(mesh: &Mesh, options: &SurfaceOptions) -> usize {
    let wanted = surface_area(mesh) * options.density;
    if wanted.is_finite() {
        (wanted.ceil() as usize).clamp(1, options.max_samples)
    } else {
        options.max_samples
    }
}

/// The F-score threshold for the ground truth `gt` where none is given: 1 % of its bounding
/// box's diagonal (None for a mesh without vertices).
pub fn default_threshold(gt: &Mesh) -> Option<f64> {
    let (lo, hi) = gt.bounds()?;
    Some(0.01 * (0..3).map(|k| ((hi[k] - lo[k]) as f64).powi(2)).sum::<f64>().sqrt())
}

/// Distances from each point of `points` to the surface of `mesh` (the ground truth), e.g. to
/// colour a reconstruction's vertices by their error.
pub fn distances_to_surface(mesh: &Mesh, points: &[[f32; 3]]) -> Result<Vec<f64>> {
    Ok(distances(&trimesh(mesh, "ground-truth")?, points))
}

/// Distances from each point to the surface of `mesh`.
fn distances(mesh: &TriMesh, points: &[[f32; 3]]) -> Vec<f64> {
    points.par_iter().map(|p| mesh.distance_to_local_point(Vector::new(p[0], p[1], p[2]), true) as f64).collect()
}

/// Compare a predicted mesh with the ground truth.
pub fn surface_metrics(pred: &Mesh, gt: &Mesh, options: &SurfaceOptions) -> Result<SurfaceMetrics> {
    let (pred_shape, gt_shape) = (trimesh(pred, "predicted")?, trimesh(gt, "ground-truth")?);
    let threshold = match options.threshold {
        Some(t) => t,
        None => default_threshold(gt).ok_or(Error::NoSurfaceArea { which: "ground-truth" })?,
    };
    let pred_points = sample_surface(pred, sample_count(pred, options), options.seed);
    let gt_points = sample_surface(gt, sample_count(gt, options), options.seed.wrapping_add(1));
    if pred_points.is_empty() {
        return Err(Error::NoSurfaceArea { which: "predicted" });
    }
    if gt_points.is_empty() {
        return Err(Error::NoSurfaceArea { which: "ground-truth" });
    }
    let to_gt = distances(&gt_shape, &pred_points);
    let to_pred = distances(&pred_shape, &gt_points);
    let cap = |d: f64| options.max_distance.map_or(d, |m| d.min(m));
    let mean = |v: &[f64]| v.iter().map(|&d| cap(d)).sum::<f64>() / v.len() as f64;
    let within = |v: &[f64]| v.iter().filter(|&&d| d < threshold).count() as f64 / v.len() as f64;
    let (accuracy, completeness) = (mean(&to_gt), mean(&to_pred));
    let (precision, recall) = (within(&to_gt), within(&to_pred));
    let fscore = if precision + recall > 0.0 { 2.0 * precision * recall / (precision + recall) } else { 0.0 };
    Ok(SurfaceMetrics {
        accuracy,
        completeness,
        chamfer: 0.5 * (accuracy + completeness),
        precision,
        recall,
        fscore,
        threshold,
        samples: [pred_points.len(), gt_points.len()],
    })
}
