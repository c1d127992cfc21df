//! What a reconstruction leaves on disk besides the mesh: per-view normal maps and re-rendered
//! Stokes images from the trained field, and a picture comparing them with the input.
//!
//! Forward only, and only where the surface is: every view is first sphere traced on a coarse
//! grid of pixels ([`BLOCK`] apart); the pixels of the blocks around a hit, and those of the
//! view's mask when it has one, are then traced one by one, each from a little before the
//! nearest surface that the coarse rays met around it. A pixel whose ray meets the surface
//! gets the SDF's normal there and, in the views that want Stokes, the radiance networks'
//! Stokes at that point: surface rendering, what NeuS's volume rendering converges to once
//! the surface is sharp (within 2 % of the full sampling's S0, median, in
//! `tests/training.rs`), at one field evaluation per pixel instead of a band of samples.
//! Everything else is background: zero.

use crate::data::dilate;
use crate::model::STOKES;
use crate::trace::{sphere_trace, TraceLimits, TraceRay};
use crate::train::Trainer;
use crate::volume::{shade_points, Ray};
use rayon::prelude::*;
use rmvp_dataset::{Camera, Image, Stokes};

/// Side of the blocks of pixels the first, coarse trace looks at (one ray each).
pub const BLOCK: usize = 4;
/// How far before the nearest surface met by the coarse rays around a pixel its own ray
/// starts (unit-sphere units).
const LEAD: f32 = 0.1;
/// Surface tracing: slightly short steps (a learned SDF's slope can exceed 1), at most 0.05 long.
const SURFACE: TraceLimits = TraceLimits { step_scale: 0.9, max_step: 0.05, max_steps: 128 };
/// Rays per parallel work item.
const CHUNK: usize = 256;

/// Images rendered from the trained field in one view.
pub struct RenderedView {
    /// Stokes in the input's units (views rendered with Stokes only).
    pub stokes: Option<Stokes>,
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
    // Each ray traced from `start(pixel)` (no nearer than its entry into the unit sphere); a
    // ray that finds itself inside the surface at a later start (something nearer than its
    // neighbours' surface) is traced again from its entry.
    let trace = |pixels: &[usize], start: &(dyn Fn(usize) -> f32 + Sync)| -> Vec<(usize, Ray, f32)> {
        pixels
            .par_chunks(CHUNK)
            .flat_map_iter(|chunk| {
                let rays: Vec<(usize, Ray)> = chunk.iter().filter_map(|&k| ray_at(k).map(|r| (k, r))).collect();
                let traced: Vec<TraceRay> = rays
                    .iter()
                    .map(|&(k, r)| TraceRay { origin: r.origin, dir: r.dir, start: start(k).max(r.near), end: r.far })
                    .collect();
                let mut hits = sphere_trace(model, params, &level_weight, &traced, SURFACE);
                let again: Vec<usize> = (0..rays.len())
                    .filter(|&i| traced[i].start > rays[i].1.near && hits[i] == Some(traced[i].start))
                    .collect();
                if !again.is_empty() {
                    let from_entry: Vec<TraceRay> =
                        again.iter().map(|&i| TraceRay { start: rays[i].1.near, ..traced[i] }).collect();
                    for (i, hit) in
                        again.into_iter().zip(sphere_trace(model, params, &level_weight, &from_entry, SURFACE))
                    {
                        hits[i] = hit;
                    }
                }
                rays.into_iter().zip(hits).filter_map(|((k, r), t)| Some((k, r, t?))).collect::<Vec<_>>()
            })
            .collect()
    };

    // Coarse: one ray per block; the blocks around a hit are traced in full, each ray from a
    // little before the nearest surface that the coarse rays met around it.
    let (bw, bh) = (w.div_ceil(BLOCK), h.div_ceil(BLOCK));
    let centres: Vec<usize> = (0..bw * bh)
        .map(|b| ((b / bw) * BLOCK + BLOCK / 2).min(h - 1) * w + ((b % bw) * BLOCK + BLOCK / 2).min(w - 1))
        .collect();
    let mut block_depth = vec![f32::INFINITY; bw * bh];
    for (k, _, t) in trace(&centres, &|_| 0.0) {
        block_depth[(k / w) / BLOCK * bw + (k % w) / BLOCK] = t;
    }
    let nearest_around = |k: usize| {
        let (bx, by) = ((k % w) / BLOCK, (k / w) / BLOCK);
        let (xs, ys) = (bx.saturating_sub(1)..(bx + 2).min(bw), by.saturating_sub(1)..(by + 2).min(bh));
        ys.flat_map(|y| xs.clone().map(move |x| y * bw + x)).map(|b| block_depth[b]).fold(f32::INFINITY, f32::min)
    };
    let masked = mask.map(|m| dilate(&m.data().iter().map(|&v| v > 127).collect::<Vec<_>>(), w, h, 2));
    let candidates: Vec<usize> =
        (0..w * h).filter(|&k| nearest_around(k).is_finite() || masked.as_ref().is_some_and(|m| m[k])).collect();
    let traced = centres.len() + candidates.len();
    let surface = trace(&candidates, &|k| match nearest_around(k) {
        d if d.is_finite() => d - LEAD,
        _ => 0.0,
    });

    // The surface: the SDF gradient at each hit is its normal; with the field's features
    // there, the radiance networks shade it once (what NeuS's compositing converges to once
    // the surface is sharp).
    let shaded: Vec<(usize, [f32; 3], [f32; STOKES])> = surface
        .par_chunks(CHUNK)
        .flat_map_iter(|chunk| {
            let rays: Vec<Ray> = chunk.iter().map(|c| c.1).collect();
            let depths: Vec<f32> = chunk.iter().map(|c| c.2).collect();
            let (field, stokes) = shade_points(model, params, &level_weight, &rays, &depths, fd_step, with_stokes);
            let stokes = stokes.unwrap_or_else(|| vec![0.0; STOKES * chunk.len()]);
            let normals = field.normals.chunks_exact(3).map(|n| [n[0], n[1], n[2]]);
            let stokes = stokes.chunks_exact(STOKES).map(|s| std::array::from_fn(|i| s[i]));
            chunk.iter().zip(normals).zip(stokes).map(|((c, n), s)| (c.0, n, s)).collect::<Vec<_>>()
        })
        .collect();
    let mut normals = Image::new(w, h, 3);
    let mut mask = Image::new(w, h, 1);
    let mut s = [0, 1, 2].map(|_| Image::new(w, h, 3));
    let scale = trainer.set.stokes_scale;
    for (k, n, st) in &shaded {
        let world = frame.dir_to_world(*n);
        normals.data_mut()[3 * k..3 * k + 3].copy_from_slice(&[world.x as f32, world.y as f32, world.z as f32]);
        mask.data_mut()[*k] = 255;
        for (c, image) in s.iter_mut().enumerate() {
            let rgb = [st[3 * c], st[3 * c + 1], st[3 * c + 2]].map(|v| v / scale);
            image.data_mut()[3 * k..3 * k + 3].copy_from_slice(&rgb);
        }
    }
    let [s0, s1, s2] = s;
    let stokes = with_stokes.then_some(Stokes { s0, s1, s2 });
    RenderedView { stokes, mask, normals, traced, surface_pixels: surface.len() }
}
