//! Pictures as people have them: PNG (8 or 16 bits), JPEG and TIFF through the `image` crate,
//! OpenEXR and Radiance HDR through [`exr`](super::exr) and [`hdr`](super::hdr).
//!
//! One rule says what the numbers mean. Samples of 8 bits are what phones, photo cameras and
//! image editors write: gamma-encoded (sRGB) values, kept as they are ([`Pixels::Encoded`]).
//! Samples of 16 bits (PNG, TIFF: our own writers, machine-vision cameras' linear exports), 32-bit
//! float TIFF, EXR and HDR are linear light ([`Pixels::Linear`], 16-bit divided by 65535).
//! Alpha is dropped: a picture has 1 or 3 colour channels.
//!
//! The file's camera, where its EXIF block names one, comes along ([`Picture::camera`]): a
//! calibration refuses pictures from different cameras or focal lengths.

use super::input;
use crate::visualize::srgb_to_linear;
use crate::{Error, Image, Result};
use image::{DynamicImage, ImageDecoder, ImageReader, Limits};
use std::io::Cursor;
use std::path::Path;

/// The extensions [`read_picture`] reads, lower case.
pub const PICTURE_EXTENSIONS: [&str; 7] = ["png", "jpg", "jpeg", "tif", "tiff", "exr", "hdr"];

/// The most pixels a compressed picture may declare per byte of its file: far beyond what
/// deflate (1032:1 on bytes) or LZW reach, so that only a forged size is refused, before the
/// decoder allocates for it.
const MAX_PIXELS_PER_BYTE: u64 = 4096;
/// The same for JPEG: every 8x8 block of its fullest-resolution component takes at least one
/// bit (a one-bit Huffman code for "no change"), 512 pixels per byte at most.
const MAX_JPEG_PIXELS_PER_BYTE: u64 = 512;

/// A picture's samples and what they mean.
#[derive(Clone, Debug, PartialEq)]
pub enum Pixels {
    /// 8-bit gamma-encoded (sRGB) values, as displayed.
    Encoded(Image<u8>),
    /// Linear light.
    Linear(Image<f32>),
}

impl Pixels {
    /// Width and height.
    pub fn size(&self) -> (usize, usize) {
        match self {
            Pixels::Encoded(i) => i.size(),
            Pixels::Linear(i) => i.size(),
        }
    }

    /// A mask: 255 where the first channel is above half its scale, else 0.
    pub fn to_mask(&self) -> Image<u8> {
        match self {
            Pixels::Encoded(i) => i.channel(0).map(|v| if v > 127 { 255 } else { 0 }),
            Pixels::Linear(i) => i.channel(0).map(|v| if v > 0.5 { 255 } else { 0 }),
        }
    }

    /// Linear light: encoded values sRGB-decoded, linear ones as they are.
    pub fn into_linear(self) -> Image<f32> {
        match self {
            Pixels::Encoded(i) => i.map(|v| srgb_to_linear(v as f32 / 255.0)),
            Pixels::Linear(i) => i,
        }
    }
}

/// A picture read from a file.
#[derive(Clone, Debug, PartialEq)]
pub struct Picture {
    /// The samples.
    pub pixels: Pixels,
    /// The camera the file's EXIF block names (make, model, serial number and focal length,
    /// those present), if it has one.
    pub camera: Option<String>,
}

/// Whether `path` has one of the [`PICTURE_EXTENSIONS`].
pub fn is_picture(path: &Path) -> bool {
    path.extension().is_some_and(|e| PICTURE_EXTENSIONS.iter().any(|x| e.eq_ignore_ascii_case(x)))
}

/// The picture named `stem` in `folder` with any of the [`PICTURE_EXTENSIONS`] (either case),
/// the first that exists in that order; `None` if there is none.
pub fn find_picture(folder: &Path, stem: &str) -> Option<std::path::PathBuf> {
    PICTURE_EXTENSIONS
        .iter()
        .flat_map(|e| [e.to_string(), e.to_ascii_uppercase()])
        .map(|e| folder.join(format!("{stem}.{e}")))
        .find(|p| p.exists())
}

