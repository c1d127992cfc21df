//! COLMAP sparse models (`cameras`, `images`, `points3D`), text or binary, as COLMAP 3.8 writes
//! them. COLMAP's cameras are OpenCV's (x right, y down, z forward, `x_cam = R x_world + t`,
//! `R` from the quaternion `QW QX QY QZ`) and its pixel centres are at +0.5, as rmvp's: no
//! conversion is needed.

use crate::camera::{Camera, Distortion};
use crate::io::{input, write_bytes_atomically};
use crate::{Error, Result};
use nalgebra::{Point3, Quaternion, UnitQuaternion, Vector3};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

/// The most keypoints, over all images, rmvp reads from a model: a model of one object (a few
/// hundred images of at most 8192 keypoints each, COLMAP's default) holds far fewer.
pub const MAX_KEYPOINTS: usize = 1 << 23;
/// The most 3D points rmvp reads from a model.
pub const MAX_POINTS: usize = 1 << 22;
/// The longest image name a binary model may hold, in bytes.
const MAX_NAME_BYTES: usize = 4096;
/// The most parameters a camera of a model rmvp does not know may have (COLMAP's largest has 12).
const MAX_CAMERA_PARAMS: usize = 16;

/// One camera (intrinsics) of a model.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapCamera {
    /// COLMAP's model name (`PINHOLE`, `OPENCV`, ...).
    pub model: String,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// The model's parameters in COLMAP's order.
    pub params: Vec<f64>,
}

/// One registered image of a model.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapImage {
    /// Image id.
    pub id: u32,
    /// World-to-camera rotation as a quaternion `(w, x, y, z)`.
    pub qvec: [f64; 4],
    /// World-to-camera translation.
    pub tvec: [f64; 3],
    /// Its camera's id.
    pub camera_id: u32,
    /// File name, relative to the image folder.
    pub name: String,
    /// Its keypoints: `(x, y, point3D id or -1)`.
    pub points2d: Vec<(f64, f64, i64)>,
}

/// A sparse model.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ColmapModel {
    /// Cameras by id.
    pub cameras: BTreeMap<u32, ColmapCamera>,
    /// Registered images.
    pub images: Vec<ColmapImage>,
    /// 3D points by id.
    pub points: BTreeMap<u64, [f64; 3]>,
}

/// COLMAP's camera models: id, name, parameter count.
const MODELS: [(i32, &str, usize); 11] = [
    (0, "SIMPLE_PINHOLE", 3),
    (1, "PINHOLE", 4),
    (2, "SIMPLE_RADIAL", 4),
    (3, "RADIAL", 5),
    (4, "OPENCV", 8),
    (5, "OPENCV_FISHEYE", 8),
    (6, "FULL_OPENCV", 12),
    (7, "FOV", 5),
    (8, "SIMPLE_RADIAL_FISHEYE", 4),
    (9, "RADIAL_FISHEYE", 5),
    (10, "THIN_PRISM_FISHEYE", 12),
];

impl ColmapCamera {
    /// Intrinsics and distortion as rmvp's camera (with `r`, `t` to complete it); `None` for
    /// fisheye and other models rmvp's OpenCV model cannot hold.
    fn intrinsics(&self) -> Option<(nalgebra::Matrix3<f64>, Option<Distortion>)> {
        let p = &self.params;
        let k = |fx: f64, fy: f64, cx: f64, cy: f64| nalgebra::Matrix3::new(fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0);
        let radial = |k1: f64, k2: f64, p1: f64, p2: f64| Some(Distortion { k1, k2, p1, p2, k3: 0.0 });
        Some(match self.model.as_str() {
            "SIMPLE_PINHOLE" => (k(p[0], p[0], p[1], p[2]), None),
            "PINHOLE" => (k(p[0], p[1], p[2], p[3]), None),
            "SIMPLE_RADIAL" => (k(p[0], p[0], p[1], p[2]), radial(p[3], 0.0, 0.0, 0.0)),
            "RADIAL" => (k(p[0], p[0], p[1], p[2]), radial(p[3], p[4], 0.0, 0.0)),
            "OPENCV" => (k(p[0], p[1], p[2], p[3]), radial(p[4], p[5], p[6], p[7])),
            _ => return None,
        })
    }

