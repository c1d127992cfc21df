//! Pinhole cameras in the OpenCV convention.
//!
//! - Camera frame: x right, y down, z forward; `x_cam = R x_world + t`.
//! - Pixel coordinates are continuous; pixel `(i, j)` (column, row) has its centre at
//!   `(i + 0.5, j + 0.5)`.
//! - `K` maps camera-frame directions to pixels: `(u, v, 1) ~ K (x/z, y/z, 1)`, with optional
//!   OpenCV distortion applied to the normalised coordinates `(x/z, y/z)` first.

use crate::{Error, Result};
use nalgebra::{Matrix3, Matrix3x4, Point2, Point3, Vector3};
use serde::{Deserialize, Serialize};

/// OpenCV lens distortion `(k1, k2, p1, p2, k3)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Distortion {
    /// Radial coefficients k1, k2, k3.
    pub k1: f64,
    /// Second radial coefficient.
    pub k2: f64,
    /// Tangential coefficient p1.
    pub p1: f64,
    /// Tangential coefficient p2.
    pub p2: f64,
    /// Third radial coefficient.
    pub k3: f64,
}

impl Distortion {
    /// Distort normalised coordinates `(x, y)` (OpenCV `projectPoints` model).
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        (
            x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        )
    }

    /// Invert [`Distortion::distort`] by fixed-point iteration (as OpenCV `undistortPoints`),
    /// run until it converges to 1e-12 or for 50 iterations.
    pub fn undistort(&self, xd: f64, yd: f64) -> (f64, f64) {
        let (mut x, mut y) = (xd, yd);
        for _ in 0..50 {
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
            let dx = 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
            let dy = self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
            let (nx, ny) = ((xd - dx) / radial, (yd - dy) / radial);
            let step = (nx - x).abs().max((ny - y).abs());
            (x, y) = (nx, ny);
            if step < 1e-12 {
                break;
            }
        }
        (x, y)
    }
}

/// A ray `origin + s * direction`, `direction` of unit length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start point (the camera centre for camera rays).
    pub origin: Point3<f64>,
    /// Unit direction.
    pub direction: Vector3<f64>,
}

/// A calibrated pinhole camera with its image size.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Intrinsic matrix K (upper triangular, positive focal lengths, `K[2][2] = 1`).
    pub k: Matrix3<f64>,
    /// Optional lens distortion.
    pub distortion: Option<Distortion>,
    /// World-to-camera rotation R (proper: `det R = +1`).
    pub r: Matrix3<f64>,
    /// World-to-camera translation t.
    pub t: Vector3<f64>,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

impl Camera {
    /// A camera from K, R, t and image size, without distortion.
    pub fn new(k: Matrix3<f64>, r: Matrix3<f64>, t: Vector3<f64>, width: u32, height: u32) -> Self {
        Self { k, distortion: None, r, t, width, height }
    }

    /// The camera centre in world coordinates, `-R^T t`.
    pub fn center(&self) -> Point3<f64> {
        Point3::from(-(self.r.transpose() * self.t))
    }

    /// A world point in the camera frame.
    pub fn world_to_camera(&self, p: &Point3<f64>) -> Point3<f64> {
        Point3::from(self.r * p.coords + self.t)
    }

    /// A world direction in the camera frame.
    pub fn direction_to_camera(&self, d: &Vector3<f64>) -> Vector3<f64> {
        self.r * d
    }

    /// Project a world point to continuous pixel coordinates; `None` behind the camera.
    pub fn project(&self, p: &Point3<f64>) -> Option<Point2<f64>> {
        let c = self.world_to_camera(p);
        if c.z <= 0.0 {
            return None;
        }
        let (mut x, mut y) = (c.x / c.z, c.y / c.z);
        if let Some(d) = &self.distortion {
            (x, y) = d.distort(x, y);
        }
        let k = &self.k;
        Some(Point2::new(k[(0, 0)] * x + k[(0, 1)] * y + k[(0, 2)], k[(1, 1)] * y + k[(1, 2)]))
    }

    /// Normalised camera coordinates `(x/z, y/z)` seen at continuous pixel `(u, v)`.
    fn normalized(&self, u: f64, v: f64) -> (f64, f64) {
        let k = &self.k;
        let y = (v - k[(1, 2)]) / k[(1, 1)];
        let x = (u - k[(0, 2)] - k[(0, 1)] * y) / k[(0, 0)];
        match &self.distortion {
            Some(d) => d.undistort(x, y),
            None => (x, y),
        }
    }

