//! Evaluation of reconstructions against ground truth: surface metrics (accuracy, completeness,
//! Chamfer distance, F-score) from exact point-to-triangle distances on area-uniform samples
//! ([`surface`]), and the normal angular error in the views of a scene ([`normals`]).
//!
//! Scans are aligned to reconstructions by a similarity (rotation, translation, scale) found by
//! a coarse multistart and point-to-plane ICP ([`icp`]).

pub mod icp;
pub mod normals;
pub mod sampling;
pub mod surface;

pub use icp::{align, Alignment, IcpOptions, Similarity};
pub use normals::{normal_errors, NormalReport, ViewNormalError};
pub use surface::{surface_metrics, SurfaceMetrics, SurfaceOptions};
