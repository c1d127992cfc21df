//! The rmvp data model shared by every stage: cameras, views, Stokes images, masks, normals,
//! meshes and environment maps, with their file formats and the two scene layouts
//! (the official NeRSP loader's and our canonical, manifest-based one).
//!
//! Conventions (camera frames, Stokes and angle of polarization) are defined once, in
//! [`camera`] and [`polarization`], and documented in `docs/conventions.md`.

pub mod camera;
pub mod error;
pub mod image;
pub mod io;
pub mod layout;
pub mod mesh;
pub mod polarization;
pub mod scene;
pub mod visualize;

pub use camera::{Camera, Distortion, Ray};
pub use error::{Error, Result};
pub use image::Image;
pub use mesh::Mesh;
pub use scene::{PolarizerImages, Scene, Split, Stokes, View};