    /// The world point at continuous pixel `(u, v)` and depth `z` along the camera's z axis.
    pub fn unproject(&self, pixel: &Point2<f64>, depth: f64) -> Point3<f64> {
        let (x, y) = self.normalized(pixel.x, pixel.y);
        let c = Vector3::new(x * depth, y * depth, depth);
        Point3::from(self.r.transpose() * (c - self.t))
    }

    /// The world ray through continuous pixel coordinates `(u, v)`.
    pub fn ray(&self, u: f64, v: f64) -> Ray {
        let (x, y) = self.normalized(u, v);
        let d = self.r.transpose() * Vector3::new(x, y, 1.0);
        Ray { origin: self.center(), direction: d.normalize() }
    }

    /// This camera at 1/`factor` of its size: pixel `(i, j)` of the smaller image covers the
    /// `factor x factor` block at `(factor i, factor j)`. With pixel centres at +0.5 the
    /// continuous pixel coordinates simply divide: `K' = diag(1/f, 1/f, 1) K` (no half-pixel
    /// shift); the size is rounded down (the last incomplete block is dropped).
    pub fn downscaled(&self, factor: u32) -> Camera {
        let f = factor.max(1) as f64;
        let mut camera = self.clone();
        for c in 0..3 {
            camera.k[(0, c)] /= f;
            camera.k[(1, c)] /= f;
        }
        camera.width = self.width / factor.max(1);
        camera.height = self.height / factor.max(1);
        camera
    }

    /// The world ray through the centre of pixel `(i, j)` (column `i`, row `j`).
    pub fn pixel_ray(&self, i: u32, j: u32) -> Ray {
        self.ray(i as f64 + 0.5, j as f64 + 0.5)
    }

    /// The Stokes reference frame `(x_r, y_r)` of light arriving along the world ray `direction`
    /// (unit): `x_r = normalize(direction x up)` with `up` the camera's up (`-y` of the camera
    /// frame), `y_r = direction x x_r`. For the optical axis this is exactly image +x (right) and
    /// +y (down); off axis it follows the ray, as Mitsuba's per-ray Stokes frame does. An azimuth
    /// in this frame is `atan2(a . y_r, a . x_r)`.
    pub fn stokes_frame(&self, direction: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        let up = -(self.r.transpose() * Vector3::y());
        let x = direction.cross(&up).normalize();
        (x, direction.cross(&x))
    }

    /// The 3x4 projection matrix `P = K [R | t]` (distortion not included).
    pub fn projection(&self) -> Matrix3x4<f64> {
        let mut rt = Matrix3x4::zeros();
        rt.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.r);
        rt.set_column(3, &self.t);
        self.k * rt
    }

    /// Decompose a projection matrix `P ~ K [R | t]` (any non-zero scale) into a camera with
    /// positive focal lengths, `K[2][2] = 1` and a proper rotation, by RQ decomposition.
    pub fn from_projection(p: &Matrix3x4<f64>, width: u32, height: u32) -> Result<Self> {
        let m = p.fixed_view::<3, 3>(0, 0).into_owned();
        if !m.iter().chain(p.column(3).iter()).all(|v| v.is_finite()) || m.determinant().abs() < 1e-300 {
            return Err(Error::invalid("projection matrix is singular or not finite"));
        }
        // RQ of M through QR of the row-reversed transpose: M = K R, K upper triangular.
        let flip = Matrix3::new(0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0);
        let qr = (flip * m).transpose().qr();
        let (q, upper) = (qr.q(), qr.r());
        let mut k = flip * upper.transpose() * flip;
        let mut r = flip * q.transpose();
        // Make the diagonal of K positive: K R = (K D)(D R) with D = diag(+-1).
        let d = Matrix3::from_diagonal(&Vector3::new(k[(0, 0)].signum(), k[(1, 1)].signum(), k[(2, 2)].signum()));
        k *= d;
        r = d * r;
        // P is defined up to scale: absorb the scale into t and choose the sign giving det R = +1.
        let mut scale = k[(2, 2)];
        if r.determinant() < 0.0 {
            r = -r;
            scale = -scale;
        }
        k /= k[(2, 2)];
        let t = k.try_inverse().ok_or_else(|| Error::invalid("degenerate intrinsics"))? * p.column(3) / scale;
        Ok(Self::new(k, r, t, width, height))
    }
}

/// The serialised form of a camera (row-major matrices), as stored in manifests.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraRecord {
    /// Intrinsics K, row-major.
    pub k: [[f64; 3]; 3],
    /// World-to-camera rotation R, row-major.
    pub r: [[f64; 3]; 3],
    /// World-to-camera translation t.
    pub t: [f64; 3],
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// OpenCV distortion, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distortion: Option<Distortion>,
}

/// A 3x3 matrix as rows.
pub fn matrix_rows(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    [0, 1, 2].map(|i| [0, 1, 2].map(|j| m[(i, j)]))
}

