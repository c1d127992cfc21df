//! The sensor's micro-polarizer and colour mosaics.
//!
//! IMX250MYR (colour): each 2x2 cell carries four polarizers,
//! [`SENSOR_POLARIZER_CELL`] `[90 135; 45 0]`
//! in the image frame (the vendor's names `[90 45; 135 0]` turn towards image *up*), and sits
//! under one colour of an RGGB Bayer pattern of cells, so the pattern repeats every 4x4 pixels. Taking one polarizer position from every cell gives a
//! half-resolution image that is an ordinary RGGB Bayer mosaic (GenICam `BayerRG`).
//! IMX250MZR (mono): the same polarizer cells, no colour filters.

use crate::RawFrame;
use rayon::prelude::*;
use rmvp_dataset::polarization::{polarizer_offsets, SENSOR_POLARIZER_CELL};
use rmvp_dataset::Image;

/// Which polarization sensor produced a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SensorLayout {
    /// IMX250MYR: polarizer cells under an RGGB Bayer pattern.
    #[default]
    ColorPolarized,
    /// IMX250MZR: polarizer cells only.
    MonoPolarized,
}

impl SensorLayout {
    /// Colour channels after demosaicing: 3 (RGB) or 1.
    pub fn channels(self) -> usize {
        match self {
            SensorLayout::ColorPolarized => 3,
            SensorLayout::MonoPolarized => 1,
        }
    }
}

/// Offset `(dx, dy)` inside the sensor's 2x2 cell of the polarizer at 0, 45, 90 and 135
/// degrees (the order of [`rmvp_dataset::polarization::POLARIZER_ANGLES_DEG`]).
pub const POLARIZER_OFFSETS: [(usize, usize); 4] = polarizer_offsets(&SENSOR_POLARIZER_CELL);

/// Colour channel (0 R, 1 G, 2 B) of pixel `(x, y)` of a half-resolution RGGB sub-mosaic.
pub fn bayer_channel(x: usize, y: usize) -> usize {
    [[0, 1], [1, 2]][y % 2][x % 2]
}

/// How far apart a mosaic's Bayer colours are, read as the colour sensor's: the largest
/// difference of the red and blue cells' mean from the green cells' mean, relative to green.
/// A colour sensor's raw colours differ by tens of percent (its red, green and blue filters
/// pass different shares of any light); a mono sensor's mosaic read as colour, by a fraction of
/// a percent (0.06-0.08 % on real IMX250MZR frames).
pub fn bayer_colour_spread(raw: &RawFrame) -> f64 {
    let w = raw.pixels.width();
    // Frames are whole 4x4 tiles: as many cells of each colour.
    let mut sums = [0f64; 4];
    for (y, row) in raw.pixels.data().chunks_exact(w).enumerate() {
        for (x, &v) in row.iter().enumerate() {
            // Cell (x / 2, y / 2) sits under the colour of [`bayer_channel`]: R, G / G, B.
            sums[(y / 2 % 2) * 2 + x / 2 % 2] += f64::from(v);
        }
    }
    let green = (sums[1] + sums[2]) / 2.0;
    if green <= 0.0 {
        return 0.0;
    }
    ((sums[0] - green).abs()).max((sums[3] - green).abs()) / green
}

/// Split a raw frame into its four half-resolution polarizer sub-mosaics, ordered 0, 45, 90,
/// 135 degrees. For the colour sensor each is an RGGB Bayer mosaic.
pub fn split(raw: &RawFrame) -> [Image<u16>; 4] {
    let mut subs = Default::default();
    split_into(raw, &mut subs);
    subs
}

