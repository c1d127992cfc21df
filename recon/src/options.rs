//! The settings of a reconstruction, defined once: [`ReconOptions`] is `rmvp recon`'s flags
//! (with the `clap` feature; each field's doc comment is its help), a batch plan variant's
//! `options` table and a quality-bench variant (serde), under the same names
//! (`mesh_res` is `--mesh-res`), and it is recorded in `checkpoint.bin`.
//!
//! Adding an option: a field here with its doc comment, its default in [`ReconOptions::default`]
//! and its effect in [`ReconOptions::config`] (or in the outputs); the command line, batch plans,
//! the bench and the checkpoint take it from here. `recon/tests/options.rs` holds that every
//! field is accepted everywhere under its name.

use crate::extract::Device;
use crate::losses::Term;
use crate::presets::{self, Preset};
use crate::train::TrainConfig;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// What a caller sets for one reconstruction; [`ReconOptions::default`] holds every default.
/// How one call runs (resuming, stopping early) is [`RunControl`], not an option.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default, deny_unknown_fields)]
pub struct ReconOptions {
    /// Model preset: `fast` (hash grid, minutes on a CPU), `dense` (a finer grid, twice the
    /// rays, 4000 iterations: a dataset's reference shape) or `paper` (NeRSP's 8x256 MLP).
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value_t = Preset::Fast))]
    pub preset: Preset,
    /// Training iterations (default: the preset's; fast 3300, about 2 minutes on 2 cores).
    #[cfg_attr(feature = "clap", arg(long))]
    pub iters: Option<u32>,
    /// Photometric cue only (the PANDORA-like ablation).
    #[cfg_attr(feature = "clap", arg(long))]
    pub no_geometric: bool,
    /// Geometric cue only (the MVAS-like ablation).
    #[cfg_attr(feature = "clap", arg(long))]
    pub no_photometric: bool,
    /// Rays per iteration (default: the preset's; fast 256, dense and paper 512).
    #[cfg_attr(feature = "clap", arg(long))]
    pub batch: Option<usize>,
    /// Uniform samples per ray between near and far (default: the preset's; fast 32).
    #[cfg_attr(feature = "clap", arg(long))]
    pub coarse_samples: Option<usize>,
    /// Samples per ray added near the surface by up-sampling (default: the preset's; fast 32).
    #[cfg_attr(feature = "clap", arg(long))]
    pub fine_samples: Option<usize>,
    /// Render in a training step only the samples that carry at least this compositing weight
    /// (or whose density still responds where light reaches them); 0 renders all (default: the
    /// preset's; fast and dense 1e-4, paper 0).
    #[cfg_attr(feature = "clap", arg(long, value_name = "WEIGHT"))]
    pub min_sample_weight: Option<f32>,
    /// Dilation of the masks that object rays are drawn from, pixels (default: the preset's, 8).
    #[cfg_attr(feature = "clap", arg(long))]
    pub margin: Option<usize>,
    /// Learn one scale of the specular lobe's degree of polarization for the object (a
    /// conductor's reflection is nearly unpolarized); `false` keeps NeRSP's fixed dielectric
    /// Fresnel; default: the preset's (fixed). The value learned is in log.jsonl
    /// (`polarization`) and printed at the end.
    #[cfg_attr(feature = "clap", arg(long, num_args = 0..=1, default_missing_value = "true"))]
    pub learned_polarization: Option<bool>,
    /// Dim the diffuse lobe by its Fresnel transmission at the view angle (relative to normal
    /// incidence); default: the preset's (on in fast and dense; off in paper, NeRSP's
    /// normalised diffuse).
    #[cfg_attr(feature = "clap", arg(long, num_args = 0..=1, default_missing_value = "true"))]
    pub diffuse_transmission: Option<bool>,
    /// Let the AoP tangent loss turn normals about the views' rays only, never tilt them towards
    /// a camera; default: the preset's (on in fast and dense; off in paper, NeRSP's full
    /// gradient).
    #[cfg_attr(feature = "clap", arg(long, num_args = 0..=1, default_missing_value = "true"))]
    pub tangent_azimuth_only: Option<bool>,
    /// Make each view's AoP tangent term robust where the surface curves: a view whose AoP
    /// strays more than about this many degrees from both of the normal's planes pulls less and
    /// less (Geman-McClure), in full where the surface curves tightly, less on gentle curves,
    /// not at all on a flat face; default: the preset's (20 in fast; 0, NeRSP's plain term, in
    /// dense and paper).
    #[cfg_attr(feature = "clap", arg(long, value_name = "DEGREES"))]
    pub tangent_robust_angle: Option<f32>,
    /// Compare at most this many of the views that face a surface point with its normal in the
    /// AoP tangent loss, a systematic sample drawn for each ray (an unbiased estimate of the
    /// mean over them all; the occlusion tests, a quarter of a dense step, fall with it); 0
    /// compares every one; default: the preset's (8 in fast and dense; 0 in paper, NeRSP).
    #[cfg_attr(feature = "clap", arg(long, value_name = "N"))]
    pub tangent_views: Option<usize>,
    /// Let the specular lobe's AoP turn off the normal (a rough lobe lit from one side is
    /// polarized about its lit half vectors, which lean towards the light that the specular
    /// network puts beside the mirror direction), and take that predicted turn out of each
    /// view's AoP before the tangent loss, in full where the surface is curved and less towards
    /// flat faces, where the light's gradient is unknown; default: the preset's (on in fast; off
    /// in dense and paper: NeRSP's lobe, polarized about the normal). Without the photometric
    /// cue nothing fits the specular network it is read from, and the lobe stays untilted.
    #[cfg_attr(feature = "clap", arg(long, num_args = 0..=1, default_missing_value = "true"))]
    pub specular_tilt: Option<bool>,
    /// Weight of the curvature term, the SDF's mean absolute Laplacian over the samples
    /// (Neuralangelo's smoothing against the hash grid's noise): more rounds a smooth object's
    /// fine ripple away and a sharp one's creases with it. In the fast preset the weight while
    /// the coarse hash-grid levels alone are open, falling as the finer ones open to a fifth of
    /// it; in the others the weight throughout. Default: the preset's (fast 0.015, dense
    /// 0.005, paper 0).
    #[cfg_attr(feature = "clap", arg(long, value_name = "WEIGHT"))]
    pub curvature_weight: Option<f32>,
    /// Radius of the sphere the SDF starts from, in the scene's unit sphere; the surface grows
    /// out of it to meet the masks, so a concavity the masks do not show (a bowl, a cup) opens
    /// only where the start lies inside it; default: the preset's (0.2 in fast; NeuS's 0.5 in
    /// dense and paper). A radius too small for the network to start with a surface (about 0.1
    /// in fast, 0.32 in paper) is refused before training, naming the least that has one.
    #[cfg_attr(feature = "clap", arg(long, value_name = "RADIUS"))]
    pub initial_radius: Option<f32>,
    /// Train at 1/N of the views' size (Stokes and masks averaged over N x N blocks, the
    /// intrinsics scaled); the outputs are written at the scene's size. The official code trains
    /// RMVP3D at 2 (612x512), PANDORA at 4.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 1))]
    pub downscale: u32,
    /// Random seed.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 0))]
    pub seed: u64,
    /// Marching grid cells per axis for the mesh.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 256))]
    pub mesh_res: usize,
    /// Where the mesh's SDF is evaluated: `cuda` runs it on the first NVIDIA GPU (needs its
    /// driver and NVRTC; training stays on the CPU).
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value_t = Device::Cpu))]
    pub mesh_device: Device,
    /// Write the mesh alone (no normal maps, Stokes, comparison or residual pictures): a
    /// dataset's reference shape.
    #[cfg_attr(feature = "clap", arg(long))]
    pub mesh_only: bool,
    /// Keep the mesh's connected parts that no training view sees (by default a part that is
    /// the first surface at under a tenth of the training views' object pixels whose rays
    /// cross it is left out: space the views never showed, such as a blob beneath an object
    /// seen only from above).
    #[cfg_attr(feature = "clap", arg(long))]
    pub keep_unseen_parts: bool,
    /// Iterations between checkpoints.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 500))]
    pub checkpoint_every: u32,
}

