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
fn read_array<T: Element, R: Read>(reader: R, path: &Path, available: u64, max_elements: u64) -> Result<Array<T>> {
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
    read_array(BufReader::new(file), path, bytes, u64::MAX)
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
    reader: R,
    path: &Path,
    max_elements: u64,
) -> Result<Vec<(String, Array<T>)>> {
    let mut zip =
        zip::ZipArchive::new(reader).map_err(|e| Error::format(path, format!("not a readable NPZ archive: {e}")))?;
    let mut arrays = Vec::new();
    for i in 0..zip.len() {
        let entry = zip.by_index(i).map_err(|e| Error::format(path, format!("entry {i}: {e}")))?;
        let entry_name = entry.name().map_err(|e| Error::format(path, format!("entry {i}: {e}")))?.into_owned();
        let Some(name) = npyz::npz::array_name_from_file_name(&entry_name).map(str::to_owned) else {
            continue;
        };
        // The entry's declared size bounds what is inflated; the array must fit in it.
        let available = entry.size();
        let array = read_array(entry, path, available, max_elements).map_err(|e| match e {
            Error::Format { message, .. } => Error::format(path, format!("array {name}: {message}")),
            other => other,
        })?;
        arrays.push((name, array));
    }
    Ok(arrays)
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
