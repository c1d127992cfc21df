//! Sensor corrections: dark-frame subtraction (raw counts) and a colour-correction matrix
//! (linear RGB; the pipeline applies it to the Stokes images, which commutes with the Stokes
//! estimation because both are linear).

use crate::{Error, RawFrame, Result};
use rmvp_dataset::Image;

/// Subtract a dark frame (the mean of frames taken with the lens capped), clamping at 0.
pub fn subtract_dark(frame: &mut RawFrame, dark: &RawFrame) -> Result<()> {
    if frame.pixels.size() != dark.pixels.size() || frame.bits != dark.bits {
        return Err(Error::Unsupported(format!(
            "dark frame is {}x{} at {} bits, the frame {}x{} at {} bits",
            dark.pixels.width(),
            dark.pixels.height(),
            dark.bits,
            frame.pixels.width(),
            frame.pixels.height(),
            frame.bits
        )));
    }
    for (v, d) in frame.pixels.data_mut().iter_mut().zip(dark.pixels.data()) {
        *v = v.saturating_sub(*d);
    }
    Ok(())
}

/// The per-pixel mean of several raw frames, rounded (for dark frames and K-frame averaging).
pub fn mean_frame(frames: &[RawFrame]) -> Result<RawFrame> {
    let first = frames.first().ok_or_else(|| Error::Unsupported("no frames to average".into()))?;
    let mut sum = vec![0u32; first.pixels.data().len()];
    for f in frames {
        if f.pixels.size() != first.pixels.size() {
            return Err(Error::Unsupported("frames to average differ in size".into()));
        }
        sum.iter_mut().zip(f.pixels.data()).for_each(|(s, &v)| *s += v as u32);
    }
    let n = frames.len() as u32;
    let data = sum.into_iter().map(|s| ((s + n / 2) / n) as u16).collect();
    let pixels = Image::from_vec(first.pixels.width(), first.pixels.height(), 1, data)?;
    Ok(RawFrame { pixels, ..first.clone() })
}

/// Apply a 3x3 colour-correction matrix (`out = M rgb`) to interleaved RGB samples in place.
pub fn apply_color_matrix(rgb_samples: &mut [f32], m: &[[f32; 3]; 3]) {
    for p in rgb_samples.chunks_exact_mut(3) {
        let rgb = [p[0], p[1], p[2]];
        for (out, row) in p.iter_mut().zip(m) {
            *out = row[0] * rgb[0] + row[1] * rgb[1] + row[2] * rgb[2];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mosaic::SensorLayout;

    fn frame(values: Vec<u16>) -> RawFrame {
        RawFrame { layout: SensorLayout::MonoPolarized, bits: 12, pixels: Image::from_vec(2, 1, 1, values).unwrap() }
    }

    #[test]
    fn dark_subtraction_clamps_at_zero() {
        let mut f = frame(vec![100, 5]);
        subtract_dark(&mut f, &frame(vec![10, 10])).unwrap();
        assert_eq!(f.pixels.data(), &[90, 0]);
    }

    #[test]
    fn averaging_rounds_to_nearest() {
        let m = mean_frame(&[frame(vec![1, 10]), frame(vec![2, 13])]).unwrap();
        assert_eq!(m.pixels.data(), &[2, 12]);
    }

    #[test]
    fn color_matrix_mixes_channels() {
        let mut samples = vec![1.0, 2.0, 3.0, 1.0, 0.0, 0.0];
        apply_color_matrix(&mut samples, &[[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.5, 0.0]]);
        assert_eq!(samples, vec![3.0, 2.0, 2.0, 0.0, 0.0, 1.0]);
    }
}
