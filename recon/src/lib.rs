//! NeRSP reconstruction: an SDF trained by volume rendering of Stokes vectors through a
//! polarimetric BRDF plus the multi-view AoP tangent-space loss, mask and Eikonal losses.

pub mod engine;
pub mod model;
pub mod pbrdf;
pub mod volume;
