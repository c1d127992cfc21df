//! The normal error against a scene's ground truth while training: a fixed sample of the
//! object pixels of every view with ground-truth normals (training and held out), sphere traced
//! through the field every [`TRACK_EVERY`] iterations and at the last. The run's log records it
//! (`normal_error_deg`) and its report plots it against the iteration.
//!
//! The figure is the one the evaluation gives the extracted mesh (the mean over views of each
//! view's mean angle, over the pixels where both the truth and the surface are), estimated on
//! [`TRACK_PIXELS`] pixels and taken on the field itself: it follows the evaluation's figure to
//! a few tenths of a degree once the surface is sharp, and costs a few tenths of a second each
//! time. Training is the same with it or without it.

use crate::data::Frame;
use crate::ray::Ray;
use crate::trace::{sphere_trace, TraceRay, SURFACE_LIMITS};
use crate::train::Trainer;
use crate::volume::shade_points;
use rayon::prelude::*;
use rmvp_dataset::Scene;

/// Iterations between two measurements.
pub const TRACK_EVERY: u32 = 250;
/// Pixels sampled over all the views, spread in proportion to each view's object.
pub const TRACK_PIXELS: usize = 2048;
/// Rays per parallel work item.
const CHUNK: usize = 256;

/// One pixel of the sample: its view, its ray and its true normal (both in the unit frame).
struct TrackedPixel {
    view: usize,
    ray: Ray,
    normal: [f32; 3],
}

/// The pixels the normal error is measured on.
pub struct NormalTrack {
    pixels: Vec<TrackedPixel>,
    views: usize,
}

impl NormalTrack {
    /// The sample of `scene`'s views with ground-truth normals (None where none has them), in
    /// the unit frame of `frame`: every k-th object pixel of the views taken in turn, k such
    /// that about [`TRACK_PIXELS`] remain.
    pub fn new(scene: &Scene, frame: &Frame) -> Option<Self> {
        let truth: Vec<_> = scene.views.iter().filter_map(|v| Some((v, v.normals.as_ref()?))).collect();
        let on_object = |view: &rmvp_dataset::View, normals: &rmvp_dataset::Image<f32>, k: usize| {
            let n = &normals.data()[3 * k..3 * k + 3];
            let in_mask = view.mask.as_ref().is_none_or(|m| m.data()[k] > 127);
            in_mask && n[0] * n[0] + n[1] * n[1] + n[2] * n[2] > 0.25
        };
        let total: usize = truth
            .iter()
            .map(|(view, normals)| {
                (0..normals.width() * normals.height()).filter(|&k| on_object(view, normals, k)).count()
            })
            .sum();
        if total == 0 {
            return None;
        }
        let stride = total.div_ceil(TRACK_PIXELS);
        let mut pixels = Vec::new();
        let mut seen = 0usize;
        for (index, (view, normals)) in truth.iter().enumerate() {
            let width = normals.width();
            for k in 0..width * normals.height() {
                if !on_object(view, normals, k) {
                    continue;
                }
                seen += 1;
                if !(seen - 1).is_multiple_of(stride) {
                    continue;
                }
                let Some(ray) = frame.pixel_ray(&view.camera, (k % width) as u32, (k / width) as u32) else {
                    continue;
                };
                let n = &normals.data()[3 * k..3 * k + 3];
                let normal = frame.dir_from_world(&nalgebra::Vector3::new(n[0] as f64, n[1] as f64, n[2] as f64));
                pixels.push(TrackedPixel { view: index, ray, normal });
            }
        }
        Some(Self { pixels, views: truth.len() })
    }

    /// Pixels in the sample.
    pub fn pixels(&self) -> usize {
        self.pixels.len()
    }

    /// The mean over views of the mean angle, in degrees, between the field's normal and the
    /// truth at the sampled pixels its surface covers; None where it covers none.
    pub fn normal_error_deg(&self, trainer: &Trainer) -> Option<f64> {
        let (model, params) = (&trainer.model, &trainer.params[..]);
        let level_weight = trainer.level_weight();
        let fd_step = trainer.output_fd_step(&level_weight);
        let angles: Vec<(usize, f64)> = self
            .pixels
            .par_chunks(CHUNK)
            .flat_map_iter(|chunk| {
                let traced: Vec<TraceRay> = chunk
                    .iter()
                    .map(|p| TraceRay { origin: p.ray.origin, dir: p.ray.dir, start: p.ray.near, end: p.ray.far })
                    .collect();
                let hits = sphere_trace(model, params, &level_weight, &traced, SURFACE_LIMITS);
                let (hit, depths): (Vec<&TrackedPixel>, Vec<f32>) =
                    chunk.iter().zip(hits).filter_map(|(p, t)| Some((p, t?))).unzip();
                let rays: Vec<Ray> = hit.iter().map(|p| p.ray).collect();
                let (field, _) = shade_points(model, params, &level_weight, &rays, &depths, fd_step, false);
                hit.into_iter()
                    .zip(field.normals.chunks_exact(3))
                    .map(|(p, n)| {
                        let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt().max(1e-12);
                        let cos = (0..3).map(|k| n[k] * p.normal[k]).sum::<f32>() / length;
                        (p.view, (cos.clamp(-1.0, 1.0) as f64).acos().to_degrees())
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        let mut per_view = vec![(0.0f64, 0usize); self.views];
        for (view, angle) in angles {
            per_view[view].0 += angle;
            per_view[view].1 += 1;
        }
        let means: Vec<f64> = per_view.iter().filter(|v| v.1 > 0).map(|(sum, n)| sum / *n as f64).collect();
        (!means.is_empty()).then(|| means.iter().sum::<f64>() / means.len() as f64)
    }
}

/// Whether the run measures the normal error after `iteration` iterations of `total`.
pub fn tracked_at(iteration: u32, total: u32) -> bool {
    iteration.is_multiple_of(TRACK_EVERY) || iteration == total
}