    /// The `OPENCV` camera of rmvp's `camera` (its intrinsics and distortion).
    pub fn opencv(camera: &Camera) -> Self {
        let k = &camera.k;
        let d = camera.distortion.unwrap_or(Distortion { k1: 0.0, k2: 0.0, p1: 0.0, p2: 0.0, k3: 0.0 });
        Self {
            model: "OPENCV".into(),
            width: camera.width,
            height: camera.height,
            params: vec![k[(0, 0)], k[(1, 1)], k[(0, 2)], k[(1, 2)], d.k1, d.k2, d.p1, d.p2],
        }
    }
}

impl ColmapImage {
    /// The world-to-camera rotation.
    pub fn rotation(&self) -> nalgebra::Matrix3<f64> {
        let [w, x, y, z] = self.qvec;
        UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)).to_rotation_matrix().into_inner()
    }
}

impl ColmapModel {
    /// Read the model in `dir`: `cameras.bin`, `images.bin`, `points3D.bin` if present, else the
    /// `.txt` files.
    pub fn read(dir: &Path) -> Result<Self> {
        if dir.join("images.bin").is_file() {
            Ok(Self {
                cameras: read_cameras_bin(&dir.join("cameras.bin"))?,
                images: read_images_bin(&dir.join("images.bin"))?,
                points: read_points_bin(&dir.join("points3D.bin"))?,
            })
        } else if dir.join("images.txt").is_file() {
            Ok(Self {
                cameras: read_cameras_txt(&dir.join("cameras.txt"))?,
                images: read_images_txt(&dir.join("images.txt"))?,
                points: read_points_txt(&dir.join("points3D.txt"))?,
            })
        } else {
            Err(Error::format(dir, "not a COLMAP model: neither images.bin nor images.txt"))
        }
    }

    /// Every registered image as rmvp's camera, by image name; images of camera models rmvp
    /// cannot hold are an error naming the model.
    pub fn cameras(&self, dir: &Path) -> Result<Vec<(String, Camera)>> {
        self.images
            .iter()
            .map(|image| {
                let c = self.cameras.get(&image.camera_id).ok_or_else(|| {
                    Error::format(
                        dir,
                        format!("image {} uses camera {}, which is not in the model", image.name, image.camera_id),
                    )
                })?;
                let (k, distortion) = c.intrinsics().ok_or_else(|| {
                    Error::format(dir, format!("camera model {} is not an OpenCV pinhole model rmvp reads", c.model))
                })?;
                let mut camera = Camera::new(k, image.rotation(), Vector3::from(image.tvec), c.width, c.height);
                camera.distortion = distortion;
                camera.validate().map_err(|e| Error::format(dir, format!("image {}: {e}", image.name)))?;
                Ok((image.name.clone(), camera))
            })
            .collect()
    }

    /// RMS reprojection error (pixels) and the number of triangulated keypoints of image `i`.
    pub fn residual(&self, i: usize, camera: &Camera) -> (f64, usize) {
        let (mut sum, mut n) = (0.0, 0usize);
        for &(x, y, id) in &self.images[i].points2d {
            let Some(p) = (id >= 0).then(|| self.points.get(&(id as u64))).flatten() else { continue };
            if let Some(q) = camera.project(&Point3::from(*p)) {
                sum += (q.x - x).powi(2) + (q.y - y).powi(2);
                n += 1;
            }
        }
        (if n > 0 { (sum / n as f64).sqrt() } else { f64::NAN }, n)
    }

    /// Write the model as text into `dir` (created): `cameras.txt`, `images.txt` (keypoints
    /// included), `points3D.txt` (points without tracks).
    pub fn write_text(&self, dir: &Path) -> Result<()> {
        let mut cameras = String::from("# CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n");
        for (id, c) in &self.cameras {
            let params: Vec<String> = c.params.iter().map(|p| format!("{p:.17}")).collect();
            cameras += &format!("{id} {} {} {} {}\n", c.model, c.width, c.height, params.join(" "));
        }
        let mut images = String::from(
            "# IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n# POINTS2D[] as (X, Y, POINT3D_ID)\n",
        );
        for i in &self.images {
            let [w, x, y, z] = i.qvec;
            let [tx, ty, tz] = i.tvec;
            images += &format!(
                "{} {w:.17} {x:.17} {y:.17} {z:.17} {tx:.17} {ty:.17} {tz:.17} {} {}\n",
                i.id, i.camera_id, i.name
            );
            let points: Vec<String> = i.points2d.iter().map(|(x, y, id)| format!("{x} {y} {id}")).collect();
            images += &points.join(" ");
            images += "\n";
        }
        let mut points = String::from("# POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n");
        for (id, p) in &self.points {
            points += &format!("{id} {} {} {} 128 128 128 0\n", p[0], p[1], p[2]);
        }
        write_bytes_atomically(&dir.join("cameras.txt"), cameras.as_bytes())?;
        write_bytes_atomically(&dir.join("images.txt"), images.as_bytes())?;
        write_bytes_atomically(&dir.join("points3D.txt"), points.as_bytes())
    }

