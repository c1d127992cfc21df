//! The training loop: ray batches, losses (photometric L1 on Stokes, geometric tangent-space,
//! mask BCE, Eikonal), Adam, non-finite handling and checkpoints that resume bit for bit.
//!
//! A batch is cut into a fixed number of chunks whose gradients are summed in order, so results
//! do not depend on the number of threads, and every random number derives from (seed,
//! iteration), so a resumed run repeats an uninterrupted one exactly.

use crate::data::TrainingSet;
use crate::engine::{Adam, AdamConfig};
use crate::geometric::{curved_robust_scale, robust_scale, tangent_loss, tangents};
use crate::losses::{curvature, eikonal, l1, mask_bce, PerTerm, Term};
use crate::model::{GridGradient, Model, ModelConfig, STOKES};
use crate::options::ReconOptions;
use crate::volume::{sample_depths, Forward, RayGrad, Sampling};
use crate::{Error, Result};
use rayon::prelude::*;
use rmvp_dataset::io::atomic::write_bytes_atomically;
use rmvp_dataset::rng::Rng;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Loss weights (official NeRSP: photometric 1, geometric 1, mask 1, Eikonal 0.1; curvature is
/// ours, from Neuralangelo, 0 in the paper preset).
pub type LossWeights = PerTerm<f32>;

/// Everything that defines a training run.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct TrainConfig {
    /// Network shapes.
    pub model: ModelConfig,
    /// Total iterations.
    pub iterations: u32,
    /// Rays per iteration.
    pub batch_rays: usize,
    /// Samples per ray.
    pub sampling: Sampling,
    /// Optimiser.
    pub adam: AdamConfig,
    /// Loss weights.
    pub weights: LossWeights,
    /// Use the photometric cue (off: MVAS-like, geometric only).
    pub photometric: bool,
    /// Use the geometric cue (off: PANDORA-like, photometric only).
    pub geometric: bool,
    /// The DoP at which a view's geometric term has half its weight (`dop^2 / (dop^2 + r^2)`);
    /// 0 weights every view that sees a point alike (NeRSP).
    #[serde(default)]
    pub aop_reliability: f32,
    /// The geometric loss turns each normal about the rays of the views only (its gradient's
    /// azimuthal part); off: NeRSP's full gradient, which also tilts normals towards cameras.
    #[serde(default)]
    pub tangent_azimuth_only: bool,
    /// The AoP's distance from a normal's planes, degrees, beyond which a view's geometric term
    /// stops growing (Geman-McClure on the term) where the surface curves
    /// ([`crate::geometric::curved_robust_scale`]); 0 keeps NeRSP's plain term.
    #[serde(default)]
    pub tangent_robust_angle: f32,
    /// Initial iterations with the diffuse lobe and S0 only, no geometric loss.
    pub diffuse_only: u32,
    /// Dilation of the masks that object rays are drawn from, pixels.
    pub margin: usize,
    /// Share of each batch drawn from the background (rays that cross the unit sphere outside
    /// the dilated masks), which only the mask loss sees.
    #[serde(default)]
    pub background_share: f32,
    /// Hash-grid levels active at the start; one more every `anneal_every` iterations.
    pub start_levels: usize,
    /// Iterations between two hash-grid levels.
    pub anneal_every: u32,
    /// Random seed.
    pub seed: u64,
    /// Training views at 1/`downscale` of their size (Stokes and masks averaged over blocks);
    /// the outputs stay at the scene's size.
    #[serde(default = "full_size")]
    pub downscale: u32,
}

fn full_size() -> u32 {
    1
}

/// Rays per chunk of a batch; chunks run in parallel and are summed in order.
const CHUNK_RAYS: usize = 32;

