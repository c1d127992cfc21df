//! HDR bracketing: raw frames of one view at several exposure times merged into one linear
//! frame, per sensor pixel, before demosaicing (so every polarizer angle is merged on its own).

use crate::{Error, RawFrame, Result};
use rmvp_dataset::Image;

/// A sample at or above this fraction of full scale counts as saturated.
pub const SATURATION_FRACTION: f64 = 0.95;

/// Merge black-level-corrected frames of one view taken at `exposures_us` into a 16-bit frame
/// whose full scale (65535) is the full scale of the shortest exposure: each pixel is the
/// exposure-weighted mean `sum v_i / sum t_i` over the exposures where it is not saturated
/// (the maximum-likelihood radiance under shot noise), scaled by the shortest exposure time;
/// a pixel saturated in every exposure is 65535, which the saturation-aware Stokes estimate
/// then drops.
pub fn merge(frames: &[RawFrame], exposures_us: &[f64]) -> Result<RawFrame> {
    let first = frames.first().ok_or_else(|| Error::Unsupported("no frames to merge".into()))?;
    if frames.len() != exposures_us.len() || frames.iter().any(|f| f.pixels.size() != first.pixels.size()) {
        return Err(Error::Unsupported("HDR frames and exposure times do not match".into()));
    }
    let shortest = exposures_us.iter().copied().fold(f64::INFINITY, f64::min);
    let out_scale = 65535.0 * shortest;
    let limits: Vec<(u16, f64)> = frames
        .iter()
        .map(|f| {
            let full = f.full_scale() as f64;
            ((SATURATION_FRACTION * full) as u16, full)
        })
        .collect();
    let n = first.pixels.data().len();
    let data = (0..n)
        .map(|i| {
            let (mut counts, mut time) = (0.0, 0.0);
            for ((frame, &(limit, full)), &t) in frames.iter().zip(&limits).zip(exposures_us) {
                let v = frame.pixels.data()[i];
                if v < limit {
                    counts += v as f64 / full;
                    time += t;
                }
            }
            if time == 0.0 {
                u16::MAX
            } else {
                (counts / time * out_scale).round().min(65534.0) as u16
            }
        })
        .collect();
    let pixels = Image::from_vec(first.pixels.width(), first.pixels.height(), 1, data)?;
    Ok(RawFrame { layout: first.layout, bits: 16, pixels })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mosaic::SensorLayout;

    fn frame(values: &[u16]) -> RawFrame {
        RawFrame {
            layout: SensorLayout::ColorPolarized,
            bits: 12,
            pixels: Image::from_vec(values.len(), 1, 1, values.to_vec()).unwrap(),
        }
    }

    #[test]
    fn merges_unsaturated_exposures_and_flags_the_rest() {
        // Radiances 0.01, 0.2 and 2.0 of full scale per 1000 us, seen at 1000 and 4000 us.
        let short = frame(&[41, 819, 4095]);
        let long = frame(&[164, 3276, 4095]);
        let merged = merge(&[short, long], &[1000.0, 4000.0]).unwrap();
        assert_eq!(merged.bits, 16);
        let px = merged.pixels.data();
        // Pixel 0: (41 + 164) / 4095 / 5000 us * 65535 * 1000 us = 656.
        assert_eq!(px[0], 656);
        // Pixel 1: both below 0.95 full scale: (819 + 3276) / 4095 / 5 * 65535 = 0.2 * 65535.
        assert_eq!(px[1], 13107);
        // Pixel 2: saturated in both.
        assert_eq!(px[2], u16::MAX);
        // Saturated in the long exposure only: the short one alone gives the radiance.
        let merged = merge(&[frame(&[4095]), frame(&[1000])], &[4000.0, 1000.0]).unwrap();
        assert_eq!(merged.pixels.data()[0], (1000.0f64 / 4095.0 * 65535.0).round() as u16);
        assert!(merge(&[frame(&[1])], &[1.0, 2.0]).is_err());
    }
}
