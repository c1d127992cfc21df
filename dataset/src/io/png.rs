//! PNG images, 8 and 16 bits per sample, 1 to 4 channels (the `png` crate).

use super::atomic::write_atomically;
use super::input;
use crate::{Error, Image, Result};
use png::{BitDepth, ColorType, Transformations};
use std::io::BufReader;
use std::path::Path;

/// A decoded PNG, at the bit depth it was stored with.
#[derive(Clone, Debug, PartialEq)]
pub enum PngImage {
    /// 8 bits per sample (lower depths and palettes are expanded to this).
    U8(Image<u8>),
    /// 16 bits per sample.
    U16(Image<u16>),
}

/// Read any PNG; palettes and depths below 8 bits are expanded to 8-bit samples.
///
/// The size the header declares is checked against [`input::max_pixels`] and against what the
/// file's compressed bytes can hold before the image is allocated.
pub fn read_png(path: &Path) -> Result<PngImage> {
    let file = input::open_regular(path)?;
    let file_bytes = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut decoder = png::Decoder::new(BufReader::new(file));
    decoder.set_transformations(Transformations::EXPAND);
    let bad = |e: png::DecodingError| Error::format(path, format!("not a readable PNG: {e}"));
    let mut reader = decoder.read_info().map_err(bad)?;
    let (width, height) = (reader.info().width as u64, reader.info().height as u64);
    input::check_pixels(path, width, height)?;
    let size = reader.output_buffer_size().ok_or_else(|| Error::format(path, "PNG too large"))?;
    // Deflate expands at most 1032:1; each row adds one filter byte before compression.
    let raw = reader.info().raw_bytes() as u64 + height;
    if raw > file_bytes.saturating_mul(MAX_DEFLATE_RATIO) {
        return Err(Error::format(
            path,
            format!(
                "declares a {width}x{height} image, more than its {file_bytes} bytes can hold (truncated or forged)"
            ),
        ));
    }
    // A 16-bit image is decoded into bytes, then made samples.
    let decoding = if reader.info().bit_depth == BitDepth::Sixteen { 2 * size as u64 } else { size as u64 };
    input::check_decoding_bytes(path, width, height, decoding)?;
    let mut buf = vec![0u8; size];
    let info = reader.next_frame(&mut buf).map_err(bad)?;
    buf.truncate(info.buffer_size());
    let (w, h) = (info.width as usize, info.height as usize);
    let channels = info.color_type.samples();
    let image = match info.bit_depth {
        BitDepth::Sixteen => {
            let samples = buf.chunks_exact(2).map(|b| u16::from_be_bytes([b[0], b[1]])).collect();
            PngImage::U16(Image::from_vec(w, h, channels, samples)?)
        }
        _ => PngImage::U8(Image::from_vec(w, h, channels, buf)?),
    };
    Ok(image)
}

/// The most a deflate stream expands (RFC 1951: 258 bytes from a 2-bit code at best; 1032:1).
const MAX_DEFLATE_RATIO: u64 = 1032;

/// Read an 8-bit PNG; a 16-bit one is an error.
pub fn read_png_u8(path: &Path) -> Result<Image<u8>> {
    match read_png(path)? {
        PngImage::U8(image) => Ok(image),
        PngImage::U16(_) => Err(Error::format(path, "expected an 8-bit PNG, found 16-bit")),
    }
}

/// Read a 16-bit PNG; an 8-bit one is an error.
pub fn read_png_u16(path: &Path) -> Result<Image<u16>> {
    match read_png(path)? {
        PngImage::U16(image) => Ok(image),
        PngImage::U8(_) => Err(Error::format(path, "expected a 16-bit PNG, found 8-bit")),
    }
}

fn color_type(channels: usize, path: &Path) -> Result<ColorType> {
    Ok(match channels {
        1 => ColorType::Grayscale,
        2 => ColorType::GrayscaleAlpha,
        3 => ColorType::Rgb,
        4 => ColorType::Rgba,
        n => return Err(Error::format(path, format!("a PNG cannot hold {n} channels"))),
    })
}

fn write_png_bytes(path: &Path, w: usize, h: usize, c: usize, depth: BitDepth, bytes: &[u8]) -> Result<()> {
    write_png_file(path, w, h, c, depth, bytes, None)
}

fn write_png_file(
    path: &Path,
    w: usize,
    h: usize,
    c: usize,
    depth: BitDepth,
    bytes: &[u8],
    dpi: Option<f64>,
) -> Result<()> {
    let color = color_type(c, path)?;
    write_atomically(path, |out| {
        let mut encoder = png::Encoder::new(out, w as u32, h as u32);
        encoder.set_color(color);
        encoder.set_depth(depth);
        encoder.set_compression(png::Compression::Fast);
        if let Some(dpi) = dpi {
            let per_metre = (dpi / 0.0254).round() as u32;
            encoder.set_pixel_dims(Some(png::PixelDimensions {
                xppu: per_metre,
                yppu: per_metre,
                unit: png::Unit::Meter,
            }));
        }
        let mut writer = encoder.write_header()?;
        writer.write_image_data(bytes)?;
        writer.finish()?;
        Ok(())
    })
}

/// An 8-bit PNG (1 to 4 channels) in memory, e.g. to serve it.
pub fn encode_png_u8(image: &Image<u8>) -> Result<Vec<u8>> {
    let path = Path::new("<memory>");
    let color = color_type(image.channels(), path)?;
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, image.width() as u32, image.height() as u32);
    encoder.set_color(color);
    encoder.set_depth(BitDepth::Eight);
    encoder.set_compression(png::Compression::Fast);
    let encoded = encoder.write_header().and_then(|mut w| w.write_image_data(image.data()).and_then(|_| w.finish()));
    encoded.map_err(|e| Error::format(path, format!("PNG encoding: {e}")))?;
    Ok(bytes)
}

/// Write an 8-bit PNG (1 to 4 channels).
pub fn write_png_u8(path: &Path, image: &Image<u8>) -> Result<()> {
    let (w, h) = image.size();
    write_png_bytes(path, w, h, image.channels(), BitDepth::Eight, image.data())
}

/// Write an 8-bit PNG that states its print resolution (`pHYs`, dots per inch), so that it
/// prints at its true size.
pub fn write_png_u8_for_print(path: &Path, image: &Image<u8>, dpi: f64) -> Result<()> {
    let (w, h) = image.size();
    write_png_file(path, w, h, image.channels(), BitDepth::Eight, image.data(), Some(dpi))
}

/// The print resolution a PNG states (dots per inch), if it states one in metres.
pub fn read_png_dpi(path: &Path) -> Result<Option<f64>> {
    let file = input::open_regular(path)?;
    let reader = png::Decoder::new(BufReader::new(file))
        .read_info()
        .map_err(|e| Error::format(path, format!("not a readable PNG: {e}")))?;
    Ok(reader.info().pixel_dims.filter(|d| d.unit == png::Unit::Meter).map(|d| d.xppu as f64 * 0.0254))
}

/// Write a 16-bit PNG (1 to 4 channels).
pub fn write_png_u16(path: &Path, image: &Image<u16>) -> Result<()> {
    let (w, h) = image.size();
    let bytes: Vec<u8> = image.data().iter().flat_map(|v| v.to_be_bytes()).collect();
    write_png_bytes(path, w, h, image.channels(), BitDepth::Sixteen, &bytes)
}
