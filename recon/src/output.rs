//! What a reconstruction leaves on disk besides the mesh: per-view normal maps and re-rendered
//! Stokes images from the trained field, and a picture comparing them with the input.

use crate::model::STOKES;
use crate::train::Trainer;
use crate::volume::{sample_depths, Forward, Ray};
use rayon::prelude::*;
use rmvp_dataset::{Camera, Image, Stokes};

/// Images volume-rendered from the trained field in one view.
pub struct RenderedView {
    /// Stokes in the input's units.
    pub stokes: Stokes,
    /// Accumulated opacity.
    pub opacity: Image<f32>,
    /// World-frame unit normals (0 where the opacity is below 0.5).
    pub normals: Image<f32>,
}

/// Render `camera`'s view of the trained field, in the input's units.
pub fn render_view(trainer: &Trainer, camera: &Camera) -> RenderedView {
    let (model, params, frame) = (&trainer.model, &trainer.params[..], &trainer.set.frame);
    let level_weight = trainer.level_weight();
    let fd_step = trainer.fd_step(&level_weight);
    let (sampling, stokes_scale) = (trainer.config.sampling, trainer.set.stokes_scale);
    let (w, h) = (camera.width as usize, camera.height as usize);
    let rays: Vec<(usize, Ray)> =
        (0..w * h).filter_map(|k| frame.pixel_ray(camera, (k % w) as u32, (k / w) as u32).map(|r| (k, r))).collect();
    let results: Vec<(usize, [f32; STOKES], f32, [f32; 3])> = rays
        .par_chunks(128)
        .flat_map_iter(|chunk| {
            let rs: Vec<Ray> = chunk.iter().map(|c| c.1).collect();
            let depths = sample_depths(model, params, &level_weight, &rs, sampling, &vec![0.5; rs.len()]);
            let fwd = Forward::run(model, params, &level_weight, &rs, &depths, fd_step, false);
            chunk.iter().zip(fwd.rays).map(|(&(k, _), o)| (k, o.stokes, o.opacity, o.normal)).collect::<Vec<_>>()
        })
        .collect();
    let mut s = [0, 1, 2].map(|_| Image::new(w, h, 3));
    let mut opacity = Image::new(w, h, 1);
    let mut normals = Image::new(w, h, 3);
    for (k, st, a, n) in results {
        for (c, img) in s.iter_mut().enumerate() {
            img.data_mut()[3 * k..3 * k + 3]
                .copy_from_slice(&[st[3 * c], st[3 * c + 1], st[3 * c + 2]].map(|v| v / stokes_scale));
        }
        opacity.data_mut()[k] = a;
        if a > 0.5 {
            let world = frame.dir_to_world(n);
            normals.data_mut()[3 * k..3 * k + 3].copy_from_slice(&[world.x as f32, world.y as f32, world.z as f32]);
        }
    }
    let [s0, s1, s2] = s;
    RenderedView { stokes: Stokes { s0, s1, s2 }, opacity, normals }
}