    /// A model of `cameras` (name, camera), one `OPENCV` camera each, no points.
    pub fn from_cameras(cameras: &[(String, Camera)]) -> Self {
        let mut model = Self::default();
        for (k, (name, camera)) in cameras.iter().enumerate() {
            let id = k as u32 + 1;
            model.cameras.insert(id, ColmapCamera::opencv(camera));
            let q = UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(camera.r));
            model.images.push(ColmapImage {
                id,
                qvec: [q.w, q.i, q.j, q.k],
                tvec: [camera.t.x, camera.t.y, camera.t.z],
                camera_id: id,
                name: name.clone(),
                points2d: Vec::new(),
            });
        }
        model
    }
}

fn model_by_id(path: &Path, id: i32) -> Result<(&'static str, usize)> {
    MODELS
        .iter()
        .find(|m| m.0 == id)
        .map(|m| (m.1, m.2))
        .ok_or_else(|| Error::format(path, format!("unknown camera model id {id}")))
}

/// A binary model file read in order, every count checked against the bytes left before
/// anything is allocated for it.
struct Bytes<'a> {
    path: &'a Path,
    reader: BufReader<File>,
    at: u64,
    len: u64,
}

impl<'a> Bytes<'a> {
    fn open(path: &'a Path) -> Result<Self> {
        let file = input::open_regular(path)?;
        let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
        Ok(Self { path, reader: BufReader::new(file), at: 0, len })
    }

    fn truncated(&self) -> Error {
        Error::format(self.path, format!("truncated at byte {}", self.at))
    }

    fn take<const N: usize>(&mut self) -> Result<[u8; N]> {
        let mut bytes = [0; N];
        self.reader.read_exact(&mut bytes).map_err(|_| self.truncated())?;
        self.at += N as u64;
        Ok(bytes)
    }

    /// Pass over `n` bytes.
    fn skip(&mut self, n: u64) -> Result<()> {
        if n > self.len.saturating_sub(self.at) {
            return Err(self.truncated());
        }
        self.reader.seek_relative(n as i64).map_err(|e| Error::io(self.path, e))?;
        self.at += n;
        Ok(())
    }

    fn u64(&mut self) -> Result<u64> {
        Ok(u64::from_le_bytes(self.take()?))
    }

    fn i64(&mut self) -> Result<i64> {
        Ok(i64::from_le_bytes(self.take()?))
    }

    fn i32(&mut self) -> Result<i32> {
        Ok(i32::from_le_bytes(self.take()?))
    }

    fn f64(&mut self) -> Result<f64> {
        Ok(f64::from_le_bytes(self.take()?))
    }

    /// A NUL-terminated image name of at most [`MAX_NAME_BYTES`].
    fn string(&mut self) -> Result<String> {
        let mut bytes = Vec::new();
        let limit = MAX_NAME_BYTES as u64 + 1;
        (&mut self.reader).take(limit).read_until(0, &mut bytes).map_err(|e| Error::io(self.path, e))?;
        self.at += bytes.len() as u64;
        if bytes.last() != Some(&0) {
            let why = if bytes.len() as u64 == limit {
                format!("an image name longer than {MAX_NAME_BYTES} bytes")
            } else {
                "unterminated image name".to_string()
            };
            return Err(Error::format(self.path, why));
        }
        bytes.pop();
        Ok(String::from_utf8_lossy(&bytes).into_owned())
    }

    /// A count of items of at least `size` bytes each, checked against what is left.
    fn count(&mut self, size: u64) -> Result<usize> {
        let n = self.u64()?;
        if n.saturating_mul(size) > self.len.saturating_sub(self.at) {
            return Err(Error::format(self.path, format!("claims {n} entries, more than the file holds")));
        }
        Ok(n as usize)
    }
}

