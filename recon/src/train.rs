//! The training loop: ray batches, losses (photometric L1 on Stokes, geometric tangent-space,
//! mask BCE, Eikonal), Adam and non-finite handling; [`crate::checkpoint`] saves and resumes a
//! run bit for bit.
//!
//! A batch is cut into a fixed number of chunks whose gradients are summed in order, so results
//! do not depend on the number of threads, and every random number derives from (seed,
//! iteration), so a resumed run repeats an uninterrupted one exactly.

pub use crate::config::{LossWeights, TrainConfig};
use crate::data::TrainingSet;
use crate::engine::Adam;
use crate::losses::{PerTerm, Term};
use crate::model::Model;
use crate::occupancy::{OccupancyGrid, REFRESH_EVERY};
use crate::step::{Batch, CpuStep, StepCompute, StepLosses};
use rayon::prelude::*;
use rmvp_dataset::rng::Rng;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// The outputs' normals take central differences over this many of the hash grid's finest
/// cells, where training takes one: on the eight Mitsuba scenes one and a half lower the
/// normal error on six, by up to 0.11 degrees, and hold the fandisk and the horse; two cost
/// the horse 0.11 (`docs/design.md`). A ripple of the finest cells is not the shape.
pub const OUTPUT_NORMAL_CELLS: f32 = 1.5;