impl Default for ReconOptions {
    fn default() -> Self {
        Self {
            preset: Preset::Fast,
            iters: None,
            no_geometric: false,
            no_photometric: false,
            batch: None,
            coarse_samples: None,
            fine_samples: None,
            min_sample_weight: None,
            margin: None,
            learned_polarization: None,
            diffuse_transmission: None,
            tangent_azimuth_only: None,
            tangent_robust_angle: None,
            tangent_views: None,
            specular_tilt: None,
            curvature_weight: None,
            initial_radius: None,
            downscale: 1,
            seed: 0,
            mesh_res: 256,
            mesh_device: Device::Cpu,
            mesh_only: false,
            keep_unseen_parts: false,
            checkpoint_every: 500,
        }
    }
}

/// The options earlier versions of rmvp took and this one does not, each with what took its
/// place: each preset holds one setting for every object (what they measured:
/// `docs/experiments.md`). Options read from a file ([`ReconOptions::from_recorded`]) that set
/// one are refused in these words.
pub const REMOVED_OPTIONS: [(&str, &str); 7] = [
    ("samples_per_step", "every step renders the preset's rays, `batch`"),
    ("regularised_left_out", "the fast preset regularises two samples per ray behind the surface"),
    ("regularise_left_out_every", "no preset regularised the samples left out so"),
    ("regularise_inside_every", "no preset regularised the object's inside so"),
    ("regularise_near_surface", "the fast and dense presets regularise the samples within 0.05 of the surface"),
    ("grid_level_decay", "every hash-grid level learns at the same rate"),
    ("aop_reliability", "every view's AoP tangent term weighs alike, as NeRSP's"),
];

