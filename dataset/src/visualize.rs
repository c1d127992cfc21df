//! Pictures for people: previews, AoP hue wheels, grey ramps and contact sheets (8-bit RGB).

use crate::Image;
use std::f32::consts::PI;

/// The value at quantile `q` (0..1) of the finite samples, or 0 for none.
pub fn quantile(values: &[f32], q: f32) -> f32 {
    let mut v: Vec<f32> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return 0.0;
    }
    let k = ((v.len() - 1) as f32 * q.clamp(0.0, 1.0)).round() as usize;
    *v.select_nth_unstable_by(k, f32::total_cmp).1
}

/// Decode an sRGB-encoded value in `[0, 1]` to linear.
pub fn srgb_to_linear(encoded: f32) -> f32 {
    if encoded <= 0.040_45 {
        encoded / 12.92
    } else {
        ((encoded + 0.055) / 1.055).powf(2.4)
    }
}

fn srgb_encode(linear: f32) -> u8 {
    let c = linear.clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 { 12.92 * c } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0).round() as u8
}

fn to_rgb(image: &Image<f32>, f: impl Fn(f32) -> u8) -> Image<u8> {
    let c = image.channels();
    let data = image
        .data()
        .chunks_exact(c)
        .flat_map(|p| if c >= 3 { [f(p[0]), f(p[1]), f(p[2])] } else { [f(p[0]); 3] })
        .collect();
    Image::from_vec(image.width(), image.height(), 3, data).expect("size kept")
}

/// An sRGB preview of linear radiance (1 or 3 channels), exposed so that the 99.5th percentile
/// maps to 90 % of full scale.
pub fn preview(linear: &Image<f32>) -> Image<u8> {
    let white = quantile(linear.data(), 0.995).max(1e-12) / 0.9;
    to_rgb(linear, |v| srgb_encode(v / white))
}

/// A single-channel value as a grey ramp: `lo` black, `hi` white.
pub fn gray_ramp(image: &Image<f32>, lo: f32, hi: f32) -> Image<u8> {
    to_rgb(&image.channel(0), |v| ((v - lo) / (hi - lo) * 255.0).clamp(0.0, 255.0).round() as u8)
}

/// A signed single-channel value as colour: positive red, negative blue, its brightness
/// `|v| / scale` sRGB-encoded as a preview is (full at `scale` and beyond), zero black; pixels
/// outside `mask` are black.
pub fn signed_picture(image: &Image<f32>, scale: f32, mask: Option<&Image<u8>>) -> Image<u8> {
    let scale = scale.max(1e-12);
    let mut out = Image::new(image.width(), image.height(), 3);
    for (i, px) in out.data_mut().chunks_exact_mut(3).enumerate() {
        if mask.is_some_and(|m| m.data()[i * m.channels()] == 0) {
            continue;
        }
        let v = image.data()[i * image.channels()];
        let level = srgb_encode(v.abs() / scale);
        px[if v >= 0.0 { 0 } else { 2 }] = level;
    }
    out
}

/// HSV (hue in turns, saturation and value in `[0, 1]`) to 8-bit RGB.
pub fn hsv_to_rgb(hue: f32, saturation: f32, value: f32) -> [u8; 3] {
    let h = hue.rem_euclid(1.0) * 6.0;
    let f = |n: f32| {
        let k = (n + h) % 6.0;
        value - value * saturation * k.min(4.0 - k).clamp(0.0, 1.0)
    };
    [f(5.0), f(3.0), f(1.0)].map(|v| (v * 255.0).round() as u8)
}

/// AoP as a hue wheel (0 red, pi/3 green, 2pi/3 blue, back to red at pi), its brightness the
/// DoP relative to the image's 99th DoP percentile (brightest at or above it); pixels outside
/// `mask` are black.
pub fn aop_picture(aop: &Image<f32>, dop: &Image<f32>, mask: Option<&Image<u8>>) -> Image<u8> {
    let dop_full = quantile(dop.data(), 0.99).clamp(1e-3, 1.0);
    let mut out = Image::new(aop.width(), aop.height(), 3);
    for (i, px) in out.data_mut().chunks_exact_mut(3).enumerate() {
        if mask.is_some_and(|m| m.data()[i * m.channels()] == 0) {
            continue;
        }
        let value = (dop.data()[i] / dop_full).clamp(0.0, 1.0);
        px.copy_from_slice(&hsv_to_rgb(aop.data()[i] / PI, 1.0, value));
    }
    out
}

/// Unit normals (3 channels, any frame) as an 8-bit RGB picture: `(n + 1) / 2` of full scale,
/// black where the normal is zero (background). Every normal picture rmvp writes comes from
/// here, so that a release's pictures agree.
pub fn normal_picture(normals: &Image<f32>) -> Image<u8> {
    let data = normals
        .data()
        .chunks_exact(normals.channels())
        .flat_map(|n| {
            if n.iter().all(|&v| v == 0.0) {
                [0; 3]
            } else {
                [n[0], n[1], n[2]].map(|v| ((v + 1.0) * 127.5).round().clamp(0.0, 255.0) as u8)
            }
        })
        .collect();
    Image::from_vec(normals.width(), normals.height(), 3, data).expect("size kept")
}

