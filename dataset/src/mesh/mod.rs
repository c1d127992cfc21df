//! Triangle meshes and point clouds with normals, colours and extra per-vertex properties,
//! read and written as PLY ([`ply`]) and OBJ ([`obj`]), read from STL ([`stl`]).

pub mod obj;
pub mod ply;
mod ply_binary;
pub mod stl;

use crate::{Error, Result};
use std::path::Path;

/// The storage type of a per-vertex property, kept so that files round-trip without loss.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScalarKind {
    /// Signed 8-bit integer.
    I8,
    /// Unsigned 8-bit integer.
    U8,
    /// Signed 16-bit integer.
    I16,
    /// Unsigned 16-bit integer.
    U16,
    /// Signed 32-bit integer.
    I32,
    /// Unsigned 32-bit integer.
    U32,
    /// 32-bit float.
    F32,
    /// 64-bit float.
    F64,
}

impl ScalarKind {
    /// The full-scale value of an integer colour of this kind (255 for `U8`), 1 for floats.
    pub fn color_full_scale(self) -> f64 {
        match self {
            ScalarKind::U8 | ScalarKind::I8 => 255.0,
            ScalarKind::U16 | ScalarKind::I16 => 65535.0,
            ScalarKind::U32 | ScalarKind::I32 => u32::MAX as f64,
            ScalarKind::F32 | ScalarKind::F64 => 1.0,
        }
    }
}

/// A named per-vertex scalar (colour, roughness, confidence, ...), every type held exactly as
/// `f64`.
#[derive(Clone, Debug, PartialEq)]
pub struct VertexProperty {
    /// Property name as in the file (`red`, `roughness_0`, ...).
    pub name: String,
    /// Storage type in the file.
    pub kind: ScalarKind,
    /// One value per vertex.
    pub values: Vec<f64>,
}

/// A triangle mesh (or, with no faces, a point cloud).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Per-vertex normals, if the file has them.
    pub normals: Option<Vec<[f32; 3]>>,
    /// Triangles as vertex indices (polygons are split into fans on reading).
    pub faces: Vec<[u32; 3]>,
    /// Every other per-vertex property, in file order.
    pub vertex_properties: Vec<VertexProperty>,
}

impl Mesh {
    /// Read a mesh by extension: `.ply`, `.obj` or `.stl`.
    pub fn read(path: &Path) -> Result<Self> {
        let mesh = match extension(path).as_str() {
            "ply" => ply::read_ply(path)?,
            "obj" => obj::read_obj(path)?,
            "stl" => stl::read_stl(path)?,
            other => {
                return Err(Error::format(path, format!("unknown mesh format {other:?} (use .ply, .obj or .stl)")))
            }
        };
        mesh.validate().map_err(|e| e.in_file(path))?;
        Ok(mesh)
    }

    /// Write a mesh by extension: `.ply` (binary) or `.obj`.
    pub fn write(&self, path: &Path) -> Result<()> {
        self.validate().map_err(|e| e.in_file(path))?;
        match extension(path).as_str() {
            "ply" => ply::write_ply(path, self, ply::PlyEncoding::Binary),
            "obj" => obj::write_obj(path, self),
            other => Err(Error::format(path, format!("unknown mesh format {other:?} (use .ply or .obj)"))),
        }
    }

    /// The property called `name`, if present.
    pub fn property(&self, name: &str) -> Option<&VertexProperty> {
        self.vertex_properties.iter().find(|p| p.name == name)
    }

    /// Per-vertex RGB colours in `[0, 1]` from `red/green/blue` or `r/g/b` properties; integer
    /// colours are divided by their full scale.
    pub fn colors(&self) -> Option<Vec<[f32; 3]>> {
        let channels = [["red", "green", "blue"], ["r", "g", "b"]]
            .iter()
            .find_map(|names| names.iter().map(|n| self.property(n)).collect::<Option<Vec<_>>>())?;
        Some(
            (0..self.positions.len())
                .map(|i| [0, 1, 2].map(|c| (channels[c].values[i] / channels[c].kind.color_full_scale()) as f32))
                .collect(),
        )
    }