/// One line of the loss log.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct StepReport {
    /// Iteration this step computed (0-based).
    pub iteration: u32,
    /// Weighted total.
    pub loss: f64,
    /// Each term, unweighted.
    pub losses: PerTerm<f64>,
    /// NeuS sharpness.
    pub inv_s: f32,
    /// The specular lobe's learned polarization scale, when the model learns it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub polarization: Option<f32>,
    /// Rays rendered.
    pub rays: usize,
    /// Samples evaluated (each costs 7 field evaluations).
    pub samples: usize,
    /// Learning-rate factor of the schedule.
    pub lr_factor: f32,
    /// What went wrong, if the step was not applied.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub event: Option<StepEvent>,
}

/// A step that was not applied.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum StepEvent {
    /// A non-finite loss or gradient: the update was skipped.
    Skipped,
    /// Non-finite three times in a row: parameters and optimiser rolled back to the last safe
    /// state, that of iteration `to`.
    RolledBack {
        /// The iteration whose state was restored.
        to: u32,
    },
}

impl std::fmt::Display for StepEvent {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StepEvent::Skipped => f.write_str("non-finite loss or gradient: step skipped"),
            StepEvent::RolledBack { to } => write!(
                f,
                "non-finite loss or gradient three times in a row: rolled back to the state of iteration {to}"
            ),
        }
    }
}

#[derive(Default)]
struct ChunkSums {
    losses: PerTerm<f64>,
    samples: usize,
}

/// A model being trained on a training set.
pub struct Trainer {
    /// The run's definition.
    pub config: TrainConfig,
    /// Network shapes and layout.
    pub model: Model,
    /// The data.
    pub set: TrainingSet,
    /// Current parameters.
    pub params: Vec<f32>,
    /// Optimiser state.
    pub adam: Adam,
    /// Next iteration to run.
    pub iteration: u32,
    /// The options the run was started with, where a caller gave them (recorded in the
    /// checkpoint).
    pub options: Option<ReconOptions>,
    /// Consecutive non-finite steps.
    bad_steps: u32,
    /// The last state known to be finite (every 100 iterations): (params, adam, iteration).
    safe: (Vec<f32>, Adam, u32),
}

impl Trainer {
    /// A fresh run. Without the photometric cue the specular lobe's tilt is dropped: it is read
    /// from the specular network, which nothing else fits, so each AoP is taken as measured.
    pub fn new(mut config: TrainConfig, set: TrainingSet) -> Self {
        config.model.specular_tilt &= config.photometric;
        let model = Model::new(config.model.clone());
        let params = model.init(config.seed);
        let adam = Adam::new(params.len());
        let safe = (params.clone(), adam.clone(), 0);
        Self { config, model, set, params, adam, iteration: 0, options: None, bad_steps: 0, safe }
    }

    /// Per-level weights of the hash grid at the current iteration (coarse to fine).
    pub fn level_weight(&self) -> Vec<f32> {
        let levels = self.model.field.levels();
        let active = self.config.start_levels + (self.iteration / self.config.anneal_every.max(1)) as usize;
        (0..levels).map(|l| if l < active { 1.0 } else { 0.0 }).collect()
    }

    /// Finite-difference step of the normals: the finest active grid cell (Neuralangelo), or
    /// a fixed 0.005 for the MLP.
    pub fn fd_step(&self, level_weight: &[f32]) -> f32 {
        match self.model.field.finest_active(level_weight) {
            Some(res) => (2.0 / res as f32).max(2e-3),
            None => 5e-3,
        }
    }

    /// Whether the current iteration is in the diffuse-only warm-up.
    fn warming_up(&self) -> bool {
        self.config.photometric && self.iteration < self.config.diffuse_only
    }

