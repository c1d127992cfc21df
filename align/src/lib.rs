//! Evaluation of reconstructions against ground truth: surface metrics (accuracy, completeness,
//! Chamfer distance, F-score) from exact point-to-triangle distances on area-uniform samples
//! ([`surface`]), and the normal angular error in the views of a scene ([`normals`]).
//!
//! Alignment of laser scans (ICP with scale) is still to come (issue 4).

pub mod normals;
pub mod sampling;
pub mod surface;

pub use normals::{normal_errors, NormalReport, ViewNormalError};
pub use surface::{surface_metrics, SurfaceMetrics, SurfaceOptions};