    /// Per-vertex texture coordinates from `u/v`, `s/t` or `texture_u/texture_v` properties
    /// (OpenGL convention: `v = 0` at the bottom row of the texture image).
    pub fn texcoords(&self) -> Option<Vec<[f32; 2]>> {
        let [u, v] = [["u", "v"], ["s", "t"], ["texture_u", "texture_v"]]
            .iter()
            .find_map(|names| Some([self.property(names[0])?, self.property(names[1])?]))?;
        Some(u.values.iter().zip(&v.values).map(|(&a, &b)| [a as f32, b as f32]).collect())
    }

    /// Largest distance of a vertex from the origin (0 for an empty mesh).
    pub fn radius(&self) -> f32 {
        self.positions.iter().map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt()).fold(0.0, f32::max)
    }

    /// Axis-aligned bounds `(min, max)`; `None` for an empty mesh.
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        let first = *self.positions.first()?;
        Some(self.positions.iter().fold((first, first), |(lo, hi), p| {
            ([0, 1, 2].map(|k| lo[k].min(p[k])), [0, 1, 2].map(|k| hi[k].max(p[k])))
        }))
    }

    /// Each face's connected part: faces that share a vertex, directly or through others, are
    /// in one part; parts are numbered from 0 in the order of their first face. Returns the
    /// part of each face and the number of parts.
    pub fn face_parts(&self) -> (Vec<u32>, usize) {
        let mut parent: Vec<u32> = (0..self.positions.len() as u32).collect();
        fn root(parent: &mut [u32], mut i: u32) -> u32 {
            while parent[i as usize] != i {
                let up = parent[parent[i as usize] as usize];
                parent[i as usize] = up;
                i = up;
            }
            i
        }
        for face in &self.faces {
            let a = root(&mut parent, face[0]);
            for &v in &face[1..] {
                let b = root(&mut parent, v);
                parent[b.max(a) as usize] = b.min(a);
            }
        }
        let mut number = vec![u32::MAX; self.positions.len()];
        let mut parts = 0u32;
        let of_face = self
            .faces
            .iter()
            .map(|face| {
                let r = root(&mut parent, face[0]) as usize;
                if number[r] == u32::MAX {
                    number[r] = parts;
                    parts += 1;
                }
                number[r]
            })
            .collect();
        (of_face, parts as usize)
    }

    /// The mesh with only the faces where `keep` is true, and only the vertices they use (with
    /// their normals and properties), in their order.
    pub fn with_faces(&self, keep: &[bool]) -> Mesh {
        let kept = || self.faces.iter().zip(keep).filter(|(_, &k)| k).map(|(face, _)| face);
        let mut index = vec![u32::MAX; self.positions.len()];
        kept().flatten().for_each(|&v| index[v as usize] = 0);
        let used: Vec<usize> = (0..index.len()).filter(|&i| index[i] == 0).collect();
        for (new, &old) in used.iter().enumerate() {
            index[old] = new as u32;
        }
        let faces = kept().map(|f| f.map(|v| index[v as usize])).collect();
        let pick = |values: &[[f32; 3]]| used.iter().map(|&i| values[i]).collect::<Vec<_>>();
        Mesh {
            positions: pick(&self.positions),
            normals: self.normals.as_deref().map(pick),
            faces,
            vertex_properties: self
                .vertex_properties
                .iter()
                .map(|p| VertexProperty {
                    name: p.name.clone(),
                    kind: p.kind,
                    values: used.iter().map(|&i| p.values[i]).collect(),
                })
                .collect(),
        }
    }

    /// Check counts, indices and finiteness.
    pub fn validate(&self) -> Result<()> {
        let n = self.positions.len();
        if let Some(i) = self.positions.iter().position(|p| !p.iter().all(|v| v.is_finite())) {
            return Err(Error::invalid(format!("vertex {i} has a non-finite position")));
        }
        if let Some(normals) = &self.normals {
            if normals.len() != n {
                return Err(Error::invalid(format!("{} normals for {n} vertices", normals.len())));
            }
        }
        for p in &self.vertex_properties {
            if p.values.len() != n {
                return Err(Error::invalid(format!(
                    "property {} has {} values for {n} vertices",
                    p.name,
                    p.values.len()
                )));
            }
        }
        if let Some((f, face)) = self.faces.iter().enumerate().find(|(_, f)| f.iter().any(|&i| i as usize >= n)) {
            return Err(Error::invalid(format!("face {f} {face:?} refers to a vertex beyond the {n} vertices")));
        }
        Ok(())
    }
}

