//! From raw polarization-camera frames to Stokes images: pixel-format decoding ([`raw`]), the
//! sensor's polarizer/colour mosaic ([`mosaic`]), OpenCV demosaicing ([`demosaic`]), Stokes
//! estimation ([`stokes`]), corrections ([`correction`]), the whole per-frame chain
//! ([`pipeline`]) and, the other way round, a model of the sensor that turns rendered light
//! into raw frames ([`sensor`]).
//!
//! With the `acquisition` feature (default): GenICam cameras through aravis ([`camera`]), the
//! simulated camera ([`simulator`]), capture sessions ([`session`]; their files are read
//! through [`rmvp_dataset::session`], without this crate) and the live preview ([`preview`]).
//!
//! Target sensor: Sony IMX250MYR (FLIR Blackfly S BFS-U3-51S5PC-C), 2448x2048, each 2x2 cell of
//! polarizers `[90 135; 45 0]` in the image frame (the vendor's `[90 45; 135 0]`, counted
//! towards image up) under one colour of an RGGB Bayer pattern; and its mono sibling
//! IMX250MZR. Polarization conventions are those of [`rmvp_dataset::polarization`].

#![warn(missing_docs)]

#[cfg(feature = "acquisition")]
pub mod camera;
pub mod correction;
pub mod demosaic;
pub mod error;
#[cfg(feature = "acquisition")]
pub mod gigevision;
pub mod mosaic;
pub mod pipeline;
#[cfg(feature = "acquisition")]
pub mod preview;
pub mod raw;
pub mod sensor;
#[cfg(feature = "acquisition")]
pub mod session;
#[cfg(feature = "acquisition")]
pub mod simulator;
pub mod stokes;

pub use error::{Error, Result};
pub use pipeline::{FrameProcessor, ProcessedFrame};
pub use raw::{PixelFormat, RawFrame};