/// Refuse a model with more than `limit` `what` (keypoints, points), naming its file.
fn check_total(path: &Path, total: usize, limit: usize, what: &str) -> Result<()> {
    if total > limit {
        let why =
            format!("holds more than the {limit} {what} rmvp reads from a model (a model of one object has far fewer)");
        return Err(Error::format(path, why));
    }
    Ok(())
}

fn read_cameras_bin(path: &Path) -> Result<BTreeMap<u32, ColmapCamera>> {
    let mut b = Bytes::open(path)?;
    let n = b.count(24)?;
    let mut cameras = BTreeMap::new();
    for _ in 0..n {
        let id = b.i32()? as u32;
        let (model, count) = model_by_id(path, b.i32()?)?;
        let (width, height) = (b.u64()? as u32, b.u64()? as u32);
        let params = (0..count).map(|_| b.f64()).collect::<Result<_>>()?;
        cameras.insert(id, ColmapCamera { model: model.into(), width, height, params });
    }
    Ok(cameras)
}

fn read_images_bin(path: &Path) -> Result<Vec<ColmapImage>> {
    let mut b = Bytes::open(path)?;
    let n = b.count(64)?;
    let mut images = Vec::with_capacity(n);
    let mut keypoints = 0;
    for _ in 0..n {
        let id = b.i32()? as u32;
        let qvec = [b.f64()?, b.f64()?, b.f64()?, b.f64()?];
        let tvec = [b.f64()?, b.f64()?, b.f64()?];
        let camera_id = b.i32()? as u32;
        let name = b.string()?;
        let count = b.count(24)?;
        keypoints += count;
        check_total(path, keypoints, MAX_KEYPOINTS, "keypoints")?;
        let points2d = (0..count).map(|_| Ok((b.f64()?, b.f64()?, b.i64()?))).collect::<Result<_>>()?;
        images.push(ColmapImage { id, qvec, tvec, camera_id, name, points2d });
    }
    Ok(images)
}

fn read_points_bin(path: &Path) -> Result<BTreeMap<u64, [f64; 3]>> {
    if !path.is_file() {
        return Ok(BTreeMap::new());
    }
    let mut b = Bytes::open(path)?;
    let n = b.count(43)?;
    check_total(path, n, MAX_POINTS, "3D points")?;
    let mut points = BTreeMap::new();
    for _ in 0..n {
        let id = b.u64()?;
        let p = [b.f64()?, b.f64()?, b.f64()?];
        let _rgb: [u8; 3] = b.take()?;
        let _error = b.f64()?;
        let track = b.count(8)?;
        b.skip(track as u64 * 8)?;
        points.insert(id, p);
    }
    Ok(points)
}

/// The non-comment lines of a text model file, numbered from 1.
fn lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines().enumerate().filter(|(_, l)| !l.starts_with('#')).map(|(i, l)| (i + 1, l))
}

/// The first `n` whitespace-separated fields of `line` and the rest of it, trimmed; `None`
/// when it has fewer.
fn fields(line: &str, n: usize) -> Option<(Vec<&str>, &str)> {
    let mut rest = line.trim_start();
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let end = rest.find(char::is_whitespace).unwrap_or(rest.len());
        if end == 0 {
            return None;
        }
        out.push(&rest[..end]);
        rest = rest[end..].trim_start();
    }
    Some((out, rest.trim_end()))
}

fn parse<T: std::str::FromStr>(path: &Path, line: usize, field: &str) -> Result<T> {
    field.parse().map_err(|_| Error::format(path, format!("line {line}: {field:?} is not a number")))
}

fn read_cameras_txt(path: &Path) -> Result<BTreeMap<u32, ColmapCamera>> {
    let text = input::read_text(path)?;
    let mut cameras = BTreeMap::new();
    for (n, line) in lines(&text).filter(|(_, l)| !l.trim().is_empty()) {
        let Some((f, rest)) = fields(line, 4) else {
            return Err(Error::format(path, format!("line {n}: expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS")));
        };
        let params: Vec<&str> = rest.split_whitespace().take(MAX_CAMERA_PARAMS + 1).collect();
        let count = MODELS.iter().find(|m| m.1 == f[1]).map_or(params.len().min(MAX_CAMERA_PARAMS), |m| m.2);
        if params.len() != count {
            return Err(Error::format(path, format!("line {n}: {} needs {count} parameters", f[1])));
        }
        let params = params.iter().map(|v| parse(path, n, v)).collect::<Result<_>>()?;
        let camera =
            ColmapCamera { model: f[1].into(), width: parse(path, n, f[2])?, height: parse(path, n, f[3])?, params };
        cameras.insert(parse(path, n, f[0])?, camera);
    }
    Ok(cameras)
}

