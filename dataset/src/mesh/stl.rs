//! STL meshes (ASCII or binary, `stl_io`), as laser-scanner software exports them: vertices are
//! merged by position, facet normals are dropped (vertex normals can be recomputed).

use super::Mesh;
use crate::{Error, Result};
use std::io::BufReader;
use std::path::Path;

/// Read an STL file.
pub fn read_stl(path: &Path) -> Result<Mesh> {
    let file = crate::io::input::open_regular(path)?;
    let stl = stl_io::read_stl(&mut BufReader::new(file))
        .map_err(|e| Error::format(path, format!("not a readable STL file (truncated or malformed): {e}")))?;
    let faces = stl
        .faces
        .iter()
        .map(|f| {
            let ids = f.vertices.map(|i| u32::try_from(i).unwrap_or(u32::MAX));
            if ids.iter().any(|&i| i as usize >= stl.vertices.len()) {
                return Err(Error::format(path, "facet refers to a missing vertex"));
            }
            Ok(ids)
        })
        .collect::<Result<_>>()?;
    Ok(Mesh { positions: stl.vertices.iter().map(|v| v.0).collect(), faces, ..Mesh::default() })
}
