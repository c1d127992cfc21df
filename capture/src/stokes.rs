//! Stokes estimation from the four polarizer images, by least squares, optionally dropping
//! saturated measurements (as the PANDORA capture code does).
//!
//! With all four angles the least-squares solution of the measurement model
//! `I(theta) = row(theta) . S` ([`rmvp_dataset::polarization::measurement_row`]) is the closed
//! form of [`polarization::stokes_from_four`]. When exactly one angle of a pixel and colour is
//! saturated, the remaining three determine `S` exactly; with two or more saturated the pixel
//! keeps the (biased) four-angle estimate and is flagged.

use rayon::prelude::*;
use rmvp_dataset::polarization::{self, measurement_row, POLARIZER_ANGLES_DEG};
use rmvp_dataset::{Image, Stokes};

/// Stokes images with a per-pixel saturation count.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StokesEstimate {
    /// Linear Stokes, in units of the sensor's full scale.
    pub stokes: Stokes,
    /// Per pixel: the largest number of saturated angles over its colour channels (0 to 4).
    pub saturated: Image<u8>,
}

/// Estimates Stokes images from polarizer images of integer counts.
#[derive(Clone, Debug)]
pub struct StokesEstimator {
    /// Counts at or above this are saturated (counted in [`StokesEstimate::saturated`]).
    pub saturation_level: u16,
    /// Whether a pixel's one saturated angle is dropped from its estimate.
    pub drop_saturated: bool,
    /// Inverse measurement matrices for each dropped angle.
    drop_one: [[[f32; 3]; 3]; 4],
}

fn invert3(m: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let c = |r: usize, k: usize| {
        let (r1, r2, k1, k2) = ((r + 1) % 3, (r + 2) % 3, (k + 1) % 3, (k + 2) % 3);
        m[r1][k1] * m[r2][k2] - m[r1][k2] * m[r2][k1]
    };
    let det = m[0][0] * c(0, 0) + m[0][1] * c(0, 1) + m[0][2] * c(0, 2);
    // inverse = adjugate / det, adjugate = transposed cofactors.
    [0, 1, 2].map(|i| [0, 1, 2].map(|j| c(j, i) / det))
}

impl StokesEstimator {
    /// An estimator that counts the angles at or above `saturation_level` and, with
    /// `drop_saturated`, drops them.
    pub fn new(saturation_level: u16, drop_saturated: bool) -> Self {
        let drop_one = std::array::from_fn(|dropped| {
            let rows: Vec<[f64; 3]> = POLARIZER_ANGLES_DEG
                .iter()
                .enumerate()
                .filter(|&(k, _)| k != dropped)
                .map(|(_, &deg)| measurement_row((deg as f64).to_radians()))
                .collect();
            invert3([rows[0], rows[1], rows[2]]).map(|r| r.map(|v| v as f32))
        });
        Self { saturation_level, drop_saturated, drop_one }
    }

    /// Stokes of one pixel and channel from counts `i` scaled by `gain` (1 / full scale).
    /// Returns the Stokes vector and the number of saturated angles. Sums and differences are
    /// taken of the counts, exactly, and scaled once: scaling first would cancel digits where
    /// two angles' counts are close (an AoP off by 1e-4 degrees at S1 = 1, S2 = -1 count).
    #[inline]
    pub fn solve(&self, i: [u16; 4], gain: f32) -> ([f32; 3], u8) {
        let v = i.map(f32::from);
        let saturated = i.map(|c| c >= self.saturation_level);
        let count = saturated.iter().filter(|&&s| s).count() as u8;
        if count != 1 || !self.drop_saturated {
            return (polarization::stokes_from_four(v).map(|s| s * gain), count);
        }
        let dropped = saturated.iter().position(|&s| s).expect("one");
        let kept: Vec<f32> = (0..4).filter(|&k| k != dropped).map(|k| v[k]).collect();
        let m = &self.drop_one[dropped];
        (m.map(|row| (row[0] * kept[0] + row[1] * kept[1] + row[2] * kept[2]) * gain), 1)
    }

    /// Stokes images from four polarizer images (0, 45, 90, 135 degrees) of counts whose full
    /// scale is `full_scale`.
    pub fn estimate(&self, angles: &[Image<u16>; 4], full_scale: u16) -> StokesEstimate {
        let mut out = StokesEstimate::default();
        self.estimate_into(angles, full_scale, &mut out);
        out
    }

