//! Wavefront OBJ meshes: read with `tobj` (triangulated, one index per vertex), written as text.

use super::{Mesh, ScalarKind, VertexProperty};
use crate::io::{input, write_atomically};
use crate::{Error, Result};
use std::io::{BufReader, Write};
use std::path::Path;

/// Read an OBJ file; all its objects are merged into one mesh. Texture coordinates become the
/// vertex properties `u` and `v`. Materials are ignored: the `mtllib` files an OBJ names are
/// never opened.
pub fn read_obj(path: &Path) -> Result<Mesh> {
    let options = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let mut reader = BufReader::new(input::open_regular(path)?);
    let no_materials = |_: &Path| Ok((Vec::new(), Default::default()));
    let (models, _materials) = tobj::load_obj_buf(&mut reader, &options, no_materials)
        .map_err(|e| Error::format(path, format!("not a readable OBJ file: {e}")))?;
    let mut mesh = Mesh::default();
    let mut normals = Vec::new();
    let (mut u, mut v) = (Vec::new(), Vec::new());
    let all_have_normals = models.iter().all(|m| m.mesh.normals.len() == m.mesh.positions.len());
    let all_have_texcoords = models.iter().all(|m| 2 * m.mesh.positions.len() == 3 * m.mesh.texcoords.len());
    for model in &models {
        let m = &model.mesh;
        let offset = mesh.positions.len() as u32;
        mesh.positions.extend(m.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        normals.extend(m.normals.chunks_exact(3).map(|n| [n[0], n[1], n[2]]));
        u.extend(m.texcoords.chunks_exact(2).map(|t| t[0] as f64));
        v.extend(m.texcoords.chunks_exact(2).map(|t| t[1] as f64));
        mesh.faces.extend(m.indices.chunks_exact(3).map(|f| [f[0] + offset, f[1] + offset, f[2] + offset]));
    }
    if all_have_normals && !normals.is_empty() {
        mesh.normals = Some(normals);
    }
    if all_have_texcoords && !u.is_empty() {
        mesh.vertex_properties.push(VertexProperty { name: "u".into(), kind: ScalarKind::F32, values: u });
        mesh.vertex_properties.push(VertexProperty { name: "v".into(), kind: ScalarKind::F32, values: v });
    }
    Ok(mesh)
}

/// Write positions, texture coordinates, normals and triangles as OBJ text (other properties are
/// not representable).
pub fn write_obj(path: &Path, mesh: &Mesh) -> Result<()> {
    write_atomically(path, |out| {
        writeln!(out, "# rmvp mesh: {} vertices, {} triangles", mesh.positions.len(), mesh.faces.len())?;
        for p in &mesh.positions {
            writeln!(out, "v {} {} {}", p[0], p[1], p[2])?;
        }
        let texcoords = mesh.texcoords();
        for t in texcoords.iter().flatten() {
            writeln!(out, "vt {} {}", t[0], t[1])?;
        }
        if let Some(normals) = &mesh.normals {
            for n in normals {
                writeln!(out, "vn {} {} {}", n[0], n[1], n[2])?;
            }
        }
        for f in &mesh.faces {
            let [a, b, c] = f.map(|i| i + 1);
            match (texcoords.is_some(), mesh.normals.is_some()) {
                (true, true) => writeln!(out, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}")?,
                (true, false) => writeln!(out, "f {a}/{a} {b}/{b} {c}/{c}")?,
                (false, true) => writeln!(out, "f {a}//{a} {b}//{b} {c}//{c}")?,
                (false, false) => writeln!(out, "f {a} {b} {c}")?,
            }
        }
        Ok(())
    })
}
