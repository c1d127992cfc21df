//! NumPy `.npy` arrays and `.npz` archives of them (`npyz` and `zip`).

use super::atomic::write_atomically;
use super::input;
use crate::{Error, Result};
use npyz::{NpyFile, WriterBuilder};
use std::io::{BufReader, Read, Seek, Write};
use std::path::Path;

/// An n-dimensional array in C order.
#[derive(Clone, Debug, PartialEq)]
pub struct Array<T> {
    /// Extent of each axis.
    pub shape: Vec<usize>,
    /// Elements, last axis fastest.
    pub data: Vec<T>,
}

/// Element types we read from and write to NumPy files: `f32` and `f64`.
pub trait Element: npyz::Deserialize + npyz::AutoSerialize + Copy {
    /// Convert any float array element type to this one.
    fn from_f64(v: f64) -> Self;
}

impl Element for f32 {
    fn from_f64(v: f64) -> Self {
        v as f32
    }
}

impl Element for f64 {
    fn from_f64(v: f64) -> Self {
        v
    }
}

/// Read one array of at most `max_elements` from `reader`, which holds `available` bytes: the
/// shape its header declares is checked against both before the elements are allocated.
/// An array from `reader`, refused from its header when it holds more than `max_elements`,
/// more than the `available` bytes, or, for an archive entry of `compressed` bytes, more than
/// [`MAX_INFLATION`] times them.
fn read_array<T: Element, R: Read>(
    reader: R,
    path: &Path,
    available: u64,
    max_elements: u64,
    compressed: Option<u64>,
) -> Result<Array<T>> {
    let npy = NpyFile::new(reader).map_err(|e| Error::format(path, format!("bad NPY header: {e}")))?;
    if npy.order() != npyz::Order::C {
        return Err(Error::format(path, "Fortran-ordered arrays are not supported"));
    }
    let shape: Vec<usize> = npy.shape().iter().map(|&n| n as usize).collect();
    let descr = npy.dtype().descr().trim_matches('\'').to_string();
    let element_bytes = match descr.as_str() {
        "<f4" | ">f4" => 4,
        "<f8" | ">f8" => 8,
        other => return Err(Error::format(path, format!("expected a float array, found dtype {other}"))),
    };
    let elements = npy.shape().iter().try_fold(1u64, |n, &d| n.checked_mul(d)).unwrap_or(u64::MAX);
    if elements > max_elements {
        return Err(Error::format(
            path,
            format!("array of shape {shape:?} has more than the {max_elements} elements such a file may hold"),
        ));
    }
    if elements.saturating_mul(element_bytes) > available {
        return Err(Error::format(
            path,
            format!(
                "shape {shape:?} needs {} bytes, the file holds {available} (truncated or forged)",
                elements * element_bytes
            ),
        ));
    }
    let bytes = elements.saturating_mul(element_bytes);
    if let Some(compressed) = compressed.filter(|&c| bytes > c.saturating_mul(MAX_INFLATION).saturating_add(1 << 20)) {
        return Err(Error::format(
            path,
            format!(
                "shape {shape:?} inflates to {bytes} bytes from {compressed}, more than {MAX_INFLATION} times: a \
                 decompression bomb, not an image"
            ),
        ));
    }
    let expected = elements as usize;
    let truncated =
        |e: std::io::Error| Error::format(path, format!("cannot read {expected} elements of shape {shape:?}: {e}"));
    let data: Vec<T> = match descr.as_str() {
        "<f4" | ">f4" if std::mem::size_of::<T>() == 4 => npy.into_vec::<T>().map_err(truncated)?,
        "<f8" | ">f8" if std::mem::size_of::<T>() == 8 => npy.into_vec::<T>().map_err(truncated)?,
        "<f4" | ">f4" => npy.into_vec::<f32>().map_err(truncated)?.into_iter().map(|v| T::from_f64(v as f64)).collect(),
        _ => npy.into_vec::<f64>().map_err(truncated)?.into_iter().map(T::from_f64).collect(),
    };
    if data.len() != expected {
        return Err(Error::format(path, format!("shape {shape:?} needs {expected} elements, file has {}", data.len())));
    }
    Ok(Array { shape, data })
}