    /// Run one iteration; non-finite losses or gradients skip the update (and after three in a
    /// row roll back to the last safe state), which the report's `event` says.
    pub fn step(&mut self) -> StepReport {
        let it = self.iteration;
        let mut rng = Rng::for_pixel(self.config.seed, it, 0);
        let set = &self.set;
        let from_background = if set.background.is_empty() {
            0
        } else {
            (self.config.background_share * self.config.batch_rays as f32).round() as usize
        };
        let batch: Vec<(u32, u32)> = (0..self.config.batch_rays)
            .map(|i| {
                let pool = if i < from_background { &set.background } else { &set.pool };
                pool[rng.next_u32() as usize % pool.len()]
            })
            .collect();
        let jitter: Vec<f32> = (0..batch.len()).map(|_| rng.next_f32()).collect();
        let masked_total = batch.iter().filter(|&&(v, p)| self.set.views[v as usize].mask[p as usize]).count().max(1);
        let level_weight = self.level_weight();
        let fd_step = self.fd_step(&level_weight);
        let warm = self.warming_up();
        let use_geometric = self.config.geometric && !warm;
        let samples_per_ray = self.config.sampling.coarse + self.config.sampling.fine;
        let norm = Norms {
            rays: batch.len() as f32,
            masked: masked_total as f32,
            samples: (batch.len() * samples_per_ray) as f32,
        };

        let chunks: Vec<(usize, usize)> =
            (0..batch.len()).step_by(CHUNK_RAYS).map(|s| (s, (s + CHUNK_RAYS).min(batch.len()))).collect();
        let results: Vec<(Vec<f32>, GridGradient, ChunkSums)> = chunks
            .par_iter()
            .map(|&(a, b)| self.chunk(&batch[a..b], &jitter[a..b], &level_weight, fd_step, warm, use_geometric, &norm))
            .collect();
        // Summed in chunk order (the networks') and level by level in chunk order (the hash
        // grid's): the same step whatever the number of threads.
        let mut grad = vec![0f32; self.params.len()];
        let mut sums = ChunkSums::default();
        for (g, _, s) in &results {
            grad[..g.len()].iter_mut().zip(g).for_each(|(a, b)| *a += b);
            for term in Term::ALL {
                sums.losses[term] += s.losses[term];
            }
            sums.samples += s.samples;
        }
        let grid: Vec<&GridGradient> = results.iter().map(|r| &r.1).collect();
        self.model.field.add_grid_gradients(&grid, &level_weight, &mut grad);
        let w = &self.config.weights;
        let mut report = StepReport {
            iteration: it,
            losses: sums.losses,
            loss: sums.losses.iter().map(|(term, value)| w[term] as f64 * value).sum(),
            inv_s: self.model.inv_s(&self.params),
            polarization: self.model.radiance.learned_polarization(&self.params),
            rays: batch.len(),
            samples: sums.samples,
            lr_factor: Adam::schedule(&self.config.adam, it, self.config.iterations),
            event: None,
        };
        if !report.loss.is_finite() || grad.iter().any(|g| !g.is_finite()) {
            self.bad_steps += 1;
            if self.bad_steps >= 3 {
                let (params, adam, at) = self.safe.clone();
                self.params = params;
                self.adam = adam;
                report.event = Some(StepEvent::RolledBack { to: at });
                self.bad_steps = 0;
            } else {
                report.event = Some(StepEvent::Skipped);
            }
            self.iteration += 1;
            return report;
        }
        self.bad_steps = 0;
        self.adam.step(&self.model.layout, &self.config.adam, &mut self.params, &grad, it, self.config.iterations);
        self.iteration += 1;
        if self.iteration.is_multiple_of(100) {
            self.safe = (self.params.clone(), self.adam.clone(), self.iteration);
        }
        report
    }

