//! NeuS volume rendering inside the unit sphere: coarse samples, hierarchical up-sampling with
//! fixed sharpness, and alpha compositing of per-sample Stokes vectors, normals and depths, with
//! the backward pass. Normals are central finite differences of the SDF (Neuralangelo), so each
//! sample evaluates the field 7 times and no second-order gradient is needed.

use crate::model::{FieldCache, Model, ShadingCache, ShadingInput, STOKES};
use crate::pbrdf::dot;

/// A camera ray in the unit-sphere frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Ray {
    /// Origin (the camera centre).
    pub origin: [f32; 3],
    /// Unit direction.
    pub dir: [f32; 3],
    /// The ray's Stokes frame, x axis.
    pub frame_x: [f32; 3],
    /// The ray's Stokes frame, y axis.
    pub frame_y: [f32; 3],
    /// Entry into the unit sphere.
    pub near: f32,
    /// Exit from the unit sphere.
    pub far: f32,
}

impl Ray {
    /// Clip a ray to the unit sphere; `None` when it misses.
    pub fn clipped(origin: [f32; 3], dir: [f32; 3], frame_x: [f32; 3], frame_y: [f32; 3]) -> Option<Self> {
        let (near, far) = unit_sphere_span(origin, dir)?;
        (far > near + 1e-4).then_some(Self { origin, dir, frame_x, frame_y, near, far })
    }

    /// The point at depth `t`.
    pub fn at(&self, t: f32) -> [f32; 3] {
        [0, 1, 2].map(|k| self.origin[k] + t * self.dir[k])
    }
}

/// Depths `(near, far)` where the ray `origin + t dir` (unit `dir`) is inside the unit sphere,
/// `near` clamped to 0; `None` when it misses.
pub fn unit_sphere_span(origin: [f32; 3], dir: [f32; 3]) -> Option<(f32, f32)> {
    let b = dot(origin, dir);
    let disc = b * b - (dot(origin, origin) - 1.0);
    if disc <= 0.0 {
        return None;
    }
    let root = disc.sqrt();
    Some(((-b - root).max(0.0), -b + root))
}

/// How many samples each ray takes.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Sampling {
    /// Uniform samples between near and far.
    pub coarse: usize,
    /// Samples added by hierarchical up-sampling.
    pub fine: usize,
    /// Up-sampling rounds (sharpness 64 * 2^k), NeuS: 4.
    pub steps: usize,
}

fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// Sample depths for `rays`: coarse (shifted by `jitter[r]` in `[0, 1)` of a step) then NeuS's
/// up-sampling on the SDF. Every ray gets `coarse + fine` sorted depths.
pub fn sample_depths(
    model: &Model,
    params: &[f32],
    level_weight: &[f32],
    rays: &[Ray],
    sampling: Sampling,
    jitter: &[f32],
) -> Vec<Vec<f32>> {
    let mut depths: Vec<Vec<f32>> = rays
        .iter()
        .zip(jitter)
        .map(|(ray, &j)| {
            let step = (ray.far - ray.near) / sampling.coarse as f32;
            (0..sampling.coarse).map(|k| ray.near + step * (k as f32 + j)).collect()
        })
        .collect();
    let eval = |pts: Vec<f32>| model.field.sdf(params, &pts, level_weight);
    let mut sdfs: Vec<Vec<f32>> = {
        let pts: Vec<f32> = rays.iter().zip(&depths).flat_map(|(r, ts)| ts.iter().flat_map(|&t| r.at(t))).collect();
        let flat = eval(pts);
        split_like(&flat, &depths)
    };
    if sampling.steps == 0 || sampling.fine == 0 {
        return depths;
    }
    let per_step = sampling.fine / sampling.steps;
    for step in 0..sampling.steps {
        let count = if step + 1 == sampling.steps { sampling.fine - per_step * (sampling.steps - 1) } else { per_step };
        let inv_s = 64.0 * (1u32 << step) as f32;
        let new: Vec<Vec<f32>> = depths.iter().zip(&sdfs).map(|(ts, sd)| upsample(ts, sd, inv_s, count)).collect();
        let pts: Vec<f32> = rays.iter().zip(&new).flat_map(|(r, ts)| ts.iter().flat_map(|&t| r.at(t))).collect();
        let new_sdf = split_like(&eval(pts), &new);
        for r in 0..rays.len() {
            let mut merged: Vec<(f32, f32)> = depths[r]
                .iter()
                .copied()
                .zip(sdfs[r].iter().copied())
                .chain(new[r].iter().copied().zip(new_sdf[r].iter().copied()))
                .collect();
            merged.sort_by(|a, b| a.0.total_cmp(&b.0));
            depths[r] = merged.iter().map(|m| m.0).collect();
            sdfs[r] = merged.iter().map(|m| m.1).collect();
        }
    }
    depths
}

