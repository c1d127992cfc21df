//! Evaluation of reconstructions against ground truth: surface metrics (accuracy, completeness,
//! Chamfer distance, F-score) from exact point-to-triangle distances on area-uniform samples
//! ([`surface`]), the normal angular error in the views of a scene ([`normals`]) and where it
//! lies by DoP, roughness and depth complexity ([`breakdown`]), all as one record
//! ([`evaluation`]).
//!
//! Scans are aligned to reconstructions by a similarity (rotation, translation, scale) found by
//! a coarse multistart and point-to-plane ICP ([`icp`]). Points are drawn by [`sampling`].

#![warn(missing_docs)]

pub mod breakdown;
pub mod error;
pub mod evaluation;
pub mod icp;
pub mod normals;
pub mod sampling;
pub mod surface;

pub use error::{Error, Result};
pub use evaluation::{evaluate, Evaluation};
pub use icp::{align, align_files, Alignment, IcpOptions};
pub use normals::{normal_errors, NormalReport, ViewNormalError};
pub use rmvp_dataset::similarity::Similarity;
pub use surface::{surface_metrics, SurfaceMetrics, SurfaceOptions};