fn extension(path: &Path) -> String {
    path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default()
}

/// Split a polygon into a triangle fan.
pub(crate) fn push_fan(faces: &mut Vec<[u32; 3]>, polygon: &[u32]) {
    for k in 1..polygon.len().saturating_sub(1) {
        faces.push([polygon[0], polygon[k], polygon[k + 1]]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two tetrahedra apart and a triangle sharing a vertex with the second, with a normal and
    /// a property per vertex equal to the vertex's index.
    fn three_pieces() -> Mesh {
        let tet = |o: f32| [[o, 0.0, 0.0], [o + 1.0, 0.0, 0.0], [o, 1.0, 0.0], [o, 0.0, 1.0]];
        let mut positions: Vec<[f32; 3]> = tet(0.0).into_iter().chain(tet(5.0)).collect();
        positions.extend([[9.0, 9.0, 9.0], [8.0, 9.0, 9.0], [20.0, 0.0, 0.0]]);
        let tet_faces = |b: u32| [[b, b + 2, b + 1], [b, b + 1, b + 3], [b, b + 3, b + 2], [b + 1, b + 2, b + 3]];
        let mut faces: Vec<[u32; 3]> = Vec::new();
        faces.extend(tet_faces(4));
        faces.push([7, 8, 9]);
        faces.extend(tet_faces(0));
        let n = positions.len();
        Mesh {
            normals: Some((0..n).map(|i| [i as f32, 0.0, 0.0]).collect()),
            vertex_properties: vec![VertexProperty {
                name: "index".into(),
                kind: ScalarKind::U32,
                values: (0..n).map(|i| i as f64).collect(),
            }],
            positions,
            faces,
        }
    }

    #[test]
    fn faces_sharing_a_vertex_are_one_part_numbered_by_first_face() {
        let (parts, count) = three_pieces().face_parts();
        assert_eq!(count, 2);
        assert_eq!(parts, [0, 0, 0, 0, 0, 1, 1, 1, 1]);
    }

    #[test]
    fn keeping_faces_keeps_their_vertices_normals_and_properties_only() {
        let mesh = three_pieces();
        let keep: Vec<bool> = (0..mesh.faces.len()).map(|f| f == 4 || f >= 5).collect();
        let kept = mesh.with_faces(&keep);
        kept.validate().unwrap();
        let old = [0, 1, 2, 3, 7, 8, 9];
        assert_eq!(kept.positions, old.map(|i| mesh.positions[i]));
        assert_eq!(kept.normals.as_deref().unwrap(), old.map(|i| [i as f32, 0.0, 0.0]));
        assert_eq!(kept.vertex_properties[0].values, old.map(|i| i as f64));
        // The faces name the same points as before.
        let points = |m: &Mesh, f: &[u32; 3]| f.map(|v| m.positions[v as usize]);
        let before: Vec<_> = mesh.faces.iter().zip(&keep).filter(|(_, &k)| k).map(|(f, _)| points(&mesh, f)).collect();
        let after: Vec<_> = kept.faces.iter().map(|f| points(&kept, f)).collect();
        assert_eq!(before, after);
    }
}
