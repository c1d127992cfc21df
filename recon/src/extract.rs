//! Surface extraction: the SDF's zero level set on a regular grid over the unit cube, by
//! marching tetrahedra (each cube cut into six tetrahedra around its main diagonal). Unlike
//! table-driven marching cubes it has no ambiguous cases, so the mesh is watertight by
//! construction; vertices on shared grid edges are welded, and the result is mapped to the
//! world by the scene's `scale_mat`.

use crate::data::Frame;
use crate::model::Model;
use crate::Result;
use rayon::prelude::*;
use rmvp_dataset::Mesh;
use std::collections::HashMap;

/// The six tetrahedra of a cube (corner k at offset (k & 1, k >> 1 & 1, k >> 2 & 1)), all
/// sharing the diagonal 0-7.
const TETRAHEDRA: [[usize; 4]; 6] =
    [[0, 1, 3, 7], [0, 3, 2, 7], [0, 2, 6, 7], [0, 6, 4, 7], [0, 4, 5, 7], [0, 5, 1, 7]];

/// Where the mesh's SDF is evaluated.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Device {
    /// The CPU engine, on all threads.
    #[default]
    Cpu,
    /// CUDA kernels on GPU 0 (NVRTC and the driver loaded at run time).
    Cuda,
}

/// Where surface extraction evaluates the SDF (unit-sphere frame): the CPU engine
/// ([`CpuSdf`]) or, with the `cuda` feature, the GPU (`crate::cuda::CudaSdf`).
pub trait SdfEvaluator: Sync {
    /// The SDF at `points` (n x 3).
    fn sdf(&self, points: &[f32]) -> Result<Vec<f32>>;
    /// The SDF on the `(n + 1)^3` grid over `[-1, 1]^3`, x fastest; points outside the unit
    /// sphere are not evaluated (set to +1).
    fn sdf_grid(&self, n: usize) -> Result<Vec<f32>>;
}

/// The SDF by the CPU engine, on all threads.
pub struct CpuSdf<'a> {
    model: &'a Model,
    params: &'a [f32],
    level_weight: &'a [f32],
}

impl<'a> CpuSdf<'a> {
    /// `model`'s field with `params` under the hash grid's `level_weight`.
    pub fn new(model: &'a Model, params: &'a [f32], level_weight: &'a [f32]) -> Self {
        Self { model, params, level_weight }
    }
}

impl SdfEvaluator for CpuSdf<'_> {
    fn sdf(&self, points: &[f32]) -> Result<Vec<f32>> {
        Ok(points
            .par_chunks(3 * 4096)
            .flat_map_iter(|chunk| self.model.field.sdf(self.params, chunk, self.level_weight))
            .collect())
    }

    fn sdf_grid(&self, n: usize) -> Result<Vec<f32>> {
        let side = n + 1;
        let coord = |i: usize| -1.0 + 2.0 * i as f32 / n as f32;
        Ok((0..side)
            .into_par_iter()
            .flat_map_iter(|z| {
                let mut pts = Vec::new();
                let mut slots = Vec::new();
                let mut out = vec![1.0f32; side * side];
                for y in 0..side {
                    for x in 0..side {
                        let p = [coord(x), coord(y), coord(z)];
                        if p[0] * p[0] + p[1] * p[1] + p[2] * p[2] < 1.0 {
                            pts.extend(p);
                            slots.push(y * side + x);
                        }
                    }
                }
                for (chunk_pts, chunk_slots) in pts.chunks(3 * 4096).zip(slots.chunks(4096)) {
                    let values = self.model.field.sdf(self.params, chunk_pts, self.level_weight);
                    for (v, &s) in values.into_iter().zip(chunk_slots) {
                        out[s] = v;
                    }
                }
                out
            })
            .collect())
    }
}

