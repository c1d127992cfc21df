//! From raw polarization-camera frames to Stokes images: pixel-format decoding ([`raw`]), the
//! sensor's polarizer/colour mosaic ([`mosaic`]), OpenCV demosaicing ([`demosaic`]), Stokes
//! estimation ([`stokes`]), corrections ([`correction`]), the whole per-frame chain
//! ([`pipeline`]) and, the other way round, a model of the sensor that turns rendered light
//! into raw frames ([`sensor`]).
//!
//! Target sensor: Sony IMX250MYR (FLIR Blackfly S BFS-U3-51S5PC-C), 2448x2048, each 2x2 cell of
//! polarizers `[90 45; 135 0]` under one colour of an RGGB Bayer pattern; and its mono sibling
//! IMX250MZR. Polarization conventions are those of [`rmvp_dataset::polarization`].

pub mod camera;
pub mod correction;
pub mod demosaic;
pub mod error;
pub mod mosaic;
pub mod pipeline;
pub mod preview;
pub mod raw;
pub mod sensor;
pub mod session;
pub mod simulator;
pub mod stokes;

pub use error::{Error, Result};
pub use pipeline::{FrameProcessor, ProcessedFrame};
pub use raw::{PixelFormat, RawFrame};

/// A progress bar on standard error (hidden when `show` is false).
pub fn progress_bar(show: bool, total: u64, what: &str) -> indicatif::ProgressBar {
    if !show {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(total);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{prefix:>10} [{bar:30}] {pos}/{len} {msg} ({elapsed}, eta {eta})")
            .expect("valid template")
            .progress_chars("=> "),
    );
    bar.set_prefix(what.to_string());
    bar
}
