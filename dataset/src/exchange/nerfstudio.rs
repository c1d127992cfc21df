//! nerfstudio's `transforms.json`: camera-to-world matrices in the OpenGL convention (x right,
//! y up, z backwards) and intrinsics (global or per frame) with pixel centres at +0.5, as
//! rmvp's. Reading and writing turn the camera axes: `c2w_opencv = c2w_opengl diag(1, -1, -1)`.
//!
//! The intrinsics sit in the same objects as the frame's other fields; they are read field by
//! field, unknown fields skipped unkept and a field given twice refused (see
//! [`io::json`](crate::io::json) on what reading may cost).

use crate::camera::{Camera, Distortion};
use crate::io::json::{read_json, write_json};
use crate::{Error, Result};
use nalgebra::{Matrix3, Matrix4, Vector3};
use serde::de::{Error as _, IgnoredAny, MapAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize};
use std::path::Path;

/// Intrinsics as nerfstudio names them (all optional: per frame they override the file's).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Intrinsics {
    /// Focal length x, pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fl_x: Option<f64>,
    /// Focal length y, pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fl_y: Option<f64>,
    /// Principal point x.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cx: Option<f64>,
    /// Principal point y.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cy: Option<f64>,
    /// Image width.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub w: Option<u32>,
    /// Image height.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub h: Option<u32>,
    /// OpenCV radial and tangential coefficients.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k1: Option<f64>,
    /// See `k1`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k2: Option<f64>,
    /// See `k1`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k3: Option<f64>,
    /// See `k1`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub p1: Option<f64>,
    /// See `k1`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub p2: Option<f64>,
}

/// One frame.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Frame {
    /// Image, relative to the file.
    pub file_path: String,
    /// Camera to world, OpenGL axes, row-major.
    pub transform_matrix: [[f64; 4]; 4],
    /// Object mask, relative to the file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mask_path: Option<String>,
    /// Intrinsics of this frame, overriding the file's.
    #[serde(flatten)]
    pub intrinsics: Intrinsics,
}

/// A `transforms.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Transforms {
    /// `OPENCV` (nerfstudio's name of the pinhole model with OpenCV distortion).
    #[serde(default = "opencv")]
    pub camera_model: String,
    /// Intrinsics shared by the frames.
    #[serde(flatten)]
    pub intrinsics: Intrinsics,
    /// The frames.
    pub frames: Vec<Frame>,
    /// Images of the training split (nerfstudio takes a 0.9 fraction of the frames without it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub train_filenames: Option<Vec<String>>,
    /// Images of the evaluation split.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub val_filenames: Option<Vec<String>>,
}

/// How closely intrinsics must agree to be written once for all frames (relative).
pub const SHARED_INTRINSICS_TOLERANCE: f64 = 1e-9;

fn opencv() -> String {
    "OPENCV".into()
}

/// OpenGL camera axes to OpenCV's (and back: the same matrix).
fn flip() -> Matrix3<f64> {
    Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0))
}

impl Intrinsics {
    fn of(camera: &Camera) -> Self {
        let d = camera.distortion;
        Self {
            fl_x: Some(camera.k[(0, 0)]),
            fl_y: Some(camera.k[(1, 1)]),
            cx: Some(camera.k[(0, 2)]),
            cy: Some(camera.k[(1, 2)]),
            w: Some(camera.width),
            h: Some(camera.height),
            k1: d.map(|d| d.k1),
            k2: d.map(|d| d.k2),
            k3: d.map(|d| d.k3),
            p1: d.map(|d| d.p1),
            p2: d.map(|d| d.p2),
        }
    }

    /// Read the value of `key` into the field it names; `false` when it names none.
    fn read_field<'de, A: MapAccess<'de>>(&mut self, key: &str, map: &mut A) -> std::result::Result<bool, A::Error> {
        match key {
            "fl_x" => set(&mut self.fl_x, key, map),
            "fl_y" => set(&mut self.fl_y, key, map),
            "cx" => set(&mut self.cx, key, map),
            "cy" => set(&mut self.cy, key, map),
            "w" => set(&mut self.w, key, map),
            "h" => set(&mut self.h, key, map),
            "k1" => set(&mut self.k1, key, map),
            "k2" => set(&mut self.k2, key, map),
            "k3" => set(&mut self.k3, key, map),
            "p1" => set(&mut self.p1, key, map),
            "p2" => set(&mut self.p2, key, map),
            _ => Ok(false),
        }
    }

