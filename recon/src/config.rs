//! What defines a training run: the networks' shapes, sampling, optimiser, loss weights and the
//! cues' settings.

use crate::engine::AdamConfig;
use crate::losses::PerTerm;
use crate::model::ModelConfig;
use crate::volume::Sampling;
use serde::{Deserialize, Serialize};

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
    /// The geometric loss turns each normal about the rays of the views only (its gradient's
    /// azimuthal part); off: NeRSP's full gradient, which also tilts normals towards cameras.
    #[serde(default)]
    pub tangent_azimuth_only: bool,
    /// The AoP's distance from a normal's planes, degrees, beyond which a view's geometric term
    /// stops growing (Geman-McClure on the term) where the surface curves
    /// ([`crate::geometric::curved_robust_scale`]); 0 keeps NeRSP's plain term.
    #[serde(default)]
    pub tangent_robust_angle: f32,
    /// Views that the geometric loss compares with a surface point, at most: a systematic
    /// sample of those that face it, drawn for each ray ([`crate::geometric::ViewSample`]);
    /// 0 compares every one (NeRSP).
    #[serde(default)]
    pub tangent_views: usize,
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
    /// The curvature weight follows the coarse-to-fine schedule (Neuralangelo): it ramps up
    /// from 0 over the learning rate's warm-up, then falls as the hash grid's levels open, in
    /// proportion to the finest active level's cell to the power `curvature_cell_power`, from
    /// `weights` at the start levels; off, `weights` holds throughout.
    #[serde(default)]
    pub curvature_follows_levels: bool,
    /// The power of the finest active cell that the curvature weight follows
    /// (`curvature_follows_levels`): 1 is Neuralangelo's proportion.
    #[serde(default = "proportional")]
    pub curvature_cell_power: f32,
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

fn proportional() -> f32 {
    1.0
}
