//! A whole evaluation of a predicted mesh: surface metrics against the ground-truth mesh and,
//! with a scene, the normal angular error in each of its ground-truth views, stored as one
//! record (`rmvp eval --json`, batch results; the demo's report keeps its summary figures) with
//! per-view error maps and the error binned by what may cause it ([`crate::breakdown`]).

use crate::breakdown::{error_breakdown, ErrorBreakdown};
use crate::normals::{normal_errors, split_mean_deg, ViewNormalError};
use crate::surface::{surface_metrics, SurfaceMetrics, SurfaceOptions};
use crate::Result;
use rmvp_dataset::io::json::{read_json, write_json};
use rmvp_dataset::io::png;
use rmvp_dataset::visualize::gray_ramp;
use rmvp_dataset::{Mesh, Scene, Split};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Normal errors above this many degrees are white in the error maps.
pub const ERROR_MAP_MAX_DEG: f32 = 30.0;

/// The figures of one evaluation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "EvaluationRecord")]
pub struct Evaluation {
    /// Accuracy, completeness, Chamfer, F-score.
    #[serde(flatten)]
    pub surface: SurfaceMetrics,
    /// Mean of the per-view normal errors (degrees), when a scene was given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normal_mae_deg: Option<f64>,
    /// Per view, in scene order (views without ground-truth normals are skipped).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub normal_views: Vec<ViewNormalError>,
    /// The normal error by the input's DoP, the true roughness and the depth complexity, when
    /// a scene was given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub breakdown: Option<ErrorBreakdown>,
}

/// [`Evaluation`] as written, the surface metrics' fields at the top level: read field by
/// field (a flattened field would keep every unknown field of the file as a tree).
#[derive(Deserialize)]
struct EvaluationRecord {
    accuracy: f64,
    completeness: f64,
    chamfer: f64,
    precision: f64,
    recall: f64,
    fscore: f64,
    threshold: f64,
    samples: [usize; 2],
    #[serde(default)]
    normal_mae_deg: Option<f64>,
    #[serde(default)]
    normal_views: Vec<ViewNormalError>,
    #[serde(default)]
    breakdown: Option<ErrorBreakdown>,
}

impl From<EvaluationRecord> for Evaluation {
    fn from(r: EvaluationRecord) -> Self {
        let EvaluationRecord { accuracy, completeness, chamfer, precision, recall, fscore, threshold, samples, .. } = r;
        Evaluation {
            surface: SurfaceMetrics { accuracy, completeness, chamfer, precision, recall, fscore, threshold, samples },
            normal_mae_deg: r.normal_mae_deg,
            normal_views: r.normal_views,
            breakdown: r.breakdown,
        }
    }
}

/// Compare `pred` with `gt` and, when `scene` is given, with its ground-truth normal maps.
pub fn evaluate(pred: &Mesh, gt: &Mesh, scene: Option<&Scene>, options: &SurfaceOptions) -> Result<Evaluation> {
    let surface = surface_metrics(pred, gt, options)?;
    let normals = scene.map(|scene| normal_errors(pred, scene)).transpose()?;
    let breakdown = match (&normals, scene) {
        (Some(normals), Some(scene)) => Some(error_breakdown(&normals.views, scene, gt)?),
        _ => None,
    };
    Ok(Evaluation {
        surface,
        normal_mae_deg: normals.as_ref().map(|n| n.mean_mae_deg),
        normal_views: normals.map(|n| n.views).unwrap_or_default(),
        breakdown,
    })
}

impl Evaluation {
    /// The mean normal error over the views of `split` (training or held out), degrees.
    pub fn split_normal_mae_deg(&self, split: Split) -> Option<f64> {
        split_mean_deg(&self.normal_views, split)
    }

    /// Write each view's normal error map, `DIR/<view>_normal_error.png` (black 0 to white
    /// [`ERROR_MAP_MAX_DEG`]); returns the files.
    pub fn write_error_maps(&self, dir: &Path) -> Result<Vec<PathBuf>> {
        let mut files = Vec::new();
        for v in &self.normal_views {
            let path = dir.join(format!("{}_normal_error.png", v.view));
            let map = v.error_map.map(|e| if e.is_nan() { 0.0 } else { e });
            png::write_png_u8(&path, &gray_ramp(&map, 0.0, ERROR_MAP_MAX_DEG))?;
            files.push(path);
        }
        Ok(files)
    }

    /// Read a record written by [`Evaluation::write`] (error maps are not part of it).
    pub fn read(path: &Path) -> Result<Self> {
        Ok(read_json(path, "an evaluation")?)
    }

    /// Write the record to `path` (JSON, atomically).
    pub fn write(&self, path: &Path) -> Result<()> {
        Ok(write_json(path, self)?)
    }

    /// The record as pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("plain data")
    }
}
