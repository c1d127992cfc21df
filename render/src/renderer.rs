//! Rendering views: per pixel, jittered camera rays; per hit, environment light by multiple
//! importance sampling of the environment and the pBRDF, with shadow rays (self-shadowing);
//! direct light only. Every pixel has its own random stream, so images are deterministic.

use crate::envmap::EnvMap;
use crate::math::Vec3;
use crate::object::{Object, SurfacePoint};
use crate::pbrdf::{ShadingFrame, StokesRgb};
use rayon::prelude::*;
use rmvp_dataset::polarization::{intensity, POLARIZER_ANGLES_DEG};
use rmvp_dataset::rng::Rng;
use rmvp_dataset::{visualize, Camera, Image, PolarizerImages, Split, Stokes, View};

/// Sampling settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Settings {
    /// Samples per pixel (each: one camera ray, one environment sample, one BRDF sample).
    pub spp: u32,
    /// Seed of all random streams.
    pub seed: u64,
}

impl Default for Settings {
    fn default() -> Self {
        Self { spp: 64, seed: 0 }
    }
}

/// Everything rendered for one camera.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderedView {
    /// Linear Stokes (RGB) in each pixel's Stokes frame.
    pub stokes: Stokes,
    /// 255 where at least half of the pixel's samples hit the subject.
    pub mask: Image<u8>,
    /// z-depth of the pixel-centre ray's hit; 0 on background.
    pub depth: Image<f32>,
    /// World-frame shading normal, its footprint's mean ([`GeometryMaps::normals`]); 0 on background.
    pub normals: Image<f32>,
    /// Which part the pixel-centre ray hits first: 1 + its index, 0 for none.
    pub parts: Image<u8>,
}

/// Render one view. `view` selects the random streams (use the view's index).
pub fn render_view(object: &Object, env: &EnvMap, camera: &Camera, settings: Settings, view: u32) -> RenderedView {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let mut s = [Image::new(w, h, 3), Image::new(w, h, 3), Image::new(w, h, 3)];
    let mut mask = Image::new(w, h, 1);
    let [s0, s1, s2] = &mut s;
    let camera_center = Vec3::from_f64(&camera.center().coords);
    let rays = RayGenerator::new(camera);
    s0.data_mut()
        .par_chunks_mut(3 * w)
        .zip(s1.data_mut().par_chunks_mut(3 * w))
        .zip(s2.data_mut().par_chunks_mut(3 * w))
        .zip(mask.data_mut().par_chunks_mut(w))
        .enumerate()
        .for_each(|(j, (((r0, r1), r2), m))| {
            for i in 0..w {
                let mut rng = Rng::for_pixel(settings.seed, view, (j * w + i) as u64);
                let centre = camera.pixel_ray(i as u32, j as u32);
                // The pixel's Stokes frame (it turns by far less than a degree across a pixel).
                let (x, y) = camera.stokes_frame(&centre.direction);
                let (x, y) = (Vec3::from_f64(&x), Vec3::from_f64(&y));
                let mut acc = [[0.0f32; 3]; 3];
                let mut hits = 0;
                for _ in 0..settings.spp {
                    let dir = rays.direction(i as f32 + rng.next_f32(), j as f32 + rng.next_f32());
                    match object.intersect(camera_center, dir) {
                        Some(hit) => {
                            hits += u32::from(hit.subject);
                            let frame = ShadingFrame { n: hit.n, v: -dir, x, y };
                            let value = shade(object, env, &hit, &frame, &mut rng);
                            for (a, v) in acc.iter_mut().flatten().zip(value.iter().flatten()) {
                                *a += v;
                            }
                        }
                        None => {
                            let background = env.eval(dir);
                            (0..3).for_each(|c| acc[0][c] += background[c]);
                        }
                    }
                }
                let scale = 1.0 / settings.spp as f32;
                for c in 0..3 {
                    r0[3 * i + c] = acc[0][c] * scale;
                    r1[3 * i + c] = acc[1][c] * scale;
                    r2[3 * i + c] = acc[2][c] * scale;
                }
                m[i] = if 2 * hits >= settings.spp { 255 } else { 0 };
            }
        });
    let [s0, s1, s2] = s;
    let GeometryMaps { depth, normals, parts, .. } = geometry_maps(object, camera);
    RenderedView { stokes: Stokes { s0, s1, s2 }, mask, depth, normals, parts }
}

