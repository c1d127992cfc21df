//! Polarized rendering of triangle meshes under unpolarized environment light: the eyes of the
//! simulated camera, and the source of synthetic scenes with known answers.
//!
//! - [`bvh`]: ray casting; [`object`]: a mesh with shading attributes;
//! - [`pbrdf`]: the polarimetric BRDF (NeRSP/PANDORA, as Mitsuba 3's `pplastic`);
//! - [`envmap`]: lat-long environment light with importance sampling;
//! - [`rig`]: camera intrinsics of the lab rig and view layouts;
//! - [`renderer`]: per-view rendering of Stokes, masks, depth and normals;
//! - [`shapes`]: meshes with analytic answers; [`math`]: the `f32` vectors of the hot loops.
//!
//! Conventions (cameras, Stokes frames, AoP) are those of [`rmvp_dataset`].

#![warn(missing_docs)]

pub mod bvh;
pub mod envmap;
pub mod error;
pub mod math;
pub mod object;
pub mod pbrdf;
pub mod renderer;
pub mod rig;
pub mod shapes;

pub use envmap::EnvMap;
pub use error::{Error, Result};
pub use object::{Object, Part};
pub use renderer::{geometry_maps, render_view, GeometryMaps, RenderedView, Settings};

/// The built-in object: Keenan Crane's "spot" (public domain), inside the unit sphere, +Y up.
pub fn default_mesh() -> rmvp_dataset::Mesh {
    let bytes: &[u8] = include_bytes!("../assets/spot.ply");
    rmvp_dataset::mesh::ply::read_ply_bytes(bytes, std::path::Path::new("embedded spot.ply"))
        .expect("embedded mesh parses")
}
