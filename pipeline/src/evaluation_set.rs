//! The reconstruction evaluation set: shapes beyond spot and bunny (fine bumps, a thin knotted
//! tube with narrow gaps, sharp creases, a deep concavity, a ring whose underside no training
//! view sees) under several materials (rough and
//! bright, smooth and dark, a conductor, spatially varying albedo and roughness), simulated
//! with held-out views. `benches/quality.rs` reconstructs and tabulates them
//! (`docs/benchmarks.md`, "Reconstruction quality").

use crate::simulate::{simulate, SimulateOptions};
use crate::Result;
use rmvp_dataset::layout::Layout;
use rmvp_dataset::mesh::{ScalarKind, VertexProperty};
use rmvp_dataset::{Mesh, Scene};
use rmvp_render::pbrdf::Interface;
use rmvp_render::rig::RigKind;
use rmvp_render::{default_mesh, shapes};
use std::path::{Path, PathBuf};

/// The shape of a scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    /// A unit sphere with fine bumps (waves of 8 to 20 periods around it).
    Bumps,
    /// A trefoil knot: a thin tube passing close to itself.
    Knot,
    /// A sixteen-tooth star prism: flat faces, sharp creases.
    Gear,
    /// A thick-walled bowl: a deep concavity.
    Bowl,
    /// The built-in spot (public domain).
    Spot,
    /// The Stanford bunny, read from the shared meshes (`bunny.ply`).
    Bunny,
    /// A ring lying flat (a pool float), seen only from above: its underside is in no view.
    Float,
}

/// How a scene's surface looks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Material {
    /// One albedo (linear RGB) and one GGX roughness over the whole surface.
    Uniform {
        /// Diffuse albedo.
        albedo: [f32; 3],
        /// GGX roughness.
        roughness: f32,
    },
    /// Albedo and roughness varying over the surface (bands along +Y and around it).
    Varying,
}

/// One scene of the set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EvaluationScene {
    /// Short name (table rows, folder names).
    pub name: &'static str,
    /// The shape.
    pub shape: Shape,
    /// Albedo and roughness.
    pub material: Material,
    /// Dielectric or conductor.
    pub interface: Interface,
    /// Where the training views are: random directions from 20 degrees below the equator up, or
    /// the turntable's two rings above it.
    pub rig: RigKind,
}

/// Gold at 600 nm, the conductor of the set.
const GOLD: Interface = Interface::Conductor(0.25, 3.0);

/// The scenes, in table order.
pub const SCENES: [EvaluationScene; 7] = [
    EvaluationScene {
        name: "bumps",
        shape: Shape::Bumps,
        material: Material::Uniform { albedo: [0.8, 0.78, 0.75], roughness: 0.45 },
        interface: Interface::Dielectric(1.5),
        rig: RigKind::Sphere,
    },
    EvaluationScene {
        name: "knot",
        shape: Shape::Knot,
        material: Material::Uniform { albedo: [0.04, 0.04, 0.05], roughness: 0.06 },
        interface: Interface::Dielectric(1.5),
        rig: RigKind::Sphere,
    },
    EvaluationScene {
        name: "gear",
        shape: Shape::Gear,
        material: Material::Uniform { albedo: [0.0, 0.0, 0.0], roughness: 0.2 },
        interface: GOLD,
        rig: RigKind::Sphere,
    },
    EvaluationScene {
        name: "bowl",
        shape: Shape::Bowl,
        material: Material::Varying,
        interface: Interface::Dielectric(1.5),
        rig: RigKind::Sphere,
    },
    EvaluationScene {
        name: "spot",
        shape: Shape::Spot,
        material: Material::Uniform { albedo: [0.75, 0.45, 0.3], roughness: 0.1 },
        interface: Interface::Dielectric(1.5),
        rig: RigKind::Sphere,
    },
    EvaluationScene {
        name: "bunny",
        shape: Shape::Bunny,
        material: Material::Varying,
        interface: Interface::Dielectric(1.5),
        rig: RigKind::Sphere,
    },
    EvaluationScene {
        name: "float",
        shape: Shape::Float,
        material: Material::Uniform { albedo: [0.85, 0.35, 0.1], roughness: 0.15 },
        interface: Interface::Dielectric(1.5),
        rig: RigKind::Turntable,
    },
];

/// The scene named `name`.
pub fn scene(name: &str) -> Option<EvaluationScene> {
    SCENES.iter().find(|s| s.name == name).copied()
}

