//! File formats, each through a well-kept crate, with errors that name the file.
//!
//! Every reader follows the rules of [`input`] (regular files only, paths inside their root,
//! declared sizes checked before allocating). Every writer here writes atomically (see [`atomic`]): a reader never sees half a file, and an
//! interrupted or failed write (a full disk, say) leaves any previous version intact.

pub mod atomic;
pub mod exr;
pub mod hdr;
pub mod input;
pub mod json;
pub mod npy;
pub mod picture;
pub mod png;

pub use atomic::{write_atomically, write_bytes_atomically};

use crate::{Error, Image, Result};
use std::path::Path;

/// A linear image from a file: PNG samples divided by their full scale (8 or 16 bits), EXR
/// channels `R G B` or its only channel.
pub fn read_linear(path: &Path) -> Result<Image<f32>> {
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
        let (_, _, channels) = exr::read_exr_channels(path)?;
        let names: Vec<&str> = channels.iter().map(|(n, _)| n.as_str()).collect();
        return if ["R", "G", "B"].iter().all(|c| names.contains(c)) {
            exr::read_exr(path, &["R", "G", "B"])
        } else if names.len() == 1 {
            exr::read_exr(path, &[names[0]])
        } else {
            Err(Error::format(path, format!("expected channels R, G, B or a single channel, found {names:?}")))
        };
    }
    Ok(match png::read_png(path)? {
        png::PngImage::U8(i) => i.map(|v| v as f32 / 255.0),
        png::PngImage::U16(i) => i.map(|v| v as f32 / 65535.0),
    })
}
