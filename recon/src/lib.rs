//! NeRSP reconstruction: an SDF trained by volume rendering of Stokes vectors through a
//! polarimetric BRDF plus the multi-view AoP tangent-space loss, mask and Eikonal losses.

// Numeric kernels index several arrays with one counter; iterators would hide the formulas.
#![allow(clippy::needless_range_loop)]

pub mod data;
pub mod engine;
pub mod extract;
pub mod geometric;
pub mod losses;
pub mod model;
pub mod output;
pub mod pbrdf;
pub mod reconstruct;
pub mod train;
pub mod volume;
