//! Evaluation against known answers: identical meshes, concentric spheres, a mesh against its
//! own normal maps, the fixtures' ground-truth normals, and the error binned by DoP, roughness
//! and depth complexity on two spheres.

use nalgebra::{Matrix3, Vector3};
use rmvp_align::breakdown::{error_breakdown, ErrorBin};
use rmvp_align::normals::split_mean_deg;
use rmvp_align::{normal_errors, surface_metrics, SurfaceOptions, ViewNormalError};
use rmvp_dataset::layout::read_scene;
use rmvp_dataset::mesh::{ScalarKind, VertexProperty};
use rmvp_dataset::{Camera, Image, Mesh, Scene, Split, Stokes, View};
use rmvp_render::pbrdf::{Interface, Lobes};
use rmvp_render::shapes::icosphere;
use rmvp_render::{geometry_maps, Object};
use std::path::PathBuf;

fn spot_fixture() -> PathBuf {
    rmvp_testkit::fixture("spot_nersp")
}

fn scaled(mesh: &Mesh, s: f32) -> Mesh {
    Mesh { positions: mesh.positions.iter().map(|p| p.map(|v| v * s)).collect(), ..mesh.clone() }
}

#[test]
fn identical_meshes_are_at_distance_zero() {
    let sphere = icosphere(4);
    let m = surface_metrics(&sphere, &sphere, &SurfaceOptions { max_samples: 20_000, ..Default::default() }).unwrap();
    assert!(m.chamfer < 1e-6 && m.accuracy < 1e-6 && m.completeness < 1e-6, "{m:?}");
    assert_eq!((m.precision, m.recall, m.fscore), (1.0, 1.0, 1.0));
}

#[test]
fn concentric_spheres_are_their_radii_apart() {
    // Points on the sphere of radius 1.01 lie 0.01 from the unit sphere, and back. Tessellated,
    // the facet planes of both sit at the same fraction of their radius, so the distance
    // between them is 0.01 cos(facet angle): within 2e-5 of 0.01 at level 5.
    let unit = icosphere(5);
    let m = surface_metrics(
        &scaled(&unit, 1.01),
        &unit,
        &SurfaceOptions { max_samples: 50_000, threshold: Some(0.005), ..Default::default() },
    )
    .unwrap();
    assert!(
        (m.accuracy - 0.01).abs() < 2e-4 && (m.completeness - 0.01).abs() < 2e-4 && (m.chamfer - 0.01).abs() < 2e-4,
        "{m:?}"
    );
    assert_eq!((m.precision, m.recall), (0.0, 0.0), "0.01 apart, threshold 0.005");
    // Capped distances and a looser threshold.
    let capped = surface_metrics(
        &scaled(&unit, 1.01),
        &unit,
        &SurfaceOptions { max_samples: 5_000, max_distance: Some(0.004), threshold: Some(0.02), ..Default::default() },
    )
    .unwrap();
    assert!((capped.chamfer - 0.004).abs() < 1e-9 && capped.fscore == 1.0, "{capped:?}");
    // The default threshold is 1 % of the ground truth's bounding-box diagonal.
    let default = surface_metrics(&unit, &unit, &SurfaceOptions { max_samples: 100, ..Default::default() }).unwrap();
    assert!((default.threshold - 0.01 * 12f64.sqrt()).abs() < 1e-6, "{}", default.threshold);
}

#[test]
fn a_mesh_has_no_normal_error_against_its_own_normal_maps() {
    let mut scene = read_scene(&spot_fixture()).unwrap();
    let mesh = scene.mesh.clone().unwrap();
    let object = Object::new(&mesh, Interface::Dielectric(1.5), Lobes::Plastic).unwrap();
    for view in &mut scene.views {
        let maps = geometry_maps(&object, &view.camera);
        view.normals = Some(maps.normals);
        view.mask = Some(maps.mask);
    }
    let report = normal_errors(&mesh, &scene).unwrap();
    assert_eq!(report.views.len(), 8);
    // Zero up to f32 rounding, which acos turns into up to 0.026 degrees near cos = 1.
    assert!(report.mean_mae_deg < 0.03 && report.views.iter().all(|v| v.pixels > 1000), "{}", report.mean_mae_deg);
    // A rotated copy is wrong by about its rotation.
    let turned = Mesh {
        positions: mesh
            .positions
            .iter()
            .map(|p| [p[0] * 0.9848 - p[2] * 0.1736, p[1], p[0] * 0.1736 + p[2] * 0.9848])
            .collect(),
        normals: mesh
            .normals
            .as_ref()
            .map(|n| n.iter().map(|p| [p[0] * 0.9848 - p[2] * 0.1736, p[1], p[0] * 0.1736 + p[2] * 0.9848]).collect()),
        ..mesh.clone()
    };
    let report = normal_errors(&turned, &scene).unwrap();
    assert!(report.mean_mae_deg > 5.0, "a 10-degree turn gives {}", report.mean_mae_deg);
    // Each view keeps its split; a split's mean is over its own views (the fixture holds two
    // views out).
    let splits: Vec<Split> = report.views.iter().map(|v| v.split).collect();
    assert_eq!(splits, scene.views.iter().map(|v| v.split).collect::<Vec<_>>());
    let held_out: Vec<f64> = report.views.iter().filter(|v| v.split == Split::Eval).map(|v| v.mae_deg).collect();
    assert_eq!(held_out.len(), 2);
    assert_eq!(split_mean_deg(&report.views, Split::Eval), Some((held_out[0] + held_out[1]) / 2.0));
    assert_ne!(split_mean_deg(&report.views, Split::Train), split_mean_deg(&report.views, Split::Eval));
}

