//! What is rendered: one or more meshes ("parts") in one BVH, each with its own optics and
//! per-vertex or textured albedo. One part is the subject (the object being captured): masks,
//! depth and ground-truth normals are the subject's alone; the other parts (a calibration board,
//! a table) are the rest of the lab that casts shadows and fills the background.

use crate::bvh::{Bvh, Hit};
use crate::math::Vec3;
use crate::pbrdf::{Interface, Lobes, Surface};
use crate::{Error, Result};
use rmvp_dataset::mesh::VertexProperty;
use rmvp_dataset::{Image, Mesh};

/// Default albedo where the mesh has no colours.
pub const DEFAULT_ALBEDO: [f32; 3] = [0.75, 0.45, 0.3];
/// Default GGX roughness where the mesh has none.
pub const DEFAULT_ROUGHNESS: f32 = 0.1;

/// A mesh's per-vertex GGX roughness, if it has one: its `roughness_0` property (Mitsuba's
/// name) or `roughness`.
pub fn roughness_property(mesh: &Mesh) -> Option<&VertexProperty> {
    ["roughness_0", "roughness"].iter().find_map(|name| mesh.property(name))
}

/// One mesh of a scene with its material.
#[derive(Clone, Debug)]
pub struct Part {
    /// The triangles (albedo from vertex colours, roughness from `roughness_0`/`roughness`).
    pub mesh: Mesh,
    /// Optics of the surface.
    pub interface: Interface,
    /// Lobes of the surface.
    pub lobes: Lobes,
    /// Linear RGB albedo texture at the mesh's texture coordinates, replacing vertex albedo.
    pub texture: Option<Image<f32>>,
    /// Whether this is the subject (masks, depth and normals are the subject's).
    pub subject: bool,
}

impl Part {
    /// The subject: `mesh` with the given optics, untextured.
    pub fn subject(mesh: Mesh, interface: Interface, lobes: Lobes) -> Self {
        Self { mesh, interface, lobes, texture: None, subject: true }
    }
}

/// Per-part material.
struct Material {
    interface: Interface,
    lobes: Lobes,
    texture: Option<Image<f32>>,
    subject: bool,
}

/// A renderable scene of parts.
pub struct Object {
    bvh: Bvh,
    positions: Vec<Vec3>,
    faces: Vec<[u32; 3]>,
    /// Part of each face.
    face_part: Vec<u16>,
    normals: Vec<Vec3>,
    albedo: Vec<[f32; 3]>,
    roughness: Vec<f32>,
    /// Texture coordinates of every vertex (zero for parts without).
    texcoords: Vec<[f32; 2]>,
    /// Whether each part's mesh has texture coordinates.
    has_texcoords: Vec<bool>,
    materials: Vec<Material>,
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
    /// Index of the part hit.
    pub part: usize,
    /// Whether that part is the subject.
    pub subject: bool,
}

/// Vertex normals from the mesh or area-weighted face normals.
fn vertex_normals(mesh: &Mesh, positions: &[Vec3]) -> Vec<Vec3> {
    match &mesh.normals {
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
    }
}

impl Object {
    /// A scene of one part, the subject: vertex normals from the mesh or area-weighted face
    /// normals; albedo from its colours (else [`DEFAULT_ALBEDO`]); roughness from a
    /// `roughness_0` or `roughness` property (else [`DEFAULT_ROUGHNESS`]).
    pub fn new(mesh: &Mesh, interface: Interface, lobes: Lobes) -> Result<Self> {
        Self::from_parts(vec![Part::subject(mesh.clone(), interface, lobes)])
    }

    /// A mesh to ray cast for its geometry alone (normals, depth, silhouettes, crossings): a
    /// material is needed to build an object and is never looked at.
    pub fn geometry(mesh: &Mesh) -> Result<Self> {
        Self::new(mesh, Interface::Dielectric(1.5), Lobes::Plastic)
    }

