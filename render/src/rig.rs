//! Camera rigs: the real camera's intrinsics, look-at poses, sparse views on a sphere
//! (SMVP3D-like), turntable rings (RMVP3D-like) and explicit pose lists.

use crate::{Error, Result};
use nalgebra::{Matrix3, Vector3};
use rmvp_dataset::rng::Rng;
use rmvp_dataset::Camera;
use serde::Deserialize;
use std::path::Path;

/// Lens focal length of the lab rig, millimetres.
pub const FOCAL_MM: f64 = 12.0;
/// Effective pixel pitch after demosaicing (2 x 3.45 um), millimetres.
pub const PIXEL_PITCH_MM: f64 = 0.0069;
/// Image size after demosaicing.
pub const SENSOR_SIZE: (u32, u32) = (1224, 1024);

/// Intrinsics of the real rig (12 mm lens, 6.9 um pixels, 1224x1024) scaled to `width x height`.
pub fn rig_intrinsics(width: u32, height: u32) -> Matrix3<f64> {
    let f = FOCAL_MM / PIXEL_PITCH_MM * width as f64 / SENSOR_SIZE.0 as f64;
    Matrix3::new(f, 0.0, width as f64 / 2.0, 0.0, f, height as f64 / 2.0, 0.0, 0.0, 1.0)
}

/// A camera at `eye` looking at `target`, image "up" towards world `up`.
pub fn look_at(
    k: Matrix3<f64>,
    eye: Vector3<f64>,
    target: Vector3<f64>,
    up: Vector3<f64>,
    width: u32,
    height: u32,
) -> Camera {
    let z = (target - eye).normalize();
    let x = z.cross(&up).normalize();
    let y = z.cross(&x);
    let r = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    Camera::new(k, r, -(r * eye), width, height)
}

/// The distance at which a sphere of `radius` around the origin fills `fill` of the narrower
/// field of view of intrinsics `k` for an image of `width x height`.
pub fn framing_distance(k: &Matrix3<f64>, width: u32, height: u32, radius: f64, fill: f64) -> f64 {
    let half = (width.min(height) as f64 / 2.0) / k[(0, 0)].max(k[(1, 1)]);
    radius / (fill * half.atan()).sin()
}

/// The rigs a simulated capture can use, by name: each is a [`Rig`] for a number of views.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum RigKind {
    /// Sparse random views on a sphere (SMVP3D-like).
    #[default]
    Sphere,
    /// Two turntable rings, at 10 and 35 degrees of elevation (RMVP3D-like).
    Turntable,
}

/// Elevations of the lab turntable's two rings, degrees.
pub const TURNTABLE_ELEVATIONS_DEG: [f64; 2] = [10.0, 35.0];

impl RigKind {
    /// The rig of this kind with `views` cameras.
    pub fn rig(self, views: usize) -> Rig {
        match self {
            RigKind::Sphere => Rig::Sphere { views },
            RigKind::Turntable => Rig::Turntable { views, elevations: TURNTABLE_ELEVATIONS_DEG.to_vec() },
        }
    }
}

/// How to place the cameras.
#[derive(Clone, Debug, PartialEq)]
pub enum Rig {
    /// `views` random directions on the sphere (elevation -20 to 70 degrees), SMVP3D-like.
    Sphere {
        /// Number of views.
        views: usize,
    },
    /// `views` cameras evenly around the vertical axis, split over the elevations (degrees).
    Turntable {
        /// Number of views.
        views: usize,
        /// Ring elevations in degrees.
        elevations: Vec<f64>,
    },
}

impl Rig {
    /// World-space eye positions at `distance` from the origin, deterministic in `seed`.
    pub fn eyes(&self, distance: f64, seed: u64) -> Vec<Vector3<f64>> {
        let at = |azimuth: f64, elevation: f64| {
            let (se, ce) = elevation.sin_cos();
            Vector3::new(ce * azimuth.sin(), se, ce * azimuth.cos()) * distance
        };
        match self {
            Rig::Sphere { views } => {
                let mut rng = Rng::for_pixel(seed, u32::MAX, 0);
                (0..*views)
                    .map(|i| {
                        // Stratified in azimuth so that sparse views surround the object.
                        let azimuth = (i as f64 + rng.next_f32() as f64) / *views as f64 * std::f64::consts::TAU;
                        let (lo, hi) = ((-20f64).to_radians().sin(), 70f64.to_radians().sin());
                        let elevation = (lo + (hi - lo) * rng.next_f32() as f64).asin();
                        at(azimuth, elevation)
                    })
                    .collect()
            }
            Rig::Turntable { views, elevations } => {
                let rings = elevations.len().max(1);
                (0..*views)
                    .map(|i| {
                        let ring = i % rings;
                        let per_ring = views.div_ceil(rings);
                        let azimuth = (i / rings) as f64 / per_ring as f64 * std::f64::consts::TAU + ring as f64 * 0.3;
                        at(azimuth, elevations.get(ring).copied().unwrap_or(20.0).to_radians())
                    })
                    .collect()
            }
        }
    }