/// The words refusing `name`, one of [`REMOVED_OPTIONS`] (None for any other name).
pub fn removed_option(name: &str) -> Option<String> {
    let (_, instead) = REMOVED_OPTIONS.iter().find(|(removed, _)| *removed == name)?;
    Some(format!("the option `{name}` was removed from rmvp ({instead}): delete it"))
}

/// A deserializer's message with an unknown field that is one of [`REMOVED_OPTIONS`] told in
/// [`removed_option`]'s words; any other message as it is.
pub fn explain_removed(message: &str) -> String {
    let named = message.strip_prefix("unknown field `").and_then(|rest| rest.split_once('`')).map(|(name, _)| name);
    named.and_then(removed_option).unwrap_or_else(|| message.to_string())
}

/// Deserialize [`ReconOptions`] as [`ReconOptions::from_recorded`] reads them (for
/// `#[serde(deserialize_with)]` on a field of a file's record).
pub fn deserialize_recorded<'de, D: serde::Deserializer<'de>>(
    deserializer: D,
) -> std::result::Result<ReconOptions, D::Error> {
    let value = serde_json::Value::deserialize(deserializer)?;
    ReconOptions::from_recorded(value).map_err(serde::de::Error::custom)
}

/// [`deserialize_recorded`] for an optional field.
pub fn deserialize_recorded_option<'de, D: serde::Deserializer<'de>>(
    deserializer: D,
) -> std::result::Result<Option<ReconOptions>, D::Error> {
    match Option::<serde_json::Value>::deserialize(deserializer)? {
        None | Some(serde_json::Value::Null) => Ok(None),
        Some(value) => ReconOptions::from_recorded(value).map(Some).map_err(serde::de::Error::custom),
    }
}

/// How one call of [`crate::reconstruct::reconstruct`] runs; never recorded, since it does not
/// change what is trained.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RunControl {
    /// Continue from `checkpoint.bin` in the output folder (its options must be these).
    pub resume: bool,
    /// Train at most this many iterations in this call, then checkpoint and return without
    /// results (time-boxed sessions; continue with `resume`).
    pub stop_after: Option<u32>,
}

impl ReconOptions {
    /// Refuse options no training can run with, in words about their values: both cues off,
    /// zero iterations, an empty marching grid, zero rays or samples per step.
    pub fn validate(&self) -> Result<()> {
        if self.no_photometric && self.no_geometric {
            return Err(Error::BothCuesOff);
        }
        let fault = if self.iters == Some(0) {
            "the number of iterations must be at least 1"
        } else if self.mesh_res == 0 {
            "the mesh resolution (marching grid cells per axis) must be at least 1"
        } else if self.batch == Some(0) {
            "the rays per iteration (batch) must be at least 1"
        } else if self.coarse_samples == Some(0) {
            "the uniform samples per ray must be at least 1"
        } else if self.min_sample_weight.is_some_and(|w| !(w.is_finite() && (0.0..1.0).contains(&w))) {
            "the least weight of a rendered sample must be a number from 0 up to 1"
        } else if self.checkpoint_every == 0 {
            "the iterations between checkpoints must be at least 1"
        } else if self.downscale == 0 {
            "the training downscale factor must be at least 1"
        } else if self.tangent_robust_angle.is_some_and(|a| !(a.is_finite() && (0.0..=45.0).contains(&a))) {
            "the tangent term's robust angle must be a number of degrees from 0 to 45"
        } else if self.curvature_weight.is_some_and(|w| !(w.is_finite() && w >= 0.0)) {
            "the curvature term's weight must be a number of at least 0"
        } else if self.initial_radius.is_some_and(|r| !(r.is_finite() && r > 0.0 && r < 1.0)) {
            "the initial sphere's radius must be a number between 0 and 1 (the unit sphere's)"
        } else {
            return Ok(());
        };
        Err(Error::InvalidOption(fault.into()))
    }