    /// [`StokesEstimator::estimate`] into an existing estimate, reusing its buffers.
    pub fn estimate_into(&self, angles: &[Image<u16>; 4], full_scale: u16, out: &mut StokesEstimate) {
        let (w, h, c) = (angles[0].width(), angles[0].height(), angles[0].channels());
        let gain = 1.0 / full_scale as f32;
        let Stokes { s0, s1, s2 } = &mut out.stokes;
        for image in [&mut *s0, &mut *s1, &mut *s2] {
            image.ensure_shape(w, h, c);
        }
        let saturated = &mut out.saturated;
        saturated.ensure_shape(w, h, 1);
        let row = w * c;
        s0.data_mut()
            .par_chunks_mut(row)
            .zip(s1.data_mut().par_chunks_mut(row))
            .zip(s2.data_mut().par_chunks_mut(row))
            .zip(saturated.data_mut().par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, (((r0, r1), r2), sat))| {
                let inputs = angles.each_ref().map(|a| &a.data()[y * row..(y + 1) * row]);
                self.estimate_row(inputs, gain, [r0, r1, r2], sat);
            });
    }

    /// One row: `inputs` are the four angle rows (interleaved channels), `gain` is 1 / full
    /// scale, `out` the S0, S1, S2 rows and `saturated` one count per pixel.
    pub fn estimate_row(&self, inputs: [&[u16]; 4], gain: f32, out: [&mut [f32]; 3], saturated: &mut [u8]) {
        let [r0, r1, r2] = out;
        // Equal lengths up front, so that the loops need no bounds checks.
        let n = r0.len();
        let (r1, r2, inputs) = (&mut r1[..n], &mut r2[..n], inputs.map(|a| &a[..n]));
        let c = r0.len() / saturated.len();
        if !self.drop_saturated {
            // The common case as straight loops the compiler vectorises.
            for k in 0..n {
                let v = polarization::stokes_from_four(inputs.map(|a| f32::from(a[k]))).map(|s| s * gain);
                (r0[k], r1[k], r2[k]) = (v[0], v[1], v[2]);
            }
            let level = self.saturation_level;
            for (x, sat) in saturated.iter_mut().enumerate() {
                let count = |k: usize| inputs.iter().map(|a| u8::from(a[k] >= level)).sum::<u8>();
                *sat = (x * c..(x + 1) * c).map(count).max().unwrap_or(0);
            }
            return;
        }
        for (x, sat) in saturated.iter_mut().enumerate() {
            let mut worst = 0;
            for k in x * c..(x + 1) * c {
                let (v, n) = self.solve(inputs.map(|a| a[k]), gain);
                (r0[k], r1[k], r2[k]) = (v[0], v[1], v[2]);
                worst = worst.max(n);
            }
            *sat = worst;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rmvp_dataset::polarization::intensity;

    fn counts(s: [f32; 3], full: f32) -> [u16; 4] {
        POLARIZER_ANGLES_DEG
            .map(|d| (intensity(s[0], s[1], s[2], (d as f32).to_radians()) * full).round().min(full) as u16)
    }

    #[test]
    fn one_saturated_angle_is_dropped_exactly() {
        let estimator = StokesEstimator::new(4095, true);
        // S = (1.6, 0.8, 0.2) of full scale: I0 = 1.2 saturates, I45 = 0.9, I90 = 0.4 and
        // I135 = 0.7 do not, and still determine S.
        let truth = [1.6f32, 0.8, 0.2];
        let (s, n) = estimator.solve(counts(truth, 4095.0), 1.0 / 4095.0);
        assert_eq!(n, 1);
        for k in 0..3 {
            assert!((s[k] - truth[k]).abs() < 1e-3, "{s:?}");
        }
        // Without saturation handling the clipped I0 biases S1.
        let (naive, counted) = StokesEstimator::new(4095, false).solve(counts(truth, 4095.0), 1.0 / 4095.0);
        assert!((naive[1] - truth[1]).abs() > 0.15, "clipping I0 at 1.0 biases S1 by 0.2");
        assert_eq!(counted, 1, "kept, but still counted");
    }

    #[test]
    fn drop_one_inverses_reproduce_the_model() {
        let estimator = StokesEstimator::new(u16::MAX, true);
        for dropped in 0..4 {
            let s = [0.7f32, -0.2, 0.3];
            let i: Vec<f32> =
                POLARIZER_ANGLES_DEG.iter().map(|&d| intensity(s[0], s[1], s[2], (d as f32).to_radians())).collect();
            let kept: Vec<f32> = (0..4).filter(|&k| k != dropped).map(|k| i[k]).collect();
            let m = estimator.drop_one[dropped];
            for r in 0..3 {
                let v = m[r][0] * kept[0] + m[r][1] * kept[1] + m[r][2] * kept[2];
                assert!((v - s[r]).abs() < 1e-6);
            }
        }
    }
}