/// What the ray through each pixel's centre hits.
#[derive(Clone, Debug, PartialEq)]
pub struct GeometryMaps {
    /// 255 where the centre ray hits the subject first.
    pub mask: Image<u8>,
    /// z-depth of the subject's hit; 0 elsewhere.
    pub depth: Image<f32>,
    /// World-frame shading normal (facing the camera) where the centre ray hits the subject,
    /// 0 elsewhere: the mean over the pixel's footprint of the normals where it meets the
    /// subject, normalised, as a renderer's box-filtered normal image holds it (Mitsuba's,
    /// `docs/conventions.md`); on a pixel whose neighbours' centre normals all lie within
    /// [`FOOTPRINT_SMOOTH_DEG`] of its own and all hit the same part, its centre's normal.
    pub normals: Image<f32>,
    /// Which part the centre ray hits first: 1 + its index, 0 for none.
    pub parts: Image<u8>,
}

/// Sub-pixel rays a side over which a pixel's footprint normal is averaged (stratified, one at
/// the centre of each cell of a `FOOTPRINT_SAMPLES` square grid over the pixel).
pub const FOOTPRINT_SAMPLES: usize = 4;

/// Largest angle, degrees, between a pixel's centre normal and its neighbours' at which its
/// footprint's mean normal is taken to be its centre's (within a few hundredths of a degree
/// there): silhouettes, creases and occlusion edges are averaged over the footprint.
pub const FOOTPRINT_SMOOTH_DEG: f32 = 4.0;

/// Ray-cast the pixel centres of a camera: mask, depth, part and normal maps; the normals are
/// averaged over the footprint of the pixels at an edge ([`GeometryMaps::normals`]).
pub fn geometry_maps(object: &Object, camera: &Camera) -> GeometryMaps {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let mut mask = Image::new(w, h, 1);
    let mut depth = Image::new(w, h, 1);
    let mut normals = Image::new(w, h, 3);
    let mut parts = Image::new(w, h, 1);
    let camera_z = Vec3::new(camera.r[(2, 0)] as f32, camera.r[(2, 1)] as f32, camera.r[(2, 2)] as f32);
    let camera_center = Vec3::from_f64(&camera.center().coords);
    mask.data_mut()
        .par_chunks_mut(w)
        .zip(depth.data_mut().par_chunks_mut(w))
        .zip(normals.data_mut().par_chunks_mut(3 * w))
        .zip(parts.data_mut().par_chunks_mut(w))
        .enumerate()
        .for_each(|(j, (((m, d), n), p))| {
            for i in 0..w {
                let ray = camera.pixel_ray(i as u32, j as u32);
                let Some(hit) = object.intersect(camera_center, Vec3::from_f64(&ray.direction)) else { continue };
                p[i] = (hit.part + 1).min(255) as u8;
                if hit.subject {
                    m[i] = 255;
                    d[i] = (hit.p - camera_center).dot(camera_z);
                    n[3 * i..3 * i + 3].copy_from_slice(&[hit.n.x, hit.n.y, hit.n.z]);
                }
            }
        });
    let footprint = footprint_normals(object, camera, &mask, &normals, &parts);
    GeometryMaps { mask, depth, normals: footprint, parts }
}

/// The normal map averaged over the footprint of each pixel at an edge of `normals` (centre
/// normals): where a neighbour's centre misses the subject, hits another part, or has a normal
/// more than [`FOOTPRINT_SMOOTH_DEG`] from the pixel's own.
fn footprint_normals(
    object: &Object,
    camera: &Camera,
    mask: &Image<u8>,
    normals: &Image<f32>,
    parts: &Image<u8>,
) -> Image<f32> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let smooth_cos = FOOTPRINT_SMOOTH_DEG.to_radians().cos();
    let camera_center = Vec3::from_f64(&camera.center().coords);
    let rays = RayGenerator::new(camera);
    let centre = |k: usize| Vec3::new(normals.data()[3 * k], normals.data()[3 * k + 1], normals.data()[3 * k + 2]);
    let at_edge = |i: usize, j: usize| {
        let k = j * w + i;
        let n = centre(k);
        (j.saturating_sub(1)..(j + 2).min(h)).any(|y| {
            (i.saturating_sub(1)..(i + 2).min(w)).any(|x| {
                let q = y * w + x;
                mask.data()[q] == 0 || parts.data()[q] != parts.data()[k] || centre(q).dot(n) < smooth_cos
            })
        })
    };
    let mut out = normals.clone();
    out.data_mut().par_chunks_mut(3 * w).enumerate().for_each(|(j, row)| {
        for i in 0..w {
            if mask.data()[j * w + i] == 0 || !at_edge(i, j) {
                continue;
            }
            let mut sum = Vec3::new(0.0, 0.0, 0.0);
            let cell = 1.0 / FOOTPRINT_SAMPLES as f32;
            for b in 0..FOOTPRINT_SAMPLES {
                for a in 0..FOOTPRINT_SAMPLES {
                    let (u, v) = (i as f32 + (a as f32 + 0.5) * cell, j as f32 + (b as f32 + 0.5) * cell);
                    if let Some(hit) = object.intersect(camera_center, rays.direction(u, v)).filter(|hit| hit.subject) {
                        sum = sum + hit.n;
                    }
                }
            }
            if sum.length() > 0.0 {
                let n = sum.normalize();
                row[3 * i..3 * i + 3].copy_from_slice(&[n.x, n.y, n.z]);
            }
        }
    });
    out
}