fn read_images_txt(path: &Path) -> Result<Vec<ColmapImage>> {
    let text = input::read_text(path)?;
    let mut lines = lines(&text);
    let mut images = Vec::new();
    let mut keypoints = 0;
    while let Some((n, header)) = lines.next() {
        let keypoint_line = lines.next();
        if header.trim().is_empty() {
            continue;
        }
        let Some((f, name)) = fields(header, 9).filter(|(_, name)| !name.is_empty()) else {
            return Err(Error::format(
                path,
                format!("line {n}: expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME"),
            ));
        };
        let number = |k: usize| parse::<f64>(path, n, f[k]);
        let mut points2d = Vec::new();
        if let Some((m, line)) = keypoint_line {
            let values = line.split_whitespace().count();
            if values % 3 != 0 {
                return Err(Error::format(path, format!("line {m}: keypoints come in threes (X Y POINT3D_ID)")));
            }
            keypoints += values / 3;
            check_total(path, keypoints, MAX_KEYPOINTS, "keypoints")?;
            points2d.reserve_exact(values / 3);
            let mut v = line.split_whitespace();
            while let (Some(x), Some(y), Some(id)) = (v.next(), v.next(), v.next()) {
                points2d.push((parse(path, m, x)?, parse(path, m, y)?, parse(path, m, id)?));
            }
        }
        images.push(ColmapImage {
            id: parse(path, n, f[0])?,
            qvec: [number(1)?, number(2)?, number(3)?, number(4)?],
            tvec: [number(5)?, number(6)?, number(7)?],
            camera_id: parse(path, n, f[8])?,
            name: name.to_string(),
            points2d,
        });
    }
    Ok(images)
}

fn read_points_txt(path: &Path) -> Result<BTreeMap<u64, [f64; 3]>> {
    if !path.is_file() {
        return Ok(BTreeMap::new());
    }
    let text = input::read_text(path)?;
    let mut points = BTreeMap::new();
    for (n, line) in lines(&text).filter(|(_, l)| !l.trim().is_empty()) {
        let Some((f, _)) = fields(line, 4) else {
            return Err(Error::format(path, format!("line {n}: expected POINT3D_ID X Y Z ...")));
        };
        points.insert(parse(path, n, f[0])?, [parse(path, n, f[1])?, parse(path, n, f[2])?, parse(path, n, f[3])?]);
        check_total(path, points.len(), MAX_POINTS, "3D points")?;
    }
    Ok(points)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Rotation3};

    #[test]
    fn text_models_round_trip_cameras() {
        let r = *Rotation3::from_euler_angles(0.3, -0.5, 0.2).matrix();
        let mut camera = Camera::new(
            Matrix3::new(1700.0, 0.0, 611.5, 0.0, 1702.0, 513.0, 0.0, 0.0, 1.0),
            r,
            Vector3::new(0.1, -2.0, 400.0),
            1224,
            1024,
        );
        camera.distortion = Some(Distortion { k1: -0.1, k2: 0.02, p1: 0.001, p2: -0.002, k3: 0.0 });
        let dir = tempfile::tempdir().unwrap();
        ColmapModel::from_cameras(&[("000.png".into(), camera.clone())]).write_text(dir.path()).unwrap();
        let model = ColmapModel::read(dir.path()).unwrap();
        let back = &model.cameras(dir.path()).unwrap()[0];
        assert_eq!(back.0, "000.png");
        assert!((back.1.r - camera.r).abs().max() < 1e-12 && (back.1.t - camera.t).abs().max() < 1e-9);
        assert!((back.1.k - camera.k).abs().max() < 1e-9 && back.1.distortion == camera.distortion);
        std::fs::write(dir.path().join("cameras.txt"), "1 OPENCV 1224 1024 1700 1702 611.5\n").unwrap();
        let err = ColmapModel::read(dir.path()).unwrap_err().to_string();
        assert!(err.contains("cameras.txt") && err.contains("line 1: OPENCV needs 8 parameters"), "{err}");
    }
}
