//! NeuS volume rendering inside the unit sphere: coarse samples, hierarchical up-sampling with
//! fixed sharpness, and alpha compositing of per-sample Stokes vectors, normals and depths, with
//! the backward pass. A forward pass is three steps: the field at the samples
//! ([`FieldSamples`]: SDF, finite-difference normals and Laplacians, features), shading (the
//! radiance networks and the pBRDF: per-sample Stokes), compositing along each ray.

use crate::engine::vector::sigmoid;
use crate::model::{GridGradient, Model, ShadingCache, ShadingInput, STOKES, VARIANCE_SCALE};
use crate::occupancy::OccupancyGrid;
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
    /// A training step renders only the samples that carry at least this compositing weight
    /// or whose density still responds where light reaches them (see [`weighted_samples`]);
    /// 0 renders every sample.
    #[serde(default)]
    pub min_weight: f32,
    /// Of the samples a step leaves out behind the last one a ray renders (space the ray does
    /// not see), this many per ray, drawn at random, still carry the curvature term where
    /// they lie outside the surface, each for its share of them
    /// ([`crate::step::Batch::left_out_draws`]); 0: none.
    #[serde(default)]
    pub regularised_left_out: usize,
    /// Every sample a step leaves out within this distance of the surface (by the SDF the
    /// sampling found) still carries the Eikonal and curvature terms, each for itself, as it
    /// would rendered; 0: none.
    #[serde(default)]
    pub regularise_near_surface: f32,
}

impl Sampling {
    /// Whether a training step renders only the samples that carry weight, and samples
    /// through an occupancy grid (`min_weight` above 0).
    pub fn skips_empty_space(&self) -> bool {
        self.min_weight > 0.0
    }
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
    depths_and_sdf(model, params, level_weight, rays, sampling, jitter, None).0
}

/// The depths of [`sample_depths`] that a training step renders: on each ray, both ends of
/// every interval whose compositing weight (under the model's sharpness `inv_s`, from the SDF
/// the up-sampling found) reaches `sampling.min_weight`, and every sample whose SDF the
/// composited values respond to that much (transmittance times `1 - sigmoid(inv_s * sdf)`).
/// The others lie in empty space before the surface or deep behind it: leaving them out
/// changes a ray's composited values by less than `min_weight` per sample left out, and the
/// gradient they would have had is as small. A ray may keep no sample (its opacity is then 0).
/// The depths left out come back too, for the regularisers
/// ([`crate::step::Batch::left_out_draws`], [`Sampling::regularise_near_surface`]).
///
/// With `occupancy`, the SDF at a sample where the grid shows the surface to be far is the
/// grid's, and a ray whose uniform samples all lie there is not up-sampled: nothing near it
/// could carry weight.
#[allow(clippy::too_many_arguments)]
pub fn weighted_samples(
    model: &Model,
    params: &[f32],
    level_weight: &[f32],
    rays: &[Ray],
    sampling: Sampling,
    jitter: &[f32],
    occupancy: Option<&OccupancyGrid>,
) -> StepSamples {
    let (depths, sdf) = depths_and_sdf(model, params, level_weight, rays, sampling, jitter, occupancy);
    if !sampling.skips_empty_space() {
        let none = vec![Vec::new(); depths.len()];
        return StepSamples { rendered: depths, left_out: none.clone(), left_out_sdf: none };
    }
    let inv_s = model.inv_s(params);
    let mut samples = StepSamples::default();
    for (t, s) in depths.iter().zip(&sdf) {
        let keep = carrying_weight(s, inv_s, sampling.min_weight);
        let (mut kept, mut left, mut left_sdf) = (Vec::new(), Vec::new(), Vec::new());
        for ((&depth, &sdf), carries) in t.iter().zip(s).zip(keep) {
            if carries {
                kept.push(depth);
            } else {
                left.push(depth);
                left_sdf.push(sdf);
            }
        }
        samples.rendered.push(kept);
        samples.left_out.push(left);
        samples.left_out_sdf.push(left_sdf);
    }
    samples
}

/// A training step's samples on each ray ([`weighted_samples`]), in depth order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StepSamples {
    /// The depths rendered.
    pub rendered: Vec<Vec<f32>>,
    /// The depths left out (none where every sample is rendered).
    pub left_out: Vec<Vec<f32>>,
    /// The SDF the sampling found at each depth left out: the networks', or the occupancy
    /// grid's where it shows the surface to be far ([`OccupancyGrid::far_sdf`]).
    pub left_out_sdf: Vec<Vec<f32>>,
}

