//! The simulated lab: what the simulated camera and `rmvp simulate` put in front of the lens
//! when a board gives the poses. The world is the board frame ([`crate::board`]: millimetres,
//! z up): the subject stands at the board's centre, the board lies on a textured table (so that
//! COLMAP finds features beyond the board), the environment keeps its +Y-up map turned to
//! z up. A calibration session shows the board alone, held at many tilts and places in the
//! frame.

use crate::board::{board_to_y_up, Board, BoardOptions};
use crate::Result;
use nalgebra::{Matrix3, Vector3};
use rmvp_dataset::rng::Rng;
use rmvp_dataset::similarity::Similarity;
use rmvp_dataset::{Camera, Image, Mesh};
use rmvp_render::pbrdf::{Interface, Lobes};
use rmvp_render::rig::look_at;
use rmvp_render::{EnvMap, Part};
use serde::{Deserialize, Serialize};

/// Board texture resolution, pixels per millimetre.
const BOARD_PX_PER_MM: f64 = 8.0;
/// Side of the square table, millimetres.
const TABLE_MM: f64 = 1200.0;
/// Table texture side, pixels.
const TABLE_PX: usize = 1024;
/// Elevations of the object session's two camera rings, degrees (low enough to see the
/// object's sides, high enough to see the board around it).
pub const RING_ELEVATIONS_DEG: [f64; 2] = [40.0, 60.0];

/// What stands in the simulated lab.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LabOptions {
    /// The board under the subject.
    pub board: BoardOptions,
    /// The subject's bounding-sphere radius, millimetres.
    pub object_radius_mm: f64,
    /// A textured table under the board.
    pub table: bool,
    /// Distance of the object session's cameras from the object's centre, millimetres.
    pub distance_mm: f64,
    /// The subject stands on the board (off: the empty lab, for clean background plates taken
    /// at the same turntable positions).
    pub object: bool,
}

impl Default for LabOptions {
    fn default() -> Self {
        Self { board: BoardOptions::default(), object_radius_mm: 70.0, table: true, distance_mm: 430.0, object: true }
    }
}

/// The lab's scene: its parts, the subject's placement and where its bounding sphere is.
pub struct Lab {
    /// Subject (first, if it stands there), board and table.
    pub parts: Vec<Part>,
    /// The subject in the world frame.
    pub subject: Mesh,
    /// How the subject's mesh was placed: `x_world = s R x_mesh + t` (the mesh's +Y up to the
    /// board's +Z up, mesh units to millimetres).
    pub placement: Similarity,
    /// Centre of the subject's bounding sphere (world, mm).
    pub center: Vector3<f64>,
    /// Its radius (mm).
    pub radius: f64,
}

impl LabOptions {
    /// Place `object` (any units, +Y up) on the board and build the parts.
    pub fn build(&self, object: &Mesh, interface: Interface) -> Result<Lab> {
        let board = Board::new(&self.board)?;
        let rotation = board_to_y_up().transpose();
        let scale = self.object_radius_mm / (object.radius() as f64).max(1e-12);
        let lowest = object
            .positions
            .iter()
            .map(|p| (rotation * Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64)).z)
            .fold(f64::INFINITY, f64::min);
        let [w, h] = self.board.size_mm();
        // Half a millimetre above the board: the subject stands on it without sharing its plane.
        let translation = Vector3::new(w / 2.0, h / 2.0, 0.5 - scale * lowest);
        let placement = Similarity { r: rotation, t: translation, s: scale };
        let mut parts = Vec::new();
        let subject = placement.apply_to_mesh(object);
        if self.object {
            parts.push(Part::subject(subject.clone(), interface, Lobes::Plastic));
        }
        parts.push(Part {
            mesh: board.plane_mesh(),
            interface: Interface::Dielectric(1.5),
            lobes: Lobes::Lambertian,
            texture: Some(board.albedo_texture(BOARD_PX_PER_MM)?),
            subject: false,
        });
        if self.table {
            parts.push(table_part(w / 2.0, h / 2.0));
        }
        Ok(Lab { parts, subject, placement, center: translation, radius: self.object_radius_mm })
    }

    /// The object session's cameras: `views` on two rings around the subject (alternating
    /// rings, evenly turned), looking at its centre, intrinsics `k`.
    pub fn cameras(&self, lab: &Lab, views: usize, k: Matrix3<f64>, width: u32, height: u32) -> Vec<Camera> {
        (0..views)
            .map(|i| {
                let ring = i % RING_ELEVATIONS_DEG.len();
                let azimuth = (i / 2) as f64 / views.div_ceil(2) as f64 * std::f64::consts::TAU + ring as f64 * 0.35;
                let elevation = RING_ELEVATIONS_DEG[ring].to_radians();
                let direction =
                    Vector3::new(elevation.cos() * azimuth.cos(), elevation.cos() * azimuth.sin(), elevation.sin());
                look_at(k, lab.center + self.distance_mm * direction, lab.center, Vector3::z(), width, height)
            })
            .collect()
    }
}

/// The environment of a lab scene: `env` turned so that its +Y is the board's +Z.
pub fn lab_environment(env: EnvMap) -> EnvMap {
    env.with_rotation(&board_to_y_up())
}

