//! Similarities `x -> s R x + t`: where a scan or a subject is placed, how one set of poses
//! maps onto another, fitted to point pairs (Umeyama) and stored with their 4x4 matrix.

use crate::Mesh;
use nalgebra::{Matrix3, Matrix4, Vector3};
use serde::{Deserialize, Serialize};

/// A similarity `x -> s R x + t`; stored as its rotation, translation, scale and 4x4 matrix
/// (row-major), which must agree when read.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "SimilarityRecord", into = "SimilarityRecord")]
pub struct Similarity {
    /// Rotation.
    pub r: Matrix3<f64>,
    /// Translation.
    pub t: Vector3<f64>,
    /// Uniform scale.
    pub s: f64,
}

impl Similarity {
    /// The identity.
    pub fn identity() -> Self {
        Self { r: Matrix3::identity(), t: Vector3::zeros(), s: 1.0 }
    }

    /// The similarity that maps `from` onto `to` best in the least-squares sense (Umeyama 1991;
    /// a proper rotation). Needs three points not on one line.
    pub fn fit(from: &[Vector3<f64>], to: &[Vector3<f64>]) -> Self {
        let n = from.len().max(1) as f64;
        let (mean_from, mean_to) = (from.iter().sum::<Vector3<f64>>() / n, to.iter().sum::<Vector3<f64>>() / n);
        let covariance =
            from.iter().zip(to).map(|(f, t)| (t - mean_to) * (f - mean_from).transpose()).sum::<Matrix3<f64>>() / n;
        let variance = from.iter().map(|f| (f - mean_from).norm_squared()).sum::<f64>() / n;
        let svd = covariance.svd(true, true);
        let (u, v_t) = (svd.u.expect("asked for"), svd.v_t.expect("asked for"));
        let mut d = Matrix3::identity();
        if (u * v_t).determinant() < 0.0 {
            d[(2, 2)] = -1.0;
        }
        let rotation = u * d * v_t;
        let scale = svd.singular_values.component_mul(&d.diagonal()).sum() / variance.max(f64::MIN_POSITIVE);
        Self { r: rotation, t: mean_to - scale * rotation * mean_from, s: scale }
    }

    /// A uniform scaling about the origin.
    pub fn scaling(s: f64) -> Self {
        Self { s, ..Self::identity() }
    }

    /// The same rotation at scale `s`, translated so that `point` still lands where `self`
    /// puts it.
    pub fn rescaled_about(&self, s: f64, point: &Vector3<f64>) -> Self {
        Self { r: self.r, t: self.t + (self.s - s) * (self.r * point), s }
    }

    /// Apply to a point.
    pub fn apply(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.s * (self.r * p) + self.t
    }

    /// `self` after `other`: `x -> self(other(x))`.
    pub fn compose(&self, other: &Similarity) -> Similarity {
        Similarity { r: self.r * other.r, t: self.s * (self.r * other.t) + self.t, s: self.s * other.s }
    }

    /// The inverse similarity.
    pub fn inverse(&self) -> Similarity {
        let r = self.r.transpose();
        Similarity { r, t: -(r * self.t) / self.s, s: 1.0 / self.s }
    }

    /// As a 4x4 homogeneous matrix.
    pub fn matrix(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&(self.r * self.s));
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.t);
        m
    }

    /// Rotation angle in degrees ([`rotation_angle_deg`]).
    pub fn angle_deg(&self) -> f64 {
        rotation_angle_deg(&self.r)
    }

    /// A mesh moved by this similarity (positions transformed, normals rotated).
    pub fn apply_to_mesh(&self, mesh: &Mesh) -> Mesh {
        let moved = |p: &[f32; 3], f: &dyn Fn(&Vector3<f64>) -> Vector3<f64>| {
            let q = f(&Vector3::from(p.map(|v| v as f64)));
            [q.x as f32, q.y as f32, q.z as f32]
        };
        Mesh {
            positions: mesh.positions.iter().map(|p| moved(p, &|v| self.apply(v))).collect(),
            normals: mesh.normals.as_ref().map(|n| n.iter().map(|p| moved(p, &|v| self.r * v)).collect()),
            ..mesh.clone()
        }
    }
}

/// The angle of a rotation matrix, degrees (robust to rounding near the identity).
pub fn rotation_angle_deg(r: &Matrix3<f64>) -> f64 {
    ((r.trace() - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees()
}

/// The stored form of a [`Similarity`].
#[derive(Serialize, Deserialize)]
struct SimilarityRecord {
    /// Rotation, row-major.
    r: [[f64; 3]; 3],
    /// Translation.
    t: [f64; 3],
    /// Scale.
    s: f64,
    /// `s R | t` as a 4x4 matrix, row-major.
    matrix: [[f64; 4]; 4],
}

impl From<Similarity> for SimilarityRecord {
    fn from(s: Similarity) -> Self {
        let m = s.matrix();
        Self {
            r: crate::camera::matrix_rows(&s.r),
            t: [s.t.x, s.t.y, s.t.z],
            s: s.s,
            matrix: [0, 1, 2, 3].map(|i| [0, 1, 2, 3].map(|j| m[(i, j)])),
        }
    }
}

impl TryFrom<SimilarityRecord> for Similarity {
    type Error = String;

    fn try_from(rec: SimilarityRecord) -> std::result::Result<Self, String> {
        let s = Similarity { r: crate::camera::matrix_from_rows(&rec.r), t: Vector3::from(rec.t), s: rec.s };
        if !(s.s > 0.0 && s.s.is_finite()) {
            return Err(format!("scale {} is not positive", rec.s));
        }
        if (s.r * s.r.transpose() - Matrix3::identity()).abs().max() > 1e-6 || s.r.determinant() < 0.0 {
            return Err("r is not a rotation".into());
        }
        let deviation = (s.matrix() - Matrix4::from_fn(|i, j| rec.matrix[i][j])).abs().max();
        if deviation.is_nan() || deviation > 1e-9 * (1.0 + s.matrix().abs().max()) {
            return Err(format!("matrix disagrees with r, t and s (by {deviation:.1e})"));
        }
        Ok(s)
    }
}
