//! The presets, as data: every number a preset sets (network shapes, iterations, rays, samples,
//! learning rates, loss weights, schedules) is here and nowhere else. [`ReconOptions`]
//! (`crate::options`) starts from [`training`] and changes what the caller set.
//!
//! [`ReconOptions`]: crate::options::ReconOptions

use crate::config::{LossWeights, TrainConfig};
use crate::engine::AdamConfig;
use crate::losses::Term;
use crate::model::{neus_initial_radius, ModelConfig};
use crate::volume::Sampling;
use serde::{Deserialize, Serialize};

/// The presets: the model, its size and its training schedule together.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// Hash grid + small MLPs: minutes on a CPU.
    #[default]
    Fast,
    /// The official NeRSP/NeuS networks (8x256 SDF MLP): hours.
    Paper,
    /// The fast preset's networks on a finer, larger hash grid (to 2048 cells per axis), twice
    /// the rays and 4000 iterations: the reference shape of a dataset from 20-60 views at
    /// 1224x1024 (24 views: about 8 minutes on two threads).
    Dense,
}

impl Preset {
    /// Training iterations of a run of this preset unless told otherwise (fast: 3300, about 2
    /// minutes on 2 cores: 3000 lowered the error against 2000 on every scene of the evaluation
    /// set at 1224x1024, and 3300 the Mitsuba set's mean again, `docs/design.md`; dense: 4000;
    /// paper: the official 100k).
    pub fn default_iterations(self) -> u32 {
        match self {
            Preset::Fast => 3300,
            Preset::Dense => 4000,
            Preset::Paper => 100_000,
        }
    }
}

/// Curvature weight of the dense preset throughout: measured on the evaluation set
/// (`docs/benchmarks.md`): 5e-3 lowered the normal error on all six scenes against 5e-4, 1e-2
/// raised it again on the gear and the bowl.
pub const CURVATURE_WEIGHT: f32 = 5e-3;

/// Curvature weight of the fast preset while only its coarse hash-grid levels are open; it
/// falls as the finer ones open, as the finest open level's cell to the power
/// [`FAST_CURVATURE_CELL_POWER`] ([`TrainConfig::curvature_follows_levels`], Neuralangelo's
/// schedule), to about 2.05e-3 with all eight: a smooth shape settles under the coarse levels'
/// strong smoothing, and edges come with the fine levels' weak one (`docs/design.md`, coarse
/// to fine).
pub const FAST_CURVATURE_WEIGHT: f32 = 1.5e-2;

/// The power of the finest open cell that the fast preset's curvature weight follows: faster
/// than Neuralangelo's proportion (1, to about 3.1e-3), which rounded the Mitsuba fandisk's and
/// rocker arm's edges; the smooth spot keeps its normals, which the coarse levels' weight gives
/// it (`docs/experiments.md`, coarse to fine).
pub const FAST_CURVATURE_CELL_POWER: f32 = 1.256;

/// The fast preset's robust angle of the AoP tangent term, degrees, on curved surfaces
/// ([`crate::geometric::curved_robust_scale`]): on the Mitsuba set (`docs/benchmarks.md`) spot
/// fell under the photometric cue alone at three seeds while the fandisk's faces kept the plain
/// term's pull; 10 degrees lost on the fandisk, the teapot and the gold gear.
pub const TANGENT_ROBUST_ANGLE: f32 = 20.0;

/// Radius of the fast preset's initial sphere, in the unit sphere: a start that lies inside a
/// concavity the masks do not show lets the surface grow up around it instead of closing a lid
/// over it (our bowl's floor sinks from near the rim to below half its depth,
/// `docs/benchmarks.md`); NeuS starts from 0.5.
pub const FAST_INITIAL_RADIUS: f32 = 0.2;

/// The fast and dense presets' least weight of a rendered sample
/// ([`crate::volume::weighted_samples`]): the samples in empty space and behind the surface are
/// left out of a step (`docs/benchmarks.md`, a training step).
pub const MIN_SAMPLE_WEIGHT: f32 = 1e-4;

/// The fast preset's samples a ray draws among those it leaves out behind the last it renders,
/// where the curvature term still sees them ([`crate::step::Batch::left_out_draws`]): space
/// that no view sees past takes the field of the space around it, so that a turntable capture
/// grows less of a blob under its object, at some seeds none (`docs/reconstruction.md`).
pub const REGULARISED_LEFT_OUT: usize = 2;

/// The fast and dense presets' distance from the surface within which the samples a step
/// leaves out still carry the Eikonal and curvature terms
/// ([`crate::volume::Sampling::regularise_near_surface`]): the field just off the surface keeps
/// the smoothing that rendering every sample gives it, which a smooth object's normals need
/// (`docs/design.md`, a smooth object's ripple).
pub const REGULARISED_NEAR_SURFACE: f32 = 0.05;

