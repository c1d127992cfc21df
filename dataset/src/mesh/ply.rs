//! PLY meshes and point clouds, ASCII and binary (`ply-rs-bw`), keeping every scalar vertex
//! property and its type so that files round-trip without loss.

use super::{push_fan, Mesh, ScalarKind, VertexProperty};
use crate::io::write_atomically;
use crate::{Error, Result};
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{DefaultElement, ElementDef, Encoding, Ply, Property, PropertyDef, PropertyType, ScalarType};
use ply_rs_bw::writer::Writer;
use std::path::Path;

/// How a PLY file stores its payload.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlyEncoding {
    /// `binary_little_endian`: compact and fast.
    Binary,
    /// `ascii`: human-readable.
    Ascii,
}

fn kind_of(t: &ScalarType) -> ScalarKind {
    match t {
        ScalarType::Char => ScalarKind::I8,
        ScalarType::UChar => ScalarKind::U8,
        ScalarType::Short => ScalarKind::I16,
        ScalarType::UShort => ScalarKind::U16,
        ScalarType::Int => ScalarKind::I32,
        ScalarType::UInt => ScalarKind::U32,
        ScalarType::Float => ScalarKind::F32,
        ScalarType::Double => ScalarKind::F64,
    }
}

fn scalar_type(k: ScalarKind) -> ScalarType {
    match k {
        ScalarKind::I8 => ScalarType::Char,
        ScalarKind::U8 => ScalarType::UChar,
        ScalarKind::I16 => ScalarType::Short,
        ScalarKind::U16 => ScalarType::UShort,
        ScalarKind::I32 => ScalarType::Int,
        ScalarKind::U32 => ScalarType::UInt,
        ScalarKind::F32 => ScalarType::Float,
        ScalarKind::F64 => ScalarType::Double,
    }
}

fn scalar_value(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v as f64,
        Property::UChar(v) => v as f64,
        Property::Short(v) => v as f64,
        Property::UShort(v) => v as f64,
        Property::Int(v) => v as f64,
        Property::UInt(v) => v as f64,
        Property::Float(v) => v as f64,
        Property::Double(v) => v,
        _ => return None,
    })
}

fn scalar_property(k: ScalarKind, v: f64) -> Property {
    match k {
        ScalarKind::I8 => Property::Char(v as i8),
        ScalarKind::U8 => Property::UChar(v as u8),
        ScalarKind::I16 => Property::Short(v as i16),
        ScalarKind::U16 => Property::UShort(v as u16),
        ScalarKind::I32 => Property::Int(v as i32),
        ScalarKind::U32 => Property::UInt(v as u32),
        ScalarKind::F32 => Property::Float(v as f32),
        ScalarKind::F64 => Property::Double(v),
    }
}

