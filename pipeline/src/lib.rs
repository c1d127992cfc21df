//! The stages of rmvp joined into whole jobs, each a function with an options struct whose
//! `Default` holds its defaults, and typed records for what it writes:
//!
//! - [`simulate`]: a synthetic polarized capture of a mesh (render, sensor frames, layouts);
//! - [`ground_truth`]: normal, mask and depth maps of a mesh in every view of a scene;
//! - [`build`]: datasets from posed, masked capture sessions (scan ground truth, environment
//!   map from a [`panorama`]); [`publish`]: releases of datasets; [`verify`]: their checks;
//! - [`export`]: datasets in nerfstudio's, COLMAP's and RMVP3D's layouts (and RMVP3D read);
//! - [`evaluation_set`]: the reconstruction evaluation set (shapes, materials, held-out views);
//! - [`batch`]: reconstructions and evaluations of datasets x variants x seeds, on this
//!   machine or as a Slurm job array, gathered into a table;
//! - [`demo`]: the built-in example end to end: simulate, process raw frames, build the
//!   dataset, compare with the truth, reconstruct, evaluate ([`demo::DemoReport`]).
//!
//! The command line (`rmvp`) only parses arguments, builds options, calls these and prints.

#![warn(missing_docs)]

pub mod batch;
pub mod build;
pub mod demo;
pub mod error;
pub mod evaluation_set;
pub mod export;
pub mod ground_truth;
pub mod panorama;
pub mod publish;
pub mod report;
pub mod simulate;
pub mod verify;

pub use error::{Error, Result};