    /// The options that change what is trained (all but the mesh's and the checkpoints'),
    /// where `self` (recorded) and `now` differ: `name: recorded -> now` each.
    pub fn training_differences(&self, now: &ReconOptions) -> Vec<String> {
        const OUTPUT_ONLY: [&str; 5] =
            ["mesh_res", "mesh_device", "mesh_only", "keep_unseen_parts", "checkpoint_every"];
        rmvp_dataset::io::json::differences(self, now)
            .into_iter()
            .filter(|(name, _)| !OUTPUT_ONLY.contains(&name.as_str()))
            .map(|(_, change)| change)
            .collect()
    }

    /// Options as a file records them (a batch plan's variant, a checkpoint, a dataset's build
    /// record): an option of [`REMOVED_OPTIONS`] that an earlier rmvp wrote unset (`null`) is
    /// passed over; one set to a value is refused in [`removed_option`]'s words
    /// ([`explain_removed`]), and any other fault in serde's.
    pub fn from_recorded(mut value: serde_json::Value) -> std::result::Result<ReconOptions, String> {
        if let serde_json::Value::Object(fields) = &mut value {
            fields.retain(|name, field| !(field.is_null() && removed_option(name).is_some()));
        }
        serde_json::from_value(value).map_err(|e| explain_removed(&e.to_string()))
    }

    /// These options with some changed by TOML assignments (`learned_polarization = true`, one
    /// per line, the fields' names): how the quality bench writes its variants.
    pub fn with_toml(&self, assignments: &str) -> std::result::Result<ReconOptions, String> {
        let changes: toml::Table = toml::from_str(assignments).map_err(|e| e.message().trim().to_string())?;
        let mut table = toml::Table::try_from(self).map_err(|e| e.to_string())?;
        table.extend(changes);
        table.try_into().map_err(|e: toml::de::Error| explain_removed(e.message().trim()))
    }

    /// The iterations this run trains.
    pub fn iterations(&self) -> u32 {
        self.iters.unwrap_or(self.preset.default_iterations())
    }

    /// The training configuration these options give: the preset's, with what was set.
    pub fn config(&self) -> TrainConfig {
        let mut config = presets::training(self.preset, self.iterations());
        config.photometric = !self.no_photometric;
        config.geometric = !self.no_geometric;
        config.seed = self.seed;
        config.downscale = self.downscale;
        if let Some(b) = self.batch {
            config.batch_rays = b;
        }
        if let Some(n) = self.coarse_samples {
            config.sampling.coarse = n;
        }
        if let Some(n) = self.fine_samples {
            config.sampling.fine = n;
        }
        if let Some(w) = self.min_sample_weight {
            config.sampling.min_weight = w;
        }
        if let Some(m) = self.margin {
            config.margin = m;
        }
        if let Some(learned) = self.learned_polarization {
            config.model.learned_polarization = learned;
        }
        if let Some(on) = self.diffuse_transmission {
            config.model.diffuse_transmission = on;
        }
        if let Some(on) = self.tangent_azimuth_only {
            config.tangent_azimuth_only = on;
        }
        if let Some(angle) = self.tangent_robust_angle {
            config.tangent_robust_angle = angle;
        }
        if let Some(n) = self.tangent_views {
            config.tangent_views = n;
        }
        if let Some(on) = self.specular_tilt {
            config.model.specular_tilt = on;
        }
        if let Some(weight) = self.curvature_weight {
            config.weights[Term::Curvature] = weight;
        }
        if let Some(radius) = self.initial_radius {
            config.model.initial_radius = radius;
        }
        config
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_curvature_weight_replaces_the_presets() {
        for preset in [Preset::Fast, Preset::Dense, Preset::Paper] {
            let options = ReconOptions { preset, curvature_weight: Some(0.02), ..Default::default() };
            let config = options.config();
            assert_eq!(config.weights[Term::Curvature], 0.02);
            let preset_weights = ReconOptions { preset, ..Default::default() }.config().weights;
            assert_ne!(preset_weights[Term::Curvature], 0.02);
            assert_eq!(config.weights[Term::Eikonal], preset_weights[Term::Eikonal]);
        }
    }
}
