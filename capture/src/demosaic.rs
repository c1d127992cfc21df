//! Colour demosaicing of the polarizer sub-mosaics with OpenCV `cvtColor`.
//!
//! A sub-mosaic is GenICam `BayerRG` (R at (0, 0)); OpenCV names Bayer patterns after the second
//! row and column, so its codes for this pattern are the `COLOR_BayerBG2*` family.

use crate::{Error, Result};
use opencv::core::{Mat, Vec3b, Vec3w};
use opencv::imgproc;
use opencv::prelude::*;
use rmvp_dataset::Image;

/// Demosaicing algorithm.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum DemosaicMethod {
    /// Bilinear interpolation (OpenCV's default, fastest).
    #[default]
    Bilinear,
    /// Edge-aware interpolation (`_EA`).
    EdgeAware,
    /// Variable number of gradients (`_VNG`); OpenCV supports it for 8-bit frames only.
    Vng,
}

impl DemosaicMethod {
    fn opencv_code(self) -> i32 {
        match self {
            Self::Bilinear => imgproc::COLOR_BayerBG2RGB,
            Self::EdgeAware => imgproc::COLOR_BayerBG2RGB_EA,
            Self::Vng => imgproc::COLOR_BayerBG2RGB_VNG,
        }
    }
}

/// Demosaic an RGGB sub-mosaic of `bits`-bit samples into an RGB image of the same size.
pub fn demosaic(mosaic: &Image<u16>, bits: u8, method: DemosaicMethod) -> Result<Image<u16>> {
    let mut rgb = Image::new(mosaic.width(), mosaic.height(), 3);
    demosaic_into(mosaic, bits, method, &mut rgb)?;
    Ok(rgb)
}

/// [`demosaic`] into an existing RGB image of the mosaic's size, without allocating.
pub fn demosaic_into(mosaic: &Image<u16>, bits: u8, method: DemosaicMethod, rgb: &mut Image<u16>) -> Result<()> {
    let (w, h) = mosaic.size();
    if rgb.size() != (w, h) || rgb.channels() != 3 || mosaic.channels() != 1 {
        return Err(Error::Unsupported("demosaic_into needs a one-channel mosaic and an RGB image of its size".into()));
    }
    let code = method.opencv_code();
    if method == DemosaicMethod::Vng {
        if bits > 8 {
            return Err(Error::Unsupported(format!(
                "VNG demosaicing needs 8-bit frames (OpenCV limit); this one has {bits} bits: use bilinear or edge-aware"
            )));
        }
        let bytes: Vec<u8> = mosaic.data().iter().map(|&v| v as u8).collect();
        let src = Mat::new_rows_cols_with_data(h as i32, w as i32, &bytes)?;
        let mut dst = Mat::default();
        imgproc::cvt_color_def(&src, &mut dst, code)?;
        let out = dst.data_typed::<Vec3b>()?;
        for (o, p) in rgb.data_mut().chunks_exact_mut(3).zip(out) {
            o.copy_from_slice(&p.0.map(u16::from));
        }
        return Ok(());
    }
    let src = Mat::new_rows_cols_with_data(h as i32, w as i32, mosaic.data())?;
    let samples = rgb.data_mut();
    let start = samples.as_mut_ptr();
    // SAFETY: `Vec3w` is `#[repr(C)]` around `[u16; 3]` (size 6, alignment 2), so `3 n` u16
    // samples are exactly `n` `Vec3w`s; the view lives only inside this function.
    let pixels: &mut [Vec3w] = unsafe { std::slice::from_raw_parts_mut(start.cast::<Vec3w>(), samples.len() / 3) };
    let mut dst = Mat::new_rows_cols_with_data_mut(h as i32, w as i32, pixels)?;
    imgproc::cvt_color_def(&src, &mut dst, code)?;
    if dst.data() != start.cast::<u8>().cast_const() {
        return Err(Error::Unsupported("OpenCV reallocated the demosaicing output".into()));
    }
    Ok(())
}
