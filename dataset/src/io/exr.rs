//! OpenEXR images with named channels (the `exr` crate), read and written as 32-bit floats.

use super::atomic::write_atomically;
use super::input;
use crate::{Error, Image, Result};
use exr::meta::MetaData;
use exr::prelude::{
    read, AnyChannel, AnyChannels, Encoding, FlatSamples, Image as ExrFile, Layer, LayerAttributes, LineOrder,
    ReadChannels, ReadLayers, WritableImage,
};
use std::io::{BufReader, Seek, SeekFrom};
use std::path::Path;

/// Every channel of an EXR layer as `(name, samples)`, with the layer's width and height.
pub type ExrChannels = (usize, usize, Vec<(String, Vec<f32>)>);

/// Read the first layer of an EXR file: its size and every channel as `(name, samples)`, in the
/// file's (alphabetical) channel order. Half and integer samples are converted to `f32`.
///
/// Every layer's declared size is checked against [`input::max_pixels`] and against the file's
/// size before any pixel is allocated.
pub fn read_exr_channels(path: &Path) -> Result<ExrChannels> {
    let mut file = BufReader::new(input::open_regular(path)?);
    let file_bytes = file.get_ref().metadata().map_err(|e| Error::io(path, e))?.len();
    let bad = |e: exr::error::Error| Error::format(path, format!("not a readable OpenEXR file: {e}"));
    let meta = MetaData::read_from_buffered(&mut file, false).map_err(bad)?;
    for header in &meta.headers {
        let size = header.layer_size;
        let (width, height) = (size.width() as u64, size.height() as u64);
        input::check_pixels(path, width, height)?;
        // Each sample as stored and as `f32`.
        let per_pixel: u64 = header.channels.list.iter().map(|c| c.sample_type.bytes_per_sample() as u64 + 4).sum();
        input::check_decoding_bytes(path, width, height, (width * height).saturating_mul(per_pixel))?;
        // Every chunk of the layer needs at least its 8-byte offset in the file.
        if header.chunk_count as u64 > file_bytes / 8 {
            return Err(Error::format(
                path,
                format!(
                    "declares a {}x{} layer of {} chunks, more than its {file_bytes} bytes can hold (truncated or forged)",
                    size.width(),
                    size.height(),
                    header.chunk_count
                ),
            ));
        }
    }
    file.seek(SeekFrom::Start(0)).map_err(|e| Error::io(path, e))?;
    let file = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(file)
        .map_err(bad)?;
    let layer = file.layer_data;
    let channels = layer
        .channel_data
        .list
        .into_iter()
        .map(|c| {
            let values = match c.sample_data {
                FlatSamples::F32(v) => v,
                other => other.values_as_f32().collect(),
            };
            (c.name.to_string(), values)
        })
        .collect();
    Ok((layer.size.width(), layer.size.height(), channels))
}

/// Read the named channels of an EXR file, interleaved in the order given.
pub fn read_exr(path: &Path, names: &[&str]) -> Result<Image<f32>> {
    let (w, h, mut channels) = read_exr_channels(path)?;
    let mut planes = Vec::with_capacity(names.len());
    for name in names {
        let i = channels.iter().position(|(n, _)| n == name).ok_or_else(|| {
            let found: Vec<&str> = channels.iter().map(|(n, _)| n.as_str()).collect();
            Error::format(path, format!("no channel {name:?} (channels: {found:?})"))
        })?;
        planes.push(std::mem::take(&mut channels[i].1));
    }
    let mut data = Vec::with_capacity(w * h * names.len());
    for p in 0..w * h {
        data.extend(planes.iter().map(|plane| plane[p]));
    }
    Image::from_vec(w, h, names.len(), data)
}

/// How our EXR files are encoded: the `exr` crate's fast lossless RLE tiles, stored in increasing
/// line order. Its default order ("unspecified") writes tiles as the compressing threads finish
/// them, so the same pixels gave different bytes from run to run, and a published release's
/// checksums changed on every rebuild; in a fixed order the file is a function of its pixels.
const ENCODING: Encoding = Encoding { line_order: LineOrder::Increasing, ..Encoding::FAST_LOSSLESS };

/// Write an image as a 32-bit float EXR, channel `i` named `names[i]`, losslessly compressed; the
/// same image always gives the same bytes.
pub fn write_exr(path: &Path, image: &Image<f32>, names: &[&str]) -> Result<()> {
    if names.len() != image.channels() {
        return Err(Error::format(
            path,
            format!("{} channel names for a {}-channel image", names.len(), image.channels()),
        ));
    }
    let list = names
        .iter()
        .enumerate()
        .map(|(c, name)| AnyChannel::new(*name, FlatSamples::F32(image.channel(c).into_vec())))
        .collect();
    let layer =
        Layer::new((image.width(), image.height()), LayerAttributes::default(), ENCODING, AnyChannels::sort(list));
    let file = ExrFile::from_layer(layer);
    write_atomically(path, |out| file.write().to_buffered(out).map_err(|e| std::io::Error::other(e.to_string())))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An image of many tiles (compressed on several threads) with values that differ everywhere.
    fn many_tiles() -> Image<f32> {
        let (w, h) = (300, 200);
        let data = (0..w * h * 3).map(|i| (i as f32 * 0.618).sin() * 10.0).collect();
        Image::from_vec(w, h, 3, data).unwrap()
    }

    #[test]
    fn the_same_pixels_give_the_same_bytes_and_read_back_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let image = many_tiles();
        let names = ["N.X", "N.Y", "N.Z"];
        let first = dir.path().join("first.exr");
        write_exr(&first, &image, &names).unwrap();
        let meta = exr::meta::MetaData::read_from_file(&first, false).unwrap();
        assert_eq!(meta.headers[0].line_order, LineOrder::Increasing);
        let bytes = std::fs::read(&first).unwrap();
        for again in 0..8 {
            let path = dir.path().join(format!("again{again}.exr"));
            write_exr(&path, &image, &names).unwrap();
            assert!(std::fs::read(&path).unwrap() == bytes, "write {again} gave other bytes");
        }
        let back = read_exr(&first, &names).unwrap();
        assert_eq!((back.width(), back.height(), back.channels()), (300, 200, 3));
        assert!(back.data().iter().zip(image.data()).all(|(a, b)| a.to_bits() == b.to_bits()));
    }
}
