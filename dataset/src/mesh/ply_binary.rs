//! The direct path for binary little-endian PLY: a vertex element of scalar properties and an
//! optional face element with one index list, which is what scanners and rmvp write. Anything
//! else is left to the general parser (`read` returns `None`).

use super::ply::mesh_from_columns;
use super::{push_fan, Mesh, ScalarKind, VertexProperty};
use crate::{Error, Result};
use std::io::Write;
use std::path::Path;

fn kind(name: &str) -> Option<ScalarKind> {
    Some(match name {
        "char" | "int8" => ScalarKind::I8,
        "uchar" | "uint8" => ScalarKind::U8,
        "short" | "int16" => ScalarKind::I16,
        "ushort" | "uint16" => ScalarKind::U16,
        "int" | "int32" => ScalarKind::I32,
        "uint" | "uint32" => ScalarKind::U32,
        "float" | "float32" => ScalarKind::F32,
        "double" | "float64" => ScalarKind::F64,
        _ => return None,
    })
}

fn type_name(k: ScalarKind) -> &'static str {
    match k {
        ScalarKind::I8 => "char",
        ScalarKind::U8 => "uchar",
        ScalarKind::I16 => "short",
        ScalarKind::U16 => "ushort",
        ScalarKind::I32 => "int",
        ScalarKind::U32 => "uint",
        ScalarKind::F32 => "float",
        ScalarKind::F64 => "double",
    }
}

fn size(k: ScalarKind) -> usize {
    match k {
        ScalarKind::I8 | ScalarKind::U8 => 1,
        ScalarKind::I16 | ScalarKind::U16 => 2,
        ScalarKind::I32 | ScalarKind::U32 | ScalarKind::F32 => 4,
        ScalarKind::F64 => 8,
    }
}

/// Decode one little-endian scalar (the slice holds exactly its bytes).
fn decode(k: ScalarKind, b: &[u8]) -> f64 {
    match k {
        ScalarKind::I8 => b[0] as i8 as f64,
        ScalarKind::U8 => b[0] as f64,
        ScalarKind::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
        ScalarKind::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
        ScalarKind::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        ScalarKind::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        ScalarKind::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        ScalarKind::F64 => f64::from_le_bytes(b[..8].try_into().expect("8 bytes")),
    }
}

fn encode(k: ScalarKind, v: f64, out: &mut Vec<u8>) {
    match k {
        ScalarKind::I8 => out.push(v as i8 as u8),
        ScalarKind::U8 => out.push(v as u8),
        ScalarKind::I16 => out.extend((v as i16).to_le_bytes()),
        ScalarKind::U16 => out.extend((v as u16).to_le_bytes()),
        ScalarKind::I32 => out.extend((v as i32).to_le_bytes()),
        ScalarKind::U32 => out.extend((v as u32).to_le_bytes()),
        ScalarKind::F32 => out.extend((v as f32).to_le_bytes()),
        ScalarKind::F64 => out.extend(v.to_le_bytes()),
    }
}

/// The header's elements: (name, count, scalar properties, face list (count type, index type)).
struct Element {
    name: String,
    count: usize,
    scalars: Vec<(String, ScalarKind)>,
    list: Option<(ScalarKind, ScalarKind)>,
}

/// Parse the header; `None` when the file is not one the direct path handles.
fn header(bytes: &[u8]) -> Option<(Vec<Element>, usize)> {
    let end = bytes.windows(11).position(|w| w == b"end_header\n")? + 11;
    let text = std::str::from_utf8(&bytes[..end]).ok()?;
    let mut lines = text.lines();
    if lines.next()? != "ply" {
        return None;
    }
    let mut elements: Vec<Element> = Vec::new();
    for line in lines {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["format", "binary_little_endian", _] => {}
            ["format", ..] => return None,
            ["comment", ..] | ["obj_info", ..] | ["end_header"] => {}
            ["element", name, count] => elements.push(Element {
                name: name.to_string(),
                count: count.parse().ok()?,
                scalars: Vec::new(),
                list: None,
            }),
            ["property", "list", count, index, name] => {
                let e = elements.last_mut()?;
                if e.name != "face" || e.list.is_some() || !["vertex_indices", "vertex_index"].contains(name) {
                    return None;
                }
                e.list = Some((kind(count)?, kind(index)?));
            }
            ["property", ty, name] => elements.last_mut()?.scalars.push((name.to_string(), kind(ty)?)),
            _ => return None,
        }
    }
    let layout_ok = match elements.as_slice() {
        [v] => v.name == "vertex" && v.list.is_none(),
        [v, f] => {
            v.name == "vertex" && v.list.is_none() && f.name == "face" && f.scalars.is_empty() && f.list.is_some()
        }
        _ => false,
    };
    layout_ok.then_some((elements, end))
}

