//! Sphere tracing of the SDF (inference only): batched rays step by the SDF value until they
//! come within [`HIT`] of the surface or leave their span. Visibility in the geometric loss and
//! the surface of every output pixel both use it.

use crate::model::Model;

/// A ray is on the surface when the SDF is below this (unit-sphere units).
pub const HIT: f32 = 1e-3;
/// Bisection rounds that place a hit found inside the surface (an overshoot) on its zero
/// crossing.
const BISECTIONS: usize = 8;

/// One ray to trace: `origin + t dir` for `t` from `start` to `end`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceRay {
    /// Origin (unit frame).
    pub origin: [f32; 3],
    /// Unit direction.
    pub dir: [f32; 3],
    /// Depth where tracing starts.
    pub start: f32,
    /// Depth where it stops.
    pub end: f32,
}

impl TraceRay {
    fn at(&self, t: f32) -> [f32; 3] {
        [0, 1, 2].map(|k| self.origin[k] + t * self.dir[k])
    }
}

/// Tracing to a trained field's surface: slightly short steps (a learned SDF's slope can exceed
/// 1), at most 0.05 long.
pub const SURFACE_LIMITS: TraceLimits = TraceLimits { step_scale: 0.9, max_step: 0.05, max_steps: 128 };

/// How far a trace goes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceLimits {
    /// Steps are this times the SDF (1 for a true distance field; below 1 is safer where the
    /// field's slope exceeds 1, at the price of more steps).
    pub step_scale: f32,
    /// Longest step: a learned SDF far from its surface is no distance field, and a step it
    /// allows can cross a thin part whole. A step that lands inside is bisected back onto the
    /// zero crossing.
    pub max_step: f32,
    /// Steps before a ray gives up (a ray still running then counts as a miss).
    pub max_steps: usize,
}

/// The depth of the first surface along each ray, `None` where it has none before its end.
pub fn sphere_trace(
    model: &Model,
    params: &[f32],
    level_weight: &[f32],
    rays: &[TraceRay],
    limits: TraceLimits,
) -> Vec<Option<f32>> {
    let sdf_at = |points: Vec<f32>| model.field.sdf(params, &points, level_weight);
    let mut depth: Vec<f32> = rays.iter().map(|r| r.start).collect();
    let mut previous = depth.clone();
    let mut hit = vec![None; rays.len()];
    // Rays that landed inside the surface: (ray, outside depth, inside depth).
    let mut inside: Vec<(usize, f32, f32)> = Vec::new();
    let mut active: Vec<usize> = (0..rays.len()).filter(|&r| rays[r].start < rays[r].end).collect();
    for _ in 0..limits.max_steps {
        if active.is_empty() {
            break;
        }
        let sdf = sdf_at(active.iter().flat_map(|&r| rays[r].at(depth[r])).collect());
        let mut next = Vec::with_capacity(active.len());
        for (&r, &s) in active.iter().zip(&sdf) {
            if s < -HIT && depth[r] > rays[r].start {
                inside.push((r, previous[r], depth[r]));
                continue;
            }
            if s < HIT {
                hit[r] = Some(depth[r]);
                continue;
            }
            previous[r] = depth[r];
            depth[r] += (limits.step_scale * s).min(limits.max_step);
            if depth[r] < rays[r].end {
                next.push(r);
            }
        }
        active = next;
    }
    for _ in 0..BISECTIONS {
        if inside.is_empty() {
            break;
        }
        let sdf = sdf_at(inside.iter().flat_map(|&(r, a, b)| rays[r].at(0.5 * (a + b))).collect());
        for (bracket, s) in inside.iter_mut().zip(sdf) {
            let middle = 0.5 * (bracket.1 + bracket.2);
            if s > 0.0 {
                bracket.1 = middle;
            } else {
                bracket.2 = middle;
            }
        }
    }
    for (r, outside, _) in inside {
        hit[r] = Some(outside);
    }
    hit
}