    /// Whether `self` and `other` agree to [`SHARED_INTRINSICS_TOLERANCE`] (relative), sizes
    /// exactly.
    fn agrees_with(&self, other: &Intrinsics) -> bool {
        let close = |a: Option<f64>, b: Option<f64>| match (a, b) {
            (Some(a), Some(b)) => (a - b).abs() <= SHARED_INTRINSICS_TOLERANCE * a.abs().max(b.abs()).max(1.0),
            (a, b) => a == b,
        };
        self.w == other.w
            && self.h == other.h
            && [
                (self.fl_x, other.fl_x),
                (self.fl_y, other.fl_y),
                (self.cx, other.cx),
                (self.cy, other.cy),
                (self.k1, other.k1),
                (self.k2, other.k2),
                (self.k3, other.k3),
                (self.p1, other.p1),
                (self.p2, other.p2),
            ]
            .into_iter()
            .all(|(a, b)| close(a, b))
    }

    /// `self`, each missing value taken from `shared`.
    fn or(&self, shared: &Intrinsics) -> Intrinsics {
        Intrinsics {
            fl_x: self.fl_x.or(shared.fl_x),
            fl_y: self.fl_y.or(shared.fl_y),
            cx: self.cx.or(shared.cx),
            cy: self.cy.or(shared.cy),
            w: self.w.or(shared.w),
            h: self.h.or(shared.h),
            k1: self.k1.or(shared.k1),
            k2: self.k2.or(shared.k2),
            k3: self.k3.or(shared.k3),
            p1: self.p1.or(shared.p1),
            p2: self.p2.or(shared.p2),
        }
    }
}

/// Read the next value of `map` into `field`, refusing a field given twice.
fn set<'de, T: Deserialize<'de>, A: MapAccess<'de>>(
    field: &mut Option<T>,
    key: &str,
    map: &mut A,
) -> std::result::Result<bool, A::Error> {
    if field.is_some() {
        return Err(A::Error::custom(format!("field `{key}` given twice")));
    }
    *field = map.next_value()?;
    Ok(true)
}

/// Read a JSON object field by field: `read(key, map)` takes the value of a field it knows and
/// says so; the values of the others are skipped.
fn visit_fields<'de, A: MapAccess<'de>>(
    mut map: A,
    mut read: impl FnMut(&str, &mut A) -> std::result::Result<bool, A::Error>,
) -> std::result::Result<(), A::Error> {
    while let Some(key) = map.next_key::<String>()? {
        if !read(&key, &mut map)? {
            map.next_value::<IgnoredAny>()?;
        }
    }
    Ok(())
}

impl<'de> Deserialize<'de> for Frame {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> std::result::Result<Self, D::Error> {
        struct FrameVisitor;
        impl<'de> Visitor<'de> for FrameVisitor {
            type Value = Frame;

            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a frame object")
            }

            fn visit_map<A: MapAccess<'de>>(self, map: A) -> std::result::Result<Frame, A::Error> {
                let (mut file_path, mut transform_matrix, mut mask_path) = (None, None, None);
                let mut intrinsics = Intrinsics::default();
                visit_fields(map, |key, map| match key {
                    "file_path" => set(&mut file_path, key, map),
                    "transform_matrix" => set(&mut transform_matrix, key, map),
                    "mask_path" => set(&mut mask_path, key, map),
                    _ => intrinsics.read_field(key, map),
                })?;
                Ok(Frame {
                    file_path: file_path.ok_or_else(|| A::Error::missing_field("file_path"))?,
                    transform_matrix: transform_matrix.ok_or_else(|| A::Error::missing_field("transform_matrix"))?,
                    mask_path,
                    intrinsics,
                })
            }
        }
        deserializer.deserialize_map(FrameVisitor)
    }
}

