//! The per-frame chain: dark subtraction, split, demosaic, Stokes, colour correction, AoP, DoP;
//! and the files a processed frame is saved as.

use crate::correction::{correct_colors, subtract_dark};
use crate::demosaic::{demosaic, DemosaicMethod};
use crate::mosaic::{split, SensorLayout};
use crate::stokes::StokesEstimator;
use crate::{RawFrame, Result};
use rayon::prelude::*;
use rmvp_dataset::io::{exr, png};
use rmvp_dataset::layout::canonical::write_stokes;
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

/// Everything computed from one raw frame.
#[derive(Clone, Debug)]
pub struct ProcessedFrame {
    /// Significant bits of the raw samples.
    pub bits: u8,
    /// Demosaiced images behind the polarizers at 0, 45, 90, 135 degrees, raw counts.
    pub angles: [Image<u16>; 4],
    /// Stokes images in units of full scale.
    pub stokes: Stokes,
    /// AoP of the channel-mean Stokes vector, radians in `[0, pi)`.
    pub aop: Image<f32>,
    /// DoP of the channel-mean Stokes vector.
    pub dop: Image<f32>,
    /// Saturated angles per pixel (0 to 4).
    pub saturated: Image<u8>,
}

impl FrameProcessor {
    /// Process one raw frame.
    pub fn process(&self, raw: &RawFrame) -> Result<ProcessedFrame> {
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
        let subs = split(raw);
        let angles: [Image<u16>; 4] = match raw.layout {
            SensorLayout::ColorPolarized => {
                let [a, b, c, d] = subs.map(|sub| demosaic(&sub, raw.bits, self.method));
                [a?, b?, c?, d?]
            }
            SensorLayout::MonoPolarized => subs,
        };
        let full_scale = raw.full_scale();
        let estimator = StokesEstimator::new(self.saturation_aware.then_some(full_scale));
        let estimate = estimator.estimate(&angles, full_scale);
        let mut stokes = estimate.stokes;
        if let Some(m) = &self.color_correction {
            correct_colors(&mut stokes, m)?;
        }
        let (aop, dop) = aop_dop(&stokes);
        Ok(ProcessedFrame {
            bits: raw.bits,
            angles,
            stokes,
            aop,
            dop,
            saturated: estimate.saturated,
        })
    }
}

/// AoP and DoP of the channel-mean Stokes vector, in one parallel pass.
pub fn aop_dop(stokes: &Stokes) -> (Image<f32>, Image<f32>) {
    let (w, h, c) = (stokes.s0.width(), stokes.s0.height(), stokes.s0.channels());
    let mut aop = Image::new(w, h, 1);
    let mut dop = Image::new(w, h, 1);
    let scale = 1.0 / c as f32;
    aop.data_mut()
        .par_chunks_mut(w)
        .zip(dop.data_mut().par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, (a_row, d_row))| {
            let range = y * w * c..(y + 1) * w * c;
            let (s0, s1, s2) = (
                &stokes.s0.data()[range.clone()],
                &stokes.s1.data()[range.clone()],
                &stokes.s2.data()[range],
            );
            for x in 0..w {
                let mean = |s: &[f32]| s[x * c..(x + 1) * c].iter().sum::<f32>() * scale;
                let (m0, m1, m2) = (mean(s0), mean(s1), mean(s2));
                a_row[x] = polarization::aop(m1, m2);
                d_row[x] = polarization::dop(m0, m1, m2);
            }
        });
    (aop, dop)
}

impl ProcessedFrame {
    /// Save as `DIR/STEM_000.png ... _135.png` (16-bit, linear, full scale = 65535) and the
    /// polarization products of [`write_polarization`]. Returns the files written.
    pub fn write(&self, dir: &Path, stem: &str) -> Result<Vec<PathBuf>> {
        let mut written = Vec::new();
        let full_scale = ((1u32 << self.bits) - 1) as f32;
        for (image, deg) in self.angles.iter().zip(POLARIZER_ANGLES_DEG) {
            let path = dir.join(format!("{stem}_{deg:03}.png"));
            png::write_png_u16(
                &path,
                &image.map(|v| (v as f32 * 65535.0 / full_scale).round() as u16),
            )?;
            written.push(path);
        }
        written.extend(write_polarization(
            dir,
            stem,
            &self.stokes,
            &self.aop,
            &self.dop,
        )?);
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
    let outputs: [(&str, &dyn Fn(&Path) -> rmvp_dataset::Result<()>); 6] = [
        ("stokes.exr", &|p| write_stokes(p, stokes)),
        ("aop.exr", &|p| exr::write_exr(p, aop, &["AoP"])),
        ("dop.exr", &|p| exr::write_exr(p, dop, &["DoP"])),
        ("aop.png", &|p| png::write_png_u8(p, &aop_picture(aop, dop))),
        ("dop.png", &|p| {
            png::write_png_u8(p, &visualize::gray_ramp(dop, 0.0, 1.0))
        }),
        ("s0.png", &|p| {
            png::write_png_u8(p, &visualize::preview(&stokes.s0))
        }),
    ];
    let mut written = Vec::new();
    for (suffix, write) in outputs {
        let path = dir.join(format!("{stem}_{suffix}"));
        write(&path)?;
        written.push(path);
    }
    Ok(written)
}

/// The AoP hue wheel, brightness by DoP (full at the image's 99th DoP percentile).
pub fn aop_picture(aop: &Image<f32>, dop: &Image<f32>) -> Image<u8> {
    let full = visualize::quantile(dop.data(), 0.99).clamp(1e-3, 1.0);
    visualize::aop_picture(aop, dop, full, None)
}
