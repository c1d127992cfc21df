//! From a capture session to posed, masked views (OpenCV 4.6 `aruco` and `calib3d`, COLMAP):
//!
//! - [`board`]: ChArUco and chessboard boards: description, picture, corner detection, and the
//!   board frame (rmvp's world frame when a board gives the poses);
//! - [`intrinsics`]: camera calibration from images of a board (`camera.json`);
//! - [`poses`]: every view's camera: ChArUco board, COLMAP, turntable, imported;
//! - [`masks`]: object masks (threshold, background difference, GrabCut, mesh, hand-made);
//! - [`normalization`]: the unit sphere from the visual hull; [`scene`]: posed, masked views
//!   as a scene; [`undistort`]: views resampled onto the distortion-free camera;
//! - [`pictures`]: what detectors look at (a session's S0, image files);
//! - [`lab`]: the simulated lab (subject on a board on a table; calibration views).

#![warn(missing_docs)]

pub mod board;
pub mod error;
pub mod intrinsics;
pub mod lab;
pub mod masks;
pub mod normalization;
pub mod pictures;
pub mod poses;
pub mod scene;
pub mod undistort;

pub use error::{Error, Result};
