//! NeRSP reconstruction: an SDF trained by volume rendering of Stokes vectors through a
//! polarimetric BRDF plus the multi-view AoP tangent-space loss, mask and Eikonal losses.
//!
//! - [`engine`]: flat parameters, dense networks, hash grid, encodings, Adam (hand-written
//!   backward passes); [`model`]: presets, the SDF field and the radiance networks;
//!   [`pbrdf`]: Fresnel degrees of polarization and azimuths;
//! - [`samples`]: the field at sample points (finite-difference normals and Laplacians);
//!   [`volume`]: NeuS sampling, shading and compositing (and its forward-only twin);
//!   [`trace`]: sphere tracing of the SDF; [`geometric`]: the AoP tangent-space loss with
//!   visibility; [`losses`]: the loss terms by name;
//! - [`data`]: the training set in the unit sphere; [`train`]: steps and checkpoints;
//! - [`extract`]: marching tetrahedra (the SDF on the CPU or, with the `cuda` feature, by
//!   the kernels of `cuda` on a GPU); [`output`]: normal maps and re-rendered Stokes where
//!   the surface is (forward only); [`residuals`]: the model's Stokes against its input;
//!   [`reconstruct`]: a whole run in a folder.

#![warn(missing_docs)]
// Numeric kernels index several arrays with one counter; iterators would hide the formulas.
#![allow(clippy::needless_range_loop)]

#[cfg(feature = "cuda")]
pub mod cuda;
pub mod data;
pub mod engine;
pub mod error;
pub mod extract;
pub mod geometric;
pub mod losses;
pub mod model;
pub mod options;
pub mod output;
pub mod pbrdf;
pub mod presets;
pub mod reconstruct;
pub mod residuals;
pub mod samples;
pub mod trace;
pub mod train;
pub mod volume;

pub use error::{Error, Result};