/// Read a binary little-endian PLY the direct way; `None` to defer to the general parser.
pub fn read(bytes: &[u8], path: &Path) -> Option<Result<Mesh>> {
    let (elements, start) = header(bytes)?;
    Some(read_payload(&elements, &bytes[start..], path))
}

fn read_payload(elements: &[Element], payload: &[u8], path: &Path) -> Result<Mesh> {
    let truncated = |what: &str| Error::format(path, format!("not a readable PLY file (truncated): {what}"));
    let vertex = &elements[0];
    let record: usize = vertex.scalars.iter().map(|(_, k)| size(*k)).sum();
    let vertex_bytes = vertex.count.checked_mul(record).ok_or_else(|| truncated("vertex count overflows"))?;
    if payload.len() < vertex_bytes {
        return Err(truncated(&format!(
            "header declares {} vertices, the file holds {} bytes for them",
            vertex.count,
            payload.len()
        )));
    }
    let mut columns: Vec<VertexProperty> = vertex
        .scalars
        .iter()
        .map(|(name, k)| VertexProperty { name: name.clone(), kind: *k, values: Vec::with_capacity(vertex.count) })
        .collect();
    let offsets: Vec<usize> = vertex
        .scalars
        .iter()
        .scan(0, |o, (_, k)| {
            let here = *o;
            *o += size(*k);
            Some(here)
        })
        .collect();
    for r in payload[..vertex_bytes].chunks_exact(record.max(1)).take(vertex.count) {
        for ((column, (_, k)), &o) in columns.iter_mut().zip(&vertex.scalars).zip(&offsets) {
            column.values.push(decode(*k, &r[o..o + size(*k)]));
        }
    }
    let mut faces = Vec::new();
    if let Some(face) = elements.get(1) {
        let (count_kind, index_kind) = face.list.expect("checked in the header");
        let mut at = vertex_bytes;
        let mut polygon = Vec::new();
        for f in 0..face.count {
            let n_bytes = payload
                .get(at..at + size(count_kind))
                .ok_or_else(|| truncated(&format!("face {f} of {}", face.count)))?;
            let n = decode(count_kind, n_bytes);
            at += size(count_kind);
            if n < 0.0 {
                return Err(Error::format(path, format!("face {f} has {n} vertices")));
            }
            polygon.clear();
            for _ in 0..n as usize {
                let b = payload
                    .get(at..at + size(index_kind))
                    .ok_or_else(|| truncated(&format!("face {f} of {}", face.count)))?;
                let i = decode(index_kind, b);
                if i < 0.0 || i > u32::MAX as f64 {
                    return Err(Error::format(path, format!("face {f} has index {i}")));
                }
                polygon.push(i as u32);
                at += size(index_kind);
            }
            push_fan(&mut faces, &polygon);
        }
    }
    mesh_from_columns(columns, faces, path)
}

/// Write binary little-endian PLY: `float x y z`, `float nx ny nz` if present, every extra
/// property with its own type, faces as `list uchar int vertex_indices`.
pub fn write(out: &mut impl Write, mesh: &Mesh) -> std::io::Result<()> {
    let mut columns: Vec<(&str, ScalarKind)> =
        vec![("x", ScalarKind::F32), ("y", ScalarKind::F32), ("z", ScalarKind::F32)];
    if mesh.normals.is_some() {
        columns.extend([("nx", ScalarKind::F32), ("ny", ScalarKind::F32), ("nz", ScalarKind::F32)]);
    }
    columns.extend(mesh.vertex_properties.iter().map(|p| (p.name.as_str(), p.kind)));
    let mut header =
        format!("ply\nformat binary_little_endian 1.0\ncomment rmvp\nelement vertex {}\n", mesh.positions.len());
    for (name, k) in &columns {
        header.push_str(&format!("property {} {name}\n", type_name(*k)));
    }
    if !mesh.faces.is_empty() {
        header.push_str(&format!("element face {}\nproperty list uchar int vertex_indices\n", mesh.faces.len()));
    }
    header.push_str("end_header\n");
    out.write_all(header.as_bytes())?;
    let mut buf = Vec::with_capacity(64 * 1024);
    for (i, p) in mesh.positions.iter().enumerate() {
        p.iter().for_each(|&v| buf.extend(v.to_le_bytes()));
        if let Some(n) = &mesh.normals {
            n[i].iter().for_each(|&v| buf.extend(v.to_le_bytes()));
        }
        for prop in &mesh.vertex_properties {
            encode(prop.kind, prop.values[i], &mut buf);
        }
        if buf.len() > 60 * 1024 {
            out.write_all(&buf)?;
            buf.clear();
        }
    }
    for f in &mesh.faces {
        buf.push(3);
        f.iter().for_each(|&i| buf.extend((i as i32).to_le_bytes()));
        if buf.len() > 60 * 1024 {
            out.write_all(&buf)?;
            buf.clear();
        }
    }
    out.write_all(&buf)
}
