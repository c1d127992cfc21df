//! Radiance HDR (RGBE) images, read and written as 32-bit float RGB: PANDORA's Stokes files
//! and HDR panoramas.
//!
//! Reading is our own: `zune-hdr` 0.4 decodes a flat (uncompressed) scanline, which the format
//! allows and writers must use for widths under 8 or over 32767, as zeros, and exponents more
//! than 31 away from 128 wrongly; this reader takes flat, run-length (new and old style)
//! scanlines alike, and refuses a file whose declared pixels its bytes cannot hold before it
//! allocates them. Writing (run-length scanlines) goes through `zune-hdr`.

use super::atomic::write_bytes_atomically;
use super::input;
use crate::{Error, Image, Result};
use std::path::Path;
use zune_hdr::zune_core::bit_depth::BitDepth;
use zune_hdr::zune_core::colorspace::ColorSpace;
use zune_hdr::zune_core::options::EncoderOptions;
use zune_hdr::HdrEncoder;

/// Longest header read (Radiance headers are a few lines).
const MAX_HEADER_BYTES: usize = 64 << 10;

/// Read a Radiance HDR file as a 3-channel linear image. Its header is read first: the declared
/// size is checked against [`input::max_pixels`], against what its bytes can hold
/// (`least_data_bytes`) and against the decoding memory before the pixels are allocated, and
/// a file longer than its scanlines can take (`most_data_bytes`) is refused unread.
pub fn read_hdr(path: &Path) -> Result<Image<f32>> {
    let bad = |what: String| Error::format(path, format!("not a readable Radiance HDR file: {what}"));
    let (head, file_len) = input::read_head(path, MAX_HEADER_BYTES as u64)?;
    let (w, h, start) = header(&head).map_err(bad)?;
    input::check_pixels(path, w as u64, h as u64)?;
    let least = least_data_bytes(w, h);
    let data = file_len.saturating_sub(start as u64);
    if data < least {
        return Err(bad(format!("declares {w}x{h} pixels, which need at least {least} bytes; it has {data}")));
    }
    // RGBE bytes and RGB `f32` samples.
    input::check_decoding_bytes(path, w as u64, h as u64, (w as u64 * h as u64).saturating_mul(16))?;
    let bytes = input::read_bytes_limited(path, start as u64 + most_data_bytes(w, h))?;
    let data = bytes.get(start..).ok_or_else(|| bad("it changed while read".into()))?;
    let pixels = scanlines(data, w, h).map_err(bad)?;
    Image::from_vec(w, h, 3, pixels).map_err(|e| e.in_file(path))
}

/// The header's size and where the pixels start. Only the standard orientation (`-Y H +X W`:
/// rows top to bottom, each left to right) and RGBE pixels are read.
fn header(bytes: &[u8]) -> std::result::Result<(usize, usize, usize), String> {
    let head = &bytes[..bytes.len().min(MAX_HEADER_BYTES)];
    if !head.starts_with(b"#?") {
        return Err("it does not start with #? (#?RADIANCE)".into());
    }
    let mut at = 0;
    let mut line = |head: &[u8]| -> std::result::Result<String, String> {
        let end = head[at..].iter().position(|&b| b == b'\n').ok_or("its header does not end")?;
        let text = String::from_utf8_lossy(&head[at..at + end]).trim_end_matches('\r').to_string();
        at += end + 1;
        Ok(text)
    };
    loop {
        let text = line(head)?;
        if text.is_empty() {
            break;
        }
        if let Some(format) = text.strip_prefix("FORMAT=") {
            if format.trim() != "32-bit_rle_rgbe" {
                return Err(format!("pixel format {format:?}; only 32-bit_rle_rgbe is read"));
            }
        }
    }
    let resolution = line(head)?;
    let fields: Vec<&str> = resolution.split_whitespace().collect();
    match fields.as_slice() {
        ["-Y", h, "+X", w] => {
            let size = |v: &str| v.parse::<usize>().ok().filter(|&n| n > 0);
            let (w, h) = size(w).zip(size(h)).ok_or(format!("resolution line {resolution:?}"))?;
            Ok((w, h, at))
        }
        _ => Err(format!("resolution line {resolution:?}; only the standard -Y H +X W orientation is read")),
    }
}

