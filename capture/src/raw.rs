//! Raw frames as cameras send them: GenICam (PFNC) pixel formats, unpacking of the packed
//! 10p/12p formats, and raw frame files.

use crate::mosaic::SensorLayout;
use crate::{Error, Result};
use rayon::prelude::*;
use rmvp_dataset::io::{png, write_bytes_atomically};
use rmvp_dataset::Image;
use std::path::Path;

/// The family of a PFNC pixel-format name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FormatFamily {
    /// `BayerRGPolarized*`: colour polarization sensor.
    BayerRGPolarized,
    /// `BayerRG*`: the same bytes, offered by cameras that do not name the polarizers.
    BayerRG,
    /// `Polarized*`: mono polarization sensor.
    Polarized,
    /// `Mono*`: the same bytes, unnamed polarizers.
    Mono,
}

impl FormatFamily {
    const ALL: [(&'static str, FormatFamily); 4] = [
        ("BayerRGPolarized", FormatFamily::BayerRGPolarized),
        ("BayerRG", FormatFamily::BayerRG),
        ("Polarized", FormatFamily::Polarized),
        ("Mono", FormatFamily::Mono),
    ];

    /// Whether the name says the sensor has polarizers (`BayerRG*` and `Mono*` name plain
    /// sensors; polarized cameras may offer their bytes under those names too).
    pub fn names_polarizers(self) -> bool {
        matches!(self, FormatFamily::BayerRGPolarized | FormatFamily::Polarized)
    }

    /// The sensor mosaic this family is read with.
    pub fn layout(self) -> SensorLayout {
        match self {
            FormatFamily::BayerRGPolarized | FormatFamily::BayerRG => SensorLayout::ColorPolarized,
            FormatFamily::Polarized | FormatFamily::Mono => SensorLayout::MonoPolarized,
        }
    }
}

/// A GenICam pixel format of a polarization sensor (names as in the PFNC; stored by name).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct PixelFormat {
    /// The name's family, which fixes the sensor mosaic.
    pub family: FormatFamily,
    /// Significant bits per pixel: 8, 10, 12 or 16.
    pub bits: u8,
    /// Whether pixels are bit-packed (the `p` formats) rather than one per byte or per 16-bit word.
    pub packed: bool,
}

impl PixelFormat {
    /// The colour polarization sensor's 12-bit packed format, `BayerRGPolarized12p`.
    pub const BAYER_RG_POLARIZED_12P: PixelFormat =
        PixelFormat { family: FormatFamily::BayerRGPolarized, bits: 12, packed: true };

    /// Parse a PFNC name: `BayerRGPolarized`, `BayerRG` (same layout on the colour polarization
    /// sensor), `Polarized` or `Mono` (mono polarization sensor), followed by `8`, `10`, `12`,
    /// `16` (one sample per byte or little-endian 16-bit word) or `10p`, `12p` (bit-packed).
    pub fn from_name(name: &str) -> Result<Self> {
        let unsupported = || Error::Unsupported(format!("unsupported pixel format {name:?}"));
        let (family, depth) = FormatFamily::ALL
            .iter()
            .find_map(|(prefix, family)| name.strip_prefix(prefix).map(|rest| (*family, rest)))
            .ok_or_else(unsupported)?;
        let (bits, packed) = match depth {
            "8" => (8, false),
            "10" => (10, false),
            "12" => (12, false),
            "10p" => (10, true),
            "12p" => (12, true),
            "16" => (16, false),
            _ => return Err(unsupported()),
        };
        Ok(Self { family, bits, packed })
    }

    /// The PFNC name.
    pub fn name(&self) -> String {
        let prefix = FormatFamily::ALL.iter().find(|(_, f)| *f == self.family).expect("listed").0;
        format!("{prefix}{}{}", self.bits, if self.packed { "p" } else { "" })
    }

    /// Bytes of a `width` x `height` frame in this format.
    pub fn frame_bytes(&self, width: usize, height: usize) -> usize {
        let pixels = width * height;
        match (self.bits, self.packed) {
            (8, _) => pixels,
            (_, true) => (pixels * self.bits as usize).div_ceil(8),
            _ => pixels * 2,
        }
    }
}

impl std::str::FromStr for PixelFormat {
    type Err = Error;

    fn from_str(name: &str) -> Result<Self> {
        Self::from_name(name)
    }
}

impl TryFrom<String> for PixelFormat {
    type Error = Error;

    fn try_from(name: String) -> Result<Self> {
        Self::from_name(&name)
    }
}

impl From<PixelFormat> for String {
    fn from(format: PixelFormat) -> String {
        format.name()
    }
}

/// A decoded raw frame: one sample per sensor pixel, `bits` significant bits.
#[derive(Clone, Debug, PartialEq)]
pub struct RawFrame {
    /// Sensor mosaic.
    pub layout: SensorLayout,
    /// Significant bits of each sample.
    pub bits: u8,
    /// Samples, `width x height`, in `[0, 2^bits)`.
    pub pixels: Image<u16>,
}