/// Which of a ray's samples (SDF `sdf` there, in depth order) carry weight, as
/// [`weighted_samples`] says: the compositing of [`composite`] on the SDF alone.
fn carrying_weight(sdf: &[f32], inv_s: f32, min_weight: f32) -> Vec<bool> {
    let n = sdf.len();
    let sigma: Vec<f32> = sdf.iter().map(|&s| sigmoid(s * inv_s)).collect();
    let mut keep = vec![false; n];
    let mut transmittance = 1.0f32;
    for i in 0..n {
        keep[i] |= transmittance * (1.0 - sigma[i]) >= min_weight;
        if i + 1 < n {
            let alpha = section_alpha(sigma[i], sigma[i + 1]).clamp(0.0, 1.0);
            if transmittance * alpha >= min_weight {
                keep[i] = true;
                keep[i + 1] = true;
            }
            transmittance *= 1.0 - alpha;
        }
    }
    keep
}

/// NeuS's opacity of the section between two samples from `sigmoid(s * sdf)` at its start and
/// its end, before clamping to `[0, 1]`: the one formula of the up-sampling, the choice of the
/// samples that carry weight and the compositing.
fn section_alpha(before: f32, after: f32) -> f32 {
    (before - after + 1e-5) / (before + 1e-5)
}