/// The fast and dense presets' most views that the AoP tangent loss compares with a surface
/// point ([`crate::geometric::ViewSample`]); a scene of 6 views keeps every one.
pub const TANGENT_VIEWS: usize = 8;

/// Share of background rays in a batch.
pub const BACKGROUND_SHARE: f32 = 0.25;

/// The network shapes of `preset`.
pub fn model(preset: Preset) -> ModelConfig {
    match preset {
        Preset::Paper => ModelConfig {
            features: 256,
            sdf_hidden: 256,
            sdf_depth: 8,
            sdf_skip: Some(4),
            frequencies: 6,
            grid: None,
            color_hidden: 256,
            color_depth: 4,
            learned_polarization: false,
            diffuse_transmission: false,
            specular_tilt: false,
            initial_radius: neus_initial_radius(),
        },
        Preset::Fast | Preset::Dense => ModelConfig {
            features: 15,
            sdf_hidden: 64,
            sdf_depth: 2,
            sdf_skip: None,
            frequencies: 0,
            grid: Some(if preset == Preset::Dense { (16, 19, 16, 2048) } else { (8, 16, 16, 256) }),
            color_hidden: 64,
            color_depth: 2,
            learned_polarization: false,
            // Lower normal error on the Mitsuba set with the azimuth-only tangent gradient
            // (docs/benchmarks.md): a dielectric's diffuse light dims towards grazing views.
            diffuse_transmission: true,
            // Lower normal error on all eight Mitsuba scenes (docs/benchmarks.md): a rough lobe
            // lit from one side is polarized about its lit half vectors, not the normal.
            specular_tilt: preset == Preset::Fast,
            initial_radius: if preset == Preset::Fast { FAST_INITIAL_RADIUS } else { neus_initial_radius() },
        },
    }
}

/// The training configuration of `preset` for a run of `iterations`.
pub fn training(preset: Preset, iterations: u32) -> TrainConfig {
    let model = model(preset);
    let levels = model.grid.map_or(0, |g| g.0);
    let start_levels = levels.min(4);
    let anneal_every = if levels > start_levels { (iterations / 2 / (levels - start_levels) as u32).max(1) } else { 1 };
    let (batch_rays, sampling, adam) = match preset {
        Preset::Paper => (
            512,
            Sampling {
                coarse: 64,
                fine: 64,
                steps: 4,
                min_weight: 0.0,
                regularised_left_out: 0,
                regularise_near_surface: 0.0,
            },
            AdamConfig {
                lr_network: 5e-4,
                lr_grid: 0.0,
                lr_variance: 5e-4,
                warmup: 5000.min(iterations / 20),
                final_fraction: 0.05,
            },
        ),
        Preset::Fast | Preset::Dense => (
            if preset == Preset::Dense { 512 } else { 256 },
            Sampling {
                coarse: 32,
                fine: 32,
                steps: 4,
                min_weight: MIN_SAMPLE_WEIGHT,
                // The dense reference of 24 turntable views lost with them (Chamfer 0.0015 ->
                // 0.0019, 533 -> 588 s on two threads; docs/benchmarks.md).
                regularised_left_out: if preset == Preset::Fast { REGULARISED_LEFT_OUT } else { 0 },
                regularise_near_surface: REGULARISED_NEAR_SURFACE,
            },
            AdamConfig {
                lr_network: 2e-3,
                lr_grid: 1e-2,
                lr_variance: 2e-3,
                warmup: (iterations / 20).min(500),
                final_fraction: 0.05,
            },
        ),
    };
    TrainConfig {
        model,
        iterations,
        batch_rays,
        sampling,
        adam,
        weights: LossWeights::from_fn(|term| match term {
            Term::Photometric | Term::Geometric | Term::Mask => 1.0,
            Term::Eikonal => 0.1,
            Term::Curvature => match preset {
                Preset::Fast => FAST_CURVATURE_WEIGHT,
                Preset::Dense => CURVATURE_WEIGHT,
                Preset::Paper => 0.0,
            },
        }),
        photometric: true,
        geometric: true,
        // NeRSP's full gradient also tilts normals towards the cameras wherever an AoP strays
        // from the normal's planes (docs/reconstruction.md).
        tangent_azimuth_only: preset != Preset::Paper,
        // Stray AoPs on curved surfaces pull less (docs/reconstruction.md); the fast preset
        // only, where it was measured (with the tilted lobe).
        tangent_robust_angle: if preset == Preset::Fast { TANGENT_ROBUST_ANGLE } else { 0.0 },
        tangent_views: if preset == Preset::Paper { 0 } else { TANGENT_VIEWS },
        diffuse_only: 1000.min(iterations / 10),
        margin: 8,
        background_share: BACKGROUND_SHARE,
        start_levels,
        curvature_follows_levels: preset == Preset::Fast,
        curvature_cell_power: if preset == Preset::Fast { FAST_CURVATURE_CELL_POWER } else { 1.0 },
        anneal_every,
        seed: 0,
        downscale: 1,
    }
}
