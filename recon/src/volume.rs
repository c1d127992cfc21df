//! NeuS volume rendering inside the unit sphere: coarse samples, hierarchical up-sampling with
//! fixed sharpness, and alpha compositing of per-sample Stokes vectors, normals and depths, with
//! the backward pass. A forward pass is three steps: the field at the samples
//! ([`FieldSamples`]: SDF, finite-difference normals and Laplacians, features), shading (the
//! radiance networks and the pBRDF: per-sample Stokes), compositing along each ray.

use crate::engine::vector::sigmoid;
use crate::model::{GridGradient, Model, ShadingCache, ShadingInput, STOKES, VARIANCE_SCALE};
use crate::ray::Ray;
use crate::samples::{FieldGrad, FieldSamples};

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

/// The samples of a batch of rays, flattened: where each ray's samples start, their depths,
/// positions, view directions and the rays' Stokes frames (one row per sample).
struct FlatSamples {
    spans: Vec<(usize, usize)>,
    depths: Vec<f32>,
    points: Vec<f32>,
    view: Vec<f32>,
    frame_x: Vec<f32>,
    frame_y: Vec<f32>,
}

impl FlatSamples {
    fn new(rays: &[Ray], depths: &[Vec<f32>]) -> Self {
        let mut flat = FlatSamples {
            spans: Vec::with_capacity(rays.len()),
            depths: Vec::new(),
            points: Vec::new(),
            view: Vec::new(),
            frame_x: Vec::new(),
            frame_y: Vec::new(),
        };
        for (ray, ts) in rays.iter().zip(depths) {
            flat.spans.push((flat.depths.len(), ts.len()));
            for &t in ts {
                flat.depths.push(t);
                flat.points.extend(ray.at(t));
                flat.view.extend(ray.dir.map(|d| -d));
                flat.frame_x.extend(ray.frame_x);
                flat.frame_y.extend(ray.frame_y);
            }
        }
        flat
    }
}

/// Per-sample state of alpha compositing, kept for the backward pass.
#[derive(Default)]
struct Compositing {
    /// Opacity (alpha) of each sample before clamping, and after.
    alpha_raw: Vec<f32>,
    alpha: Vec<f32>,
    /// `sigmoid(s * sdf)`.
    sigma: Vec<f32>,
    transmittance: Vec<f32>,
    /// Compositing weights.
    weights: Vec<f32>,
}

fn composite(
    spans: &[(usize, usize)],
    depths: &[f32],
    sdf: &[f32],
    inv_s: f32,
    stokes: &[f32],
    normals: &[f32],
) -> (Vec<RayOutput>, Compositing) {
    let n = sdf.len();
    let sigma: Vec<f32> = sdf.iter().map(|&s| sigmoid(s * inv_s)).collect();
    let (mut alpha_raw, mut alpha, mut transmittance, mut weights) =
        (vec![0f32; n], vec![0f32; n], vec![0f32; n], vec![0f32; n]);
    let mut outputs = Vec::with_capacity(spans.len());
    for &(start, count) in spans {
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
            o.depth += w * depths[i];
            trans *= 1.0 - alpha[i];
        }
        outputs.push(o);
    }
    (outputs, Compositing { alpha_raw, alpha, sigma, transmittance, weights })
}

/// One forward pass over a set of rays, with everything the backward pass needs.
pub struct Forward {
    /// Per-ray outputs.
    pub rays: Vec<RayOutput>,
    /// The field at every sample (SDF, gradients, normals, Laplacians, features).
    pub field: FieldSamples,
    /// Per-sample Stokes (n x 9).
    pub stokes: Vec<f32>,
    samples: FlatSamples,
    compositing: Compositing,
    shading_cache: ShadingCache,
    inv_s: f32,
}

