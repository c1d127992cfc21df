//! The SDF field at a batch of sample points and at their six finite-difference neighbours
//! (Neuralangelo): SDF values, gradients, unit normals, Laplacians and features from 7 field
//! evaluations per point, so that no second-order gradient is ever needed; and the backward
//! pass from gradients on each of those quantities to the parameters.

use crate::engine::vector::dot;
use crate::model::{FieldCache, GridGradient, Model};

/// The six finite-difference offsets, in the order the field evaluates them.
const OFFSETS: [(usize, f32); 6] = [(0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0), (2, 1.0), (2, -1.0)];

/// The field evaluated at `n` points (row-major `n x k` arrays).
pub struct FieldSamples {
    /// The points (n x 3).
    pub points: Vec<f32>,
    /// SDF values (n).
    pub sdf: Vec<f32>,
    /// Central-difference SDF gradients (n x 3).
    pub gradients: Vec<f32>,
    /// Unit normals, the gradients normalised (n x 3).
    pub normals: Vec<f32>,
    /// Finite-difference Laplacians (n): twice the mean curvature on an SDF.
    pub laplacians: Vec<f32>,
    /// The field's feature vectors (n x features).
    pub features: Vec<f32>,
    /// Finite-difference step.
    pub step: f32,
    cache: FieldCache,
}

/// The points followed by their six finite-difference neighbours, offset by `step`, in
/// [`OFFSETS`] order.
fn with_neighbours(points: &[f32], step: f32) -> Vec<f32> {
    let mut all = Vec::with_capacity(7 * points.len());
    all.extend_from_slice(points);
    for (axis, sign) in OFFSETS {
        for p in points.chunks_exact(3) {
            let mut q = [p[0], p[1], p[2]];
            q[axis] += sign * step;
            all.extend(q);
        }
    }
    all
}

/// Gradients of a loss with respect to what [`FieldSamples`] holds (each `None`-free, sized
/// like the quantity).
pub struct FieldGrad<'a> {
    /// d loss / d SDF (n).
    pub sdf: &'a [f32],
    /// d loss / d unit normal (n x 3).
    pub normals: &'a [f32],
    /// d loss / d features (n x features).
    pub features: &'a [f32],
    /// d loss / d gradient, on top of what flows through the normals (n x 3, e.g. Eikonal).
    pub gradients: &'a [f32],
    /// d loss / d Laplacian (n, the curvature loss).
    pub laplacians: &'a [f32],
}

impl FieldSamples {
    /// Evaluate the field at `points` (n x 3) with finite-difference step `step`, keeping what
    /// [`FieldSamples::backward`] needs.
    pub fn evaluate(model: &Model, params: &[f32], level_weight: &[f32], points: Vec<f32>, step: f32) -> Self {
        let mut cache = FieldCache::default();
        let out = model.field.forward(params, &with_neighbours(&points, step), level_weight, &mut cache);
        Self::from_outputs(model, points, &out, step, cache)
    }

    /// The same without keeping anything for a backward pass (inference).
    pub fn infer(model: &Model, params: &[f32], level_weight: &[f32], points: Vec<f32>, step: f32) -> Self {
        let out = model.field.infer(params, &with_neighbours(&points, step), level_weight);
        Self::from_outputs(model, points, &out, step, FieldCache::default())
    }

    /// SDF, gradients, normals, Laplacians and features from the field's outputs at the points
    /// and their neighbours.
    fn from_outputs(model: &Model, points: Vec<f32>, out: &[f32], step: f32, cache: FieldCache) -> Self {
        let n = points.len() / 3;
        let width = model.field.outputs();
        let sdf: Vec<f32> = (0..n).map(|i| out[i * width]).collect();
        let features: Vec<f32> = (0..n).flat_map(|i| out[i * width + 1..(i + 1) * width].iter().copied()).collect();
        let mut gradients = vec![0f32; 3 * n];
        let mut normals = vec![0f32; 3 * n];
        let mut laplacians = vec![0f32; n];
        for i in 0..n {
            let neighbours: f32 = (1..7).map(|b| out[(b * n + i) * width]).sum();
            laplacians[i] = (neighbours - 6.0 * sdf[i]) / (step * step);
            for axis in 0..3 {
                let plus = out[((1 + 2 * axis) * n + i) * width];
                let minus = out[((2 + 2 * axis) * n + i) * width];
                gradients[3 * i + axis] = (plus - minus) / (2.0 * step);
            }
            let g = &gradients[3 * i..3 * i + 3];
            let len = dot([g[0], g[1], g[2]], [g[0], g[1], g[2]]).sqrt().max(1e-8);
            for axis in 0..3 {
                normals[3 * i + axis] = g[axis] / len;
            }
        }
        Self { points, sdf, gradients, normals, laplacians, features, step, cache }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.sdf.len()
    }

    /// True for no points.
    pub fn is_empty(&self) -> bool {
        self.sdf.is_empty()
    }

    /// Add the networks' parameter gradients of `d` into `grad`; the hash grid's are returned
    /// (see [`Field::backward`](crate::model::Field::backward)).
    pub fn backward(&self, model: &Model, params: &[f32], d: &FieldGrad, grad: &mut [f32]) -> GridGradient {
        let n = self.len();
        let width = model.field.outputs();
        let mut d_out = vec![0f32; 7 * n * width];
        let h2 = self.step * self.step;
        for i in 0..n {
            d_out[i * width] = d.sdf[i] - 6.0 * d.laplacians[i] / h2;
            for b in 1..7 {
                d_out[(b * n + i) * width] += d.laplacians[i] / h2;
            }
            d_out[i * width + 1..(i + 1) * width].copy_from_slice(&d.features[(width - 1) * i..(width - 1) * (i + 1)]);
            let nv = [self.normals[3 * i], self.normals[3 * i + 1], self.normals[3 * i + 2]];
            let dn = [0, 1, 2].map(|k| d.normals[3 * i + k]);
            let g = &self.gradients[3 * i..3 * i + 3];
            let len = dot([g[0], g[1], g[2]], [g[0], g[1], g[2]]).sqrt().max(1e-8);
            let along = dot(dn, nv);
            for axis in 0..3 {
                let dg = (dn[axis] - nv[axis] * along) / len + d.gradients[3 * i + axis];
                let step = dg / (2.0 * self.step);
                d_out[((1 + 2 * axis) * n + i) * width] += step;
                d_out[((2 + 2 * axis) * n + i) * width] -= step;
            }
        }
        model.field.backward(params, &self.cache, &d_out, grad)
    }
}