/// Read a float `.npy` file (`f4` or `f8`, converted to `T`).
pub fn read_npy<T: Element>(path: &Path) -> Result<Array<T>> {
    let file = input::open_regular(path)?;
    let bytes = file.metadata().map_err(|e| Error::io(path, e))?.len();
    read_array(BufReader::new(file), path, bytes, u64::MAX, None)
}

fn write_array<T: Element, W: Write>(out: W, array: &Array<T>) -> std::io::Result<()> {
    let shape: Vec<u64> = array.shape.iter().map(|&n| n as u64).collect();
    let mut writer = npyz::WriteOptions::new().default_dtype().shape(&shape).writer(out).begin_nd()?;
    writer.extend(array.data.iter().copied())?;
    writer.finish()
}

fn check_shape<T>(path: &Path, array: &Array<T>) -> Result<()> {
    let n: usize = array.shape.iter().product();
    if n != array.data.len() {
        return Err(Error::format(path, format!("shape {:?} does not fit {} elements", array.shape, array.data.len())));
    }
    Ok(())
}

/// Write a `.npy` file.
pub fn write_npy<T: Element>(path: &Path, array: &Array<T>) -> Result<()> {
    check_shape(path, array)?;
    write_atomically(path, |out| write_array(out, array))
}

/// The most an `.npz` entry may inflate, uncompressed bytes per compressed byte (beyond its
/// first MiB). Float images of mostly masked-out pixels compress tens of times; deflate can
/// reach 1032 on zeros, which only a forged file needs.
const MAX_INFLATION: u64 = 256;

/// Read every array of an `.npz` archive, in archive order, as `(name, array)`; each array
/// holds at most four samples per pixel of the largest image ([`input::max_pixels`]).
pub fn read_npz<T: Element>(path: &Path) -> Result<Vec<(String, Array<T>)>> {
    read_npz_limited(path, input::max_pixels().saturating_mul(4))
}

/// [`read_npz`] of an archive whose arrays hold at most `max_elements` each (a camera file's
/// 4x4 matrices, say): a larger one is refused from its header, before it is inflated.
pub fn read_npz_limited<T: Element>(path: &Path, max_elements: u64) -> Result<Vec<(String, Array<T>)>> {
    let file = input::open_regular(path)?;
    read_npz_from(BufReader::new(file), path, max_elements)
}

fn read_npz_from<T: Element, R: Read + Seek>(
    mut reader: R,
    path: &Path,
    max_elements: u64,
) -> Result<Vec<(String, Array<T>)>> {
    let listed = central_directory_entries(&mut reader).map_err(|e| Error::io(path, e))?;
    let mut zip =
        zip::ZipArchive::new(reader).map_err(|e| Error::format(path, format!("not a readable NPZ archive: {e}")))?;
    // The zip reader keeps one entry per name: more entries listed than names read means two
    // share a name, of which numpy reads the last and other readers the first.
    if listed.is_some_and(|n| n > zip.len()) {
        return Err(Error::format(
            path,
            format!(
                "lists {} entries under {} names: two entries of one array (numpy reads the last, other \
                 readers the first)",
                listed.unwrap_or_default(),
                zip.len()
            ),
        ));
    }
    let mut arrays = Vec::new();
    for i in 0..zip.len() {
        let entry = zip.by_index(i).map_err(|e| Error::format(path, format!("entry {i}: {e}")))?;
        let entry_name = entry.name().map_err(|e| Error::format(path, format!("entry {i}: {e}")))?.into_owned();
        let Some(name) = npyz::npz::array_name_from_file_name(&entry_name).map(str::to_owned) else {
            continue;
        };
        // The entry's declared size bounds what is inflated; the array must fit in it, and
        // inflate from at most [`MAX_INFLATION`] times its compressed bytes.
        let available = entry.size();
        let compressed = Some(entry.compressed_size());
        let array = read_array(entry, path, available, max_elements, compressed).map_err(|e| match e {
            Error::Format { message, .. } => Error::format(path, format!("array {name}: {message}")),
            other => other,
        })?;
        arrays.push((name, array));
    }
    Ok(arrays)
}