fn split_like(flat: &[f32], shape: &[Vec<f32>]) -> Vec<Vec<f32>> {
    let mut at = 0;
    shape
        .iter()
        .map(|s| {
            let v = flat[at..at + s.len()].to_vec();
            at += s.len();
            v
        })
        .collect()
}

/// NeuS's up-sampling: weights from the SDF with sharpness `inv_s` (the slope estimate clipped
/// to be non-positive), then `count` deterministic inverse-CDF samples.
fn upsample(t: &[f32], sdf: &[f32], inv_s: f32, count: usize) -> Vec<f32> {
    let n = t.len();
    let mut weights = Vec::with_capacity(n - 1);
    let mut transmittance = 1.0;
    let mut prev_cos = 0.0f32;
    for i in 0..n - 1 {
        let dist = t[i + 1] - t[i];
        let mid = 0.5 * (sdf[i] + sdf[i + 1]);
        let cos = (sdf[i + 1] - sdf[i]) / (dist + 1e-5);
        let slope = cos.min(prev_cos).clamp(-1e3, 0.0);
        prev_cos = cos;
        let prev_cdf = sigmoid((mid - slope * dist * 0.5) * inv_s);
        let next_cdf = sigmoid((mid + slope * dist * 0.5) * inv_s);
        let alpha = (prev_cdf - next_cdf + 1e-5) / (prev_cdf + 1e-5);
        weights.push(alpha * transmittance + 1e-5);
        transmittance *= 1.0 - alpha + 1e-7;
    }
    let total: f32 = weights.iter().sum();
    let mut cdf = Vec::with_capacity(n);
    cdf.push(0.0);
    let mut acc = 0.0;
    for w in &weights {
        acc += w / total;
        cdf.push(acc);
    }
    (0..count)
        .map(|k| {
            let u = if count > 1 { k as f32 / (count - 1) as f32 } else { 0.5 };
            let above = cdf.partition_point(|&c| c <= u).min(n - 1);
            let below = above.saturating_sub(1);
            let denom = cdf[above] - cdf[below];
            let f = if denom < 1e-5 { 0.0 } else { (u - cdf[below]) / denom };
            t[below] + f * (t[above] - t[below])
        })
        .collect()
}

/// Per-ray results of the forward pass.
#[derive(Clone, Debug, Default)]
pub struct RayOutput {
    /// Composited Stokes (S0 RGB, S1 RGB, S2 RGB).
    pub stokes: [f32; STOKES],
    /// Accumulated opacity.
    pub opacity: f32,
    /// Expected depth along the ray (weights not normalised).
    pub depth: f32,
    /// Composited normal (not normalised).
    pub normal: [f32; 3],
}

/// Gradients of the loss with respect to the per-ray outputs.
#[derive(Clone, Debug, Default)]
pub struct RayGrad {
    /// d loss / d stokes.
    pub stokes: [f32; STOKES],
    /// d loss / d opacity.
    pub opacity: f32,
    /// d loss / d normal.
    pub normal: [f32; 3],
}

/// One forward pass over a set of rays, with everything the backward pass needs.
pub struct Forward {
    /// Per-ray outputs.
    pub rays: Vec<RayOutput>,
    /// First sample of each ray and the number of samples.
    pub spans: Vec<(usize, usize)>,
    /// Sample depths (flattened).
    pub depths: Vec<f32>,
    /// Sample SDF values.
    pub sdf: Vec<f32>,
    /// Finite-difference SDF gradients (n x 3).
    pub gradients: Vec<f32>,
    /// Finite-difference SDF Laplacians (mean curvature x 2 on an SDF), from the same 7 values.
    pub laplacians: Vec<f32>,
    /// Unit normals (n x 3).
    pub normals: Vec<f32>,
    /// Per-sample Stokes (n x 9).
    pub stokes: Vec<f32>,
    /// Per-sample opacity (alpha) before clamping, and after.
    alpha_raw: Vec<f32>,
    alpha: Vec<f32>,
    sigma: Vec<f32>,
    transmittance: Vec<f32>,
    /// Compositing weights.
    pub weights: Vec<f32>,
    points: Vec<f32>,
    features: Vec<f32>,
    view: Vec<f32>,
    frame_x: Vec<f32>,
    frame_y: Vec<f32>,
    field_cache: FieldCache,
    shading_cache: ShadingCache,
    inv_s: f32,
    /// Finite-difference step.
    pub step: f32,
}

