//! One training step's compute: the gradient of the weighted losses over a batch of rays, the
//! seam between the training loop ([`crate::train`]) and an engine. [`CpuStep`] is rmvp's own
//! engine on the CPU's cores; another (a GPU's) implements [`StepCompute`] and the loop, its
//! schedule, checkpoints and reports stay as they are.
//!
//! A batch is cut into a fixed number of chunks whose gradients are summed in order, so results
//! do not depend on the number of threads.

use crate::config::TrainConfig;
use crate::data::TrainingSet;
use crate::geometric::{curved_robust_scale, robust_scale, tangent_loss, tangents, ViewSample};
use crate::losses::{curvature, eikonal, l1, mask_bce, PerTerm, Term};
use crate::model::{GridGradient, Model, STOKES};
use crate::occupancy::OccupancyGrid;
use crate::ray::Ray;
use crate::samples::{FieldGrad, FieldSamples};
use crate::volume::{weighted_samples, Forward, RayGrad};
use rayon::prelude::*;
use std::ops::Range;
use std::sync::Arc;

/// One step's rays and the schedule's state at its iteration.
#[derive(Clone, Debug)]
pub struct Batch {
    /// The rays, as (view, pixel) of the training set.
    pub rays: Vec<(u32, u32)>,
    /// Each ray's coarse-sampling shift, in `[0, 1)` of a step.
    pub jitter: Vec<f32>,
    /// Per-level weights of the hash grid (coarse to fine).
    pub level_weight: Vec<f32>,
    /// Finite-difference step of the normals.
    pub fd_step: f32,
    /// The share of the curvature weight this step applies
    /// ([`Trainer::curvature_share`](crate::train::Trainer::curvature_share)).
    pub curvature_share: f32,
    /// In the diffuse-only warm-up.
    pub warm: bool,
    /// The geometric loss is on.
    pub use_geometric: bool,
    /// The SDF on a coarse grid, read where it shows the surface to be far (None: the field
    /// everywhere).
    pub occupancy: Option<Arc<OccupancyGrid>>,
    /// For each ray, [`Sampling::regularised_left_out`](crate::volume::Sampling) numbers in
    /// `[0, 1)` that pick, among the samples left out of the step behind the last one the ray
    /// renders (space it does not see), those that the curvature term still sees, where they
    /// lie outside the surface by at least [`REGULARISED_CLEARANCE`] (empty where every sample
    /// is rendered or none is drawn). Each stands for its share of those samples, so that the
    /// term's expected gradient is the one it has over all of them.
    pub left_out_draws: Vec<f32>,
    /// For each ray, where the systematic sample of the views that the geometric loss compares
    /// with its surface point starts, in `[0, 1)` (empty where every view is compared:
    /// [`TrainConfig::tangent_views`] is 0 or at least the training set's views).
    pub tangent_view_draws: Vec<f32>,
}

/// What a step's compute returns beside the gradient it writes.
#[derive(Clone, Debug)]
pub struct StepLosses {
    /// Each term's loss, unweighted.
    pub losses: PerTerm<f64>,
    /// Samples evaluated.
    pub samples: usize,
}

/// An engine that computes a step's gradient.
pub trait StepCompute: Send + Sync {
    /// The losses of `batch` for `model` at `params` on `set` under `config`; their gradient
    /// is written over `grad` (as long as `params`), which the caller keeps from step to step
    /// so that no step allocates or first-touches the whole parameter vector.
    fn gradient(
        &self,
        model: &Model,
        params: &[f32],
        set: &TrainingSet,
        config: &TrainConfig,
        batch: &Batch,
        grad: &mut [f32],
    ) -> StepLosses;
}

/// rmvp's engine on the CPU: chunks of rays in parallel (rayon), summed in order.
#[derive(Clone, Copy, Debug, Default)]
pub struct CpuStep;

/// Rays per chunk of a batch; chunks run in parallel and are summed in order.
const CHUNK_RAYS: usize = 32;

/// The least distance outside the surface (unit sphere) at which a sample drawn behind what a
/// ray renders ([`Batch::left_out_draws`]) is regularised: the surface's neighbourhood is left
/// to the samples rendered and those within
/// [`Sampling::regularise_near_surface`](crate::volume::Sampling).
pub const REGULARISED_CLEARANCE: f32 = 0.05;

