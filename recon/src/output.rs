//! What a reconstruction leaves on disk besides the mesh: per-view normal maps and re-rendered
//! Stokes images from the trained field, and a picture comparing them with the input.
//!
//! Forward only, and only where the surface is: every view is first sphere traced on a coarse
//! grid of pixels ([`BLOCK`] apart); the blocks around a hit, and the pixels of the view's mask
//! when it has one, are then traced one by one. A pixel whose ray meets the surface gets the
//! SDF's normal there, and in the views that want Stokes, a NeuS volume rendering of samples
//! in a narrow band around that point (where all of the compositing weight lies once the
//! surface is sharp). Everything else is background: zero.

use crate::data::dilate;
use crate::model::STOKES;
use crate::samples::FieldSamples;
use crate::trace::{sphere_trace, TraceLimits, TraceRay};
use crate::train::Trainer;
use crate::volume::{render_forward, Ray};
use rayon::prelude::*;
use rmvp_dataset::{Camera, Image, Stokes};

/// Side of the blocks of pixels the first, coarse trace looks at (one ray each).
pub const BLOCK: usize = 4;
/// Samples in the band around the surface for the Stokes rendering.
const BAND_SAMPLES: usize = 16;
/// Surface tracing: slightly short steps (a learned SDF's slope can exceed 1), at most 0.05 long.
const SURFACE: TraceLimits = TraceLimits { step_scale: 0.9, max_step: 0.05, max_steps: 128 };
/// Rays per parallel work item.
const CHUNK: usize = 256;

/// Images rendered from the trained field in one view.
pub struct RenderedView {
    /// Stokes in the input's units, and their composited opacity (views rendered with Stokes
    /// only).
    pub stokes: Option<(Stokes, Image<f32>)>,
    /// 255 where the pixel's ray meets the surface.
    pub mask: Image<u8>,
    /// World-frame unit normals of the surface (0 elsewhere).
    pub normals: Image<f32>,
    /// Rays traced (coarse and fine) and pixels on the surface.
    pub traced: usize,
    /// Pixels on the surface.
    pub surface_pixels: usize,
}

/// Render `camera`'s view of the trained field: normals, and Stokes when `with_stokes`.
/// `mask` (the view's object mask, if known) adds its pixels, dilated by two, to those traced.
pub fn render_view(trainer: &Trainer, camera: &Camera, mask: Option<&Image<u8>>, with_stokes: bool) -> RenderedView {
    let (model, params, frame) = (&trainer.model, &trainer.params[..], &trainer.set.frame);
    let level_weight = trainer.level_weight();
    let fd_step = trainer.fd_step(&level_weight);
    let (w, h) = (camera.width as usize, camera.height as usize);
    let ray_at = |k: usize| frame.pixel_ray(camera, (k % w) as u32, (k / w) as u32);
    let trace = |pixels: &[usize]| -> Vec<(usize, Ray, f32)> {
        pixels
            .par_chunks(CHUNK)
            .flat_map_iter(|chunk| {
                let rays: Vec<(usize, Ray)> = chunk.iter().filter_map(|&k| ray_at(k).map(|r| (k, r))).collect();
                let traced: Vec<TraceRay> = rays
                    .iter()
                    .map(|(_, r)| TraceRay { origin: r.origin, dir: r.dir, start: r.near, end: r.far })
                    .collect();
                let hits = sphere_trace(model, params, &level_weight, &traced, SURFACE);
                rays.into_iter().zip(hits).filter_map(|((k, r), t)| Some((k, r, t?))).collect::<Vec<_>>()
            })
            .collect()
    };

    // Coarse: one ray per block; the blocks around a hit are traced in full.
    let (bw, bh) = (w.div_ceil(BLOCK), h.div_ceil(BLOCK));
    let centres: Vec<usize> = (0..bw * bh)
        .map(|b| ((b / bw) * BLOCK + BLOCK / 2).min(h - 1) * w + ((b % bw) * BLOCK + BLOCK / 2).min(w - 1))
        .collect();
    let mut blocks = vec![false; bw * bh];
    for (k, _, _) in trace(&centres) {
        blocks[(k / w) / BLOCK * bw + (k % w) / BLOCK] = true;
    }
    let blocks = dilate(&blocks, bw, bh, 1);
    let masked = mask.map(|m| dilate(&m.data().iter().map(|&v| v > 127).collect::<Vec<_>>(), w, h, 2));
    let candidates: Vec<usize> = (0..w * h)
        .filter(|&k| blocks[(k / w) / BLOCK * bw + (k % w) / BLOCK] || masked.as_ref().is_some_and(|m| m[k]))
        .collect();
    let traced = centres.len() + candidates.len();
    let surface = trace(&candidates);

    // The surface's normals: the SDF gradient at each hit.
    let mut normals = Image::new(w, h, 3);
    let mut mask = Image::new(w, h, 1);
    let hit_normals: Vec<f32> = surface
        .par_chunks(CHUNK)
        .flat_map_iter(|chunk| {
            let points: Vec<f32> = chunk.iter().flat_map(|(_, r, t)| r.at(*t)).collect();
            FieldSamples::infer(model, params, &level_weight, points, fd_step).normals
        })
        .collect();
    for ((k, _, _), n) in surface.iter().zip(hit_normals.chunks_exact(3)) {
        let world = frame.dir_to_world([n[0], n[1], n[2]]);
        normals.data_mut()[3 * k..3 * k + 3].copy_from_slice(&[world.x as f32, world.y as f32, world.z as f32]);
        mask.data_mut()[*k] = 255;
    }

    // Stokes: volume rendering in a band around each hit.
    let stokes = with_stokes.then(|| {
        let half = (6.0 / model.inv_s(params)).clamp(2.0 * fd_step, 0.25);
        let outputs: Vec<(usize, [f32; STOKES], f32)> = surface
            .par_chunks(CHUNK)
            .flat_map_iter(|chunk| {
                let rays: Vec<Ray> = chunk.iter().map(|c| c.1).collect();
                let depths: Vec<Vec<f32>> = chunk
                    .iter()
                    .map(|(_, r, t)| {
                        let (a, b) = ((t - half).max(r.near), (t + half).min(r.far));
                        let step = (b - a) / BAND_SAMPLES as f32;
                        (0..BAND_SAMPLES).map(|i| a + step * (i as f32 + 0.5)).collect()
                    })
                    .collect();
                let out = render_forward(model, params, &level_weight, &rays, &depths, fd_step, true);
                chunk.iter().zip(out).map(|(c, o)| (c.0, o.stokes, o.opacity)).collect::<Vec<_>>()
            })
            .collect();
        let scale = trainer.set.stokes_scale;
        let mut s = [0, 1, 2].map(|_| Image::new(w, h, 3));
        let mut opacity = Image::new(w, h, 1);
        for (k, st, a) in outputs {
            for (c, image) in s.iter_mut().enumerate() {
                let rgb = [st[3 * c], st[3 * c + 1], st[3 * c + 2]].map(|v| v / scale);
                image.data_mut()[3 * k..3 * k + 3].copy_from_slice(&rgb);
            }
            opacity.data_mut()[k] = a;
        }
        let [s0, s1, s2] = s;
        (Stokes { s0, s1, s2 }, opacity)
    });
    RenderedView { stokes, mask, normals, traced, surface_pixels: surface.len() }
}