    /// A scene of several parts in one BVH (each prepared as [`Object::new`] does).
    pub fn from_parts(parts: Vec<Part>) -> Result<Self> {
        if parts.is_empty() {
            return Err(Error::NoFaces);
        }
        let mut object = Object {
            bvh: Bvh::new(&[], &[]),
            positions: Vec::new(),
            faces: Vec::new(),
            face_part: Vec::new(),
            normals: Vec::new(),
            albedo: Vec::new(),
            roughness: Vec::new(),
            texcoords: Vec::new(),
            has_texcoords: Vec::new(),
            materials: Vec::new(),
        };
        let mut all_positions = Vec::new();
        for (index, part) in parts.into_iter().enumerate() {
            let mesh = &part.mesh;
            mesh.validate()?;
            if mesh.faces.is_empty() {
                return Err(Error::NoFaces);
            }
            let offset = object.positions.len() as u32;
            let positions: Vec<Vec3> = mesh.positions.iter().map(|&p| Vec3::from_array(p)).collect();
            object.normals.extend(vertex_normals(mesh, &positions));
            object.positions.extend(positions);
            all_positions.extend_from_slice(&mesh.positions);
            object.faces.extend(mesh.faces.iter().map(|f| f.map(|i| i + offset)));
            object.face_part.extend(std::iter::repeat_n(index as u16, mesh.faces.len()));
            let n = mesh.positions.len();
            object.albedo.extend(mesh.colors().unwrap_or_else(|| vec![DEFAULT_ALBEDO; n]));
            match roughness_property(mesh) {
                Some(p) => object.roughness.extend(p.values.iter().map(|&v| v as f32)),
                None => object.roughness.extend(std::iter::repeat_n(DEFAULT_ROUGHNESS, n)),
            }
            let uv = mesh.texcoords();
            object.has_texcoords.push(uv.is_some());
            object.texcoords.extend(uv.unwrap_or_else(|| vec![[0.0; 2]; n]));
            let material =
                Material { interface: part.interface, lobes: part.lobes, texture: None, subject: part.subject };
            object.materials.push(material);
            if let Some(texture) = part.texture {
                object.set_part_texture(index, texture)?;
            }
        }
        object.bvh = Bvh::new(&all_positions, &object.faces);
        Ok(object)
    }

    /// Take the subject's albedo from a linear RGB texture (see [`Object::set_part_texture`]).
    pub fn set_albedo_texture(&mut self, texture: Image<f32>) -> Result<()> {
        let subject = self.materials.iter().position(|m| m.subject).unwrap_or(0);
        self.set_part_texture(subject, texture)
    }

    /// Take part `part`'s albedo from a linear RGB texture, looked up at its mesh's texture
    /// coordinates (bilinear, wrapping; `v = 0` is the image's bottom row).
    pub fn set_part_texture(&mut self, part: usize, texture: Image<f32>) -> Result<()> {
        if !self.has_texcoords[part] {
            return Err(Error::NoTextureCoordinates);
        }
        if texture.channels() < 3 || texture.width() == 0 || texture.height() == 0 {
            return Err(Error::TextureNotRgb { channels: texture.channels() });
        }
        self.materials[part].texture = Some(texture);
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
        let part = self.face_part[triangle as usize] as usize;
        let material = &self.materials[part];
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
        let albedo = match &material.texture {
            Some(texture) => {
                let (ta, tb, tc) = (self.texcoords[ia], self.texcoords[ib], self.texcoords[ic]);
                Self::texel(texture, w * ta[0] + u * tb[0] + v * tc[0], w * ta[1] + u * tb[1] + v * tc[1])
            }
            None => mix3(self.albedo[ia], self.albedo[ib], self.albedo[ic]),
        };
        Some(SurfacePoint {
            p: origin + direction * t,
            ng,
            n,
            t,
            surface: Surface {
                albedo,
                alpha: (w * self.roughness[ia] + u * self.roughness[ib] + v * self.roughness[ic]).max(1e-3),
                interface: material.interface,
                lobes: material.lobes,
            },
            part,
            subject: material.subject,
        })
    }

    /// Whether the ray from `origin` along `direction` hits anything.
    pub fn occluded(&self, origin: Vec3, direction: Vec3) -> bool {
        self.bvh.occluded(origin, direction, 0.0, f32::MAX)
    }
}
