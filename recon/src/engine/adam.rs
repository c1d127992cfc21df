//! Adam with per-group learning rates, linear warm-up and cosine decay (NeuS's schedule).

use super::params::{Group, ParamLayout};
use multiversion::multiversion;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Learning rates and schedule.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct AdamConfig {
    /// Peak learning rate of network weights.
    pub lr_network: f32,
    /// Peak learning rate of hash-grid tables.
    pub lr_grid: f32,
    /// Peak learning rate of the NeuS variance.
    pub lr_variance: f32,
    /// Iterations of linear warm-up.
    pub warmup: u32,
    /// Final learning rate as a fraction of the peak (cosine decay).
    pub final_fraction: f32,
}

/// Adam state over the flat parameter vector.
#[derive(Debug, PartialEq)]
pub struct Adam {
    /// First moments.
    pub m: Vec<f32>,
    /// Second moments.
    pub v: Vec<f32>,
    /// Steps taken.
    pub steps: u32,
}

impl Clone for Adam {
    fn clone(&self) -> Self {
        Self { m: self.m.clone(), v: self.v.clone(), steps: self.steps }
    }

    /// Into `self`'s own buffers (a trainer's last safe state, kept every 100 iterations).
    fn clone_from(&mut self, source: &Self) {
        self.m.clone_from(&source.m);
        self.v.clone_from(&source.v);
        self.steps = source.steps;
    }
}

const BETA1: f32 = 0.9;
const BETA2: f32 = 0.99;

impl Adam {
    /// Zero moments for `len` parameters.
    pub fn new(len: usize) -> Self {
        Self { m: vec![0.0; len], v: vec![0.0; len], steps: 0 }
    }

    /// The schedule's factor at `iteration` of `total`.
    pub fn schedule(config: &AdamConfig, iteration: u32, total: u32) -> f32 {
        if iteration < config.warmup {
            return (iteration + 1) as f32 / config.warmup as f32;
        }
        let progress = (iteration - config.warmup) as f32 / (total.saturating_sub(config.warmup)).max(1) as f32;
        let cosine = 0.5 * (1.0 + (std::f32::consts::PI * progress.min(1.0)).cos());
        cosine * (1.0 - config.final_fraction) + config.final_fraction
    }

    /// One update of `params` by `grad` at `iteration` of `total`.
    pub fn step(
        &mut self,
        layout: &ParamLayout,
        config: &AdamConfig,
        params: &mut [f32],
        grad: &[f32],
        iteration: u32,
        total: u32,
    ) {
        self.steps += 1;
        let factor = Self::schedule(config, iteration, total);
        let c1 = 1.0 - BETA1.powi(self.steps as i32);
        let c2 = 1.0 - BETA2.powi(self.steps as i32);
        for (range, group) in layout.ranges() {
            let (lr, eps) = match *group {
                Group::Network => (config.lr_network, 1e-8),
                Group::Grid { .. } => (config.lr_grid, 1e-15),
                Group::Variance => (config.lr_variance, 1e-8),
                Group::Unused => continue,
            };
            let lr = lr * factor;
            let r = range.clone();
            // In parallel blocks: each parameter's update is its own, so every thread count
            // gives the same bits.
            params[r.clone()]
                .par_chunks_mut(BLOCK)
                .zip(grad[r.clone()].par_chunks(BLOCK))
                .zip(self.m[r.clone()].par_chunks_mut(BLOCK))
                .zip(self.v[r].par_chunks_mut(BLOCK))
                .for_each(|(((p, g), m), v)| update(p, g, m, v, [lr, eps, c1, c2]));
        }
    }
}

/// Parameters an Adam thread updates at a time.
const BLOCK: usize = 1 << 14;

/// Adam's update of one block, `[lr, eps, c1, c2]` the rate, epsilon and bias corrections.
#[multiversion(targets("x86_64+avx512f", "x86_64+avx2"))]
fn update(params: &mut [f32], grad: &[f32], m: &mut [f32], v: &mut [f32], [lr, eps, c1, c2]: [f32; 4]) {
    for (((p, &g), m), v) in params.iter_mut().zip(grad).zip(m.iter_mut()).zip(v.iter_mut()) {
        *m = BETA1 * *m + (1.0 - BETA1) * g;
        *v = BETA2 * *v + (1.0 - BETA2) * g * g;
        *p -= lr * (*m / c1) / ((*v / c2).sqrt() + eps);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::params::{Group, ParamLayout};

    /// Adam's first step moves every parameter by its group's rate (times the schedule), whatever
    /// the gradient's size: the networks' by `lr_network`, every hash-grid level's by `lr_grid`.
    #[test]
    fn each_group_steps_by_its_own_rate() {
        let mut layout = ParamLayout::default();
        layout.reserve(2, Group::Network);
        for level in 0..3 {
            layout.reserve(2, Group::Grid { level });
        }
        let config = AdamConfig { lr_network: 1e-3, lr_grid: 1e-2, lr_variance: 1e-3, warmup: 0, final_fraction: 1.0 };
        let mut params = vec![0f32; layout.len()];
        let grad = [1.0, 2.0, 0.1, 3.0, 1.0, 1.0, 5.0, 0.2];
        Adam::new(layout.len()).step(&layout, &config, &mut params, &grad, 0, 10);
        let want = [1e-3, 1e-3, 1e-2, 1e-2, 1e-2, 1e-2, 1e-2, 1e-2];
        for (p, w) in params.iter().zip(want) {
            assert!((p + w).abs() < 1e-5 * w, "{params:?}");
        }
    }
}