impl RawFrame {
    /// The largest sample value, `2^bits - 1`.
    pub fn full_scale(&self) -> u16 {
        ((1u32 << self.bits) - 1) as u16
    }

    /// Decode a frame buffer as the camera sent it. `source` names the file or device in errors.
    pub fn decode(bytes: &[u8], format: PixelFormat, width: usize, height: usize, source: &str) -> Result<Self> {
        let mut frame = Self { layout: format.family.layout(), bits: format.bits, pixels: Image::default() };
        frame.decode_from(bytes, format, width, height, source)?;
        Ok(frame)
    }

    /// [`RawFrame::decode`] into this frame, reusing its buffer (for streams).
    pub fn decode_from(
        &mut self,
        bytes: &[u8],
        format: PixelFormat,
        width: usize,
        height: usize,
        source: &str,
    ) -> Result<()> {
        let expected = format.frame_bytes(width, height);
        if bytes.len() < expected {
            return Err(Error::frame(
                source,
                format!(
                    "{} bytes, but a {width}x{height} {} frame needs {expected} (truncated or corrupt frame)",
                    bytes.len(),
                    format.name()
                ),
            ));
        }
        if !width.is_multiple_of(4) || !height.is_multiple_of(4) {
            return Err(Error::frame(source, format!("{width}x{height} is not a whole number of 4x4 mosaic tiles")));
        }
        self.layout = format.family.layout();
        self.bits = format.bits;
        self.pixels.ensure_shape(width, height, 1);
        let out = self.pixels.data_mut();
        let bytes = &bytes[..expected];
        match (format.bits, format.packed) {
            (8, _) => out.iter_mut().zip(bytes).for_each(|(o, &b)| *o = b as u16),
            (12, true) => unpack_12p(bytes, out),
            (10, true) => unpack_10p(bytes, out),
            (bits, _) => {
                out.iter_mut().zip(bytes.chunks_exact(2)).for_each(|(o, b)| *o = u16::from_le_bytes([b[0], b[1]]));
                let max = ((1u32 << bits) - 1) as u16;
                if let Some(i) = out.iter().position(|&w| w > max) {
                    return Err(Error::frame(
                        source,
                        format!("pixel {i} holds {}, above the {bits}-bit range", out[i]),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Encode the frame in a pixel format (the camera's side of [`RawFrame::decode`]).
    pub fn encode(&self, format: PixelFormat) -> Result<Vec<u8>> {
        if format.bits != self.bits {
            return Err(Error::Unsupported(format!("cannot store {}-bit samples as {}", self.bits, format.name())));
        }
        let samples = self.pixels.data().iter().copied();
        Ok(match (format.bits, format.packed) {
            (8, _) => samples.map(|v| v as u8).collect(),
            (12, true) => pack_12p(&samples.collect::<Vec<_>>()),
            (10, true) => pack_10p(&samples.collect::<Vec<_>>()),
            _ => samples.flat_map(u16::to_le_bytes).collect(),
        })
    }

    /// Read a raw frame file: a `.png` mosaic (8- or 16-bit grey; samples of `bits` significant
    /// bits, 8 or 16 by default) or a bare buffer (`.raw`, `.bin`) in `format` and size.
    pub fn read(path: &Path, format: PixelFormat, width: usize, height: usize) -> Result<Self> {
        let is_png = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("png"));
        if is_png {
            let (pixels, depth) = match png::read_png(path)? {
                png::PngImage::U8(i) => (i.map(u16::from), 8),
                png::PngImage::U16(i) => (i, 16),
            };
            if pixels.channels() != 1 {
                return Err(Error::in_file(
                    path,
                    format!("a raw mosaic has one channel, this PNG has {}", pixels.channels()),
                ));
            }
            let bits = if depth == 8 { 8 } else { format.bits.max(8) };
            let max = pixels.data().iter().copied().max().unwrap_or(0);
            if u32::from(max) >= 1u32 << bits {
                return Err(Error::in_file(
                    path,
                    format!("sample {max} exceeds {bits} bits (is the pixel format right?)"),
                ));
            }
            return Ok(Self { layout: format.family.layout(), bits, pixels });
        }
        let bytes = rmvp_dataset::io::input::read_bytes(path)?;
        Self::decode(&bytes, format, width, height, &path.display().to_string())
    }

    /// Write the frame: `.png` as a 16-bit (or, for 8-bit frames, 8-bit) grey mosaic, anything
    /// else as a bare buffer in `format`. Atomic.
    pub fn write(&self, path: &Path, format: PixelFormat) -> Result<()> {
        if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
            if self.bits == 8 {
                png::write_png_u8(path, &self.pixels.map(|v| v as u8))?;
            } else {
                png::write_png_u16(path, &self.pixels)?;
            }
            return Ok(());
        }
        Ok(write_bytes_atomically(path, &self.encode(format)?)?)
    }
}

/// Pixel groups per parallel task when unpacking.
const UNPACK_GROUPS: usize = 8192;

/// Unpack GenICam 12p: two pixels in three bytes, least significant bits first.
fn unpack_12p(bytes: &[u8], out: &mut [u16]) {
    out.par_chunks_mut(2 * UNPACK_GROUPS).zip(bytes.par_chunks(3 * UNPACK_GROUPS)).for_each(|(o, b)| {
        for (pair, b) in o.chunks_exact_mut(2).zip(b.chunks_exact(3)) {
            let (b0, b1, b2) = (b[0] as u16, b[1] as u16, b[2] as u16);
            pair[0] = b0 | (b1 & 0x0f) << 8;
            pair[1] = b1 >> 4 | b2 << 4;
        }
    });
}

fn pack_12p(samples: &[u16]) -> Vec<u8> {
    samples
        .chunks(2)
        .flat_map(|p| {
            let (a, b) = (p[0], p.get(1).copied().unwrap_or(0));
            [a as u8, ((a >> 8) & 0x0f) as u8 | ((b & 0x0f) << 4) as u8, (b >> 4) as u8]
        })
        .collect()
}

/// Unpack GenICam 10p: four pixels in five bytes, a little-endian bit stream.
fn unpack_10p(bytes: &[u8], out: &mut [u16]) {
    out.par_chunks_mut(4 * UNPACK_GROUPS).zip(bytes.par_chunks(5 * UNPACK_GROUPS)).for_each(|(o, b)| {
        for (quad, b) in o.chunks_exact_mut(4).zip(b.chunks_exact(5)) {
            let bits = u64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], 0, 0, 0]);
            for (k, v) in quad.iter_mut().enumerate() {
                *v = ((bits >> (10 * k)) & 0x3ff) as u16;
            }
        }
    });
}

fn pack_10p(samples: &[u16]) -> Vec<u8> {
    samples
        .chunks(4)
        .flat_map(|p| {
            let bits =
                (0..4).fold(0u64, |acc, k| acc | (u64::from(p.get(k).copied().unwrap_or(0)) & 0x3ff) << (10 * k));
            let le = bits.to_le_bytes();
            [le[0], le[1], le[2], le[3], le[4]]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(bits: u8) -> RawFrame {
        let max = (1u32 << bits) - 1;
        let data = (0..16 * 8).map(|i| ((i as u32).wrapping_mul(2654435761) % (max + 1)) as u16).collect();
        RawFrame { layout: SensorLayout::ColorPolarized, bits, pixels: Image::from_vec(16, 8, 1, data).unwrap() }
    }

    #[test]
    fn packed_formats_round_trip() {
        for name in [
            "BayerRGPolarized8",
            "BayerRGPolarized10p",
            "BayerRGPolarized12p",
            "BayerRGPolarized16",
            "BayerRG12p",
            "BayerRG12",
            "Polarized12p",
            "Mono8",
        ] {
            let format = PixelFormat::from_name(name).unwrap();
            assert_eq!(format.name(), name);
            let mut original = frame(format.bits);
            original.layout = format.family.layout();
            let bytes = original.encode(format).unwrap();
            assert_eq!(bytes.len(), format.frame_bytes(16, 8));
            let back = RawFrame::decode(&bytes, format, 16, 8, "test").unwrap();
            assert_eq!(back, original, "{name}");
        }
    }

    #[test]
    fn twelve_p_follows_the_genicam_bit_order() {
        // Pixels 0xABC and 0x123 pack as BC 3A 12 (PFNC "12p": LSB first).
        assert_eq!(pack_12p(&[0xABC, 0x123]), vec![0xBC, 0x3A, 0x12]);
        let mut out = [0u16; 2];
        unpack_12p(&[0xBC, 0x3A, 0x12], &mut out);
        assert_eq!(out, [0xABC, 0x123]);
    }

    #[test]
    fn truncated_frames_are_reported() {
        let format = PixelFormat::BAYER_RG_POLARIZED_12P;
        let bytes = frame(12).encode(format).unwrap();
        let err = RawFrame::decode(&bytes[..bytes.len() - 1], format, 16, 8, "cam0").unwrap_err().to_string();
        assert!(err.contains("cam0") && err.contains("truncated"), "{err}");
        let format12 = PixelFormat::from_name("BayerRG12").unwrap();
        let mut bytes = frame(12).encode(format12).unwrap();
        bytes[1] = 0xff;
        let err = RawFrame::decode(&bytes, format12, 16, 8, "f.raw").unwrap_err().to_string();
        assert!(err.contains("above the 12-bit range"), "{err}");
        assert!(PixelFormat::from_name("RGB8").is_err());
    }
}