    #[allow(clippy::too_many_arguments)]
    fn chunk(
        &self,
        batch: &[(u32, u32)],
        jitter: &[f32],
        level_weight: &[f32],
        fd_step: f32,
        warm: bool,
        use_geometric: bool,
        norm: &Norms,
    ) -> (Vec<f32>, GridGradient, ChunkSums) {
        let set = &self.set;
        let rays: Vec<_> = batch.iter().map(|&(v, p)| set.ray(v, p)).collect();
        let depths = sample_depths(&self.model, &self.params, level_weight, &rays, self.config.sampling, jitter);
        let fwd = Forward::run(&self.model, &self.params, level_weight, &rays, &depths, fd_step, warm);
        let w = &self.config.weights;
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
            if self.config.photometric {
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
            let robust = robust_scale(self.config.tangent_robust_angle);
            let found = tangents(
                set,
                self.config.aop_reliability,
                &self.model,
                &self.params,
                level_weight,
                &points,
                &normals,
                robust > 0.0,
            );
            for ((r, _, n), at) in surface.iter().zip(&found) {
                let robust = curved_robust_scale(robust, at.curvature_share);
                let (loss, dn) = tangent_loss(*n, &at.views, self.config.tangent_azimuth_only, robust);
                sums.losses[Term::Geometric] += loss as f64 / norm.masked as f64;
                grads[*r].normal = dn.map(|d| d * w[Term::Geometric] / norm.masked);
            }
        }
        // Eikonal on every sample's finite-difference gradient.
        let mut d_gradients = vec![0f32; fwd.field.gradients.len()];
        for (g, d) in fwd.field.gradients.chunks_exact(3).zip(d_gradients.chunks_exact_mut(3)) {
            let (loss, dg) = eikonal([g[0], g[1], g[2]]);
            sums.losses[Term::Eikonal] += loss as f64 / norm.samples as f64;
            for k in 0..3 {
                d[k] = w[Term::Eikonal] * dg[k] / norm.samples;
            }
        }
        // Curvature on every sample's finite-difference Laplacian.
        let d_laplacians: Vec<f32> = fwd
            .field
            .laplacians
            .iter()
            .map(|&l| {
                let (loss, d) = curvature(l);
                sums.losses[Term::Curvature] += loss as f64 / norm.samples as f64;
                w[Term::Curvature] * d / norm.samples
            })
            .collect();
        let mut grad = vec![0f32; self.model.network_params()];
        let grid = fwd.backward(&self.model, &self.params, &grads, &d_gradients, &d_laplacians, &mut grad);
        (grad, grid, sums)
    }

    /// Save parameters, optimiser state and iteration to `path` (atomically).
    pub fn save_checkpoint(&self, path: &Path) -> Result<()> {
        let header = serde_json::to_vec(&CheckpointHeader {
            format: CHECKPOINT_FORMAT.into(),
            config: self.config.clone(),
            options: self.options.clone(),
            iteration: self.iteration,
            adam_steps: self.adam.steps,
            parameters: self.params.len(),
        })
        .expect("plain data");
        let mut bytes = Vec::with_capacity(16 + header.len() + 12 * self.params.len());
        bytes.extend_from_slice(CHECKPOINT_MAGIC);
        bytes.extend_from_slice(&(header.len() as u64).to_le_bytes());
        bytes.extend_from_slice(&header);
        for v in [&self.params, &self.adam.m, &self.adam.v] {
            for x in v.iter() {
                bytes.extend_from_slice(&x.to_le_bytes());
            }
        }
        Ok(write_bytes_atomically(path, &bytes)?)
    }