    /// Cameras of the rig looking at the origin, `+Y` up.
    pub fn cameras(&self, k: Matrix3<f64>, width: u32, height: u32, distance: f64, seed: u64) -> Vec<Camera> {
        self.eyes(distance, seed)
            .into_iter()
            .map(|eye| look_at(k, eye, Vector3::zeros(), Vector3::y(), width, height))
            .collect()
    }
}

/// One entry of a pose list: `r` and `t`, or `eye` and `target`, and optionally `k`.
#[derive(Deserialize)]
struct PoseRecord {
    r: Option<[[f64; 3]; 3]>,
    t: Option<[f64; 3]>,
    eye: Option<[f64; 3]>,
    target: Option<[f64; 3]>,
    /// Intrinsics of this camera; default: the rig's.
    k: Option<[[f64; 3]; 3]>,
}

/// Read an explicit pose list: a JSON array whose entries are `{"r": [[..]], "t": [..]}`
/// (world to camera) or `{"eye": [..], "target": [..]}` (+Y up), each optionally with its own
/// intrinsics `"k": [[..]]` (else `k`).
pub fn read_poses(path: &Path, k: Matrix3<f64>, width: u32, height: u32) -> Result<Vec<Camera>> {
    let text = rmvp_dataset::io::json::read_json_text(path)?;
    let poses: Vec<PoseRecord> =
        serde_json::from_str(&text).map_err(|e| rmvp_dataset::Error::format(path, format!("bad pose list: {e}")))?;
    poses
        .into_iter()
        .enumerate()
        .map(|(i, p)| {
            let k = p.k.as_ref().map_or(k, rmvp_dataset::camera::matrix_from_rows);
            let camera = match (p.r, p.t, p.eye, p.target) {
                (Some(r), Some(t), None, None) => {
                    Camera::new(k, rmvp_dataset::camera::matrix_from_rows(&r), Vector3::from(t), width, height)
                }
                (None, None, Some(eye), Some(target)) => {
                    look_at(k, Vector3::from(eye), Vector3::from(target), Vector3::y(), width, height)
                }
                _ => {
                    let why = format!("pose {i}: give either \"r\" and \"t\" or \"eye\" and \"target\"");
                    return Err(rmvp_dataset::Error::format(path, why).into());
                }
            };
            camera.validate().map_err(|source| Error::BadPose { path: path.to_path_buf(), index: i, source })?;
            Ok(camera)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    #[test]
    fn look_at_sees_the_target_upright() {
        let k = rig_intrinsics(1224, 1024);
        assert!((k[(0, 0)] - 1739.13).abs() < 0.01);
        let cam = look_at(k, Vector3::new(0.0, 0.5, 3.0), Vector3::zeros(), Vector3::y(), 1224, 1024);
        let centre = cam.project(&Point3::origin()).unwrap();
        assert!((centre.x - 612.0).abs() < 1e-9 && (centre.y - 512.0).abs() < 1e-9);
        // World up appears up in the image (smaller row).
        assert!(cam.project(&Point3::new(0.0, 0.3, 0.0)).unwrap().y < 512.0);
        assert!((cam.r.determinant() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn pose_lists_accept_extrinsics_look_at_and_own_intrinsics() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("poses.json");
        let text = r#"[{"eye": [0, 0, 3], "target": [0, 0, 0]},
                       {"r": [[1,0,0],[0,1,0],[0,0,1]], "t": [0, 0, 4], "k": [[50,0,32],[0,50,24],[0,0,1]]}]"#;
        std::fs::write(&path, text).unwrap();
        let cams = read_poses(&path, rig_intrinsics(64, 48), 64, 48).unwrap();
        assert!((cams[0].center().coords - Vector3::new(0.0, 0.0, 3.0)).norm() < 1e-12);
        assert_eq!(cams[1].k[(0, 0)], 50.0);
        assert_eq!(cams[0].k, rig_intrinsics(64, 48));
        std::fs::write(&path, r#"[{"r": [[2,0,0],[0,1,0],[0,0,1]], "t": [0, 0, 4]}]"#).unwrap();
        let err = read_poses(&path, rig_intrinsics(64, 48), 64, 48).unwrap_err();
        assert!(matches!(err, Error::BadPose { index: 0, .. }), "{err}");
        assert!(err.to_string().contains("not a rotation"), "{err}");
    }

    #[test]
    fn rigs_place_every_camera_at_the_distance() {
        for rig in [Rig::Sphere { views: 6 }, Rig::Turntable { views: 60, elevations: vec![10.0, 35.0] }] {
            let cams = rig.cameras(rig_intrinsics(128, 128), 128, 128, 3.5, 1);
            assert!(cams.iter().all(|c| (c.center().coords.norm() - 3.5).abs() < 1e-9));
            assert_eq!(cams.len(), if matches!(rig, Rig::Sphere { .. }) { 6 } else { 60 });
        }
        assert_eq!(Rig::Sphere { views: 6 }.eyes(3.0, 7), Rig::Sphere { views: 6 }.eyes(3.0, 7));
    }
}