/// [`split`] into existing images, reusing their buffers.
pub fn split_into(raw: &RawFrame, subs: &mut [Image<u16>; 4]) {
    let (w, h) = raw.pixels.size();
    let hw = w / 2;
    subs.iter_mut().for_each(|s| s.ensure_shape(hw, h / 2, 1));
    let [a0, a45, a90, a135] = subs;
    fn rows(image: &mut Image<u16>, width: usize) -> Vec<&mut [u16]> {
        image.data_mut().chunks_mut(width).collect()
    }
    let (r0, r45, r90, r135) = (rows(a0, hw), rows(a45, hw), rows(a90, hw), rows(a135, hw));
    // One pass over row pairs; each angle's site is read from its offset in the cell.
    r0.into_par_iter().zip(r45).zip(r90).zip(r135).enumerate().for_each(|(y, (((o0, o45), o90), o135))| {
        let pair = &raw.pixels.data()[2 * y * w..(2 * y + 2) * w];
        for (out, &(dx, dy)) in [o0, o45, o90, o135].into_iter().zip(&POLARIZER_OFFSETS) {
            let row = &pair[dy * w..(dy + 1) * w];
            for (o, &v) in out.iter_mut().zip(row.iter().skip(dx).step_by(2)) {
                *o = v;
            }
        }
    });
}

/// The raw frame a sensor with `layout` records from four half-resolution images behind the
/// polarizers (0, 45, 90, 135 degrees; RGB for the colour sensor, one channel for mono): each
/// sensor pixel keeps its own polarizer and colour. The inverse of [`split`] plus demosaicing.
pub fn compose(layout: SensorLayout, bits: u8, angle_images: &[Image<u16>; 4]) -> RawFrame {
    let (w, h) = angle_images[0].size();
    let mut pixels = Image::new(2 * w, 2 * h, 1);
    for (image, &(dx, dy)) in angle_images.iter().zip(&POLARIZER_OFFSETS) {
        let c = image.channels();
        for y in 0..h {
            for x in 0..w {
                let channel = if layout == SensorLayout::ColorPolarized { bayer_channel(x, y) } else { 0 };
                pixels.pixel_mut(2 * x + dx, 2 * y + dy)[0] = image.data()[(y * w + x) * c + channel];
            }
        }
    }
    RawFrame { layout, bits, pixels }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polarizer_cell_is_90_135_45_0_in_the_image_frame() {
        // Sensor pixel (x, y) -> angle from image +x towards +y (down).
        let angles = [0, 45, 90, 135];
        let at = |x: usize, y: usize| angles[POLARIZER_OFFSETS.iter().position(|&o| o == (x % 2, y % 2)).unwrap()];
        assert_eq!([at(0, 0), at(1, 0), at(0, 1), at(1, 1)], [90, 135, 45, 0]);
    }

    #[test]
    fn a_mono_mosaic_has_no_colour_spread_and_a_colour_one_has() {
        // A textured grey scene, 64x64 Stokes pixels.
        let n = 64;
        let grey = |i: usize| 100 + ((i as u32).wrapping_mul(2_654_435_761) >> 26) as u16;
        let mono: [Image<u16>; 4] =
            std::array::from_fn(|_| Image::from_vec(n, n, 1, (0..n * n).map(grey).collect()).unwrap());
        let spread = bayer_colour_spread(&compose(SensorLayout::MonoPolarized, 8, &mono));
        assert!(spread < 0.01, "{spread}");
        // The same light through red, green and blue filters passing 50, 100 and 70 %.
        let colour: [Image<u16>; 4] = std::array::from_fn(|_| {
            let data = (0..n * n).flat_map(|i| [5, 10, 7].map(|f| grey(i) * f / 10)).collect();
            Image::from_vec(n, n, 3, data).unwrap()
        });
        let spread = bayer_colour_spread(&compose(SensorLayout::ColorPolarized, 8, &colour));
        assert!((spread - 0.5).abs() < 0.02, "{spread}");
    }

    #[test]
    fn split_inverts_compose() {
        let images: [Image<u16>; 4] =
            std::array::from_fn(|k| Image::from_vec(4, 2, 1, (0..8).map(|i| (100 * k + i) as u16).collect()).unwrap());
        let raw = compose(SensorLayout::MonoPolarized, 12, &images);
        assert_eq!(raw.pixels.size(), (8, 4));
        assert_eq!(raw.pixels.pixel(0, 0)[0], 200, "90 degrees at the cell's top left");
        assert_eq!(raw.pixels.pixel(1, 0)[0], 300, "135 degrees at its top right");
        assert_eq!(raw.pixels.pixel(0, 1)[0], 100, "45 degrees at its bottom left");
        assert_eq!(split(&raw), images);
    }
}
