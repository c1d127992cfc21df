//! The rmvp data model shared by every stage: cameras, views, Stokes images, masks, normals,
//! meshes and environment maps, with their file formats and the two scene layouts
//! (the official NeRSP loader's and ours, manifest-based), and capture sessions on disk.
//!
//! - [`camera`]: OpenCV pinhole cameras; [`polarization`]: Stokes, AoP, DoP (the conventions,
//!   defined once and documented in `docs/conventions.md`);
//! - [`image`], [`mesh`], [`io`]: images, meshes and file formats (atomic writes);
//! - [`exchange`]: COLMAP models and nerfstudio transforms;
//! - [`scene`]: views and ground truth; [`layout`]: scene folders; [`summary`]: what a scene
//!   holds; [`session`]: capture sessions (`session.json`);
//! - [`visualize`]: pictures for people; [`progress`]: progress bars; [`rng`]: deterministic
//!   random streams shared by every stage.

#![warn(missing_docs)]

pub mod camera;
pub mod checksums;
pub mod error;
pub mod exchange;
pub mod handedness;
pub mod image;
pub mod io;
pub mod layout;
pub mod mesh;
pub mod polarization;
pub mod progress;
pub mod rng;
pub mod scene;
pub mod session;
pub mod similarity;
pub mod summary;
pub mod visualize;

pub use camera::{Camera, Distortion, Ray};
pub use error::{Error, Result};
pub use image::Image;
pub use mesh::Mesh;
pub use scene::{PolarizerImages, Scene, Split, Stokes, View};