impl<'de> Deserialize<'de> for Transforms {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> std::result::Result<Self, D::Error> {
        struct TransformsVisitor;
        impl<'de> Visitor<'de> for TransformsVisitor {
            type Value = Transforms;

            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a transforms object")
            }

            fn visit_map<A: MapAccess<'de>>(self, map: A) -> std::result::Result<Transforms, A::Error> {
                let (mut camera_model, mut frames, mut train_filenames, mut val_filenames) = (None, None, None, None);
                let mut intrinsics = Intrinsics::default();
                visit_fields(map, |key, map| match key {
                    "camera_model" => set(&mut camera_model, key, map),
                    "frames" => set(&mut frames, key, map),
                    "train_filenames" => set(&mut train_filenames, key, map),
                    "val_filenames" => set(&mut val_filenames, key, map),
                    _ => intrinsics.read_field(key, map),
                })?;
                Ok(Transforms {
                    camera_model: camera_model.unwrap_or_else(opencv),
                    intrinsics,
                    frames: frames.ok_or_else(|| A::Error::missing_field("frames"))?,
                    train_filenames,
                    val_filenames,
                })
            }
        }
        deserializer.deserialize_map(TransformsVisitor)
    }
}

impl Transforms {
    /// The transforms of `cameras` (image path, mask path, camera), intrinsics written once at
    /// the top level when every frame's agree with the first's to
    /// [`SHARED_INTRINSICS_TOLERANCE`].
    pub fn from_cameras(cameras: &[(String, Option<String>, Camera)]) -> Self {
        let all: Vec<Intrinsics> = cameras.iter().map(|(_, _, c)| Intrinsics::of(c)).collect();
        let shared = all.iter().all(|i| i.agrees_with(&all[0]));
        let frames = cameras
            .iter()
            .zip(&all)
            .map(|((file, mask, camera), intrinsics)| {
                let mut c2w = Matrix4::identity();
                c2w.fixed_view_mut::<3, 3>(0, 0).copy_from(&(camera.r.transpose() * flip()));
                c2w.fixed_view_mut::<3, 1>(0, 3).copy_from(&camera.center().coords);
                Frame {
                    file_path: file.clone(),
                    transform_matrix: [0, 1, 2, 3].map(|i| [0, 1, 2, 3].map(|j| c2w[(i, j)])),
                    mask_path: mask.clone(),
                    intrinsics: if shared { Intrinsics::default() } else { intrinsics.clone() },
                }
            })
            .collect();
        let intrinsics = if shared { all.first().cloned().unwrap_or_default() } else { Intrinsics::default() };
        Self { camera_model: opencv(), intrinsics, frames, train_filenames: None, val_filenames: None }
    }

    /// The same frames with the split written out: `train` and `val` are image paths as in the
    /// frames.
    pub fn with_split(self, train: Vec<String>, val: Vec<String>) -> Self {
        Self { train_filenames: Some(train), val_filenames: Some(val), ..self }
    }

    /// Every frame's camera, named by its image's file stem.
    pub fn cameras(&self, path: &Path) -> Result<Vec<(String, Camera)>> {
        self.frames
            .iter()
            .map(|frame| {
                let i = frame.intrinsics.or(&self.intrinsics);
                let missing = |what: &str| Error::format(path, format!("frame {}: no {what}", frame.file_path));
                let (fx, cx, cy) = (
                    i.fl_x.ok_or_else(|| missing("fl_x"))?,
                    i.cx.ok_or_else(|| missing("cx"))?,
                    i.cy.ok_or_else(|| missing("cy"))?,
                );
                let k = Matrix3::new(fx, 0.0, cx, 0.0, i.fl_y.unwrap_or(fx), cy, 0.0, 0.0, 1.0);
                let c2w = Matrix4::from_fn(|r, c| frame.transform_matrix[r][c]);
                let rotation = c2w.fixed_view::<3, 3>(0, 0) * flip();
                let r = rotation.transpose();
                let t = -(r * c2w.fixed_view::<3, 1>(0, 3));
                let mut camera =
                    Camera::new(k, r, t, i.w.ok_or_else(|| missing("w"))?, i.h.ok_or_else(|| missing("h"))?);
                if [i.k1, i.k2, i.k3, i.p1, i.p2].iter().any(Option::is_some) {
                    let v = |x: Option<f64>| x.unwrap_or(0.0);
                    camera.distortion =
                        Some(Distortion { k1: v(i.k1), k2: v(i.k2), p1: v(i.p1), p2: v(i.p2), k3: v(i.k3) });
                }
                camera.validate().map_err(|e| Error::format(path, format!("frame {}: {e}", frame.file_path)))?;
                let name = Path::new(&frame.file_path)
                    .file_stem()
                    .map_or_else(|| frame.file_path.clone(), |s| s.to_string_lossy().into_owned());
                Ok((name, camera))
            })
            .collect()
    }