/// Read the picture at `path` (a regular file; its declared size checked against
/// [`input::max_pixels`] and against its length before decoding). The format is told by the
/// extension for EXR and HDR and by the content for the others.
pub fn read_picture(path: &Path) -> Result<Picture> {
    let extension = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    match extension.as_str() {
        "exr" => return Ok(Picture { pixels: Pixels::Linear(super::read_linear(path)?), camera: None }),
        "hdr" => return Ok(Picture { pixels: Pixels::Linear(super::hdr::read_hdr(path)?), camera: None }),
        _ => {}
    }
    let bytes = input::read_bytes_limited(path, input::max_decoding_bytes())?;
    let unreadable = |e: image::ImageError| Error::format(path, format!("not a readable picture: {e}"));
    let mut reader = ImageReader::new(Cursor::new(&bytes)).with_guessed_format().map_err(|e| Error::io(path, e))?;
    if reader.format().is_none() {
        return Err(Error::format(path, "not a picture rmvp reads (PNG, JPEG, TIFF, EXR or HDR)"));
    }
    let is_jpeg = reader.format() == Some(image::ImageFormat::Jpeg);
    let mut limits = Limits::default();
    limits.max_alloc = Some(input::max_decoding_bytes());
    reader.limits(limits);
    let mut decoder = reader.into_decoder().map_err(unreadable)?;
    let (width, height) = decoder.dimensions();
    input::check_pixels(path, width as u64, height as u64)?;
    let pixels = width as u64 * height as u64;
    let per_byte = if is_jpeg { MAX_JPEG_PIXELS_PER_BYTE } else { MAX_PIXELS_PER_BYTE };
    if pixels > (bytes.len() as u64).saturating_mul(per_byte) {
        return Err(Error::format(
            path,
            format!("declares a {width}x{height} image that its {} bytes cannot hold", bytes.len()),
        ));
    }
    input::check_decoding_bytes(path, width as u64, height as u64, decoding_bytes(&decoder, bytes.len()))?;
    if is_jpeg && !jpeg_ends(&bytes) {
        return Err(Error::format(
            path,
            "a JPEG without its end (truncated): no end-of-image marker after its last scan",
        ));
    }
    let camera = decoder.exif_metadata().ok().flatten().and_then(|exif| camera_from_exif(&exif));
    let image = DynamicImage::from_decoder(decoder).map_err(unreadable)?;
    Ok(Picture { pixels: samples(path, image)?, camera })
}

/// The memory decoding takes: the file, the decoded samples and, for each kept channel, a
/// converted sample and the kept one (an 8-bit sample stays 8 bits, others become `f32`).
fn decoding_bytes(decoder: &impl ImageDecoder, file_bytes: usize) -> u64 {
    let (width, height) = decoder.dimensions();
    let colour = decoder.color_type();
    let sample = (colour.bytes_per_pixel() / colour.channel_count()) as u64;
    let kept_channels = if colour.has_color() { 3 } else { 1 };
    let kept_sample = if sample == 1 { 1 } else { 4 };
    let per_pixel = kept_channels * (sample + kept_sample);
    (file_bytes as u64)
        .saturating_add(decoder.total_bytes())
        .saturating_add((width as u64 * height as u64).saturating_mul(per_pixel))
}

/// Whether a JPEG's last scan (`FF DA`) is followed by its end-of-image marker (`FF D9`): the
/// decoder fills a truncated file's missing blocks with grey without a word. Entropy-coded data
/// stuffs every `FF` byte, so neither marker appears inside a scan; an EXIF thumbnail's own
/// markers come before the image's scans.
fn jpeg_ends(bytes: &[u8]) -> bool {
    let last_scan = bytes.windows(2).rposition(|w| w == [0xFF, 0xDA]);
    last_scan.is_some_and(|at| bytes[at..].windows(2).any(|w| w == [0xFF, 0xD9]))
}

/// The colour channels of a decoded image (alpha dropped), by the module's rule.
fn samples(path: &Path, image: DynamicImage) -> Result<Pixels> {
    let (w, h) = (image.width() as usize, image.height() as usize);
    let sized = |e: crate::Error| e.in_file(path);
    let colour = image.color();
    let channels = if colour.has_color() { 3 } else { 1 };
    Ok(match colour.bytes_per_pixel() / colour.channel_count() {
        1 => {
            let data = if channels == 3 { image.into_rgb8().into_raw() } else { image.into_luma8().into_raw() };
            Pixels::Encoded(Image::from_vec(w, h, channels, data).map_err(sized)?)
        }
        2 => {
            let data = if channels == 3 { image.into_rgb16().into_raw() } else { image.into_luma16().into_raw() };
            let data = data.into_iter().map(|v| v as f32 / 65535.0).collect();
            Pixels::Linear(Image::from_vec(w, h, channels, data).map_err(sized)?)
        }
        _ => {
            let rgb = image.into_rgb32f().into_raw();
            let data = if channels == 3 { rgb } else { rgb.chunks_exact(3).map(|p| p[0]).collect() };
            Pixels::Linear(Image::from_vec(w, h, channels, data).map_err(sized)?)
        }
    })
}