/// Triangulate the zero level set of `values` (`(n + 1)^3`, x fastest, over `[-1, 1]^3`),
/// outward normals (towards positive values), vertices in the world `frame`.
pub fn marching_tetrahedra(values: &[f32], n: usize, frame: &Frame) -> Mesh {
    let side = n + 1;
    let index = |x: usize, y: usize, z: usize| (z * side + y) * side + x;
    let coord = |i: usize| -1.0 + 2.0 * i as f32 / n as f32;
    let position = |g: usize| [coord(g % side), coord(g / side % side), coord(g / (side * side))];
    let mut vertices: HashMap<(usize, usize), u32> = HashMap::new();
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut faces: Vec<[u32; 3]> = Vec::new();
    let mut vertex = |a: usize, b: usize, positions: &mut Vec<[f32; 3]>| -> u32 {
        let key = (a.min(b), a.max(b));
        *vertices.entry(key).or_insert_with(|| {
            let (va, vb) = (values[key.0], values[key.1]);
            let t = (va / (va - vb)).clamp(0.0, 1.0);
            let (pa, pb) = (position(key.0), position(key.1));
            positions.push([0, 1, 2].map(|k| pa[k] + t * (pb[k] - pa[k])));
            (positions.len() - 1) as u32
        })
    };
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let corner: [usize; 8] =
                    std::array::from_fn(|k| index(x + (k & 1), y + (k >> 1 & 1), z + (k >> 2 & 1)));
                let inside = corner.iter().filter(|&&c| values[c] < 0.0).count();
                if inside == 0 || inside == 8 {
                    continue;
                }
                for tet in TETRAHEDRA {
                    let g = tet.map(|k| corner[k]);
                    let (neg, pos): (Vec<usize>, Vec<usize>) = g.iter().partition(|&&c| values[c] < 0.0);
                    // Triangles as pairs of grid corners (edges); oriented on the edges' midpoints,
                    // which never degenerate, then mapped to the interpolated vertices.
                    let tris: Vec<[(usize, usize); 3]> = match (neg.len(), pos.len()) {
                        (1, 3) | (3, 1) => {
                            let (lone, others) = if neg.len() == 1 { (neg[0], &pos) } else { (pos[0], &neg) };
                            vec![[0, 1, 2].map(|k| (lone, others[k]))]
                        }
                        (2, 2) => {
                            let q = [(neg[0], pos[0]), (neg[0], pos[1]), (neg[1], pos[1]), (neg[1], pos[0])];
                            vec![[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
                        }
                        _ => Vec::new(),
                    };
                    let mean = |s: &[usize]| {
                        let mut m = [0f32; 3];
                        for &c in s {
                            let p = position(c);
                            (0..3).for_each(|k| m[k] += p[k] / s.len() as f32);
                        }
                        m
                    };
                    let (mp, mn) = (mean(&pos), mean(&neg));
                    let out_dir = [0, 1, 2].map(|k| mp[k] - mn[k]);
                    for mut t in tris {
                        let [a, b, c] = t.map(|(u, v)| mean(&[u, v]));
                        let e1 = [0, 1, 2].map(|k| b[k] - a[k]);
                        let e2 = [0, 1, 2].map(|k| c[k] - a[k]);
                        let nrm = [
                            e1[1] * e2[2] - e1[2] * e2[1],
                            e1[2] * e2[0] - e1[0] * e2[2],
                            e1[0] * e2[1] - e1[1] * e2[0],
                        ];
                        if nrm[0] * out_dir[0] + nrm[1] * out_dir[1] + nrm[2] * out_dir[2] < 0.0 {
                            t.swap(1, 2);
                        }
                        faces.push(t.map(|(u, v)| vertex(u, v, &mut positions)));
                    }
                }
            }
        }
    }
    let positions = positions
        .into_iter()
        .map(|p| {
            let w = frame.point_to_world(p);
            [w.x as f32, w.y as f32, w.z as f32]
        })
        .collect();
    Mesh { positions, normals: None, faces, vertex_properties: Vec::new() }
}

/// The surface of the SDF that `sdf` evaluates as a world-frame mesh, from an `n^3` grid,
/// with vertex normals from the SDF's gradient (central differences of step `fd_step`, as in
/// training).
pub fn extract_mesh(sdf: &dyn SdfEvaluator, n: usize, frame: &Frame, fd_step: f32) -> Result<Mesh> {
    let mut mesh = marching_tetrahedra(&sdf.sdf_grid(n)?, n, frame);
    let probes: Vec<f32> = mesh
        .positions
        .par_iter()
        .flat_map_iter(|p| {
            let u = frame.point_from_world(&nalgebra::Point3::new(p[0] as f64, p[1] as f64, p[2] as f64));
            (0..6).flat_map(move |k| {
                let mut q = u;
                q[k / 2] += if k % 2 == 0 { fd_step } else { -fd_step };
                q
            })
        })
        .collect();
    let values = sdf.sdf(&probes)?;
    let normals = values
        .chunks_exact(6)
        .map(|d| {
            let world = frame.dir_to_world([d[0] - d[1], d[2] - d[3], d[4] - d[5]]);
            [world.x as f32, world.y as f32, world.z as f32]
        })
        .collect();
    mesh.normals = Some(normals);
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix4;

    #[test]
    fn sphere_is_watertight_and_on_the_level_set() {
        let n = 40;
        let side = n + 1;
        let values: Vec<f32> = (0..side * side * side)
            .map(|g| {
                let p = [g % side, g / side % side, g / (side * side)].map(|i| -1.0 + 2.0 * i as f32 / n as f32);
                (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 0.6
            })
            .collect();
        let frame = Frame::new(Matrix4::new_scaling(2.0)).unwrap();
        let mesh = marching_tetrahedra(&values, n, &frame);
        // Every vertex on the scaled sphere (radius 1.2) up to interpolation error.
        for p in &mesh.positions {
            let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            assert!((r - 1.2).abs() < 0.02, "{r}");
        }
        // Watertight: every edge shared by exactly two faces, in opposite directions.
        let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
        for f in &mesh.faces {
            for k in 0..3 {
                *edges.entry((f[k], f[(k + 1) % 3])).or_default() += 1;
            }
        }
        let bad: Vec<_> = edges.iter().filter(|(&(a, b), &c)| c != 1 || edges.get(&(b, a)) != Some(&1)).collect();
        assert!(bad.is_empty(), "{} of {} edges: {:?}", bad.len(), edges.len(), &bad[..bad.len().min(5)]);
        // Outward orientation: positive signed volume close to the sphere's.
        let volume: f32 = mesh
            .faces
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|i| mesh.positions[i as usize]);
                (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                    + a[2] * (b[0] * c[1] - b[1] * c[0]))
                    / 6.0
            })
            .sum();
        let want = 4.0 / 3.0 * std::f32::consts::PI * 1.2f32.powi(3);
        assert!((volume / want - 1.0).abs() < 0.02, "{volume} vs {want}");
    }
}
