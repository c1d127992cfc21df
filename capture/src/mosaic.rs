//! The sensor's micro-polarizer and colour mosaics.
//!
//! IMX250MYR (colour): each 2x2 cell carries polarizers `[90 45; 135 0]` (row 0: 90 and 45
//! degrees; row 1: 135 and 0) and sits under one colour of an RGGB Bayer pattern of cells, so
//! the pattern repeats every 4x4 pixels. Taking one polarizer position from every cell gives a
//! half-resolution image that is an ordinary RGGB Bayer mosaic (GenICam `BayerRG`).
//! IMX250MZR (mono): the same polarizer cells, no colour filters.

use crate::RawFrame;
use rayon::prelude::*;
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

/// Offset `(dx, dy)` inside the 2x2 cell of the polarizer at 0, 45, 90 and 135 degrees
/// (the order of [`rmvp_dataset::polarization::POLARIZER_ANGLES_DEG`]).
pub const POLARIZER_OFFSETS: [(usize, usize); 4] = [(1, 1), (1, 0), (0, 0), (0, 1)];

/// Colour channel (0 R, 1 G, 2 B) of pixel `(x, y)` of a half-resolution RGGB sub-mosaic.
pub fn bayer_channel(x: usize, y: usize) -> usize {
    [[0, 1], [1, 2]][y % 2][x % 2]
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
    // One pass over row pairs: the even row holds 90 and 45 degrees, the odd row 135 and 0.
    r90.into_par_iter().zip(r45).zip(r135).zip(r0).enumerate().for_each(|(y, (((o90, o45), o135), o0))| {
        let even = &raw.pixels.data()[2 * y * w..(2 * y + 1) * w];
        let odd = &raw.pixels.data()[(2 * y + 1) * w..(2 * y + 2) * w];
        for x in 0..hw {
            o90[x] = even[2 * x];
            o45[x] = even[2 * x + 1];
            o135[x] = odd[2 * x];
            o0[x] = odd[2 * x + 1];
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
    fn polarizer_cell_is_90_45_135_0() {
        // Sensor pixel (x, y) -> angle, read straight off the cell [90 45; 135 0].
        let angles = [0, 45, 90, 135];
        let at = |x: usize, y: usize| angles[POLARIZER_OFFSETS.iter().position(|&o| o == (x % 2, y % 2)).unwrap()];
        assert_eq!([at(0, 0), at(1, 0), at(0, 1), at(1, 1)], [90, 45, 135, 0]);
    }

    #[test]
    fn split_inverts_compose() {
        let images: [Image<u16>; 4] =
            std::array::from_fn(|k| Image::from_vec(4, 2, 1, (0..8).map(|i| (100 * k + i) as u16).collect()).unwrap());
        let raw = compose(SensorLayout::MonoPolarized, 12, &images);
        assert_eq!(raw.pixels.size(), (8, 4));
        assert_eq!(raw.pixels.pixel(0, 0)[0], 200, "90 degrees at the cell's top left");
        assert_eq!(split(&raw), images);
    }
}