impl Forward {
    /// Render `rays` at sample `depths` (from [`sample_depths`]); `fd_step` is the
    /// finite-difference step of the normals; `diffuse_only` switches the specular lobe off.
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
        let samples = FlatSamples::new(rays, depths);
        let field = FieldSamples::evaluate(model, params, level_weight, samples.points.clone(), fd_step);
        let mut shading_cache = ShadingCache::default();
        let stokes =
            model.radiance.shade(params, &shading_input(&samples, &field), diffuse_only, Some(&mut shading_cache));
        let inv_s = model.inv_s(params);
        let (rays, compositing) =
            composite(&samples.spans, &samples.depths, &field.sdf, inv_s, &stokes, &field.normals);
        Self { rays, field, stokes, samples, compositing, shading_cache, inv_s }
    }

    /// Samples evaluated (over all rays).
    pub fn samples(&self) -> usize {
        self.samples.depths.len()
    }

    /// Backward pass: `ray_grads` per ray, `d_gradients` (n x 3, e.g. from the Eikonal loss) on
    /// the SDF gradients and `d_laplacians` (n, the curvature loss) on the Laplacians; adds the
    /// networks' parameter gradients into `grad` (at least [`Model::network_params`] long) and
    /// returns the hash grid's (for [`Field::add_grid_gradients`](crate::model::Field::add_grid_gradients)).
    pub fn backward(
        &self,
        model: &Model,
        params: &[f32],
        ray_grads: &[RayGrad],
        d_gradients: &[f32],
        d_laplacians: &[f32],
        grad: &mut [f32],
    ) -> GridGradient {
        let n = self.samples();
        let c = &self.compositing;
        let (normals, sdf) = (&self.field.normals, &self.field.sdf);
        let mut d_stokes = vec![0f32; STOKES * n];
        let mut d_normals = vec![0f32; 3 * n];
        let mut d_sdf = vec![0f32; n];
        let mut d_inv_s = 0f32;
        for (&(start, count), g) in self.samples.spans.iter().zip(ray_grads) {
            // Value of each sample's weight to the loss.
            let value = |i: usize| -> f32 {
                let mut v = g.opacity;
                for k in 0..STOKES {
                    v += g.stokes[k] * self.stokes[STOKES * i + k];
                }
                for k in 0..3 {
                    v += g.normal[k] * normals[3 * i + k];
                }
                v
            };
            let mut rest = 0f32; // R_{i+1} = sum_{k > i} w_k v_k / T_{i+1}
            for i in (start..start + count - 1).rev() {
                let v = value(i);
                let a = c.alpha[i];
                let d_alpha = c.transmittance[i] * (v - rest);
                rest = a * v + (1.0 - a) * rest;
                let w = c.weights[i];
                for k in 0..STOKES {
                    d_stokes[STOKES * i + k] += w * g.stokes[k];
                }
                for k in 0..3 {
                    d_normals[3 * i + k] += w * g.normal[k];
                }
                let raw = c.alpha_raw[i];
                if !(0.0..=1.0).contains(&raw) {
                    continue;
                }
                let (s0, s1) = (c.sigma[i], c.sigma[i + 1]);
                let d_s0 = d_alpha * s1 / ((s0 + 1e-5) * (s0 + 1e-5));
                let d_s1 = -d_alpha / (s0 + 1e-5);
                for (j, ds) in [(i, d_s0), (i + 1, d_s1)] {
                    let slope = c.sigma[j] * (1.0 - c.sigma[j]);
                    d_sdf[j] += ds * slope * self.inv_s;
                    d_inv_s += ds * slope * sdf[j];
                }
            }
        }
        grad[model.variance] += d_inv_s * VARIANCE_SCALE * self.inv_s;

        let input = shading_input(&self.samples, &self.field);
        let (dn_shading, d_features) =
            model.radiance.shade_backward(params, &input, &self.shading_cache, &d_stokes, grad);
        d_normals.iter_mut().zip(&dn_shading).for_each(|(a, b)| *a += b);
        let d = FieldGrad {
            sdf: &d_sdf,
            normals: &d_normals,
            features: &d_features,
            gradients: d_gradients,
            laplacians: d_laplacians,
        };
        self.field.backward(model, params, &d, grad)
    }
}

/// The field at one point per ray, `rays[i].at(depths[i])`, and with `shade` the radiance
/// networks' Stokes there (n x 9), forward only: surface rendering at sphere-traced hits.
pub fn shade_points(
    model: &Model,
    params: &[f32],
    level_weight: &[f32],
    rays: &[Ray],
    depths: &[f32],
    fd_step: f32,
    shade: bool,
) -> (FieldSamples, Option<Vec<f32>>) {
    let depths: Vec<Vec<f32>> = depths.iter().map(|&t| vec![t]).collect();
    let samples = FlatSamples::new(rays, &depths);
    let field = FieldSamples::infer(model, params, level_weight, samples.points.clone(), fd_step);
    let stokes = shade.then(|| model.radiance.shade(params, &shading_input(&samples, &field), false, None));
    (field, stokes)
}

/// What the radiance networks see at the samples.
fn shading_input<'a>(samples: &'a FlatSamples, field: &'a FieldSamples) -> ShadingInput<'a> {
    ShadingInput {
        points: &field.points,
        normals: &field.normals,
        features: &field.features,
        view: &samples.view,
        frame_x: &samples.frame_x,
        frame_y: &samples.frame_y,
    }
}