/// A finite-difference step of `cells` cells of a hash grid whose finest active level has
/// `finest` cells per axis across the unit sphere's cube, at least 0.002; 0.005 for the MLP
/// (`finest` None).
fn normal_step(finest: Option<u32>, cells: f32) -> f32 {
    match finest {
        Some(res) => (2.0 * cells / res as f32).max(2e-3),
        None => 5e-3,
    }
}

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
    /// The normal error against the scene's ground truth after the step, degrees, at the
    /// iterations [`crate::tracking`] measures it (a scene with ground-truth normals).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normal_error_deg: Option<f64>,
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
    /// The engine that computes each step's gradient.
    compute: Box<dyn StepCompute>,
    /// The step's gradient, kept from step to step (as long as `params`).
    grad: Vec<f32>,
    /// Consecutive non-finite steps.
    bad_steps: u32,
    /// The last state known to be finite (every 100 iterations): (params, adam, iteration).
    safe: (Vec<f32>, Adam, u32),
    /// The SDF on a coarse grid for the steps' sampling, refreshed every
    /// [`REFRESH_EVERY`](crate::occupancy::REFRESH_EVERY) iterations (None where every sample
    /// is rendered).
    occupancy: Option<Arc<OccupancyGrid>>,
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
        let compute = Box::new(CpuStep);
        let grad = vec![0.0; params.len()];
        let mut trainer =
            Self { config, model, set, params, adam, iteration: 0, compute, grad, bad_steps: 0, safe, occupancy: None };
        trainer.refresh_occupancy();
        trainer
    }

    /// The same run with its steps computed by `compute` (the CPU's [`CpuStep`] by default).
    pub fn with_compute(self, compute: Box<dyn StepCompute>) -> Self {
        Self { compute, ..self }
    }

    /// Per-level weights of the hash grid at the current iteration (coarse to fine).
    pub fn level_weight(&self) -> Vec<f32> {
        self.level_weight_at(self.iteration)
    }

    /// Per-level weights of the hash grid at `iteration`: the start levels, then one more
    /// every `anneal_every` iterations.
    fn level_weight_at(&self, iteration: u32) -> Vec<f32> {
        let levels = self.model.field.levels();
        let active = self.config.start_levels + (iteration / self.config.anneal_every.max(1)) as usize;
        (0..levels).map(|l| if l < active { 1.0 } else { 0.0 }).collect()
    }

    /// The share of the curvature weight at the current iteration, whose hash-grid levels
    /// are `level_weight`: 1 throughout unless the weight follows the levels
    /// ([`TrainConfig::curvature_follows_levels`]); then from 0 to 1 over the learning rate's
    /// warm-up, times the finest active level's cell over the start levels' finest cell to the
    /// power [`TrainConfig::curvature_cell_power`].
    pub fn curvature_share(&self, level_weight: &[f32]) -> f32 {
        if !self.config.curvature_follows_levels {
            return 1.0;
        }
        let warmup = self.config.adam.warmup;
        let ramp = if warmup == 0 { 1.0 } else { (self.iteration as f32 / warmup as f32).min(1.0) };
        let field = &self.model.field;
        let cells = match (field.finest_active(&self.level_weight_at(0)), field.finest_active(level_weight)) {
            (Some(start), Some(now)) => start as f32 / now as f32,
            _ => 1.0,
        };
        ramp * cells.powf(self.config.curvature_cell_power)
    }

    /// Finite-difference step of the normals in training: the finest active grid cell
    /// (Neuralangelo), at least 0.002; a fixed 0.005 for the MLP.
    pub fn fd_step(&self, level_weight: &[f32]) -> f32 {
        normal_step(self.model.field.finest_active(level_weight), 1.0)
    }

    /// Finite-difference step of the normals the outputs show (the mesh's vertex normals, the
    /// views' normal maps, the normal error tracked in training): [`OUTPUT_NORMAL_CELLS`] of
    /// the finest active grid cells, at least 0.002; a fixed 0.005 for the MLP.
    pub fn output_fd_step(&self, level_weight: &[f32]) -> f32 {
        normal_step(self.model.field.finest_active(level_weight), OUTPUT_NORMAL_CELLS)
    }

    /// Whether the current iteration is in the diffuse-only warm-up.
    fn warming_up(&self) -> bool {
        self.config.photometric && self.iteration < self.config.diffuse_only
    }

    /// Run one iteration; non-finite losses or gradients skip the update (and after three in a
    /// row roll back to the last safe state), which the report's `event` says.
    pub fn step(&mut self) -> StepReport {
        let it = self.iteration;
        if it > 0 && it.is_multiple_of(REFRESH_EVERY) {
            self.refresh_occupancy();
        }
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
        let level_weight = self.level_weight();
        let fd_step = self.fd_step(&level_weight);
        let curvature_share = self.curvature_share(&level_weight);
        let warm = self.warming_up();
        let use_geometric = self.config.geometric && !warm;
        let occupancy = self.occupancy.clone();
        let sampling = self.config.sampling;
        let draws = if sampling.skips_empty_space() { sampling.regularised_left_out * batch.len() } else { 0 };
        let left_out_draws = (0..draws).map(|_| rng.next_f32()).collect();
        let views = self.config.tangent_views;
        let samples_views = use_geometric && views > 0 && views < set.views.len();
        let tangent_view_draws =
            if samples_views { (0..batch.len()).map(|_| rng.next_f32()).collect() } else { Vec::new() };
        let batch = Batch {
            rays: batch,
            jitter,
            level_weight,
            fd_step,
            curvature_share,
            warm,
            use_geometric,
            occupancy,
            left_out_draws,
            tangent_view_draws,
        };
        let StepLosses { losses, samples } =
            self.compute.gradient(&self.model, &self.params, &self.set, &self.config, &batch, &mut self.grad);
        let w = &self.config.weights;
        let mut report = StepReport {
            iteration: it,
            losses,
            loss: losses
                .iter()
                .map(|(term, value)| {
                    let share = if term == Term::Curvature { batch.curvature_share } else { 1.0 };
                    (w[term] * share) as f64 * value
                })
                .sum(),
            inv_s: self.model.inv_s(&self.params),
            polarization: self.model.radiance.learned_polarization(&self.params),
            rays: batch.rays.len(),
            samples,
            lr_factor: Adam::schedule(&self.config.adam, it, self.config.iterations),
            event: None,
            normal_error_deg: None,
        };
        if !report.loss.is_finite() || !all_finite(&self.grad) {
            self.bad_steps += 1;
            if self.bad_steps >= 3 {
                let (params, adam, at) = self.safe.clone();
                self.params = params;
                self.adam = adam;
                self.refresh_occupancy();
                report.event = Some(StepEvent::RolledBack { to: at });
                self.bad_steps = 0;
            } else {
                report.event = Some(StepEvent::Skipped);
            }
            self.iteration += 1;
            return report;
        }
        self.bad_steps = 0;
        self.adam.step(&self.model.layout, &self.config.adam, &mut self.params, &self.grad, it, self.config.iterations);
        self.iteration += 1;
        if self.iteration.is_multiple_of(100) {
            // Into the buffers the last safe state had.
            let (params, adam, at) = &mut self.safe;
            params.clone_from(&self.params);
            adam.clone_from(&self.adam);
            *at = self.iteration;
        }
        report
    }

    /// Restore the state a checkpoint recorded: parameters, optimiser state, the next
    /// iteration (the last safe state too).
    pub(crate) fn restore(&mut self, params: Vec<f32>, adam: Adam, iteration: u32, occupancy: Option<OccupancyGrid>) {
        self.params = params;
        self.adam = adam;
        self.iteration = iteration;
        self.safe = (self.params.clone(), self.adam.clone(), self.iteration);
        self.occupancy = occupancy.map(Arc::new);
    }

    /// The occupancy grid the steps sample through (None where every sample is rendered).
    pub fn occupancy(&self) -> Option<&OccupancyGrid> {
        self.occupancy.as_deref()
    }

    /// Build the occupancy grid from the current parameters (none where every sample is
    /// rendered): at the start, every [`REFRESH_EVERY`] iterations and after a roll-back, and
    /// where a caller changed the configuration's sampling.
    pub fn refresh_occupancy(&mut self) {
        self.occupancy = self
            .config
            .sampling
            .skips_empty_space()
            .then(|| Arc::new(OccupancyGrid::new(&self.model, &self.params, &self.level_weight())));
    }
}

/// Whether every value is finite: in parallel blocks, each read whole (no early exit), so that
/// the test vectorises.
fn all_finite(values: &[f32]) -> bool {
    values.par_chunks(1 << 16).all(|block| block.iter().fold(true, |finite, v| finite & v.is_finite()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::presets::{self, Preset};

    #[test]
    fn the_outputs_normals_span_more_cells_than_trainings_where_the_grid_is_coarse() {
        let finest = |preset| presets::model(preset).grid.map(|g| g.3);
        // The fast preset's finest level (256 cells): one cell in training, one and a half out.
        let fast = finest(Preset::Fast);
        assert_eq!(normal_step(fast, 1.0), 2.0 / 256.0);
        assert_eq!(normal_step(fast, OUTPUT_NORMAL_CELLS), 3.0 / 256.0);
        // The dense preset's 2048 cells are finer than the least step: both stay at it, as the
        // dense reference was measured.
        let dense = finest(Preset::Dense);
        assert_eq!(normal_step(dense, 1.0), 2e-3);
        assert_eq!(normal_step(dense, OUTPUT_NORMAL_CELLS), 2e-3);
        assert_eq!(normal_step(finest(Preset::Paper), OUTPUT_NORMAL_CELLS), 5e-3);
    }
}
