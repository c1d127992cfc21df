//! The SDF field: a point to its signed distance and the features the radiance networks read.

use super::ModelConfig;
use crate::engine::encoding::positional_encoding;
use crate::engine::{hashgrid, Activation, HashGrid, Init, Mlp, MlpCache, ParamLayout};
use rmvp_dataset::rng::Rng;

/// The SDF field: point -> (SDF, features).
#[derive(Clone, Debug)]
pub struct Field {
    grid: Option<HashGrid>,
    frequencies: usize,
    mlp: Mlp,
    features: usize,
}

/// The hash grid's share of a backward pass, kept apart so that a batch's gradient need not
/// span the grid's tables (most of the parameters): where the grid was looked up, and the
/// gradient of its encoding there.
#[derive(Default)]
pub struct GridGradient {
    points: Vec<f32>,
    d_encoding: Vec<f32>,
}

impl GridGradient {
    /// Append `other`'s lookups after this one's (one part of a sum instead of two).
    pub fn extend(&mut self, other: GridGradient) {
        self.points.extend(other.points);
        self.d_encoding.extend(other.d_encoding);
    }
}

/// What [`Field::forward`] keeps for [`Field::backward`].
#[derive(Default)]
pub struct FieldCache {
    points: Vec<f32>,
    mlp: MlpCache,
}

impl Field {
    /// The SDF network's parameters reserved in `layout`; the hash grid's tables (if any) are
    /// reserved later, by [`Field::reserve_grid`], after every network's.
    pub(super) fn new(layout: &mut ParamLayout, config: &ModelConfig) -> Self {
        let encoded = match config.grid {
            Some((levels, ..)) => levels * hashgrid::FEATURES,
            None => 6 * config.frequencies,
        };
        let mlp = Mlp::new(
            layout,
            3 + encoded,
            config.sdf_hidden,
            config.sdf_depth,
            1 + config.features,
            Activation::Softplus(100.0),
            config.sdf_skip,
        );
        Self { grid: None, frequencies: config.frequencies, mlp, features: config.features }
    }

    /// Reserve the hash grid's tables of `config` at the end of `layout`.
    pub(super) fn reserve_grid(&mut self, layout: &mut ParamLayout, config: &ModelConfig) {
        self.grid = config.grid.map(|(levels, log2, base, finest)| HashGrid::new(layout, levels, log2, base, finest));
    }

    /// Values per point: the SDF then the features.
    pub fn outputs(&self) -> usize {
        1 + self.features
    }

    /// The hash grid (None for the MLP preset).
    pub fn grid(&self) -> Option<&HashGrid> {
        self.grid.as_ref()
    }

    /// The SDF network.
    pub fn mlp(&self) -> &Mlp {
        &self.mlp
    }

    /// Hash-grid levels (0 for the MLP preset).
    pub fn levels(&self) -> usize {
        self.grid.as_ref().map_or(0, |g| g.levels())
    }

    /// The hash grid's finest active resolution under `level_weight` (None without a grid).
    pub fn finest_active(&self, level_weight: &[f32]) -> Option<u32> {
        let g = self.grid.as_ref()?;
        g.resolutions().iter().zip(level_weight).rev().find(|(_, &w)| w > 0.0).map(|(&r, _)| r)
    }

    fn encode(&self, params: &[f32], points: &[f32], level_weight: &[f32]) -> Vec<f32> {
        let n = points.len() / 3;
        let width = self.mlp.inputs();
        let mut out = vec![0f32; n * width];
        match &self.grid {
            Some(g) => {
                let mut enc = vec![0f32; n * g.outputs()];
                g.encode(params, points, level_weight, &mut enc);
                for ((o, p), e) in
                    out.chunks_exact_mut(width).zip(points.chunks_exact(3)).zip(enc.chunks_exact(g.outputs()))
                {
                    o[..3].copy_from_slice(p);
                    o[3..].copy_from_slice(e);
                }
            }
            None => positional_encoding(points, self.frequencies, &mut out),
        }
        out
    }

    /// `(n x outputs)` for `points` (n x 3), keeping what backward needs.
    pub fn forward(&self, params: &[f32], points: &[f32], level_weight: &[f32], cache: &mut FieldCache) -> Vec<f32> {
        let input = self.encode(params, points, level_weight);
        cache.points = points.to_vec();
        self.mlp.forward(params, &input, points.len() / 3, &mut cache.mlp)
    }

    /// Add the network's parameter gradients of `d_out` (n x outputs) into `grad` (which
    /// needs to cover the networks only, [`super::Model::network_params`]); the hash grid's are
    /// returned, to be written by [`Field::write_grid_gradients`].
    pub fn backward(&self, params: &[f32], cache: &FieldCache, d_out: &[f32], grad: &mut [f32]) -> GridGradient {
        let d_in = self.mlp.backward(params, &cache.mlp, d_out, grad);
        match &self.grid {
            Some(_) => {
                let width = self.mlp.inputs();
                let d_encoding = d_in.chunks_exact(width).flat_map(|row| row[3..].iter().copied()).collect();
                GridGradient { points: cache.points.clone(), d_encoding }
            }
            None => GridGradient::default(),
        }
    }

    /// Write the hash grid's parameter gradients of `parts` over `grad`'s tables (`grad` holds
    /// all parameters; the networks' are left as they are), level by level in parallel, each
    /// level's parts in order.
    pub fn write_grid_gradients(&self, parts: &[&GridGradient], level_weight: &[f32], grad: &mut [f32]) {
        if let Some(g) = &self.grid {
            let batches: Vec<(&[f32], &[f32])> =
                parts.iter().map(|p| (p.points.as_slice(), p.d_encoding.as_slice())).collect();
            g.backward_batches(&batches, level_weight, grad);
        }
    }

    /// `(n x outputs)` for `points` (n x 3), keeping nothing (inference).
    pub fn infer(&self, params: &[f32], points: &[f32], level_weight: &[f32]) -> Vec<f32> {
        let input = self.encode(params, points, level_weight);
        self.mlp.infer(params, &input, points.len() / 3)
    }

    /// The SDF alone (inference).
    pub fn sdf(&self, params: &[f32], points: &[f32], level_weight: &[f32]) -> Vec<f32> {
        self.infer(params, points, level_weight).chunks_exact(self.outputs()).map(|r| r[0]).collect()
    }

    pub(super) fn init(&self, params: &mut [f32], radius: f32, rng: &mut Rng) {
        self.mlp.init(params, Init::Sphere(radius), rng);
        if let Some(g) = &self.grid {
            g.init(params, rng);
        }
    }
}