/// How to simulate a scene of the set.
#[derive(Clone, Debug)]
pub struct CaptureOptions {
    /// Image size.
    pub size: (u32, u32),
    /// Training views (the sphere rig).
    pub views: usize,
    /// Held-out views.
    pub eval_views: usize,
    /// Samples per pixel.
    pub spp: u32,
    /// Seed of the views and samples.
    pub seed: u64,
    /// Folder holding `bunny.ply` (the shared meshes).
    pub meshes: PathBuf,
}

impl Default for CaptureOptions {
    fn default() -> Self {
        Self { size: (256, 256), views: 6, eval_views: 6, spp: 32, seed: 0, meshes: PathBuf::from("meshes") }
    }
}

impl EvaluationScene {
    /// The scene's mesh in the unit sphere, its material as vertex properties (`red`, `green`,
    /// `blue`, `roughness`).
    pub fn mesh(&self, meshes: &Path) -> Result<Mesh> {
        let mut mesh = match self.shape {
            Shape::Bumps => shapes::bumpy_sphere(5, 12, 0.05, 1),
            Shape::Knot => shapes::torus_knot(2, 3, 0.3, 240, 24),
            Shape::Gear => shapes::gear(16, 0.75, 0.35),
            Shape::Bowl => shapes::bowl(0.6, 0.12, 96),
            Shape::Spot => default_mesh(),
            Shape::Bunny => Mesh::read(&meshes.join("bunny.ply"))?,
            Shape::Float => shapes::torus(0.4, 96, 24),
        };
        paint(&mut mesh, self.material);
        Ok(mesh)
    }

    /// Render the scene into `out` (`out/nersp`, the NeRSP layout with `gt/`; the mesh in
    /// `out/mesh.ply`) and return it.
    pub fn simulate(&self, out: &Path, options: &CaptureOptions) -> Result<Scene> {
        let mesh_path = out.join("mesh.ply");
        self.mesh(&options.meshes)?.write(&mesh_path)?;
        simulate(&SimulateOptions {
            output: out.to_path_buf(),
            mesh: Some(mesh_path),
            views: options.views,
            eval_views: options.eval_views,
            size: options.size,
            spp: options.spp,
            interface: self.interface,
            seed: options.seed,
            rig: self.rig,
            layouts: vec![Layout::Nersp],
            progress: false,
            ..SimulateOptions::default()
        })
    }
}

/// Replace the mesh's colours and roughness by `material`'s.
fn paint(mesh: &mut Mesh, material: Material) {
    let (albedo, roughness): (Vec<[f32; 3]>, Vec<f32>) = mesh
        .positions
        .iter()
        .map(|p| match material {
            Material::Uniform { albedo, roughness } => (albedo, roughness),
            Material::Varying => {
                // Albedo from dark red to pale blue up the object, roughness in bands around it.
                let h = (0.5 + 0.5 * p[1]).clamp(0.0, 1.0);
                let around = (6.0 * p[2].atan2(p[0])).sin() * 0.5 + 0.5;
                ([0.6 - 0.45 * h, 0.1 + 0.3 * h, 0.08 + 0.6 * h], 0.05 + 0.45 * around)
            }
        })
        .unzip();
    let names = ["red", "green", "blue", "roughness", "roughness_0", "r", "g", "b"];
    mesh.vertex_properties.retain(|p| !names.contains(&p.name.as_str()));
    for (c, name) in ["red", "green", "blue"].into_iter().enumerate() {
        let values = albedo.iter().map(|a| a[c] as f64).collect();
        mesh.vertex_properties.push(VertexProperty { name: name.into(), kind: ScalarKind::F32, values });
    }
    let values = roughness.iter().map(|&r| r as f64).collect();
    mesh.vertex_properties.push(VertexProperty { name: "roughness".into(), kind: ScalarKind::F32, values });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_scene_but_the_bunny_builds_painted_in_the_unit_sphere() {
        for scene in SCENES.iter().filter(|s| s.shape != Shape::Bunny) {
            let mesh = scene.mesh(Path::new("absent")).unwrap();
            let colors = mesh.colors().expect("painted");
            let roughness = &mesh.property("roughness").expect("roughness").values;
            assert!(colors.len() == mesh.positions.len() && roughness.len() == mesh.positions.len());
            assert!((mesh.radius() - 1.0).abs() < 0.02, "{}: radius {}", scene.name, mesh.radius());
            let spread = roughness.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
                - roughness.iter().cloned().fold(f64::INFINITY, f64::min);
            assert_eq!(spread > 0.1, scene.material == Material::Varying, "{}", scene.name);
        }
        assert!(scene("bunny").unwrap().mesh(Path::new("absent")).is_err());
    }
}
