//! The extracted surface's parts that no training view sees. The field is fitted only where
//! the views look: a connected part of the mesh that the training views' object pixels look
//! through but almost never see first stands in space no view asked about (on a ring that
//! every view sees from above, a blob the start leaves beneath its hole; a bubble inside a
//! body). Such parts are left out of the mesh, as evaluations of a field (DTU's, ScanNet's)
//! cull what no view sees, but by connected part, so that the unseen side of an object whose
//! other side the views see stays.

use crate::data::TrainingSet;
use rayon::prelude::*;
use rmvp_dataset::Mesh;
use rmvp_render::bvh::Bvh;
use rmvp_render::math::Vec3;
use serde::{Deserialize, Serialize};

/// The least share of the object pixels whose rays cross a connected part of the mesh at
/// which it must be the first surface to stay: a part in view is seen first at most of them
/// (a small sphere in front of the Mitsuba spot at all), a part behind others at almost none
/// (the blob beneath our ring at about 1 %).
pub const MIN_SEEN_SHARE: f64 = 0.1;

/// Surfaces a ray is followed through at most, so that the work a mesh can cause stays
/// bounded (a part met only beyond them counts as not crossed, which only keeps it).
const MAX_CROSSINGS: usize = 64;

/// What [`unseen_parts`] found.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct UnseenParts {
    /// Connected parts of the mesh.
    pub parts: usize,
    /// Object pixels of the training views whose ray meets the mesh (0 where the mesh is one
    /// part and nothing was cast).
    pub pixels: usize,
    /// The parts no training view sees.
    pub unseen: Vec<UnseenPart>,
    /// The unseen parts were kept in the mesh (`--keep-unseen-parts`).
    pub kept: bool,
}

/// A part of the mesh as the training views' object pixels meet it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct UnseenPart {
    /// Object pixels whose ray meets it first.
    pub seen: usize,
    /// Object pixels whose ray crosses it.
    pub crossed: usize,
    /// Its triangles.
    pub faces: usize,
}

impl UnseenParts {
    /// One line on the unseen parts for people (`None` where there are none).
    pub fn summary(&self) -> Option<String> {
        if self.unseen.is_empty() {
            return None;
        }
        let faces: usize = self.unseen.iter().map(|p| p.faces).sum();
        let seen: usize = self.unseen.iter().map(|p| p.seen).sum();
        let crossed: usize = self.unseen.iter().map(|p| p.crossed).sum();
        let (count, them) = match self.unseen.len() {
            1 => ("1 part".to_string(), "it"),
            n => (format!("{n} parts"), "them"),
        };
        let fate = if self.kept {
            "kept (--keep-unseen-parts)".into()
        } else {
            format!("left out (--keep-unseen-parts keeps {them})")
        };
        Some(format!(
            "mesh: {count} of {} ({faces} triangles) that no training view sees, the first surface at {seen} of the \
             {crossed} object pixels that cross it: {fate}",
            self.parts
        ))
    }
}

/// For each connected part of `mesh` (world frame; `part_of_face` and `parts` as
/// [`Mesh::face_parts`] numbers them), the object pixels of `set`'s views whose ray meets it
/// first and those whose ray crosses it (`seen`, `crossed`; `faces` left 0).
pub fn meet_parts(mesh: &Mesh, set: &TrainingSet, part_of_face: &[u32], parts: usize) -> Vec<UnseenPart> {
    let bvh = Bvh::new(&mesh.positions, &mesh.faces);
    let rows: Vec<(usize, u32)> =
        set.views.iter().enumerate().flat_map(|(v, view)| (0..view.camera.height).map(move |y| (v, y))).collect();
    let add = |mut a: Vec<UnseenPart>, b: Vec<UnseenPart>| {
        a.iter_mut().zip(b).for_each(|(a, b)| (a.seen, a.crossed) = (a.seen + b.seen, a.crossed + b.crossed));
        a
    };
    rows.par_iter()
        .fold(
            || vec![UnseenPart::default(); parts],
            |mut met, &(v, y)| {
                let view = &set.views[v];
                let width = view.camera.width;
                let mut crossed: Vec<u32> = Vec::new();
                for x in (0..width).filter(|&x| view.mask[(y * width + x) as usize]) {
                    let ray = view.camera.pixel_ray(x, y);
                    let (origin, direction) = (Vec3::from_f64(&ray.origin.coords), Vec3::from_f64(&ray.direction));
                    // Every surface along the ray, nearest first (each hit lies strictly beyond the last).
                    crossed.clear();
                    let mut from = 0.0;
                    for surface in 0..MAX_CROSSINGS {
                        let Some(hit) = bvh.intersect(origin, direction, from, f32::INFINITY) else { break };
                        let part = part_of_face[hit.triangle as usize];
                        if surface == 0 {
                            met[part as usize].seen += 1;
                        }
                        if !crossed.contains(&part) {
                            crossed.push(part);
                        }
                        from = hit.t;
                    }
                    crossed.iter().for_each(|&p| met[p as usize].crossed += 1);
                }
                met
            },
        )
        .reduce(|| vec![UnseenPart::default(); parts], add)
}

/// The connected parts of `mesh` (world frame) that are the first surface at fewer than
/// [`MIN_SEEN_SHARE`] of the object pixels of `set`'s views whose rays cross them, or at none,
/// and the mesh without them unless `keep`. A mesh of one part is returned as it is.
pub fn unseen_parts(mesh: Mesh, set: &TrainingSet, keep: bool) -> (Mesh, UnseenParts) {
    let (part_of_face, parts) = mesh.face_parts();
    if parts < 2 {
        return (mesh, UnseenParts { parts, kept: keep, ..Default::default() });
    }
    let mut met = meet_parts(&mesh, set, &part_of_face, parts);
    part_of_face.iter().for_each(|&p| met[p as usize].faces += 1);
    let pixels = met.iter().map(|p| p.seen).sum();
    let is_seen: Vec<bool> =
        met.iter().map(|p| p.seen > 0 && p.seen as f64 >= MIN_SEEN_SHARE * p.crossed as f64).collect();
    let unseen: Vec<UnseenPart> = met.iter().zip(&is_seen).filter(|(_, &s)| !s).map(|(p, _)| *p).collect();
    let record = UnseenParts { parts, pixels, unseen, kept: keep };
    if keep || record.unseen.is_empty() {
        return (mesh, record);
    }
    let in_seen_part: Vec<bool> = part_of_face.iter().map(|&p| is_seen[p as usize]).collect();
    (mesh.with_faces(&in_seen_part), record)
}
