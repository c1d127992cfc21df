//! Normal angular error of a predicted mesh in the views of a scene: its normal maps are ray
//! cast as the ground truth's are (each pixel its footprint's mean normal,
//! [`rmvp_render::GeometryMaps::normals`]) and compared with the scene's ground-truth normal maps
//! over the pixels where both the ground-truth mask and the prediction's centre ray cover the
//! object.

use crate::{Error, Result};
use rayon::prelude::*;
use rmvp_dataset::{Image, Mesh, Scene, Split};
use rmvp_render::{geometry_maps, Object};
use serde::{Deserialize, Serialize};

/// The error in one view.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewNormalError {
    /// View name.
    pub view: String,
    /// Whether the view was a training view or held out.
    pub split: Split,
    /// Mean angle between predicted and ground-truth normals, degrees.
    pub mae_deg: f64,
    /// Pixels compared.
    pub pixels: usize,
    /// Per-pixel error in degrees (`NaN` where not compared).
    #[serde(skip)]
    pub error_map: Image<f32>,
}

/// The error over a scene's views.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NormalReport {
    /// Per view, in scene order (views without ground-truth normals are skipped).
    pub views: Vec<ViewNormalError>,
    /// Mean of the per-view errors, degrees.
    pub mean_mae_deg: f64,
}

/// Ray cast `pred` in every view of `scene` that has ground-truth normals and compare.
pub fn normal_errors(pred: &Mesh, scene: &Scene) -> Result<NormalReport> {
    let object = Object::geometry(pred)?;
    let views: Vec<ViewNormalError> = scene
        .views
        .par_iter()
        .filter(|v| v.normals.is_some())
        .map(|view| {
            let gt = view.normals.as_ref().expect("filtered");
            let ours = geometry_maps(&object, &view.camera);
            let (w, h) = gt.size();
            let mut error_map = Image::from_vec(w, h, 1, vec![f32::NAN; w * h])?;
            let (mut sum, mut pixels) = (0.0f64, 0usize);
            for k in 0..w * h {
                let in_gt = view.mask.as_ref().is_none_or(|m| m.data()[k] > 127);
                let (a, b) = (&ours.normals.data()[3 * k..3 * k + 3], &gt.data()[3 * k..3 * k + 3]);
                let gt_len = (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt();
                if !in_gt || ours.mask.data()[k] == 0 || gt_len < 0.5 {
                    continue;
                }
                let cos = ((a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / gt_len).clamp(-1.0, 1.0) as f64;
                let angle = cos.acos().to_degrees();
                error_map.data_mut()[k] = angle as f32;
                sum += angle;
                pixels += 1;
            }
            if pixels == 0 {
                return Err(Error::NoCoverage { view: view.name.clone() });
            }
            Ok(ViewNormalError {
                view: view.name.clone(),
                split: view.split,
                mae_deg: sum / pixels as f64,
                pixels,
                error_map,
            })
        })
        .collect::<Result<_>>()?;
    if views.is_empty() {
        return Err(Error::NoGroundTruthNormals);
    }
    let mean_mae_deg = views.iter().map(|v| v.mae_deg).sum::<f64>() / views.len() as f64;
    Ok(NormalReport { views, mean_mae_deg })
}

/// The mean of the errors of the views of `split` among `views`; `None` when it has none.
pub fn split_mean_deg(views: &[ViewNormalError], split: Split) -> Option<f64> {
    let of_split: Vec<f64> = views.iter().filter(|v| v.split == split).map(|v| v.mae_deg).collect();
    (!of_split.is_empty()).then(|| of_split.iter().sum::<f64>() / of_split.len() as f64)
}