/// The camera an EXIF block names: make, model, body serial number and focal length (those
/// present, in that order); `None` when it names none of them.
fn camera_from_exif(raw: &[u8]) -> Option<String> {
    let exif = exif::Reader::new().read_raw(raw.to_vec()).ok()?;
    let text = |tag: exif::Tag| -> Option<String> {
        match &exif.get_field(tag, exif::In::PRIMARY)?.value {
            exif::Value::Ascii(parts) => {
                let s = parts.iter().map(|p| String::from_utf8_lossy(p).trim().to_string()).collect::<Vec<_>>();
                Some(s.join(" ")).filter(|s| !s.is_empty())
            }
            _ => None,
        }
    };
    let mut parts: Vec<String> = [exif::Tag::Make, exif::Tag::Model].into_iter().filter_map(text).collect();
    if let Some(serial) = text(exif::Tag::BodySerialNumber) {
        parts.push(format!("#{serial}"));
    }
    if let Some(exif::Value::Rational(f)) = exif.get_field(exif::Tag::FocalLength, exif::In::PRIMARY).map(|f| &f.value)
    {
        if let Some(f) = f.first().filter(|f| f.denom != 0) {
            parts.push(format!("{} mm", f.to_f64()));
        }
    }
    (!parts.is_empty()).then(|| parts.join(" "))
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::{ImageEncoder, Luma, Rgb};

    fn write(path: &Path, image: &DynamicImage) {
        image.save(path).unwrap();
    }

    #[test]
    fn a_truncated_jpeg_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let texture = |x: u32, y: u32| ((x * 7919 + y * 104_729) % 251) as u8;
        let image = DynamicImage::ImageRgb8(image::ImageBuffer::from_fn(256, 192, |x, y| Rgb([texture(x, y), 90, 30])));
        let path = tmp.path().join("mask.jpg");
        write(&path, &image);
        assert!(read_picture(&path).is_ok());
        let bytes = std::fs::read(&path).unwrap();
        // Cut inside the scan (the decoder would fill the rest with grey), or only its end marker.
        for keep in [bytes.len() * 3 / 4, bytes.len() - 2] {
            std::fs::write(&path, &bytes[..keep]).unwrap();
            let err = read_picture(&path).map(drop).unwrap_err().to_string();
            assert!(err.contains("mask.jpg") && err.contains("truncated"), "{keep}: {err}");
        }
    }

    #[test]
    fn eight_bits_stay_encoded_and_sixteen_bits_are_linear() {
        let tmp = tempfile::tempdir().unwrap();
        let grey = DynamicImage::ImageLuma8(image::ImageBuffer::from_fn(5, 4, |x, y| Luma([(x * 40 + y) as u8])));
        let rgb16 =
            DynamicImage::ImageRgb16(image::ImageBuffer::from_fn(5, 4, |x, _| Rgb([x as u16 * 1000, 7, 65535])));
        for name in ["a.png", "a.tif", "a.jpg"] {
            let path = tmp.path().join(name);
            write(&path, &grey);
            let picture = read_picture(&path).unwrap();
            let Pixels::Encoded(image) = picture.pixels else { panic!("{name}: 8-bit pictures are encoded") };
            assert_eq!((image.width(), image.height(), image.channels()), (5, 4, 1));
            let tolerance = if name.ends_with("jpg") { 3 } else { 0 };
            assert!(image.pixel(3, 2)[0].abs_diff(122) <= tolerance, "{name}: {}", image.pixel(3, 2)[0]);
        }
        for name in ["b.png", "b.tif"] {
            let path = tmp.path().join(name);
            write(&path, &rgb16);
            let Pixels::Linear(image) = read_picture(&path).unwrap().pixels else { panic!("{name}: linear") };
            assert_eq!(image.pixel(2, 1), &[2000.0 / 65535.0, 7.0 / 65535.0, 1.0]);
        }
    }

    #[test]
    fn the_exif_camera_is_named_and_a_forged_size_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let exif = rmvp_testkit::exif_block("Acme", "X100 Pro", 35);
        let mut jpeg = Vec::new();
        let mut encoder = image::codecs::jpeg::JpegEncoder::new(&mut jpeg);
        encoder.set_exif_metadata(exif).unwrap();
        encoder.write_image(&[128; 64], 8, 8, image::ExtendedColorType::L8).unwrap();
        let path = tmp.path().join("photo.JPG");
        std::fs::write(&path, &jpeg).unwrap();
        assert_eq!(read_picture(&path).unwrap().camera.as_deref(), Some("Acme X100 Pro 35 mm"));

        // The same file declaring more pixels in its frame header: beyond the limit, then
        // within it but beyond what its bytes can hold.
        let sof = jpeg.windows(2).position(|w| w == [0xff, 0xc0]).unwrap();
        for (size, words) in [([0xea, 0x60], "more than the limit"), ([0x3e, 0x80], "cannot hold")] {
            jpeg[sof + 5..sof + 9].copy_from_slice(&[size, size].concat());
            std::fs::write(&path, &jpeg).unwrap();
            let err = read_picture(&path).unwrap_err().to_string();
            assert!(err.contains("photo.JPG") && err.contains(words), "{err}");
        }
    }
}