/// Most pixels read per byte of a file's pixel data. A run-length scanline packs at most about
/// 16 pixels into a byte; old-style runs (`1 1 1 n`, rare since Radiance 2.0) could pack far
/// more, and a file that does so beyond this is refused rather than allowed to ask for
/// gigabytes from a few kilobytes.
const MAX_PIXELS_PER_BYTE: u64 = 64;

/// The fewest bytes of pixel data `w` x `h` pixels are read from: 4 a scanline (its first
/// pixel or run-length marker), and no more than [`MAX_PIXELS_PER_BYTE`] pixels a byte.
fn least_data_bytes(w: usize, h: usize) -> u64 {
    (4 * h as u64).max((w as u64 * h as u64).div_ceil(MAX_PIXELS_PER_BYTE))
}

/// The most bytes `h` scanlines of `w` pixels take: each a 4-byte marker and, per channel, its
/// bytes and a count byte for every 128 of them (run-length scanlines of noise); flat
/// scanlines take less.
fn most_data_bytes(w: usize, h: usize) -> u64 {
    let (w, h) = (w as u64, h as u64);
    h * (4 + 4 * (w + w.div_ceil(128)))
}

/// Decode `h` scanlines of `w` RGBE pixels to linear RGB.
fn scanlines(data: &[u8], w: usize, h: usize) -> std::result::Result<Vec<f32>, String> {
    let mut out = Vec::with_capacity(w * h * 3);
    let mut rgbe = vec![0u8; 4 * w];
    let mut at = 0;
    for y in 0..h {
        let truncated = || format!("it ends inside scanline {y} of {h}");
        let marker = data.get(at..at + 4).ok_or_else(truncated)?;
        let run_length = (8..=0x7fff).contains(&w) && marker[0] == 2 && marker[1] == 2 && marker[2] & 0x80 == 0;
        if run_length {
            if usize::from(marker[2]) << 8 | usize::from(marker[3]) != w {
                return Err(format!(
                    "scanline {y} declares a width of {}, not {w}",
                    usize::from(marker[2]) << 8 | usize::from(marker[3])
                ));
            }
            at += 4;
            for component in 0..4 {
                let mut x = 0;
                while x < w {
                    let count = *data.get(at).ok_or_else(truncated)? as usize;
                    at += 1;
                    if count > 128 {
                        let n = count - 128;
                        let value = *data.get(at).ok_or_else(truncated)?;
                        at += 1;
                        if x + n > w {
                            return Err(format!("a run in scanline {y} passes its end"));
                        }
                        (x..x + n).for_each(|i| rgbe[4 * i + component] = value);
                        x += n;
                    } else {
                        if count == 0 || x + count > w {
                            return Err(format!("a literal of {count} in scanline {y} at pixel {x} of {w}"));
                        }
                        let values = data.get(at..at + count).ok_or_else(truncated)?;
                        at += count;
                        values.iter().enumerate().for_each(|(i, &v)| rgbe[4 * (x + i) + component] = v);
                        x += count;
                    }
                }
            }
        } else {
            // Flat pixels, in which old-style runs (1, 1, 1, n) repeat the pixel before.
            let (mut x, mut shift) = (0, 0);
            while x < w {
                let pixel = data.get(at..at + 4).ok_or_else(truncated)?;
                at += 4;
                if pixel[..3] == [1, 1, 1] {
                    if x == 0 || shift > 16 {
                        return Err(format!("a repeat with nothing to repeat in scanline {y}"));
                    }
                    let n = usize::from(pixel[3]) << shift;
                    if x + n > w {
                        return Err(format!("a repeat in scanline {y} passes its end"));
                    }
                    for i in x..x + n {
                        rgbe.copy_within(4 * (x - 1)..4 * x, 4 * i);
                    }
                    x += n;
                    shift += 8;
                } else {
                    rgbe[4 * x..4 * x + 4].copy_from_slice(pixel);
                    x += 1;
                    shift = 0;
                }
            }
        }
        out.extend(rgbe.chunks_exact(4).flat_map(|p| {
            // Mantissas over 256 times two to the exponent over 128 (Radiance's RGBE).
            let scale = if p[3] == 0 { 0.0 } else { 2f64.powi(i32::from(p[3]) - 136) };
            [p[0], p[1], p[2]].map(|m| (f64::from(m) * scale) as f32)
        }));
    }
    Ok(out)
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

    /// A file with `header` and scanlines of RGBE pixels given per row, flat.
    fn flat_file(header: &str, rows: &[Vec<[u8; 4]>]) -> Vec<u8> {
        let mut bytes = header.as_bytes().to_vec();
        for row in rows {
            bytes.extend(row.iter().flatten());
        }
        bytes
    }

    fn read(bytes: &[u8]) -> Result<Image<f32>> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.hdr");
        std::fs::write(&path, bytes).unwrap();
        read_hdr(&path)
    }

    #[test]
    fn flat_scanlines_are_read_as_they_are_written() {
        // Width 5 (under 8: writers must store it flat); mantissa 128 at exponent 129 is 1.0.
        let row: Vec<[u8; 4]> = (0..5).map(|i| [128, 64 * (i % 2) as u8, 32, 129]).collect();
        let bytes = flat_file("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 5\n", &[row.clone(), row]);
        let image = read(&bytes).unwrap();
        assert_eq!(image.size(), (5, 2));
        assert_eq!(image.pixel(0, 0), [1.0, 0.0, 0.25]);
        assert_eq!(image.pixel(3, 1), [1.0, 0.5, 0.25]);
        // The same flat, at width 40, where run-length would be allowed too.
        let row: Vec<[u8; 4]> = (0..40).map(|i| [i as u8 + 1, 7, 9, 140]).collect();
        let image = read(&flat_file("#?RADIANCE\n\n-Y 1 +X 40\n", &[row])).unwrap();
        assert_eq!(image.pixel(39, 0)[0], 40.0 * 2f32.powi(140 - 136));
        // Old-style runs repeat the pixel before.
        let row = vec![[10, 20, 30, 128], [1, 1, 1, 3], [5, 5, 5, 128]];
        let image = read(&flat_file("#?RADIANCE\n\n-Y 1 +X 5\n", &[row])).unwrap();
        assert_eq!(image.pixel(3, 0), image.pixel(0, 0));
        assert_eq!(image.pixel(4, 0)[0], 5.0 / 256.0);
    }

    #[test]
    fn exponents_far_from_128_keep_their_values() {
        let row: Vec<[u8; 4]> =
            vec![[128, 0, 0, 128 + 40], [128, 0, 0, 128 - 60], [1, 2, 3, 0], [0, 0, 0, 1], [255, 1, 0, 255]];
        let image = read(&flat_file("#?RADIANCE\n\n-Y 1 +X 5\n", &[row])).unwrap();
        assert_eq!(image.pixel(0, 0)[0], 2f32.powi(39));
        assert_eq!(image.pixel(1, 0)[0], 2f32.powi(-61));
        assert_eq!(image.pixel(2, 0), [0.0; 3], "exponent 0 is black");
        assert_eq!(image.pixel(4, 0)[0], 255.0 * 2f32.powi(255 - 136));
    }

    #[test]
    fn claims_the_bytes_cannot_hold_and_broken_runs_are_refused() {
        // 60 bytes declaring 16384x16384: refused before anything is allocated.
        let err = read(b"#?RADIANCE\n\n-Y 16384 +X 16384\n\x02\x02\x40\x00").unwrap_err().to_string();
        assert!(err.contains("x.hdr") && err.contains("need at least"), "{err}");
        let cases: [(&[u8], &str); 5] = [
            (b"#?RADIANCE\n\n-Y 1 +X 2\n\x01\x01\x01\x05\x00\x00\x00\x00", "nothing to repeat"),
            (b"#?RADIANCE\n\n-Y 2 +X 2\n\x01\x02\x03\x80\x01\x02\x03\x80\x01\x02\x03\x80", "ends inside scanline 1"),
            (b"#?RADIANCE\n\n+Y 1 +X 1\n\x01\x02\x03\x80", "orientation"),
            (b"#?RADIANCE\nFORMAT=32-bit_rle_xyze\n\n-Y 1 +X 1\n\x01\x02\x03\x80", "xyze"),
            (b"P6 1 1 255\n\x00\x00\x00", "#?"),
        ];
        for (bytes, why) in cases {
            let err = read(bytes).unwrap_err().to_string();
            assert!(err.contains("x.hdr") && err.contains(why), "{why}: {err}");
        }
        // A run-length scanline whose runs pass its end.
        let mut bytes = b"#?RADIANCE\n\n-Y 1 +X 8\n\x02\x02\x00\x08".to_vec();
        bytes.extend([0x80 + 9, 7].repeat(4));
        assert!(read(&bytes).unwrap_err().to_string().contains("passes its end"));
    }

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