/// The losses' normalisers: rays, rays inside the masks, samples a step takes when it renders
/// every sample.
struct Norms {
    rays: f32,
    masked: f32,
    samples: f32,
}

/// How many of the step's samples (of its every-sample count) a regularised point stands for
/// in each term.
#[derive(Clone, Copy)]
struct Shares {
    eikonal: f32,
    curvature: f32,
}

#[derive(Default)]
struct ChunkSums {
    losses: PerTerm<f64>,
    samples: usize,
}

/// One step's inputs, shared by its chunks.
struct Step<'a> {
    model: &'a Model,
    params: &'a [f32],
    set: &'a TrainingSet,
    config: &'a TrainConfig,
    batch: &'a Batch,
    norm: Norms,
}

impl StepCompute for CpuStep {
    fn gradient(
        &self,
        model: &Model,
        params: &[f32],
        set: &TrainingSet,
        config: &TrainConfig,
        batch: &Batch,
        grad: &mut [f32],
    ) -> StepLosses {
        let rays = &batch.rays;
        let masked_total = rays.iter().filter(|&&(v, p)| set.views[v as usize].mask[p as usize]).count().max(1);
        let chunks: Vec<Range<usize>> =
            (0..rays.len()).step_by(CHUNK_RAYS).map(|s| s..(s + CHUNK_RAYS).min(rays.len())).collect();
        // The regularisers keep the weight each sample has when every sample is rendered: the
        // samples left out are not regularised, and the others' gradients are what they were.
        // (Means over the samples taken, as NeuS2 and instant-nsr-pl, weigh the curvature
        // term near the surface up to eight times as much: on the Mitsuba horse 5.54 degrees
        // against 4.28, about a degree more on most of the eight scenes.)
        let every = rays.len() * (config.sampling.coarse + config.sampling.fine);
        let norm = Norms { rays: rays.len() as f32, masked: masked_total as f32, samples: every as f32 };
        let step = Step { model, params, set, config, batch, norm };
        let results: Vec<(Vec<f32>, GridGradient, ChunkSums)> =
            chunks.into_par_iter().map(|range| step.chunk(range)).collect();
        // Summed in chunk order (the networks') and level by level in chunk order (the hash
        // grid's): the same step whatever the number of threads.
        grad[..model.network_params()].fill(0.0);
        let mut sums = ChunkSums::default();
        for (g, _, s) in &results {
            grad[..g.len()].iter_mut().zip(g).for_each(|(a, b)| *a += b);
            for term in Term::ALL {
                sums.losses[term] += s.losses[term];
            }
            sums.samples += s.samples;
        }
        let grid: Vec<&GridGradient> = results.iter().map(|r| &r.1).collect();
        model.field.write_grid_gradients(&grid, &batch.level_weight, grad);
        StepLosses { losses: sums.losses, samples: sums.samples }
    }
}

