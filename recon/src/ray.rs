//! Camera rays in the unit-sphere frame, with the Stokes frame each carries.

use crate::engine::vector::dot;

/// A camera ray in the unit-sphere frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Ray {
    /// Origin (the camera centre).
    pub origin: [f32; 3],
    /// Unit direction.
    pub dir: [f32; 3],
    /// The ray's Stokes frame, x axis.
    pub frame_x: [f32; 3],
    /// The ray's Stokes frame, y axis.
    pub frame_y: [f32; 3],
    /// Entry into the unit sphere.
    pub near: f32,
    /// Exit from the unit sphere.
    pub far: f32,
}

impl Ray {
    /// Clip a ray to the unit sphere; `None` when it misses.
    pub fn clipped(origin: [f32; 3], dir: [f32; 3], frame_x: [f32; 3], frame_y: [f32; 3]) -> Option<Self> {
        let (near, far) = unit_sphere_span(origin, dir)?;
        (far > near + 1e-4).then_some(Self { origin, dir, frame_x, frame_y, near, far })
    }

    /// The point at depth `t`.
    pub fn at(&self, t: f32) -> [f32; 3] {
        [0, 1, 2].map(|k| self.origin[k] + t * self.dir[k])
    }
}

/// Depths `(near, far)` where the ray `origin + t dir` (unit `dir`) is inside the unit sphere,
/// `near` clamped to 0; `None` when it misses.
pub fn unit_sphere_span(origin: [f32; 3], dir: [f32; 3]) -> Option<(f32, f32)> {
    let b = dot(origin, dir);
    let disc = b * b - (dot(origin, origin) - 1.0);
    if disc <= 0.0 {
        return None;
    }
    let root = disc.sqrt();
    Some(((-b - root).max(0.0), -b + root))
}