/// Camera ray directions in `f32`: through `R^T K^-1 (u, v, 1)` for pinhole cameras, through
/// [`Camera::ray`] when the lens has distortion.
struct RayGenerator<'a> {
    camera: &'a Camera,
    pinhole: Option<[Vec3; 3]>,
}

impl<'a> RayGenerator<'a> {
    fn new(camera: &'a Camera) -> Self {
        let pinhole = match (camera.distortion, camera.k.try_inverse()) {
            (None, Some(k_inv)) => {
                let m = camera.r.transpose() * k_inv;
                Some([0, 1, 2].map(|c| Vec3::new(m[(0, c)] as f32, m[(1, c)] as f32, m[(2, c)] as f32)))
            }
            _ => None,
        };
        Self { camera, pinhole }
    }

    /// The unit world direction through continuous pixel coordinates `(u, v)`.
    fn direction(&self, u: f32, v: f32) -> Vec3 {
        match &self.pinhole {
            Some([cu, cv, c1]) => (*cu * u + *cv * v + *c1).normalize(),
            None => Vec3::from_f64(&self.camera.ray(u as f64, v as f64).direction),
        }
    }
}

/// Radiance towards the viewer at a surface point: one environment sample and one BRDF sample,
/// combined by the power heuristic.
fn shade(object: &Object, env: &EnvMap, hit: &SurfacePoint, frame: &ShadingFrame, rng: &mut Rng) -> StokesRgb {
    let mut out = [[0.0f32; 3]; 3];
    let surface = &hit.surface;
    let eps = 1e-4 * (1.0 + hit.p.length());
    let mut add = |l: Vec3, radiance: [f32; 3], weight_over_pdf: f32| {
        let f = surface.eval(frame, l);
        if f[0].iter().all(|&v| v <= 0.0) {
            return;
        }
        let origin = hit.p + hit.ng * if hit.ng.dot(l) >= 0.0 { eps } else { -eps };
        if object.occluded(origin, l) {
            return;
        }
        for k in 0..3 {
            for c in 0..3 {
                out[k][c] += f[k][c] * radiance[c] * weight_over_pdf;
            }
        }
    };
    let (l, pdf_light, radiance) = env.sample(rng.next_f32(), rng.next_f32());
    if pdf_light > 0.0 {
        let pdf_brdf = surface.pdf(frame, l);
        add(l, radiance, pdf_light / (pdf_light * pdf_light + pdf_brdf * pdf_brdf));
    }
    let (a, b, c) = (rng.next_f32(), rng.next_f32(), rng.next_f32());
    if let Some(l) = surface.sample(frame, a, b, c) {
        let pdf_brdf = surface.pdf(frame, l);
        if pdf_brdf > 0.0 {
            let (radiance, pdf_light) = env.eval_and_pdf(l);
            add(l, radiance, pdf_brdf / (pdf_brdf * pdf_brdf + pdf_light * pdf_light));
        }
    }
    out
}

impl RenderedView {
    /// The images behind the four polarizers, as 16-bit counts of `intensity * scale`.
    pub fn polarizer_images(&self, scale: f64) -> PolarizerImages {
        let s = &self.stokes;
        let images = POLARIZER_ANGLES_DEG.map(|deg| {
            let theta = (deg as f32).to_radians();
            let data = (0..s.s0.data().len())
                .map(|k| {
                    let i = intensity(s.s0.data()[k], s.s1.data()[k], s.s2.data()[k], theta) as f64 * scale;
                    (i.clamp(0.0, 1.0) * 65535.0).round() as u16
                })
                .collect();
            Image::from_vec(s.s0.width(), s.s0.height(), 3, data).expect("sized")
        });
        PolarizerImages { scale, images }
    }

    /// A dataset view holding everything rendered: Stokes, mask, AoP, DoP, ground-truth normals
    /// and depth, polarizer images at `polarizer_scale`, and a preview.
    pub fn into_view(self, name: impl Into<String>, split: Split, camera: Camera, polarizer_scale: f64) -> View {
        let mut view = View::new(name, split, camera);
        view.polarized = Some(self.polarizer_images(polarizer_scale));
        let (aop, dop) = self.stokes.aop_dop();
        view.aop = Some(aop);
        view.dop = Some(dop);
        view.preview = Some(visualize::preview(&self.stokes.s0));
        view.mask = Some(self.mask);
        view.depth = Some(self.depth);
        view.normals = Some(self.normals);
        view.stokes = Some(self.stokes);
        view
    }
}