/// The six finite-difference offsets, in the order the field evaluates them.
const OFFSETS: [(usize, f32); 6] = [(0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0), (2, 1.0), (2, -1.0)];

impl Forward {
    /// Render `rays` at sample `depths` (from [`sample_depths`]); `fd_step` is the
    /// finite-difference step of the normals.
    #[allow(clippy::too_many_arguments)]
    pub fn run(
        model: &Model,
        params: &[f32],
        level_weight: &[f32],
        rays: &[Ray],
        depths: &[Vec<f32>],
        fd_step: f32,
        diffuse_only: bool,
    ) -> Self {
        let mut spans = Vec::with_capacity(rays.len());
        let mut flat_depths = Vec::new();
        let mut points = Vec::new();
        let (mut view, mut frame_x, mut frame_y) = (Vec::new(), Vec::new(), Vec::new());
        for (ray, ts) in rays.iter().zip(depths) {
            spans.push((flat_depths.len(), ts.len()));
            for &t in ts {
                flat_depths.push(t);
                points.extend(ray.at(t));
                view.extend(ray.dir.map(|d| -d));
                frame_x.extend(ray.frame_x);
                frame_y.extend(ray.frame_y);
            }
        }
        let n = flat_depths.len();
        let mut all = Vec::with_capacity(7 * 3 * n);
        all.extend_from_slice(&points);
        for (axis, sign) in OFFSETS {
            for p in points.chunks_exact(3) {
                let mut q = [p[0], p[1], p[2]];
                q[axis] += sign * fd_step;
                all.extend(q);
            }
        }
        let mut field_cache = FieldCache::default();
        let out = model.field.forward(params, &all, level_weight, &mut field_cache);
        let width = model.field.outputs();
        let sdf: Vec<f32> = (0..n).map(|i| out[i * width]).collect();
        let features: Vec<f32> = (0..n).flat_map(|i| out[i * width + 1..(i + 1) * width].iter().copied()).collect();
        let mut gradients = vec![0f32; 3 * n];
        let mut normals = vec![0f32; 3 * n];
        let mut laplacians = vec![0f32; n];
        for i in 0..n {
            let neighbours: f32 = (1..7).map(|b| out[(b * n + i) * width]).sum();
            laplacians[i] = (neighbours - 6.0 * sdf[i]) / (fd_step * fd_step);
            for axis in 0..3 {
                let plus = out[((1 + 2 * axis) * n + i) * width];
                let minus = out[((2 + 2 * axis) * n + i) * width];
                gradients[3 * i + axis] = (plus - minus) / (2.0 * fd_step);
            }
            let g = &gradients[3 * i..3 * i + 3];
            let len = dot([g[0], g[1], g[2]], [g[0], g[1], g[2]]).sqrt().max(1e-8);
            for axis in 0..3 {
                normals[3 * i + axis] = g[axis] / len;
            }
        }
        let mut shading_cache = ShadingCache::default();
        let input = ShadingInput {
            points: &points,
            normals: &normals,
            features: &features,
            view: &view,
            frame_x: &frame_x,
            frame_y: &frame_y,
        };
        let stokes = model.radiance.shade(params, &input, diffuse_only, &mut shading_cache);

        let inv_s = model.inv_s(params);
        let sigma: Vec<f32> = sdf.iter().map(|&s| sigmoid(s * inv_s)).collect();
        let (mut alpha_raw, mut alpha, mut transmittance, mut weights) =
            (vec![0f32; n], vec![0f32; n], vec![0f32; n], vec![0f32; n]);
        let mut outputs = Vec::with_capacity(rays.len());
        for &(start, count) in &spans {
            let mut trans = 1.0f32;
            let mut o = RayOutput::default();
            for i in start..start + count {
                transmittance[i] = trans;
                if i + 1 == start + count {
                    break;
                }
                let raw = (sigma[i] - sigma[i + 1] + 1e-5) / (sigma[i] + 1e-5);
                alpha_raw[i] = raw;
                alpha[i] = raw.clamp(0.0, 1.0);
                let w = trans * alpha[i];
                weights[i] = w;
                for k in 0..STOKES {
                    o.stokes[k] += w * stokes[STOKES * i + k];
                }
                for k in 0..3 {
                    o.normal[k] += w * normals[3 * i + k];
                }
                o.opacity += w;
                o.depth += w * flat_depths[i];
                trans *= 1.0 - alpha[i];
            }
            outputs.push(o);
        }
        Self {
            rays: outputs,
            spans,
            depths: flat_depths,
            sdf,
            gradients,
            laplacians,
            normals,
            stokes,
            alpha_raw,
            alpha,
            sigma,
            transmittance,
            weights,
            points,
            features,
            view,
            frame_x,
            frame_y,
            field_cache,
            shading_cache,
            inv_s,
            step: fd_step,
        }
    }