#[test]
fn ray_cast_normals_agree_with_the_fixture_normal_maps() {
    let scene = read_scene(&spot_fixture()).unwrap();
    let report = normal_errors(scene.mesh.as_ref().unwrap(), &scene).unwrap();
    for v in &report.views {
        let mut errors: Vec<f32> = v.error_map.data().iter().copied().filter(|e| !e.is_nan()).collect();
        errors.sort_by(f32::total_cmp);
        let median = errors[errors.len() / 2];
        assert!(median < 1.0, "view {}: median normal error {median} degrees", v.view);
    }
}

/// A sphere of `radius` about `centre` whose vertices have GGX roughness `roughness`.
fn rough_sphere(centre: [f32; 3], radius: f32, roughness: f64) -> Mesh {
    let unit = icosphere(4);
    let positions = unit.positions.iter().map(|p| [0, 1, 2].map(|k| centre[k] + radius * p[k])).collect();
    let values = vec![roughness; unit.positions.len()];
    let property = VertexProperty { name: "roughness_0".into(), kind: ScalarKind::F32, values };
    Mesh { positions, normals: None, faces: unit.faces, vertex_properties: vec![property] }
}

#[test]
fn the_error_is_binned_by_dop_roughness_and_depth_complexity() {
    // The truth: a sphere (roughness 0.12) with a second one (0.25) hidden behind it. Seen from
    // (0, 0, -4) along +z, the back sphere's angular radius is asin(0.5 / 6), the front one's
    // asin(0.5 / 4): the rays within the first cross the surface four times, the others twice.
    let (front, back) = (rough_sphere([0.0; 3], 0.5, 0.12), rough_sphere([0.0, 0.0, 2.0], 0.5, 0.25));
    let offset = front.positions.len() as u32;
    let truth = Mesh {
        positions: [front.positions.clone(), back.positions].concat(),
        normals: None,
        faces: [front.faces.clone(), back.faces.iter().map(|f| f.map(|i| i + offset)).collect()].concat(),
        vertex_properties: vec![VertexProperty {
            values: [front.vertex_properties[0].values.clone(), back.vertex_properties[0].values.clone()].concat(),
            ..front.vertex_properties[0].clone()
        }],
    };
    let (size, f) = (200u32, 600.0);
    let k = Matrix3::new(f, 0.0, 100.0, 0.0, f, 100.0, 0.0, 0.0, 1.0);
    let camera = Camera::new(k, Matrix3::identity(), Vector3::new(0.0, 0.0, 4.0), size, size);
    let object = Object::new(&truth, Interface::Dielectric(1.5), Lobes::Plastic).unwrap();
    let maps = geometry_maps(&object, &camera);
    // The input: DoP 0.03 on the left half, 0.15 on the right; the error: 1 degree on the
    // left, 3 on the right, over the object.
    let n = (size * size) as usize;
    let left = |k: usize| k % size as usize <= 100;
    let stokes = Stokes {
        s0: Image::from_vec(200, 200, 3, vec![1.0; 3 * n]).unwrap(),
        s1: Image::from_vec(200, 200, 3, (0..3 * n).map(|c| if left(c / 3) { 0.03 } else { 0.15 }).collect()).unwrap(),
        s2: Image::new(200, 200, 3),
    };
    let errors = (0..n).map(|k| {
        if maps.mask.data()[k] == 0 {
            f32::NAN
        } else if left(k) {
            1.0
        } else {
            3.0
        }
    });
    let view = ViewNormalError {
        view: "000".into(),
        split: Split::Train,
        mae_deg: 2.0,
        pixels: maps.mask.data().iter().filter(|&&m| m > 0).count(),
        error_map: Image::from_vec(200, 200, 1, errors.collect()).unwrap(),
    };
    let mut scene = Scene::new();
    scene.views.push(View { stokes: Some(stokes), ..View::new("000", Split::Train, camera) });

    let breakdown = error_breakdown(std::slice::from_ref(&view), &scene, &truth).unwrap();
    let bin = |bins: &[ErrorBin], from: f64| bins.iter().find(|b| b.from == from).unwrap().clone();
    let (low, high) = (bin(&breakdown.by_dop, 0.02), bin(&breakdown.by_dop, 0.1));
    assert_eq!((low.mae_deg, high.mae_deg), (Some(1.0), Some(3.0)));
    assert_eq!(low.pixels + high.pixels, view.pixels);
    let rough = bin(&breakdown.by_roughness, 0.1);
    assert_eq!(rough.pixels, view.pixels, "only the front sphere is seen: {:?}", breakdown.by_roughness);
    let (two, four) = (bin(&breakdown.by_crossings, 1.0), bin(&breakdown.by_crossings, 3.0));
    assert_eq!(two.pixels + four.pixels, view.pixels);
    let want = ((0.5f64 / 6.0).asin().tan() / (0.5f64 / 4.0).asin().tan()).powi(2);
    let share = four.pixels as f64 / view.pixels as f64;
    eprintln!("{share:.4} of {} pixels cross the surface four times (analytic {want:.4})", view.pixels);
    assert!((share - want).abs() < 0.01, "{share} of the pixels cross four times, want {want}");
    // No roughness property: no roughness bins.
    let plain = Mesh { vertex_properties: Vec::new(), ..truth };
    assert!(error_breakdown(&[view], &scene, &plain).unwrap().by_roughness.is_empty());
}