/// The depths of [`sample_depths`] and the SDF at them, read from `occupancy` where it shows
/// the surface to be far (see [`weighted_samples`]).
fn depths_and_sdf(
    model: &Model,
    params: &[f32],
    level_weight: &[f32],
    rays: &[Ray],
    sampling: Sampling,
    jitter: &[f32],
    occupancy: Option<&OccupancyGrid>,
) -> (Vec<Vec<f32>>, Vec<Vec<f32>>) {
    let mut depths: Vec<Vec<f32>> = rays
        .iter()
        .zip(jitter)
        .map(|(ray, &j)| {
            let step = (ray.far - ray.near) / sampling.coarse as f32;
            (0..sampling.coarse).map(|k| ray.near + step * (k as f32 + j)).collect()
        })
        .collect();
    // The SDF at points (n x 3): the grid's where it stands in, the networks' elsewhere; and
    // whether each came from the grid.
    let eval = |pts: Vec<f32>| -> (Vec<f32>, Vec<bool>) {
        let Some(grid) = occupancy else {
            let n = pts.len() / 3;
            return (model.field.sdf(params, &pts, level_weight), vec![false; n]);
        };
        let far: Vec<Option<f32>> = pts.chunks_exact(3).map(|p| grid.far_sdf([p[0], p[1], p[2]])).collect();
        let near: Vec<f32> =
            pts.chunks_exact(3).zip(&far).filter(|(_, f)| f.is_none()).flat_map(|(p, _)| p.to_vec()).collect();
        let mut evaluated = model.field.sdf(params, &near, level_weight).into_iter();
        let sdf = far.iter().map(|f| f.unwrap_or_else(|| evaluated.next().expect("one a near point"))).collect();
        (sdf, far.iter().map(Option::is_some).collect())
    };
    let (mut sdfs, empty_rays): (Vec<Vec<f32>>, Vec<bool>) = {
        let pts: Vec<f32> = rays.iter().zip(&depths).flat_map(|(r, ts)| ts.iter().flat_map(|&t| r.at(t))).collect();
        let (flat, from_grid) = eval(pts);
        // A ray whose uniform samples all lie where the surface is far is not up-sampled.
        let empty = split_like(&from_grid, &depths).iter().map(|g| g.iter().all(|&f| f)).collect();
        (split_like(&flat, &depths), empty)
    };
    if sampling.steps == 0 || sampling.fine == 0 {
        return (depths, sdfs);
    }
    let per_step = sampling.fine / sampling.steps;
    for step in 0..sampling.steps {
        let count = if step + 1 == sampling.steps { sampling.fine - per_step * (sampling.steps - 1) } else { per_step };
        let inv_s = 64.0 * (1u32 << step) as f32;
        let new: Vec<Vec<f32>> = depths
            .iter()
            .zip(&sdfs)
            .zip(&empty_rays)
            .map(|((ts, sd), &empty)| if empty { Vec::new() } else { upsample(ts, sd, inv_s, count) })
            .collect();
        let pts: Vec<f32> = rays.iter().zip(&new).flat_map(|(r, ts)| ts.iter().flat_map(|&t| r.at(t))).collect();
        let new_sdf = split_like(&eval(pts).0, &new);
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
    (depths, sdfs)
}

fn split_like<T: Copy>(flat: &[T], shape: &[Vec<f32>]) -> Vec<Vec<T>> {
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
        let alpha = section_alpha(prev_cdf, next_cdf);
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
            let raw = section_alpha(sigma[i], sigma[i + 1]);
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
    /// returns the hash grid's (for [`Field::write_grid_gradients`](crate::model::Field::write_grid_gradients)).
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
            for i in (start..(start + count).saturating_sub(1)).rev() {
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

#[cfg(test)]
mod tests {
    use super::*;
    use rmvp_dataset::rng::Rng;

    /// Rays through random slabs, some far thinner than the spacing of the samples, at the
    /// sharpness of a start, a middle and an end of training: what the samples left out by
    /// [`carrying_weight`] change in each ray's composited opacity, depth, Stokes and normal
    /// stays within their count times the least weight, and a ray that reaches a surface keeps
    /// it however thin.
    #[test]
    fn samples_left_out_change_no_ray_by_more_than_their_weight() {
        let min_weight = 1e-4;
        let mut rng = Rng::for_pixel(5, 0, 0);
        let (mut left_out, mut total, mut worst_share, mut worst_slope) = (0, 0, 0f32, 0f32);
        for case in 0..3000 {
            let inv_s = [30.0, 300.0, 3000.0][case % 3];
            // Slabs along the ray: centre and half-thickness (down to 0.002, a tenth of a step).
            let slabs: Vec<(f32, f32)> =
                (0..1 + case % 3).map(|_| (0.3 + 1.4 * rng.next_f32(), 0.002 + 0.2 * rng.next_f32().powi(3))).collect();
            let sdf_at = |t: f32| slabs.iter().map(|&(c, h)| (t - c).abs() - h).fold(f32::INFINITY, f32::min);
            // 32 uniform samples over [0, 2], 32 clustered near the first surface.
            let first = slabs.iter().map(|&(c, h)| c - h).fold(f32::INFINITY, f32::min);
            let mut t: Vec<f32> = (0..32).map(|k| (k as f32 + rng.next_f32()) / 16.0).collect();
            t.extend((0..32).map(|_| (first + 0.05 * (rng.next_f32() - 0.5)).clamp(0.0, 2.0)));
            t.sort_by(f32::total_cmp);
            let sdf: Vec<f32> = t.iter().map(|&d| sdf_at(d)).collect();
            let stokes: Vec<f32> =
                t.iter().flat_map(|&d| (0..STOKES).map(move |k| (d * (k + 1) as f32).sin())).collect();
            let normals: Vec<f32> = t.iter().flat_map(|&d| [d.cos(), d.sin(), 0.5]).collect();
            let (all, _) = composite(&[(0, t.len())], &t, &sdf, inv_s, &stokes, &normals);
            let keep = carrying_weight(&sdf, inv_s, min_weight);
            let pick = |v: &[f32], width: usize| -> Vec<f32> {
                v.chunks_exact(width).zip(&keep).filter(|(_, k)| **k).flat_map(|(x, _)| x.to_vec()).collect()
            };
            let kept = keep.iter().filter(|k| **k).count();
            let (some, _) = composite(
                &[(0, kept)],
                &pick(&t, 1),
                &pick(&sdf, 1),
                inv_s,
                &pick(&stokes, STOKES),
                &pick(&normals, 3),
            );
            let (a, b) = (&all[0], &some[0]);
            let dropped = (t.len() - kept) as f32;
            let bound = dropped * min_weight + 1e-5;
            let differences = [
                a.opacity - b.opacity,
                (a.depth - b.depth) / 2.0,
                a.stokes[4] - b.stokes[4],
                a.normal[1] - b.normal[1],
            ];
            let worst = differences.iter().fold(0f32, |m, d| m.max(d.abs()));
            assert!(worst <= bound, "case {case}: inv_s {inv_s}, slabs {slabs:?}: {differences:?} beyond {bound}");
            if a.opacity > 0.5 {
                assert!(b.opacity > 0.5, "case {case}: a surface left out");
            }
            // Nor do their gradients matter: a sample left out, its SDF moved by one unit of
            // the sharpness either way, moves the ray's opacity by little more than the least
            // weight.
            for j in (0..t.len()).filter(|&j| !keep[j]) {
                let opacity = |shift: f32| {
                    let mut moved = sdf.clone();
                    moved[j] += shift / inv_s;
                    composite(&[(0, t.len())], &t, &moved, inv_s, &stokes, &normals).0[0].opacity
                };
                let slope = (opacity(1.0) - opacity(-1.0)).abs() / 2.0;
                worst_slope = worst_slope.max(slope);
                assert!(slope < 2.0 * min_weight, "case {case}: sample {j} left out moves the opacity by {slope}");
            }
            worst_share = worst_share.max(worst / bound);
            left_out += t.len() - kept;
            total += t.len();
        }
        println!(
            "left out {left_out} of {total} samples; the largest change {worst_share:.2} of its bound, the largest \
             opacity slope {worst_slope:.1e}"
        );
        assert!(left_out > total / 3, "left out only {left_out} of {total}");
    }
}
