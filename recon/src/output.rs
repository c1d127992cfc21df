//! What a reconstruction leaves on disk besides the mesh: per-view normal maps and re-rendered
//! Stokes images from the trained field, and a picture comparing them with the input.
//!
//! Forward only, and only where the surface is: the extracted mesh (the field's zero level set
//! on the marching grid) is ray cast through a BVH, which finds for every pixel whether and
//! where its ray meets the surface; each pixel it hits is then placed on the field's own zero
//! crossing by a secant across a marching cell either side of that point (sphere traced from
//! two cells before it where the SDF keeps its sign there). A
//! pixel whose ray meets the surface gets the SDF's normal there and, in the views that want
//! Stokes, the radiance networks' Stokes at that point: surface rendering, what NeuS's volume
//! rendering converges to once the surface is sharp (within 2 % of the full sampling's S0,
//! median, in `tests/training.rs`), at one field evaluation per pixel instead of a band of
//! samples. Everything else is background: zero.

use crate::data::Frame;
use crate::model::{Model, STOKES};
use crate::ray::Ray;
use crate::trace::{sphere_trace, TraceRay, SURFACE_LIMITS};
use crate::train::Trainer;
use crate::volume::shade_points;
use rayon::prelude::*;
use rmvp_dataset::{Camera, Image, Mesh, Stokes};
use rmvp_render::bvh::Bvh;
use rmvp_render::math::Vec3;

/// Rays per parallel work item (and per batch of field evaluations).
const CHUNK: usize = 4096;

/// The extracted surface in the unit frame, ready to be ray cast: where each pixel's ray meets
/// the field's surface, to within a marching cell.
pub struct SurfaceGuide {
    bvh: Bvh,
    /// The marching grid's cell (unit-sphere units).
    cell: f32,
}

impl SurfaceGuide {
    /// `mesh` (world frame), extracted on an `n^3` grid over the unit cube of `frame`.
    pub fn new(mesh: &Mesh, frame: &Frame, n: usize) -> Self {
        let positions: Vec<[f32; 3]> = mesh
            .positions
            .par_iter()
            .map(|p| frame.point_from_world(&nalgebra::Point3::new(p[0] as f64, p[1] as f64, p[2] as f64)))
            .collect();
        Self { bvh: Bvh::new(&positions, &mesh.faces), cell: 2.0 / n as f32 }
    }

    /// Where `ray` first meets the mesh, if it does inside its span.
    fn first_hit(&self, ray: &Ray) -> Option<f32> {
        let (o, d) = (Vec3::from_array(ray.origin), Vec3::from_array(ray.dir));
        self.bvh.intersect(o, d, ray.near, ray.far).map(|hit| hit.t)
    }
}

/// Images rendered from the trained field in one view.
pub struct RenderedView {
    /// Stokes in the input's units (views rendered with Stokes only).
    pub stokes: Option<Stokes>,
    /// 255 where the pixel's ray meets the surface.
    pub mask: Image<u8>,
    /// World-frame unit normals of the surface (0 elsewhere).
    pub normals: Image<f32>,
    /// Pixels on the surface.
    pub surface_pixels: usize,
}

/// Render `camera`'s view of the trained field, whose extracted surface `guide` holds:
/// normals, and Stokes when `with_stokes`.
pub fn render_view(trainer: &Trainer, camera: &Camera, guide: &SurfaceGuide, with_stokes: bool) -> RenderedView {
    let (model, params, frame) = (&trainer.model, &trainer.params[..], &trainer.set.frame);
    let level_weight = trainer.level_weight();
    let fd_step = trainer.output_fd_step(&level_weight);
    let (w, h) = (camera.width as usize, camera.height as usize);
    let on_mesh: Vec<(usize, Ray, f32)> = (0..w * h)
        .into_par_iter()
        .with_min_len(CHUNK)
        .filter_map(|k| {
            let ray = frame.pixel_ray(camera, (k % w) as u32, (k / w) as u32)?;
            let t = guide.first_hit(&ray)?;
            Some((k, ray, t))
        })
        .collect();
    let surface: Vec<(usize, Ray, f32)> = on_mesh
        .par_chunks(CHUNK)
        .flat_map_iter(|chunk| {
            let depths = field_depths(model, params, &level_weight, chunk, guide.cell);
            chunk.iter().zip(depths).filter_map(|(&(k, r, _), t)| Some((k, r, t?))).collect::<Vec<_>>()
        })
        .collect();

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
    RenderedView { stokes, mask, normals, surface_pixels: surface.len() }
}

/// Where each ray of `rays` (pixel, ray, depth of its mesh hit) crosses the field's zero level
/// set near its mesh hit: the secant between the SDF one marching `cell` before and one after
/// (two field evaluations per ray, in one batch). The few rays whose SDF keeps its sign there
/// (grazing rays, parts thinner than a cell) are sphere traced from two cells before the mesh,
/// and from their entry into the unit sphere if they start inside the surface; `None` where
/// the field has no surface along the ray.
fn field_depths(
    model: &Model,
    params: &[f32],
    level_weight: &[f32],
    rays: &[(usize, Ray, f32)],
    cell: f32,
) -> Vec<Option<f32>> {
    let before = |r: &Ray, t: f32| (t - cell).max(r.near);
    let after = |r: &Ray, t: f32| (t + cell).min(r.far);
    let points: Vec<f32> =
        rays.iter().flat_map(|(_, r, t)| [r.at(before(r, *t)), r.at(after(r, *t))]).flatten().collect();
    let sdf = model.field.sdf(params, &points, level_weight);
    let mut depths: Vec<Option<f32>> = rays
        .iter()
        .zip(sdf.chunks_exact(2))
        .map(|((_, r, t), s)| {
            let (a, b) = (before(r, *t), after(r, *t));
            (s[0] > 0.0 && s[1] <= 0.0).then(|| a + (b - a) * s[0] / (s[0] - s[1]))
        })
        .collect();
    let missed: Vec<usize> = (0..rays.len()).filter(|&i| depths[i].is_none()).collect();
    if missed.is_empty() {
        return depths;
    }
    let traced: Vec<TraceRay> = missed
        .iter()
        .map(|&i| {
            let (_, r, t) = rays[i];
            TraceRay { origin: r.origin, dir: r.dir, start: (t - 2.0 * cell).max(r.near), end: r.far }
        })
        .collect();
    let mut hits = sphere_trace(model, params, level_weight, &traced, SURFACE_LIMITS);
    // A ray that is on or inside the surface where it starts is traced again from its entry.
    let again: Vec<usize> = (0..missed.len())
        .filter(|&m| traced[m].start > rays[missed[m]].1.near && hits[m] == Some(traced[m].start))
        .collect();
    let from_entry: Vec<TraceRay> =
        again.iter().map(|&m| TraceRay { start: rays[missed[m]].1.near, ..traced[m] }).collect();
    for (m, hit) in again.into_iter().zip(sphere_trace(model, params, level_weight, &from_entry, SURFACE_LIMITS)) {
        hits[m] = hit;
    }
    for (m, hit) in missed.into_iter().zip(hits) {
        depths[m] = hit;
    }
    depths
}
