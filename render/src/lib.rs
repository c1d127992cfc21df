//! Polarized rendering of triangle meshes under unpolarized environment light: the eyes of the
//! simulated camera, and the source of synthetic scenes with known answers.
//!
//! - [`bvh`]: ray casting; [`object`]: a mesh with shading attributes;
//! - [`pbrdf`]: the polarimetric BRDF (NeRSP/PANDORA, as Mitsuba 3's `pplastic`);
//! - [`envmap`]: lat-long environment light with importance sampling;
//! - [`rig`]: camera intrinsics of the lab rig and view layouts;
//! - [`renderer`]: per-view rendering of Stokes, masks, depth and normals.
//!
//! Conventions (cameras, Stokes frames, AoP) are those of [`rmvp_dataset`].

pub mod bvh;
pub mod envmap;
pub mod math;
pub mod object;
pub mod pbrdf;
pub mod renderer;
pub mod rig;
pub mod rng;
pub mod shapes;

pub use envmap::EnvMap;
pub use object::Object;
pub use renderer::{geometry_maps, render_view, GeometryMaps, RenderedView, Settings};

/// The built-in object: Keenan Crane's "spot" (public domain), inside the unit sphere, +Y up.
pub fn default_mesh() -> rmvp_dataset::Mesh {
    let bytes: &[u8] = include_bytes!("../assets/spot.ply");
    rmvp_dataset::mesh::ply::read_ply_bytes(bytes, std::path::Path::new("embedded spot.ply"))
        .expect("embedded mesh parses")
}