impl Step<'_> {
    /// The gradient and losses of the batch's rays in `range`.
    fn chunk(&self, range: Range<usize>) -> (Vec<f32>, GridGradient, ChunkSums) {
        let (set, model, params, config) = (self.set, self.model, self.params, self.config);
        let (batch, jitter) = (&self.batch.rays[range.clone()], &self.batch.jitter[range.clone()]);
        let (level_weight, fd_step, warm) = (&self.batch.level_weight[..], self.batch.fd_step, self.batch.warm);
        let (use_geometric, norm) = (self.batch.use_geometric, &self.norm);
        let rays: Vec<Ray> = batch.iter().map(|&(v, p)| set.ray(v, p)).collect();
        let occupancy = self.batch.occupancy.as_deref();
        let samples = weighted_samples(model, params, level_weight, &rays, config.sampling, jitter, occupancy);
        let depths = &samples.rendered;
        let fwd = Forward::run(model, params, level_weight, &rays, depths, fd_step, warm);
        let w = &config.weights;
        let mut sums = ChunkSums { samples: fwd.samples(), ..Default::default() };
        let mut grads = vec![RayGrad::default(); rays.len()];
        let mut surface = Vec::new();
        for (r, (&(v, p), out)) in batch.iter().zip(&fwd.rays).enumerate() {
            let view = &set.views[v as usize];
            let inside = view.mask[p as usize];
            let (loss, d) = mask_bce(out.opacity, inside);
            sums.losses[Term::Mask] += loss as f64 / norm.rays as f64;
            grads[r].opacity = w[Term::Mask] * d / norm.rays;
            if !inside {
                continue;
            }
            if config.photometric {
                let target = &view.stokes[STOKES * p as usize..STOKES * (p as usize + 1)];
                let used = if warm { 3 } else { STOKES };
                for k in 0..used {
                    // Mean over the colour channels, summed over S0, S1, S2.
                    let (loss, d) = l1(out.stokes[k], target[k]);
                    sums.losses[Term::Photometric] += loss as f64 / 3.0 / norm.masked as f64;
                    grads[r].stokes[k] = w[Term::Photometric] * d / 3.0 / norm.masked;
                }
            }
            if use_geometric && out.opacity > 0.5 {
                let t = out.depth / out.opacity;
                surface.push((r, rays[r].at(t), out.normal));
            }
        }
        if use_geometric && !surface.is_empty() {
            let points: Vec<[f32; 3]> = surface.iter().map(|s| s.1).collect();
            let normals: Vec<[f32; 3]> = surface.iter().map(|s| s.2).collect();
            let robust = robust_scale(config.tangent_robust_angle);
            let draws = &self.batch.tangent_view_draws;
            let offsets: Vec<f32> =
                if draws.is_empty() { Vec::new() } else { surface.iter().map(|s| draws[range.start + s.0]).collect() };
            let sample = (!draws.is_empty()).then_some(ViewSample { views: config.tangent_views, offsets: &offsets });
            let found = tangents(set, model, params, level_weight, &points, &normals, robust > 0.0, sample);
            for ((r, _, n), at) in surface.iter().zip(&found) {
                let robust = curved_robust_scale(robust, at.curvature_share);
                let (loss, dn) = tangent_loss(*n, &at.views, config.tangent_azimuth_only, robust);
                sums.losses[Term::Geometric] += loss as f64 / norm.masked as f64;
                grads[*r].normal = dn.map(|d| d * w[Term::Geometric] / norm.masked);
            }
        }
        // Eikonal and curvature on every sample's finite differences, each sample once.
        let d_gradients = self.eikonal_gradients(&fwd.field, |_| 1.0, &mut sums);
        let d_laplacians = self.curvature_gradients(&fwd.field, |_| 1.0, &mut sums);
        let mut grad = vec![0f32; model.network_params()];
        let mut grid = fwd.backward(model, params, &grads, &d_gradients, &d_laplacians, &mut grad);
        let draws = &self.batch.left_out_draws;
        let per_ray = config.sampling.regularised_left_out;
        if !draws.is_empty() && per_ray > 0 {
            // Each ray's draws pick among its samples left out behind the last it renders, in
            // space the ray does not see; each stands for its share of them. The curvature term
            // there carries the field of the space the views see past into the pockets no view
            // sees (the Eikonal term and the objects' insides do not, and cost sharp edges).
            let draws = &draws[per_ray * range.start..per_ray * range.end];
            let (mut points, mut shares) = (Vec::new(), Vec::new());
            for ((ray, (rendered, left_out)), u) in
                rays.iter().zip(depths.iter().zip(&samples.left_out)).zip(draws.chunks_exact(per_ray))
            {
                let Some(&last) = rendered.last() else { continue };
                let unseen: Vec<f32> = left_out.iter().copied().filter(|&depth| depth > last).collect();
                if unseen.is_empty() {
                    continue;
                }
                let share = unseen.len() as f32 / per_ray as f32;
                for &u in u {
                    let pick = ((u * unseen.len() as f32) as usize).min(unseen.len() - 1);
                    points.extend(ray.at(unseen[pick]));
                    shares.push(share);
                }
            }
            if !points.is_empty() {
                // The curvature term alone, outside the surface by the clearance.
                let share = |field: &FieldSamples, i: usize| Shares {
                    eikonal: 0.0,
                    curvature: if field.sdf[i] < REGULARISED_CLEARANCE { 0.0 } else { shares[i] },
                };
                grid.extend(self.regularise(points, share, &mut sums, &mut grad));
            }
        }
        let near = config.sampling.regularise_near_surface;
        if near > 0.0 {
            // Every sample left out within that distance of the surface (by the SDF the
            // sampling found) carries both terms for itself, as it would rendered: the rendered
            // samples alone leave the field just off the surface without them, and a smooth
            // object's normals ripple.
            let mut points = Vec::new();
            for (ray, (left_out, sdf)) in rays.iter().zip(samples.left_out.iter().zip(&samples.left_out_sdf)) {
                for (&depth, &sdf) in left_out.iter().zip(sdf) {
                    if sdf.abs() < near {
                        points.extend(ray.at(depth));
                    }
                }
            }
            if !points.is_empty() {
                let own = |_: &FieldSamples, _: usize| Shares { eikonal: 1.0, curvature: 1.0 };
                grid.extend(self.regularise(points, own, &mut sums, &mut grad));
            }
        }
        (grad, grid, sums)
    }

    /// The regularisers alone at `points` (n x 3), point `i` weighing `share(field, i)`
    /// samples in each term; adds the networks' gradient into `grad` and returns the hash
    /// grid's.
    fn regularise(
        &self,
        points: Vec<f32>,
        share: impl Fn(&FieldSamples, usize) -> Shares,
        sums: &mut ChunkSums,
        grad: &mut [f32],
    ) -> GridGradient {
        let batch = self.batch;
        let field = FieldSamples::evaluate(self.model, self.params, &batch.level_weight, points, batch.fd_step);
        let shares: Vec<Shares> = (0..field.sdf.len()).map(|i| share(&field, i)).collect();
        let d_gradients = self.eikonal_gradients(&field, |i| shares[i].eikonal, sums);
        let d_laplacians = self.curvature_gradients(&field, |i| shares[i].curvature, sums);
        let zeros = |n: usize| vec![0f32; n];
        let d = FieldGrad {
            sdf: &zeros(field.sdf.len()),
            normals: &zeros(field.normals.len()),
            features: &zeros(field.features.len()),
            gradients: &d_gradients,
            laplacians: &d_laplacians,
        };
        field.backward(self.model, self.params, &d, grad)
    }

    /// The Eikonal term on `field`'s finite-difference gradients, point `i` weighing
    /// `share(i)` samples (of the step's every-sample count; none where 0): its loss added to
    /// `sums`, and its gradient with respect to the gradients (n x 3).
    fn eikonal_gradients(&self, field: &FieldSamples, share: impl Fn(usize) -> f32, sums: &mut ChunkSums) -> Vec<f32> {
        let (w, samples) = (&self.config.weights, self.norm.samples);
        let mut d_gradients = vec![0f32; field.gradients.len()];
        for (i, (g, d)) in field.gradients.chunks_exact(3).zip(d_gradients.chunks_exact_mut(3)).enumerate() {
            let share = share(i);
            if share == 0.0 {
                continue;
            }
            let (loss, dg) = eikonal([g[0], g[1], g[2]]);
            sums.losses[Term::Eikonal] += (loss * share) as f64 / samples as f64;
            for k in 0..3 {
                d[k] = w[Term::Eikonal] * dg[k] * share / samples;
            }
        }
        d_gradients
    }

    /// The curvature term on `field`'s Laplacians, point `i` weighing `share(i)` samples (of
    /// the step's every-sample count; none where 0): its loss added to `sums`, and its
    /// gradient with respect to the Laplacians (n).
    fn curvature_gradients(
        &self,
        field: &FieldSamples,
        share: impl Fn(usize) -> f32,
        sums: &mut ChunkSums,
    ) -> Vec<f32> {
        let (w, samples) = (&self.config.weights, self.norm.samples);
        field
            .laplacians
            .iter()
            .enumerate()
            .map(|(i, &l)| {
                let share = share(i);
                if share == 0.0 {
                    return 0.0;
                }
                let (loss, d) = curvature(l);
                sums.losses[Term::Curvature] += (loss * share) as f64 / samples as f64;
                w[Term::Curvature] * self.batch.curvature_share * d * share / samples
            })
            .collect()
    }
}
