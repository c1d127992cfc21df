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
pub const SURFACE_LIMITS: TraceLimits =
    TraceLimits { step_scale: 0.9, max_step: 0.05, max_steps: 128, relaxation: 1.0 };

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
    /// Over-relaxation (Keinert et al. 2014, "Enhanced Sphere Tracing"): steps are this times
    /// longer while each point's unbounding sphere overlaps the previous one's; where they do
    /// not, something may lie between, and the ray goes back to the plain step from the previous
    /// point and on without relaxation. 1 is plain sphere tracing.
    pub relaxation: f32,
}

/// The depth of the first surface along each ray, `None` where it has none before its end.
pub fn sphere_trace(
    model: &Model,
    params: &[f32],
    level_weight: &[f32],
    rays: &[TraceRay],
    limits: TraceLimits,
) -> Vec<Option<f32>> {
    trace_field(|points| model.field.sdf(params, &points, level_weight), rays, limits)
}

/// [`sphere_trace`] through the SDF `sdf_at` gives at points (n x 3).
fn trace_field(sdf_at: impl Fn(Vec<f32>) -> Vec<f32>, rays: &[TraceRay], limits: TraceLimits) -> Vec<Option<f32>> {
    let mut depth: Vec<f32> = rays.iter().map(|r| r.start).collect();
    let mut previous = depth.clone();
    let mut hit = vec![None; rays.len()];
    // Rays that landed inside the surface: (ray, outside depth, inside depth).
    let mut inside: Vec<(usize, f32, f32)> = Vec::new();
    let mut active: Vec<usize> = (0..rays.len()).filter(|&r| rays[r].start < rays[r].end).collect();
    // Each ray's relaxation, and its last step with the SDF it was taken from.
    let mut relaxation = vec![limits.relaxation; rays.len()];
    let (mut last_step, mut last_radius) = (vec![0f32; rays.len()], vec![0f32; rays.len()]);
    for _ in 0..limits.max_steps {
        if active.is_empty() {
            break;
        }
        let sdf = sdf_at(active.iter().flat_map(|&r| rays[r].at(depth[r])).collect());
        let mut next = Vec::with_capacity(active.len());
        for (&r, &s) in active.iter().zip(&sdf) {
            if relaxation[r] > 1.0 && s.abs() + last_radius[r] < last_step[r] {
                depth[r] = previous[r] + last_step[r] / relaxation[r];
                relaxation[r] = 1.0;
                if depth[r] < rays[r].end {
                    next.push(r);
                }
                continue;
            }
            if s < -HIT && depth[r] > rays[r].start {
                inside.push((r, previous[r], depth[r]));
                continue;
            }
            if s < HIT {
                hit[r] = Some(depth[r]);
                continue;
            }
            previous[r] = depth[r];
            last_step[r] = (relaxation[r] * limits.step_scale * s).min(limits.max_step);
            last_radius[r] = s;
            depth[r] += last_step[r];
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::occupancy::tests::sphere_and_plate;
    use rmvp_dataset::rng::Rng;
    use std::cell::Cell;

    #[test]
    fn over_relaxed_tracing_finds_what_plain_tracing_finds_in_fewer_steps() {
        let mut rng = Rng::for_pixel(5, 0, 0);
        // Rays leaving points near the surfaces in every direction, many at grazing angles.
        let rays: Vec<TraceRay> = (0..4000)
            .map(|_| {
                let on_plate = rng.next_f32() < 0.5;
                let origin = if on_plate {
                    [1.6 * rng.next_f32() - 0.8, 1.6 * rng.next_f32() - 0.8, 0.3 + 0.02 * rng.normal().signum()]
                } else {
                    let d = [rng.normal(), rng.normal(), rng.normal()];
                    let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                    d.map(|x| x / l * 0.52)
                };
                let d = [rng.normal(), rng.normal(), rng.normal()];
                let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                TraceRay { origin, dir: d.map(|x| x / l), start: 0.0, end: 2.0 }
            })
            .filter(|r| sphere_and_plate(&r.origin) > 0.01)
            .collect();
        let evaluations = Cell::new(0usize);
        let field = |points: Vec<f32>| {
            evaluations.set(evaluations.get() + points.len() / 3);
            points.chunks_exact(3).map(sphere_and_plate).collect::<Vec<f32>>()
        };
        let plain = TraceLimits { step_scale: 1.0, max_step: f32::INFINITY, max_steps: 400, relaxation: 1.0 };
        let relaxed = TraceLimits { relaxation: 1.6, ..plain };
        let want = trace_field(field, &rays, plain);
        let plain_evaluations = evaluations.replace(0);
        let got = trace_field(field, &rays, relaxed);
        let relaxed_evaluations = evaluations.get();
        let hits = want.iter().filter(|h| h.is_some()).count();
        assert!(hits > rays.len() / 5 && hits < rays.len() * 4 / 5, "{hits} of {} rays hit", rays.len());
        for (k, (a, b)) in want.iter().zip(&got).enumerate() {
            match (a, b) {
                (Some(a), Some(b)) => assert!((a - b).abs() < 4.0 * HIT, "ray {k}: depth {b} against {a}"),
                (None, None) => {}
                _ => panic!("ray {k}: {b:?} against {a:?} ({:?})", rays[k]),
            }
        }
        println!("evaluations: plain {plain_evaluations}, relaxed {relaxed_evaluations}");
        assert!(relaxed_evaluations * 10 < plain_evaluations * 9, "{relaxed_evaluations} against {plain_evaluations}");
    }
}
