//! A summary of a scene folder (what `rmvp dataset info` shows): its layout, every view's
//! camera and contents, the ground truth, the provenance. Serialisable, for scripts.

use crate::layout::{read_scene, Layout};
use crate::{Result, Scene, Split, View};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// One view in a [`SceneSummary`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewSummary {
    /// Its name.
    pub name: String,
    /// Train or eval.
    pub split: Split,
    /// Image size.
    pub size: [u32; 2],
    /// Focal lengths in pixels.
    pub focal_px: [f64; 2],
    /// Camera centre in the world.
    pub center: [f64; 3],
    /// Share of mask pixels on the object, if it has a mask.
    pub mask_fraction: Option<f64>,
    /// What the view holds: `stokes`, `mask`, `aop`, `dop`, `polarizers`, `preview`, `normals`,
    /// `depth`.
    pub contents: Vec<String>,
}

/// The ground-truth mesh of a [`SceneSummary`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeshSummary {
    /// Vertices.
    pub vertices: usize,
    /// Triangles.
    pub triangles: usize,
    /// Axis-aligned bounds.
    pub bounds: Option<([f32; 3], [f32; 3])>,
}

/// A validated scene, summarised.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneSummary {
    /// Its layout's name.
    pub layout: String,
    /// Every view.
    pub views: Vec<ViewSummary>,
    /// Training views.
    pub train_views: usize,
    /// Unit sphere to world (`scale_mat`), row-major.
    pub normalization: [[f64; 4]; 4],
    /// The ground-truth mesh.
    pub mesh: Option<MeshSummary>,
    /// Size of the environment map.
    pub env_map: Option<[usize; 2]>,
    /// Provenance.
    pub metadata: serde_json::Map<String, serde_json::Value>,
}

fn contents(view: &View) -> Vec<String> {
    [
        (view.stokes.is_some(), "stokes"),
        (view.mask.is_some(), "mask"),
        (view.aop.is_some(), "aop"),
        (view.dop.is_some(), "dop"),
        (view.polarized.is_some(), "polarizers"),
        (view.preview.is_some(), "preview"),
        (view.normals.is_some(), "normals"),
        (view.depth.is_some(), "depth"),
    ]
    .into_iter()
    .filter(|(present, _)| *present)
    .map(|(_, name)| name.to_string())
    .collect()
}

impl SceneSummary {
    /// Read, validate and summarise the scene folder `dir` (either layout).
    pub fn of_folder(dir: &Path) -> Result<Self> {
        let layout = Layout::detect(dir)?;
        Ok(Self::of(&read_scene(dir)?, layout))
    }

    /// Summarise `scene`, stored in `layout`.
    pub fn of(scene: &Scene, layout: Layout) -> Self {
        let views = scene
            .views
            .iter()
            .map(|v| {
                let c = &v.camera;
                let centre = c.center();
                ViewSummary {
                    name: v.name.clone(),
                    split: v.split,
                    size: [c.width, c.height],
                    focal_px: [c.k[(0, 0)], c.k[(1, 1)]],
                    center: [centre.x, centre.y, centre.z],
                    mask_fraction: v
                        .mask
                        .as_ref()
                        .map(|m| m.data().iter().filter(|&&x| x > 127).count() as f64 / m.data().len() as f64),
                    contents: contents(v),
                }
            })
            .collect();
        Self {
            layout: layout.name().into(),
            views,
            train_views: scene.train_views().count(),
            normalization: [0, 1, 2, 3].map(|i| [0, 1, 2, 3].map(|j| scene.normalization[(i, j)])),
            mesh: scene.mesh.as_ref().map(|m| MeshSummary {
                vertices: m.positions.len(),
                triangles: m.faces.len(),
                bounds: m.bounds(),
            }),
            env_map: scene.env_map.as_ref().map(|e| [e.width(), e.height()]),
            metadata: scene.metadata.clone(),
        }
    }
}