/// The board alone for a calibration session (no subject, no table): its parts.
pub fn calibration_parts(spec: &BoardOptions) -> Result<Vec<Part>> {
    let board = Board::new(spec)?;
    Ok(vec![Part {
        mesh: board.plane_mesh(),
        interface: Interface::Dielectric(1.5),
        lobes: Lobes::Lambertian,
        texture: Some(board.albedo_texture(BOARD_PX_PER_MM)?),
        subject: true,
    }])
}

/// Cameras of a calibration session: the board seen at tilts of 10 to 52 degrees from every
/// direction, at several distances and rolls, landing in every part of the frame (a set that
/// determines the intrinsics; deterministic in `seed`).
pub fn calibration_cameras(
    spec: &BoardOptions,
    views: usize,
    k: Matrix3<f64>,
    width: u32,
    height: u32,
    seed: u64,
) -> Vec<Camera> {
    let [w, h] = spec.size_mm();
    let centre = Vector3::new(w / 2.0, h / 2.0, 0.0);
    // Far enough for the board to fill about 70 % of the narrower side of the frame.
    let base = 1.43 * w.max(h) * k[(0, 0)] / width.min(height) as f64;
    let mut rng = Rng::for_pixel(seed, u32::MAX - 1, 0);
    (0..views)
        .map(|i| {
            let f = i as f64;
            let azimuth = (f * 360.0 / views as f64 + 20.0 * rng.next_f32() as f64).to_radians();
            let elevation = (38.0 + 42.0 * ((f * 0.7).sin() * 0.5 + 0.5)).to_radians();
            let distance = base * (0.9 + 0.25 * rng.next_f32() as f64);
            let roll = (20.0 * (f * 1.3).sin()).to_radians();
            let aside = Vector3::new(0.16 * w * (f * 2.1).cos(), 0.16 * h * (f * 2.1).sin(), 0.0);
            let eye = centre
                + distance
                    * Vector3::new(elevation.cos() * azimuth.cos(), elevation.cos() * azimuth.sin(), elevation.sin());
            let up = Vector3::new(-roll.sin(), roll.cos(), 0.0);
            look_at(k, eye, centre + aside, up, width, height)
        })
        .collect()
}

/// A square table of [`TABLE_MM`] centred under `(x, y)`, just below the board, with a
/// granite-like texture (four octaves of value noise, the finest 2 texels: features at every
/// scale).
fn table_part(x: f64, y: f64) -> Part {
    let half = (TABLE_MM / 2.0) as f32;
    let (x, y) = (x as f32, y as f32);
    let corners = [[x - half, y - half], [x + half, y - half], [x + half, y + half], [x - half, y + half]];
    let uv = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let property = |name: &str, axis: usize| rmvp_dataset::mesh::VertexProperty {
        name: name.into(),
        kind: rmvp_dataset::mesh::ScalarKind::F32,
        values: uv.iter().map(|c: &[f64; 2]| c[axis]).collect(),
    };
    let mesh = Mesh {
        positions: corners.iter().map(|c| [c[0], c[1], -0.5]).collect(),
        normals: Some(vec![[0.0, 0.0, 1.0]; 4]),
        faces: vec![[0, 1, 2], [0, 2, 3]],
        vertex_properties: vec![property("u", 0), property("v", 1)],
    };
    Part {
        mesh,
        interface: Interface::Dielectric(1.5),
        lobes: Lobes::Lambertian,
        texture: Some(granite(TABLE_PX)),
        subject: false,
    }
}

/// Value noise of four octaves, as a neutral grey linear RGB albedo.
fn granite(size: usize) -> Image<f32> {
    let lattice = |cell: usize, seed: u64| -> Vec<f32> {
        let n = size / cell + 2;
        let mut rng = Rng::for_pixel(seed, 7, 0);
        (0..n * n).map(|_| rng.next_f32()).collect()
    };
    let octaves: Vec<(usize, Vec<f32>, f32)> = [(128, 0.35), (32, 0.3), (8, 0.2), (2, 0.15)]
        .iter()
        .enumerate()
        .map(|(k, &(c, a))| (c, lattice(c, k as u64), a))
        .collect();
    let mut data = Vec::with_capacity(size * size * 3);
    for y in 0..size {
        for x in 0..size {
            let mut v = 0.0;
            for (cell, grid, amplitude) in &octaves {
                let n = size / cell + 2;
                let (fx, fy) = (x as f32 / *cell as f32, y as f32 / *cell as f32);
                let (ix, iy) = (fx as usize, fy as usize);
                let (tx, ty) = (fx - ix as f32, fy - iy as f32);
                let at = |i: usize, j: usize| grid[j * n + i];
                let top = at(ix, iy) * (1.0 - tx) + at(ix + 1, iy) * tx;
                let bottom = at(ix, iy + 1) * (1.0 - tx) + at(ix + 1, iy + 1) * tx;
                v += amplitude * (top * (1.0 - ty) + bottom * ty);
            }
            let albedo = 0.08 + 0.5 * v;
            data.extend([albedo; 3]);
        }
    }
    Image::from_vec(size, size, 3, data).expect("sized")
}