/// A 3x3 matrix from rows.
pub fn matrix_from_rows(rows: &[[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| rows[i][j])
}

impl From<&Camera> for CameraRecord {
    fn from(c: &Camera) -> Self {
        Self {
            k: matrix_rows(&c.k),
            r: matrix_rows(&c.r),
            t: [c.t.x, c.t.y, c.t.z],
            width: c.width,
            height: c.height,
            distortion: c.distortion,
        }
    }
}

impl TryFrom<&CameraRecord> for Camera {
    type Error = Error;

    fn try_from(rec: &CameraRecord) -> Result<Self> {
        let camera = Camera {
            k: matrix_from_rows(&rec.k),
            distortion: rec.distortion,
            r: matrix_from_rows(&rec.r),
            t: Vector3::from(rec.t),
            width: rec.width,
            height: rec.height,
        };
        camera.validate()?;
        Ok(camera)
    }
}

impl Camera {
    /// Check that the camera is usable: finite, positive focal lengths, a rotation, a size.
    pub fn validate(&self) -> Result<()> {
        let finite = self.k.iter().chain(self.r.iter()).chain(self.t.iter()).all(|v| v.is_finite());
        if !finite {
            return Err(Error::invalid("camera has non-finite entries"));
        }
        if self.k[(0, 0)] <= 0.0 || self.k[(1, 1)] <= 0.0 {
            return Err(Error::invalid("camera focal lengths must be positive"));
        }
        let orthogonality = (self.r * self.r.transpose() - Matrix3::identity()).abs().max();
        if orthogonality > 1e-6 || (self.r.determinant() - 1.0).abs() > 1e-6 {
            return Err(Error::invalid(format!("camera R is not a rotation (|R R^T - I| = {orthogonality:.2e})")));
        }
        if self.width == 0 || self.height == 0 {
            return Err(Error::invalid("camera image size is zero"));
        }
        if let Some(d) = &self.distortion {
            self.check_distortion(d)?;
        }
        Ok(())
    }

    /// A lens distortion must be finite and invertible over the image: every pixel of the
    /// border (the farthest from the centre) comes back from undistorting to within 1e-3 of a
    /// pixel (OpenCV's iteration, as the rest of rmvp undoes it), and the radial factor stays
    /// positive out to it.
    fn check_distortion(&self, d: &Distortion) -> Result<()> {
        let coefficients = [d.k1, d.k2, d.p1, d.p2, d.k3];
        if coefficients.iter().any(|c| !c.is_finite()) {
            return Err(Error::invalid(format!("camera distortion has non-finite coefficients {coefficients:?}")));
        }
        let (w, h) = (f64::from(self.width), f64::from(self.height));
        let (fx, fy, cx, cy) = (self.k[(0, 0)], self.k[(1, 1)], self.k[(0, 2)], self.k[(1, 2)]);
        let border = (0..=16).flat_map(|i| {
            let s = f64::from(i) / 16.0;
            [(s * w, 0.0), (s * w, h), (0.0, s * h), (w, s * h)]
        });
        for (u, v) in border {
            let (xd, yd) = ((u - cx) / fx, (v - cy) / fy);
            let (x, y) = d.undistort(xd, yd);
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3));
            let (rx, ry) = d.distort(x, y);
            let off = ((rx - xd) * fx).hypot((ry - yd) * fy);
            // NaN (an iteration that diverged) fails both tests.
            let undone = radial > 0.0 && off < 1e-3;
            if !undone {
                return Err(Error::invalid(format!(
                    "camera distortion {coefficients:?} cannot be undone at pixel ({u:.0}, {v:.0}) of its \
                     {}x{} image",
                    self.width, self.height
                )));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    #[test]
    fn distortions_that_cannot_be_undone_are_refused() {
        let mut c = camera();
        c.distortion = Some(Distortion { k1: -0.28, k2: 0.07, p1: 0.001, p2: -0.0005, k3: 0.0 });
        c.validate().unwrap();
        for bad in [f64::NAN, -1e6, 1e6] {
            c.distortion = Some(Distortion { k1: bad, k2: 0.0, p1: 0.0, p2: 0.0, k3: 0.0 });
            let err = c.validate().unwrap_err().to_string();
            assert!(err.contains("distortion"), "{bad}: {err}");
        }
    }

    fn camera() -> Camera {
        let r = *Rotation3::from_euler_angles(0.3, -0.5, 0.2).matrix();
        let k = Matrix3::new(900.0, 0.5, 611.5, 0.0, 905.0, 515.0, 0.0, 0.0, 1.0);
        Camera::new(k, r, Vector3::new(0.1, -0.2, 3.0), 1224, 1024)
    }
    #[test]
    fn a_downscaled_camera_sees_each_block_where_the_full_camera_sees_its_pixels() {
        let full = camera();
        for factor in [2u32, 4] {
            let small = full.downscaled(factor);
            assert_eq!((small.width, small.height), (1224 / factor, 1024 / factor));
            let f = factor as f64;
            // Pixel (i, j) of the small image is the block whose centre is ((i + 0.5) f, (j + 0.5) f).
            for (i, j) in [(0u32, 0u32), (17, 250), (305, 3)] {
                let (a, b) = (small.pixel_ray(i, j), full.ray((i as f64 + 0.5) * f, (j as f64 + 0.5) * f));
                assert!((a.direction - b.direction).norm() < 1e-12 && (a.origin - b.origin).norm() < 1e-12);
            }
            let p = Point3::new(0.2, -0.1, 0.4);
            let (a, b) = (small.project(&p).unwrap(), full.project(&p).unwrap());
            assert!((a.coords * f - b.coords).norm() < 1e-9);
        }
    }

    #[test]
    fn project_inverts_unproject_and_rays_pass_through_pixel_centres() {
        for distortion in [None, Some(Distortion { k1: -0.12, k2: 0.05, p1: 1e-3, p2: -2e-3, k3: 0.01 })] {
            let cam = Camera { distortion, ..camera() };
            let pixel = Point2::new(100.5, 900.5);
            let p = cam.unproject(&pixel, 2.5);
            assert!((cam.world_to_camera(&p).z - 2.5).abs() < 1e-12);
            assert!((cam.project(&p).unwrap() - pixel).norm() < 1e-9);
            let ray = cam.pixel_ray(100, 900);
            assert!((ray.origin - cam.center()).norm() < 1e-12 && (ray.direction.norm() - 1.0).abs() < 1e-12);
            assert!((cam.project(&(ray.origin + 7.0 * ray.direction)).unwrap() - pixel).norm() < 1e-9);
        }
        // Behind the camera there is no projection.
        let cam = camera();
        assert!(cam.project(&(cam.center() - 1.0 * (cam.r.transpose() * Vector3::z()))).is_none());
    }

    #[test]
    fn stokes_frame_is_the_image_frame_on_axis() {
        let cam = camera();
        let axis = cam.r.transpose() * Vector3::z();
        let (x, y) = cam.stokes_frame(&axis);
        assert!((x - cam.r.transpose() * Vector3::x()).norm() < 1e-12);
        assert!((y - cam.r.transpose() * Vector3::y()).norm() < 1e-12);
        let off_axis = cam.pixel_ray(0, 0).direction;
        let (x, y) = cam.stokes_frame(&off_axis);
        assert!(x.dot(&off_axis).abs() < 1e-12 && y.dot(&off_axis).abs() < 1e-12 && x.dot(&y).abs() < 1e-12);
    }

    #[test]
    fn distortion_inverts() {
        let d = Distortion { k1: -0.3, k2: 0.1, p1: 2e-3, p2: -1e-3, k3: -0.02 };
        for (x, y) in [(0.0, 0.0), (0.3, -0.2), (-0.45, 0.35)] {
            let (xd, yd) = d.distort(x, y);
            let (xu, yu) = d.undistort(xd, yd);
            assert!((xu - x).abs() < 1e-10 && (yu - y).abs() < 1e-10, "({x}, {y})");
        }
    }

    #[test]
    fn projection_matrices_decompose_at_any_scale_and_sign() {
        let cam = camera();
        for scale in [1.0, 42.0, -0.01] {
            let back = Camera::from_projection(&(cam.projection() * scale), cam.width, cam.height).unwrap();
            assert!((back.k - cam.k).abs().max() < 1e-9, "K at scale {scale}");
            assert!((back.r - cam.r).abs().max() < 1e-12, "R at scale {scale}");
            assert!((back.t - cam.t).abs().max() < 1e-12, "t at scale {scale}");
        }
        assert!(Camera::from_projection(&Matrix3x4::zeros(), 4, 4).is_err());
    }

    #[test]
    fn records_round_trip_and_reject_bad_cameras() {
        let cam = camera();
        assert_eq!(Camera::try_from(&CameraRecord::from(&cam)).unwrap(), cam);
        let mut rec = CameraRecord::from(&cam);
        rec.r[0][0] = 2.0;
        assert!(Camera::try_from(&rec).unwrap_err().to_string().contains("not a rotation"));
        let mut rec = CameraRecord::from(&cam);
        rec.k[1][1] = -5.0;
        assert!(Camera::try_from(&rec).unwrap_err().to_string().contains("focal lengths"));
    }
}
