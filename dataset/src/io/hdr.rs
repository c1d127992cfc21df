//! Radiance HDR (RGBE) images, read and written as 32-bit float RGB (`zune-hdr`): PANDORA's
//! Stokes files and HDR panoramas.

use super::atomic::write_bytes_atomically;
use super::input;
use crate::{Error, Image, Result};
use std::path::Path;
use zune_hdr::zune_core::bit_depth::BitDepth;
use zune_hdr::zune_core::colorspace::ColorSpace;
use zune_hdr::zune_core::options::EncoderOptions;
use zune_hdr::{HdrDecoder, HdrEncoder};

/// Read a Radiance HDR file as a 3-channel linear image; its declared size is checked against
/// [`input::max_pixels`] before the pixels are allocated.
pub fn read_hdr(path: &Path) -> Result<Image<f32>> {
    let bytes = input::read_bytes(path)?;
    let bad = |what: String| Error::format(path, format!("not a readable Radiance HDR file: {what}"));
    let mut decoder = HdrDecoder::new(&bytes);
    decoder.decode_headers().map_err(|e| bad(format!("{e:?}")))?;
    let (w, h) = decoder.get_dimensions().ok_or_else(|| bad("no image size in the header".into()))?;
    input::check_pixels(path, w as u64, h as u64)?;
    let data = decoder.decode().map_err(|e| bad(format!("{e:?}")))?;
    Image::from_vec(w, h, 3, data).map_err(|e| e.in_file(path))
}

/// Write a 3-channel image as Radiance HDR (RGBE: 8-bit mantissas sharing an exponent, a
/// relative precision of about 1 %; negative values are not representable), atomically.
pub fn write_hdr(path: &Path, image: &Image<f32>) -> Result<()> {
    if image.channels() != 3 {
        return Err(Error::format(path, format!("Radiance HDR holds RGB, not {} channels", image.channels())));
    }
    if let Some(v) = image.data().iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
        return Err(Error::format(path, format!("Radiance HDR holds finite non-negative values, not {v}")));
    }
    let options = EncoderOptions::new(image.width(), image.height(), ColorSpace::RGB, BitDepth::Float32);
    let bytes = HdrEncoder::new(image.data(), options)
        .encode()
        .map_err(|e| Error::format(path, format!("Radiance HDR encoding: {e:?}")))?;
    write_bytes_atomically(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn images_round_trip_within_rgbe_precision() {
        let (w, h) = (37, 11);
        let data: Vec<f32> = (0..w * h * 3).map(|i| 0.001 + (i as f32 * 0.37).sin().abs() * 40.0).collect();
        let image = Image::from_vec(w, h, 3, data).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.hdr");
        write_hdr(&path, &image).unwrap();
        let back = read_hdr(&path).unwrap();
        assert_eq!(back.size(), (w, h));
        for (a, b) in back.data().iter().zip(image.data()) {
            // RGBE: each value within one step of the pixel's shared exponent (max / 256).
            assert!((a - b).abs() <= 40.0 / 128.0, "{a} vs {b}");
        }
        assert!(write_hdr(&path, &image.map(|v| -v)).unwrap_err().to_string().contains("non-negative"));
    }
}
