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
    /// Parse `bilinear`, `edge-aware` or `vng`.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "bilinear" => Ok(Self::Bilinear),
            "edge-aware" | "ea" => Ok(Self::EdgeAware),
            "vng" => Ok(Self::Vng),
            other => Err(Error::Unsupported(format!(
                "unknown demosaicing method {other:?} (bilinear, edge-aware, vng)"
            ))),
        }
    }

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
    let (w, h) = mosaic.size();
    let code = method.opencv_code();
    let mut dst = Mat::default();
    if method == DemosaicMethod::Vng {
        if bits > 8 {
            return Err(Error::Unsupported(format!("VNG demosaicing needs 8-bit frames (OpenCV limit); this one has {bits} bits: use bilinear or edge-aware")));
        }
        let bytes: Vec<u8> = mosaic.data().iter().map(|&v| v as u8).collect();
        let src = Mat::new_rows_cols_with_data(h as i32, w as i32, &bytes)?;
        imgproc::cvt_color_def(&src, &mut dst, code)?;
        let rgb: Vec<u16> = dst
            .data_typed::<Vec3b>()?
            .iter()
            .flat_map(|p| p.0.map(u16::from))
            .collect();
        return Ok(Image::from_vec(w, h, 3, rgb)?);
    }
    let src = Mat::new_rows_cols_with_data(h as i32, w as i32, mosaic.data())?;
    imgproc::cvt_color_def(&src, &mut dst, code)?;
    let rgb: Vec<u16> = dst
        .data_typed::<Vec3w>()?
        .iter()
        .flat_map(|p| p.0)
        .collect();
    Ok(Image::from_vec(w, h, 3, rgb)?)
}
