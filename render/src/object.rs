//! A mesh prepared for rendering: its BVH and per-vertex shading attributes.

use crate::bvh::{Bvh, Hit};
use crate::math::Vec3;
use crate::pbrdf::{Interface, Lobes, Surface};
use rmvp_dataset::{Error, Image, Mesh, Result};

/// Default albedo where the mesh has no colours.
pub const DEFAULT_ALBEDO: [f32; 3] = [0.75, 0.45, 0.3];
/// Default GGX roughness where the mesh has none.
pub const DEFAULT_ROUGHNESS: f32 = 0.1;

/// A renderable object.
pub struct Object {
    bvh: Bvh,
    positions: Vec<Vec3>,
    faces: Vec<[u32; 3]>,
    normals: Vec<Vec3>,
    albedo: Vec<[f32; 3]>,
    roughness: Vec<f32>,
    texcoords: Option<Vec<[f32; 2]>>,
    /// Linear RGB albedo texture, replacing the per-vertex albedo when set.
    texture: Option<Image<f32>>,
    /// Optics of the surface.
    pub interface: Interface,
    /// Lobes of the surface.
    pub lobes: Lobes,
}

/// A ray hit with interpolated attributes.
pub struct SurfacePoint {
    /// Position.
    pub p: Vec3,
    /// Geometric (face) normal, facing the incoming ray.
    pub ng: Vec3,
    /// Interpolated shading normal, facing the incoming ray.
    pub n: Vec3,
    /// Distance along the ray.
    pub t: f32,
    /// Material at the point.
    pub surface: Surface,
}

impl Object {
    /// Prepare a triangle mesh: vertex normals from the mesh or area-weighted face normals;
    /// albedo from its colours (else [`DEFAULT_ALBEDO`]); roughness from a `roughness_0` or
    /// `roughness` property (else [`DEFAULT_ROUGHNESS`]).
    pub fn new(mesh: &Mesh, interface: Interface, lobes: Lobes) -> Result<Self> {
        mesh.validate()?;
        if mesh.faces.is_empty() {
            return Err(Error::invalid("cannot render a mesh without faces"));
        }
        let positions: Vec<Vec3> = mesh.positions.iter().map(|&p| Vec3::from_array(p)).collect();
        let normals = match &mesh.normals {
            Some(n) => n.iter().map(|&v| Vec3::from_array(v).normalize()).collect(),
            None => {
                let mut acc = vec![Vec3::default(); positions.len()];
                for f in &mesh.faces {
                    let [a, b, c] = f.map(|i| positions[i as usize]);
                    let area_normal = (b - a).cross(c - a);
                    f.iter().for_each(|&i| acc[i as usize] = acc[i as usize] + area_normal);
                }
                acc.into_iter().map(Vec3::normalize).collect()
            }
        };
        let albedo = mesh.colors().unwrap_or_else(|| vec![DEFAULT_ALBEDO; positions.len()]);
        let roughness = ["roughness_0", "roughness"]
            .iter()
            .find_map(|n| mesh.property(n))
            .map(|p| p.values.iter().map(|&v| v as f32).collect())
            .unwrap_or_else(|| vec![DEFAULT_ROUGHNESS; positions.len()]);
        Ok(Self {
            bvh: Bvh::new(&mesh.positions, &mesh.faces),
            positions,
            faces: mesh.faces.clone(),
            normals,
            albedo,
            roughness,
            texcoords: mesh.texcoords(),
            texture: None,
            interface,
            lobes,
        })
    }

    /// Take the albedo from a linear RGB texture, looked up at the mesh's texture coordinates
    /// (bilinear, wrapping; `v = 0` is the image's bottom row).
    pub fn set_albedo_texture(&mut self, texture: Image<f32>) -> Result<()> {
        if self.texcoords.is_none() {
            return Err(Error::invalid(
                "the mesh has no texture coordinates (u v or s t vertex properties, or OBJ vt)",
            ));
        }
        if texture.channels() < 3 || texture.width() == 0 || texture.height() == 0 {
            return Err(Error::invalid("an albedo texture must be RGB"));
        }
        self.texture = Some(texture);
        Ok(())
    }

    /// Bilinear lookup of the texture at `(u, v)`.
    fn texel(texture: &Image<f32>, u: f32, v: f32) -> [f32; 3] {
        let (w, h) = (texture.width() as f32, texture.height() as f32);
        let (x, y) = (u * w - 0.5, (1.0 - v) * h - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |i: f32, j: f32| {
            let (i, j) = (i.rem_euclid(w) as usize, j.rem_euclid(h) as usize);
            let p = texture.pixel(i.min(texture.width() - 1), j.min(texture.height() - 1));
            [p[0], p[1], p[2]]
        };
        let (a, b, c, d) = (at(x0, y0), at(x0 + 1.0, y0), at(x0, y0 + 1.0), at(x0 + 1.0, y0 + 1.0));
        [0, 1, 2].map(|k| (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy)
    }

    /// The nearest surface point along a ray, attributes interpolated.
    pub fn intersect(&self, origin: Vec3, direction: Vec3) -> Option<SurfacePoint> {
        let Hit { t, triangle, u, v } = self.bvh.intersect(origin, direction, 0.0, f32::MAX)?;
        let f = self.faces[triangle as usize];
        let [a, b, c] = f.map(|i| self.positions[i as usize]);
        let w = 1.0 - u - v;
        let mix3 = |x: [f32; 3], y: [f32; 3], z: [f32; 3]| [0, 1, 2].map(|k| w * x[k] + u * y[k] + v * z[k]);
        let [ia, ib, ic] = f.map(|i| i as usize);
        let mut ng = (b - a).cross(c - a).normalize();
        if ng.dot(direction) > 0.0 {
            ng = -ng;
        }
        let mut n = (self.normals[ia] * w + self.normals[ib] * u + self.normals[ic] * v).normalize();
        if n.dot(direction) >= 0.0 {
            n = ng; // interpolated normal facing away from the viewer: fall back to the face
        }
        Some(SurfacePoint {
            p: origin + direction * t,
            ng,
            n,
            t,
            surface: Surface {
                albedo: match (&self.texture, &self.texcoords) {
                    (Some(texture), Some(uv)) => {
                        let (ta, tb, tc) = (uv[ia], uv[ib], uv[ic]);
                        Self::texel(texture, w * ta[0] + u * tb[0] + v * tc[0], w * ta[1] + u * tb[1] + v * tc[1])
                    }
                    _ => mix3(self.albedo[ia], self.albedo[ib], self.albedo[ic]),
                },
                alpha: (w * self.roughness[ia] + u * self.roughness[ib] + v * self.roughness[ic]).max(1e-3),
                interface: self.interface,
                lobes: self.lobes,
            },
        })
    }

    /// Whether the ray from `origin` along `direction` hits anything.
    pub fn occluded(&self, origin: Vec3, direction: Vec3) -> bool {
        self.bvh.occluded(origin, direction, 0.0, f32::MAX)
    }
}