fn list_indices(p: &Property) -> Option<Vec<i64>> {
    Some(match p {
        Property::ListChar(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListUChar(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListShort(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListUShort(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListInt(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListUInt(v) => v.iter().map(|&i| i as i64).collect(),
        _ => return None,
    })
}

/// Read a PLY file (ASCII or binary). Positions become `f32`; `nx ny nz` become normals;
/// every other scalar vertex property is kept; polygons are split into triangle fans.
pub fn read_ply(path: &Path) -> Result<Mesh> {
    let bytes = crate::io::input::read_bytes(path)?;
    read_ply_bytes(&bytes, path)
}

/// Refuse a header whose element counts need more bytes than the file holds after it (at least
/// each property's size in binary, two characters per property in ASCII), before anything is
/// allocated for them.
fn check_declared_counts(bytes: &[u8], path: &Path) -> Result<()> {
    let Some(end) = bytes.windows(10).position(|w| w == b"end_header").map(|p| p + 10) else {
        return Ok(()); // not a PLY header: the parser says so
    };
    let header = String::from_utf8_lossy(&bytes[..end]);
    let ascii = header.lines().any(|l| l.split_whitespace().take(2).eq(["format", "ascii"]));
    let binary_size = |t: &str| match t {
        "char" | "int8" | "uchar" | "uint8" => 1,
        "short" | "int16" | "ushort" | "uint16" => 2,
        "double" | "float64" => 8,
        _ => 4,
    };
    let mut elements: Vec<(String, u64, u64)> = Vec::new();
    for line in header.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["element", name, count] => elements.push((name.to_string(), count.parse().unwrap_or(u64::MAX), 0)),
            ["property", "list", count_type, ..] => {
                if let Some(e) = elements.last_mut() {
                    e.2 += if ascii { 2 } else { binary_size(count_type) };
                }
            }
            ["property", scalar, ..] => {
                if let Some(e) = elements.last_mut() {
                    e.2 += if ascii { 2 } else { binary_size(scalar) };
                }
            }
            _ => {}
        }
    }
    let payload = (bytes.len() - end) as u64;
    let mut needed = 0u64;
    for (name, count, least) in &elements {
        needed = needed.saturating_add(count.saturating_mul((*least).max(1)));
        if needed > payload {
            return Err(Error::format(
                path,
                format!("header declares {count} {name} elements, more than the {payload} bytes after it can hold (truncated or forged)"),
            ));
        }
    }
    Ok(())
}

/// [`read_ply`] from the bytes of a file; `path` names the source in errors. Binary
/// little-endian files with scalar vertex properties and face lists (what scanners and rmvp
/// write) take a direct path about 30 times faster than the general parser, which handles
/// everything else.
pub fn read_ply_bytes(bytes: &[u8], path: &Path) -> Result<Mesh> {
    check_declared_counts(bytes, path)?;
    match super::ply_binary::read(bytes, path) {
        Some(result) => result,
        None => read_ply_generic(&mut std::io::Cursor::new(bytes), path),
    }
}

/// The general parser (`ply-rs-bw`): ASCII, big-endian, any element layout.
pub fn read_ply_generic(reader: &mut impl std::io::BufRead, path: &Path) -> Result<Mesh> {
    let ply = Parser::<DefaultElement>::new()
        .read_ply(reader)
        .map_err(|e| Error::format(path, format!("not a readable PLY file (truncated or malformed): {e}")))?;
    let def = ply.header.elements.get("vertex").ok_or_else(|| Error::format(path, "no vertex element"))?;
    let vertices = ply.payload.get("vertex").map(Vec::as_slice).unwrap_or_default();
    if vertices.len() != def.count {
        return Err(Error::format(
            path,
            format!("header declares {} vertices, file holds {}", def.count, vertices.len()),
        ));
    }
    let mut columns: Vec<VertexProperty> = def
        .properties
        .values()
        .filter_map(|p| match &p.data_type {
            PropertyType::Scalar(t) => {
                Some(VertexProperty { name: p.name.clone(), kind: kind_of(t), values: Vec::with_capacity(def.count) })
            }
            PropertyType::List(..) => None,
        })
        .collect();
    for (i, v) in vertices.iter().enumerate() {
        for column in &mut columns {
            let value = v
                .get(&column.name)
                .and_then(scalar_value)
                .ok_or_else(|| Error::format(path, format!("vertex {i} lacks scalar property {}", column.name)))?;
            column.values.push(value);
        }
    }
    let mut faces = Vec::new();
    if let Some(face_elements) = ply.payload.get("face") {
        for (f, face) in face_elements.iter().enumerate() {
            let indices = ["vertex_indices", "vertex_index"]
                .iter()
                .find_map(|n| face.get(*n).and_then(list_indices))
                .ok_or_else(|| Error::format(path, format!("face {f} has no vertex_indices list")))?;
            let polygon: Vec<u32> = indices
                .iter()
                .map(|&i| u32::try_from(i).map_err(|_| Error::format(path, format!("face {f} has index {i}"))))
                .collect::<Result<_>>()?;
            push_fan(&mut faces, &polygon);
        }
    }
    mesh_from_columns(columns, faces, path)
}

/// A mesh from its vertex property columns: `x y z` become positions, `nx ny nz` normals, the
/// rest stays as properties.
pub(super) fn mesh_from_columns(mut columns: Vec<VertexProperty>, faces: Vec<[u32; 3]>, path: &Path) -> Result<Mesh> {
    let mut take = |name: &str| columns.iter().position(|c| c.name == name).map(|i| columns.remove(i).values);
    let xyz = [take("x"), take("y"), take("z")];
    let [Some(x), Some(y), Some(z)] = xyz else {
        return Err(Error::format(path, "vertex element lacks x, y or z"));
    };
    let positions = (0..x.len()).map(|i| [x[i] as f32, y[i] as f32, z[i] as f32]).collect();
    let normals = match [take("nx"), take("ny"), take("nz")] {
        [Some(nx), Some(ny), Some(nz)] => {
            Some((0..nx.len()).map(|i| [nx[i] as f32, ny[i] as f32, nz[i] as f32]).collect())
        }
        _ => None,
    };
    Ok(Mesh { positions, normals, faces, vertex_properties: columns })
}

/// Write a mesh as PLY: `float x y z`, `float nx ny nz` if present, every extra property with
/// its own type, and faces as `list uchar int vertex_indices`; binary by the direct writer, ASCII
/// through `ply-rs-bw`.
pub fn write_ply(path: &Path, mesh: &Mesh, encoding: PlyEncoding) -> Result<()> {
    if encoding == PlyEncoding::Binary {
        return write_atomically(path, |out| super::ply_binary::write(out, mesh));
    }
    let mut ply = Ply::<DefaultElement>::new();
    ply.header.encoding = Encoding::Ascii;
    let mut names: Vec<(String, ScalarKind)> =
        ["x", "y", "z"].iter().map(|n| (n.to_string(), ScalarKind::F32)).collect();
    if mesh.normals.is_some() {
        names.extend(["nx", "ny", "nz"].iter().map(|n| (n.to_string(), ScalarKind::F32)));
    }
    names.extend(mesh.vertex_properties.iter().map(|p| (p.name.clone(), p.kind)));
    let mut vertex_def = ElementDef::new("vertex".to_string());
    for (name, kind) in &names {
        vertex_def
            .properties
            .insert(name.clone(), PropertyDef::new(name.clone(), PropertyType::Scalar(scalar_type(*kind))));
    }
    vertex_def.count = mesh.positions.len();
    ply.header.elements.insert("vertex".to_string(), vertex_def);
    let vertices = (0..mesh.positions.len())
        .map(|i| {
            let mut e = DefaultElement::with_capacity(names.len());
            let p = mesh.positions[i];
            for (k, name) in ["x", "y", "z"].iter().enumerate() {
                e.insert(name.to_string(), Property::Float(p[k]));
            }
            if let Some(normals) = &mesh.normals {
                for (k, name) in ["nx", "ny", "nz"].iter().enumerate() {
                    e.insert(name.to_string(), Property::Float(normals[i][k]));
                }
            }
            for prop in &mesh.vertex_properties {
                e.insert(prop.name.clone(), scalar_property(prop.kind, prop.values[i]));
            }
            e
        })
        .collect();
    ply.payload.insert("vertex".to_string(), vertices);
    if !mesh.faces.is_empty() {
        let mut face_def = ElementDef::new("face".to_string());
        let list = PropertyType::List(ScalarType::UChar, ScalarType::Int);
        face_def.properties.insert("vertex_indices".to_string(), PropertyDef::new("vertex_indices".to_string(), list));
        face_def.count = mesh.faces.len();
        ply.header.elements.insert("face".to_string(), face_def);
        let faces = mesh
            .faces
            .iter()
            .map(|f| {
                let mut e = DefaultElement::with_capacity(1);
                e.insert("vertex_indices".to_string(), Property::ListInt(f.map(|i| i as i32).to_vec()));
                e
            })
            .collect();
        ply.payload.insert("face".to_string(), faces);
    }
    write_atomically(path, |out| Writer::new().write_ply(out, &mut ply).map(|_| ()))
}
