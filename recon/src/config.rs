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
    /// Rays per iteration: every step's, or the first's where `samples_per_step` is set.
    pub batch_rays: usize,
    /// Samples a step should render: each step's rays are those of the step before scaled by
    /// this over the samples that step rendered (instant-NGP's dynamic batch), between
    /// [`RAYS_RANGE`] times fewer and more than `batch_rays`; 0: every step renders
    /// `batch_rays` rays.
    #[serde(default)]
    pub samples_per_step: usize,
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
    /// Iterations between two hash-grid levels.
    pub anneal_every: u32,
    /// Random seed.
    pub seed: u64,
    /// Training views at 1/`downscale` of their size (Stokes and masks averaged over blocks);
    /// the outputs stay at the scene's size.
    #[serde(default = "full_size")]
    pub downscale: u32,
}

/// How far a step's rays may stray from `batch_rays` where they follow its samples: at most
/// this many times fewer or more.
pub const RAYS_RANGE: usize = 4;

impl TrainConfig {
    /// The rays a step of this run may render: within [`RAYS_RANGE`] of `batch_rays` where they
    /// follow the samples, `batch_rays` alone where the count is fixed.
    pub fn ray_range(&self) -> std::ops::RangeInclusive<usize> {
        match self.samples_per_step {
            0 => self.batch_rays..=self.batch_rays,
            _ => self.batch_rays.div_ceil(RAYS_RANGE)..=self.batch_rays * RAYS_RANGE,
        }
    }

    /// The rays of the step after one that rendered `samples` samples of `rays` rays: those
    /// that would have rendered `samples_per_step` at the same samples per ray, within
    /// [`TrainConfig::ray_range`].
    pub fn next_rays(&self, rays: usize, samples: usize) -> usize {
        let wanted = (rays as f64 * self.samples_per_step as f64 / samples.max(1) as f64).round() as usize;
        let range = self.ray_range();
        wanted.clamp(*range.start(), *range.end())
    }
}

fn full_size() -> u32 {
    1
}

#[cfg(test)]
mod tests {
    use crate::presets::{training, Preset};

    #[test]
    fn a_steps_rays_follow_the_samples_per_ray_of_the_step_before_within_their_range() {
        let mut config = training(Preset::Fast, 100);
        config.batch_rays = 256;
        assert_eq!(config.next_rays(100, 9000), 256, "a fixed count stays fixed");
        config.samples_per_step = 4096;
        assert_eq!(config.next_rays(256, 8192), 128);
        assert_eq!(config.next_rays(300, 2400), 512);
        assert_eq!(config.next_rays(256, 3000), 350, "rounded to the nearest ray");
        assert_eq!(config.next_rays(256, 1 << 20), 64, "a quarter of the batch at least");
        assert_eq!(config.next_rays(256, 0), 1024, "four times the batch at most");
    }
}