    /// Read `transforms.json`.
    pub fn read(path: &Path) -> Result<Self> {
        read_json(path, "a nerfstudio transforms.json")
    }

    /// Write `transforms.json` atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        write_json(path, self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    #[test]
    fn transforms_round_trip_cameras_through_opengl_axes() {
        let r = *Rotation3::from_euler_angles(0.2, 0.7, -0.4).matrix();
        let camera = Camera::new(
            Matrix3::new(900.0, 0.0, 320.0, 0.0, 905.0, 250.0, 0.0, 0.0, 1.0),
            r,
            Vector3::new(1.0, 2.0, 3.0),
            640,
            512,
        );
        let t = Transforms::from_cameras(&[("images/007.png".into(), None, camera.clone())]);
        // OpenGL: the camera looks down its -z; OpenCV's +z is the viewing direction.
        let c2w = Matrix4::from_fn(|i, j| t.frames[0].transform_matrix[i][j]);
        let forward = -c2w.fixed_view::<3, 1>(0, 2).into_owned();
        assert!((forward - camera.r.transpose() * Vector3::z()).norm() < 1e-12);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("transforms.json");
        t.write(&path).unwrap();
        let back = Transforms::read(&path).unwrap().cameras(&path).unwrap();
        assert_eq!(back[0].0, "007");
        assert!((back[0].1.r - camera.r).abs().max() < 1e-12 && (back[0].1.t - camera.t).abs().max() < 1e-12);
        assert_eq!(back[0].1.k, camera.k);
    }

    #[test]
    fn intrinsics_are_shared_when_they_agree_to_the_tolerance_and_the_split_is_written() {
        let camera = |fx: f64, t: f64| {
            let k = Matrix3::new(fx, 0.0, 611.5, 0.0, 1700.0, 511.5, 0.0, 0.0, 1.0);
            Camera::new(k, Matrix3::identity(), Vector3::new(t, 0.0, 3.0), 1224, 1024)
        };
        let frames = |fx2: f64| {
            vec![
                ("images/000.png".to_string(), None, camera(1700.0, 0.0)),
                ("images/001.png".into(), None, camera(fx2, 0.1)),
            ]
        };
        let shared = Transforms::from_cameras(&frames(1700.0 * (1.0 + 1e-12)));
        assert_eq!(shared.intrinsics.fl_x, Some(1700.0));
        assert!(shared.frames.iter().all(|f| f.intrinsics == Intrinsics::default()));
        let apart = Transforms::from_cameras(&frames(1700.0 * (1.0 + 1e-6)));
        assert_eq!(apart.intrinsics, Intrinsics::default());
        assert_eq!(apart.frames[1].intrinsics.fl_x, Some(1700.0 * (1.0 + 1e-6)));

        let split = shared.with_split(vec!["images/000.png".into()], vec!["images/001.png".into()]);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("transforms.json");
        split.write(&path).unwrap();
        let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        assert_eq!(json["train_filenames"], serde_json::json!(["images/000.png"]));
        assert_eq!(json["val_filenames"], serde_json::json!(["images/001.png"]));
        assert_eq!(json["fl_x"], serde_json::json!(1700.0));
        assert_eq!(Transforms::read(&path).unwrap(), split);
    }
}