    /// Backward pass: `ray_grads` per ray, `d_gradients` (n x 3, e.g. from the Eikonal loss) on
    /// the SDF gradients and `d_laplacians` (n, the curvature loss) on the Laplacians; adds every
    /// parameter gradient into `grad`.
    #[allow(clippy::too_many_arguments)]
    pub fn backward(
        &self,
        model: &Model,
        params: &[f32],
        level_weight: &[f32],
        ray_grads: &[RayGrad],
        d_gradients: &[f32],
        d_laplacians: &[f32],
        grad: &mut [f32],
    ) {
        let n = self.depths.len();
        let mut d_stokes = vec![0f32; STOKES * n];
        let mut d_normals = vec![0f32; 3 * n];
        let mut d_sdf = vec![0f32; n];
        let mut d_inv_s = 0f32;
        for (&(start, count), g) in self.spans.iter().zip(ray_grads) {
            // Value of each sample's weight to the loss.
            let value = |i: usize| -> f32 {
                let mut v = g.opacity;
                for k in 0..STOKES {
                    v += g.stokes[k] * self.stokes[STOKES * i + k];
                }
                for k in 0..3 {
                    v += g.normal[k] * self.normals[3 * i + k];
                }
                v
            };
            let mut rest = 0f32; // R_{i+1} = sum_{k > i} w_k v_k / T_{i+1}
            for i in (start..start + count - 1).rev() {
                let v = value(i);
                let a = self.alpha[i];
                let d_alpha = self.transmittance[i] * (v - rest);
                rest = a * v + (1.0 - a) * rest;
                let w = self.weights[i];
                for k in 0..STOKES {
                    d_stokes[STOKES * i + k] += w * g.stokes[k];
                }
                for k in 0..3 {
                    d_normals[3 * i + k] += w * g.normal[k];
                }
                let raw = self.alpha_raw[i];
                if !(0.0..=1.0).contains(&raw) {
                    continue;
                }
                let (s0, s1) = (self.sigma[i], self.sigma[i + 1]);
                let d_s0 = d_alpha * s1 / ((s0 + 1e-5) * (s0 + 1e-5));
                let d_s1 = -d_alpha / (s0 + 1e-5);
                for (j, ds) in [(i, d_s0), (i + 1, d_s1)] {
                    let slope = self.sigma[j] * (1.0 - self.sigma[j]);
                    d_sdf[j] += ds * slope * self.inv_s;
                    d_inv_s += ds * slope * self.sdf[j];
                }
            }
        }
        grad[model.variance] += d_inv_s * 10.0 * self.inv_s;

        let input = ShadingInput {
            points: &self.points,
            normals: &self.normals,
            features: &self.features,
            view: &self.view,
            frame_x: &self.frame_x,
            frame_y: &self.frame_y,
        };
        let (dn_shading, d_features) =
            model.radiance.shade_backward(params, &input, &self.shading_cache, &d_stokes, grad);
        let width = model.field.outputs();
        let mut d_out = vec![0f32; 7 * n * width];
        let h2 = self.step * self.step;
        for i in 0..n {
            d_out[i * width] = d_sdf[i] - 6.0 * d_laplacians[i] / h2;
            for b in 1..7 {
                d_out[(b * n + i) * width] += d_laplacians[i] / h2;
            }
            d_out[i * width + 1..(i + 1) * width].copy_from_slice(&d_features[(width - 1) * i..(width - 1) * (i + 1)]);
            let nv = [self.normals[3 * i], self.normals[3 * i + 1], self.normals[3 * i + 2]];
            let dn = [0, 1, 2].map(|k| d_normals[3 * i + k] + dn_shading[3 * i + k]);
            let g = &self.gradients[3 * i..3 * i + 3];
            let len = dot([g[0], g[1], g[2]], [g[0], g[1], g[2]]).sqrt().max(1e-8);
            let along = dot(dn, nv);
            for axis in 0..3 {
                let dg = (dn[axis] - nv[axis] * along) / len + d_gradients[3 * i + axis];
                let d = dg / (2.0 * self.step);
                d_out[((1 + 2 * axis) * n + i) * width] += d;
                d_out[((2 + 2 * axis) * n + i) * width] -= d;
            }
        }
        model.field.backward(params, &self.field_cache, level_weight, &d_out, grad);
    }
}
