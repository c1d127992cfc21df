//! NeRSP reconstruction: an SDF trained by volume rendering of Stokes vectors through a
//! polarimetric BRDF plus the multi-view AoP tangent-space loss, mask and Eikonal losses.
//!
//! The modules form layers that import only downwards (`tests/layers.rs` keeps the order):
//!
//! - [`engine`]: flat parameters, dense networks, hash grid, encodings, Adam (hand-written
//!   backward passes), vector helpers; [`pbrdf`]: Fresnel degrees of polarization and azimuths;
//! - [`model`]: the SDF field, the radiance networks and the specular tilt; [`occupancy`]: the
//!   SDF on a coarse grid, where sampling skips empty space;
//! - rendering: [`ray`], [`samples`] (the field at sample points), [`volume`] (NeuS sampling,
//!   shading and compositing), [`trace`] (sphere tracing of the SDF);
//! - [`data`]: the training set in the unit sphere; [`geometric`]: the AoP tangent-space loss
//!   with visibility; [`losses`]: the loss terms by name;
//! - [`config`]: a run's definition; [`step`]: a step's gradient behind [`step::StepCompute`];
//!   [`train`]: the loop; [`presets`]: the presets' settings;
//! - [`extract`]: marching tetrahedra (the SDF on the CPU or, with the `cuda` feature, by the
//!   kernels of `cuda` on a GPU); [`unseen`]: the mesh's parts that no training view sees;
//!   [`options`]: `rmvp recon`'s options; [`checkpoint`]: save and
//!   resume bit for bit; [`output`]: normal maps and re-rendered Stokes where the surface is;
//!   [`residuals`]: the model's Stokes against its input; [`tracking`]: the normal error against
//!   a ground truth while training; [`reconstruct`]: a whole run in a folder.

#![warn(missing_docs)]
// Numeric kernels index several arrays with one counter; iterators would hide the formulas.
#![allow(clippy::needless_range_loop)]

pub mod checkpoint;
pub mod config;
#[cfg(feature = "cuda")]
pub mod cuda;
pub mod data;
pub mod engine;
pub mod error;
pub mod extract;
pub mod geometric;
pub mod losses;
pub mod model;
pub mod occupancy;
pub mod options;
pub mod output;
pub mod pbrdf;
pub mod presets;
pub mod ray;
pub mod reconstruct;
pub mod residuals;
pub mod samples;
pub mod step;
pub mod trace;
pub mod tracking;
pub mod train;
pub mod unseen;
pub mod volume;

pub use error::{Error, Result};