    /// Restore a run from a checkpoint written by [`Trainer::save_checkpoint`]; the training
    /// set must be the one it was trained on. The checkpoint's header is compared with the run's
    /// `config` (and with `options`, where both have them) before anything is built from it: a
    /// header may declare any model, and only the run's is built.
    pub fn load_checkpoint(
        path: &Path,
        set: TrainingSet,
        config: &TrainConfig,
        options: Option<&ReconOptions>,
    ) -> Result<Self> {
        let bad = |m: &str| Error::BadCheckpoint { path: path.to_path_buf(), problem: m.to_string() };
        let (header, len, file_len) = checkpoint_header(path)?;
        let changed = match (&header.options, options) {
            (Some(recorded), Some(now)) => recorded.training_differences(now),
            _ => Vec::new(),
        };
        if !changed.is_empty() || header.config != *config {
            let changed = if changed.is_empty() { "the training configuration".into() } else { changed.join(", ") };
            return Err(Error::CheckpointSettings { path: path.to_path_buf(), changed });
        }
        // The file's size against its header's count before anything is read or built.
        let body = file_len - 16 - len as u64;
        let expected = 12u64.saturating_mul(header.parameters as u64);
        if body != expected {
            let state = if body < expected { "truncated" } else { "too long" };
            return Err(bad(&format!("{state}: {body} bytes of parameters and optimiser state, expected {expected}")));
        }
        let mut trainer = Self::new(config.clone(), set);
        trainer.options = header.options;
        let n = trainer.params.len();
        if header.parameters != n {
            return Err(bad(&format!("{} parameters, the model has {n}", header.parameters)));
        }
        let bytes = rmvp_dataset::io::input::read_bytes_limited(path, file_len)?;
        let floats: Vec<f32> = bytes
            .get(16 + len..)
            .unwrap_or_default()
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect();
        if floats.len() != 3 * n {
            return Err(bad("changed while read"));
        }
        trainer.params = floats[..n].to_vec();
        trainer.adam.m = floats[n..2 * n].to_vec();
        trainer.adam.v = floats[2 * n..].to_vec();
        trainer.adam.steps = header.adam_steps;
        trainer.iteration = header.iteration;
        if trainer.params.iter().any(|p| !p.is_finite()) {
            return Err(bad("non-finite parameters"));
        }
        trainer.safe = (trainer.params.clone(), trainer.adam.clone(), trainer.iteration);
        Ok(trainer)
    }
}

struct Norms {
    rays: f32,
    masked: f32,
    samples: f32,
}

const CHECKPOINT_MAGIC: &[u8; 8] = b"RMVPCKPT";
/// The checkpoint's format: 2 since the hash grid's tables come after the networks.
const CHECKPOINT_FORMAT: &str = "rmvp-recon-checkpoint-2";

/// The options a checkpoint's run was started with (`None` for a run started without them).
pub fn checkpoint_options(path: &Path) -> Result<Option<ReconOptions>> {
    Ok(checkpoint_header(path)?.0.options)
}

/// The most bytes a checkpoint's header (JSON: the configuration and options) may have.
const MAX_CHECKPOINT_HEADER_BYTES: u64 = 1 << 20;

/// A checkpoint's header, its length in bytes and the file's length: only the header is read.
fn checkpoint_header(path: &Path) -> Result<(CheckpointHeader, usize, u64)> {
    use std::io::Read;
    let bad = |m: &str| Error::BadCheckpoint { path: path.to_path_buf(), problem: m.to_string() };
    let file = rmvp_dataset::io::input::open_regular(path)?;
    let file_len = file.metadata().map_err(|e| rmvp_dataset::Error::io(path, e))?.len();
    let mut head = Vec::new();
    let mut reader = file.take(16 + MAX_CHECKPOINT_HEADER_BYTES);
    reader.by_ref().take(16).read_to_end(&mut head).map_err(|e| rmvp_dataset::Error::io(path, e))?;
    if head.len() < 16 || &head[..8] != CHECKPOINT_MAGIC {
        return Err(bad("not an rmvp checkpoint"));
    }
    let len = u64::from_le_bytes(head[8..16].try_into().expect("8 bytes"));
    if len > MAX_CHECKPOINT_HEADER_BYTES || 16 + len > file_len {
        return Err(bad("truncated header"));
    }
    let mut text = Vec::with_capacity(len as usize);
    reader.take(len).read_to_end(&mut text).map_err(|e| rmvp_dataset::Error::io(path, e))?;
    if text.len() as u64 != len {
        return Err(bad("truncated header"));
    }
    let header: CheckpointHeader = serde_json::from_slice(&text).map_err(|e| bad(&format!("header: {e}")))?;
    if header.format != CHECKPOINT_FORMAT {
        return Err(bad(&format!("format {}, this version reads {CHECKPOINT_FORMAT}", header.format)));
    }
    Ok((header, len as usize, file_len))
}

#[derive(Serialize, Deserialize)]
struct CheckpointHeader {
    format: String,
    config: TrainConfig,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    options: Option<ReconOptions>,
    iteration: u32,
    adam_steps: u32,
    parameters: usize,
}