/// The number of entries a zip archive's end-of-central-directory record lists (`None` when it
/// has none in its last 64 KiB, or is Zip64: the zip reader then decides).
fn central_directory_entries<R: Read + Seek>(reader: &mut R) -> std::io::Result<Option<usize>> {
    let size = reader.seek(std::io::SeekFrom::End(0))?;
    let tail_len = size.min(22 + 0xFFFF);
    reader.seek(std::io::SeekFrom::Start(size - tail_len))?;
    let mut tail = vec![0u8; tail_len as usize];
    reader.read_exact(&mut tail)?;
    reader.seek(std::io::SeekFrom::Start(0))?;
    let Some(at) = tail.windows(4).rposition(|w| w == b"PK\x05\x06") else { return Ok(None) };
    let entries = tail.get(at + 10..at + 12).map(|b| u16::from_le_bytes([b[0], b[1]]));
    Ok(entries.filter(|&n| n != 0xFFFF).map(usize::from))
}

/// Write an `.npz` archive (deflate-compressed, as `numpy.savez_compressed`).
pub fn write_npz<T: Element>(path: &Path, arrays: &[(String, Array<T>)]) -> Result<()> {
    for (_, array) in arrays {
        check_shape(path, array)?;
    }
    write_atomically(path, |out| {
        let mut zip = zip::ZipWriter::new(out);
        let options = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
        for (name, array) in arrays {
            zip.start_file(npyz::npz::file_name_from_array_name(name), options)?;
            write_array(&mut zip, array)?;
        }
        zip.finish()?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_entries_of_one_array_and_a_decompression_bomb_are_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("cameras.npz");
        let small = |v: f64| Array { shape: vec![2], data: vec![v, v] };
        write_npz(&path, &[("a".into(), small(1.0)), ("b".into(), small(2.0))]).unwrap();
        assert_eq!(read_npz::<f64>(&path).unwrap().len(), 2);
        // The second entry renamed to the first's name, in its local header and the directory.
        let bytes = std::fs::read(&path).unwrap();
        let renamed: Vec<u8> = bytes.windows(5).map(|w| w == b"b.npy").collect::<Vec<_>>().iter().enumerate().fold(
            bytes.clone(),
            |mut out, (i, &hit)| {
                if hit {
                    out[i] = b'a';
                }
                out
            },
        );
        std::fs::write(&path, renamed).unwrap();
        let err = read_npz::<f64>(&path).unwrap_err().to_string();
        assert!(err.contains("cameras.npz") && err.contains("two entries of one array"), "{err}");

        // 32 MB of zeros deflate to about 32 kB.
        let zeros = Array { shape: vec![8 << 20], data: vec![0f32; 8 << 20] };
        write_npz(&path, &[("S0".into(), zeros)]).unwrap();
        let err = read_npz::<f32>(&path).unwrap_err().to_string();
        assert!(err.contains("cameras.npz") && err.contains("decompression bomb"), "{err}");
        // An image of mostly masked-out pixels still reads.
        let masked: Vec<f32> = (0..1 << 20).map(|i| if i % 16 == 0 { (i as f32).sin() } else { 0.0 }).collect();
        write_npz(&path, &[("S0".into(), Array { shape: vec![1 << 20], data: masked })]).unwrap();
        assert!(read_npz::<f32>(&path).is_ok());
    }
}