/// A view's pictures, those it has the data for: S0 ([`preview`]), AoP by DoP
/// ([`aop_picture`], within its mask) and its true normals ([`normal_picture`]).
pub fn view_pictures(view: &crate::View) -> [Option<Image<u8>>; 3] {
    let polarization = view.stokes.as_ref().map(|stokes| {
        let (aop, dop) = stokes.aop_dop();
        (preview(&stokes.s0), aop_picture(&aop, &dop, view.mask.as_ref()))
    });
    let (s0, aop) = polarization.unzip();
    [s0, aop, view.normals.as_ref().map(normal_picture)]
}

/// Shrink an 8-bit image by an integer `factor`, averaging each `factor x factor` block.
pub fn downsample(image: &Image<u8>, factor: usize) -> Image<u8> {
    let f = factor.max(1);
    let (w, h, c) = (image.width() / f, image.height() / f, image.channels());
    let mut out = Image::new(w, h, c);
    for y in 0..h {
        for x in 0..w {
            for ch in 0..c {
                let sum: u32 = (0..f * f).map(|k| image.pixel(x * f + k % f, y * f + k / f)[ch] as u32).sum();
                out.pixel_mut(x, y)[ch] = ((sum + (f * f / 2) as u32) / (f * f) as u32) as u8;
            }
        }
    }
    out
}

/// Tiles of equal size side by side, `columns` per row, separated by a 4-pixel dark border.
pub fn contact_sheet(tiles: &[Image<u8>], columns: usize) -> Image<u8> {
    const GAP: usize = 4;
    let (w, h) = tiles.first().map_or((0, 0), |t| t.size());
    let columns = columns.max(1).min(tiles.len().max(1));
    let rows = tiles.len().div_ceil(columns);
    let mut sheet = Image::new(columns * (w + GAP) + GAP, rows * (h + GAP) + GAP, 3);
    sheet.data_mut().fill(32);
    for (k, tile) in tiles.iter().enumerate() {
        let (x0, y0) = (GAP + (k % columns) * (w + GAP), GAP + (k / columns) * (h + GAP));
        for y in 0..h.min(tile.height()) {
            for x in 0..w.min(tile.width()) {
                let p = tile.pixel(x, y);
                let rgb = if p.len() >= 3 { [p[0], p[1], p[2]] } else { [p[0]; 3] };
                sheet.pixel_mut(x0 + x, y0 + y).copy_from_slice(&rgb);
            }
        }
    }
    sheet
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hue_wheel_primaries() {
        assert_eq!(hsv_to_rgb(0.0, 1.0, 1.0), [255, 0, 0]);
        assert_eq!(hsv_to_rgb(1.0 / 3.0, 1.0, 1.0), [0, 255, 0]);
        assert_eq!(hsv_to_rgb(2.0 / 3.0, 1.0, 1.0), [0, 0, 255]);
        assert_eq!(hsv_to_rgb(0.5, 0.0, 0.5), [128, 128, 128]);
    }

    #[test]
    fn signed_pictures_are_red_above_zero_blue_below_and_black_outside_the_mask() {
        let values = Image::from_vec(4, 1, 1, vec![0.5, -1.0, 0.25, 3.0]).unwrap();
        let mask = Image::from_vec(4, 1, 1, vec![255, 255, 255, 0]).unwrap();
        let picture = signed_picture(&values, 0.5, Some(&mask));
        assert_eq!(picture.data(), &[255, 0, 0, 0, 0, 255, 188, 0, 0, 0, 0, 0]);
    }

    #[test]
    fn srgb_decoding_inverts_encoding() {
        for code in [0u8, 1, 10, 100, 200, 255] {
            assert_eq!(srgb_encode(srgb_to_linear(code as f32 / 255.0)), code);
        }
    }

    #[test]
    fn normal_pictures_map_unit_normals_and_black_background() {
        let normals = Image::from_vec(3, 1, 3, vec![0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0]).unwrap();
        assert_eq!(normal_picture(&normals).data(), &[128, 128, 255, 0, 0, 0, 0, 128, 128]);
    }

    #[test]
    fn downsample_averages_blocks() {
        let image = Image::from_vec(4, 2, 1, vec![0, 2, 10, 10, 4, 6, 10, 11]).unwrap();
        assert_eq!(downsample(&image, 2).data(), &[3, 10]);
    }

    #[test]
    fn contact_sheet_places_tiles() {
        let tile = |v: u8| Image::from_vec(2, 2, 3, vec![v; 12]).unwrap();
        let sheet = contact_sheet(&[tile(10), tile(20), tile(30)], 2);
        assert_eq!(sheet.size(), (2 * 6 + 4, 2 * 6 + 4));
        assert_eq!(sheet.pixel(4, 4), &[10, 10, 10]);
        assert_eq!(sheet.pixel(10, 4), &[20, 20, 20]);
        assert_eq!(sheet.pixel(4, 10), &[30, 30, 30]);
        assert_eq!(sheet.pixel(10, 10), &[32, 32, 32]);
    }
}
