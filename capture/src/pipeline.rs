//! The per-frame chain: dark subtraction, split, demosaic, Stokes, colour correction, AoP, DoP;
//! and the files a processed frame is saved as.

use crate::correction::{apply_color_matrix, subtract_dark};
use crate::demosaic::{demosaic_into, DemosaicMethod};
use crate::mosaic::{split_into, SensorLayout};
use crate::stokes::{StokesEstimate, StokesEstimator};
use crate::{Error, RawFrame, Result};
use rayon::prelude::*;
use rmvp_dataset::io::{exr, png};
use rmvp_dataset::layout::rmvp::write_stokes;
use rmvp_dataset::polarization::{self, POLARIZER_ANGLES_DEG};
use rmvp_dataset::{visualize, Image, Stokes};
use std::path::{Path, PathBuf};

/// How frames are processed.
#[derive(Clone, Debug, Default)]
pub struct FrameProcessor {
    /// Colour demosaicing algorithm.
    pub method: DemosaicMethod,
    /// Drop saturated angles from the Stokes estimate.
    pub saturation_aware: bool,
    /// Dark frame subtracted from every raw frame.
    pub dark: Option<RawFrame>,
    /// Colour-correction matrix applied to the Stokes images.
    pub color_correction: Option<[[f32; 3]; 3]>,
}

/// Everything computed from one raw frame. Reuse one with [`FrameProcessor::process_into`] to
/// process a stream without allocating per frame.
#[derive(Clone, Debug, Default)]
pub struct ProcessedFrame {
    /// Significant bits of the raw samples.
    pub bits: u8,
    /// The four polarizer sub-mosaics (0, 45, 90, 135 degrees) before demosaicing, raw counts.
    pub mosaics: [Image<u16>; 4],
    /// Demosaiced images behind the polarizers (for the mono sensor, the sub-mosaics), raw counts.
    pub angles: [Image<u16>; 4],
    /// Stokes images in units of full scale, and saturated angles per pixel (0 to 4).
    pub estimate: StokesEstimate,
    /// AoP of the channel-mean Stokes vector, radians in `[0, pi)`.
    pub aop: Image<f32>,
    /// DoP of the channel-mean Stokes vector.
    pub dop: Image<f32>,
}

impl FrameProcessor {
    /// Process one raw frame.
    pub fn process(&self, raw: &RawFrame) -> Result<ProcessedFrame> {
        let mut out = ProcessedFrame::default();
        self.process_into(raw, &mut out)?;
        Ok(out)
    }

    /// Process one raw frame into `out`, reusing its buffers.
    pub fn process_into(&self, raw: &RawFrame, out: &mut ProcessedFrame) -> Result<()> {
        let corrected;
        let raw = match &self.dark {
            Some(dark) => {
                let mut frame = raw.clone();
                subtract_dark(&mut frame, dark)?;
                corrected = frame;
                &corrected
            }
            None => raw,
        };
        out.bits = raw.bits;
        split_into(raw, &mut out.mosaics);
        let (w, h) = out.mosaics[0].size();
        for (sub, angle) in out.mosaics.iter().zip(&mut out.angles) {
            match raw.layout {
                SensorLayout::ColorPolarized => {
                    angle.ensure_shape(w, h, 3);
                    demosaic_into(sub, raw.bits, self.method, angle)?;
                }
                SensorLayout::MonoPolarized => angle.clone_from(sub),
            }
        }
        let full_scale = raw.full_scale();
        let estimator = StokesEstimator::new(full_scale, self.saturation_aware);
        if self.color_correction.is_some() && raw.layout == SensorLayout::MonoPolarized {
            return Err(Error::Unsupported("a colour-correction matrix needs RGB frames".into()));
        }
        // One pass over rows: Stokes, colour correction, AoP and DoP while the row is in cache.
        let c = out.angles[0].channels();
        let row = w * c;
        let gain = 1.0 / full_scale as f32;
        let Stokes { s0, s1, s2 } = &mut out.estimate.stokes;
        for image in [&mut *s0, &mut *s1, &mut *s2] {
            image.ensure_shape(w, h, c);
        }
        for image in [&mut out.aop, &mut out.dop] {
            image.ensure_shape(w, h, 1);
        }
        out.estimate.saturated.ensure_shape(w, h, 1);
        let angles = &out.angles;
        s0.data_mut()
            .par_chunks_mut(row)
            .zip(s1.data_mut().par_chunks_mut(row))
            .zip(s2.data_mut().par_chunks_mut(row))
            .zip(out.estimate.saturated.data_mut().par_chunks_mut(w))
            .zip(out.aop.data_mut().par_chunks_mut(w))
            .zip(out.dop.data_mut().par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, (((((r0, r1), r2), sat), a_row), d_row))| {
                let inputs = angles.each_ref().map(|a| &a.data()[y * row..(y + 1) * row]);
                estimator.estimate_row(inputs, gain, [&mut *r0, &mut *r1, &mut *r2], sat);
                if let Some(m) = &self.color_correction {
                    for r in [&mut *r0, &mut *r1, &mut *r2] {
                        apply_color_matrix(r, m);
                    }
                }
                polarization::aop_dop_row([r0, r1, r2], c, a_row, d_row);
            });
        Ok(())
    }
}

impl ProcessedFrame {
    /// Save as `DIR/STEM_000.png ... _135.png` (16-bit, linear, full scale = 65535) and the
    /// polarization products of [`write_polarization`]. Returns the files written.
    pub fn write(&self, dir: &Path, stem: &str) -> Result<Vec<PathBuf>> {
        let mut written = Vec::new();
        let full_scale = ((1u32 << self.bits) - 1) as f32;
        for (image, deg) in self.angles.iter().zip(POLARIZER_ANGLES_DEG) {
            let path = dir.join(format!("{stem}_{deg:03}.png"));
            png::write_png_u16(&path, &image.map(|v| (v as f32 * 65535.0 / full_scale).round() as u16))?;
            written.push(path);
        }
        written.extend(write_polarization(dir, stem, &self.estimate.stokes, &self.aop, &self.dop)?);
        Ok(written)
    }
}

/// Save Stokes, AoP and DoP as `DIR/STEM_stokes.exr`, `STEM_aop.exr`, `STEM_dop.exr`, and the
/// pictures `STEM_aop.png` (hue wheel weighted by DoP), `STEM_dop.png` (grey ramp 0 to 1) and
/// `STEM_s0.png` (preview). Returns the files written.
pub fn write_polarization(
    dir: &Path,
    stem: &str,
    stokes: &Stokes,
    aop: &Image<f32>,
    dop: &Image<f32>,
) -> Result<Vec<PathBuf>> {
    type Writer<'a> = &'a dyn Fn(&Path) -> rmvp_dataset::Result<()>;
    let outputs: [(&str, Writer); 6] = [
        ("stokes.exr", &|p| write_stokes(p, stokes)),
        ("aop.exr", &|p| exr::write_exr(p, aop, &["AoP"])),
        ("dop.exr", &|p| exr::write_exr(p, dop, &["DoP"])),
        ("aop.png", &|p| png::write_png_u8(p, &visualize::aop_picture(aop, dop, None))),
        ("dop.png", &|p| png::write_png_u8(p, &visualize::gray_ramp(dop, 0.0, 1.0))),
        ("s0.png", &|p| png::write_png_u8(p, &visualize::preview(&stokes.s0))),
    ];
    let mut written = Vec::new();
    for (suffix, write) in outputs {
        let path = dir.join(format!("{stem}_{suffix}"));
        write(&path)?;
        written.push(path);
    }
    Ok(written)
}
