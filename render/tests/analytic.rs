//! The renderer on scenes with analytic answers: a sphere under uniform light.

use nalgebra::Vector3;
use rmvp_dataset::polarization::diffuse_dop;
use rmvp_dataset::{Camera, Mesh};
use rmvp_render::pbrdf::{fresnel_dielectric, Interface, Lobes};
use rmvp_render::renderer::FOOTPRINT_SAMPLES;
use rmvp_render::rig::{look_at, rig_intrinsics};
use rmvp_render::shapes::icosphere;
use rmvp_render::{render_view, EnvMap, Object, RenderedView, Settings};
use std::f64::consts::PI;

const SIZE: u32 = 96;

fn camera() -> Camera {
    look_at(rig_intrinsics(SIZE, SIZE), Vector3::new(0.6, 0.8, 4.0), Vector3::zeros(), Vector3::y(), SIZE, SIZE)
}

fn render(lobes: Lobes, albedo: f32, alpha: f32, spp: u32) -> (Camera, RenderedView) {
    let mut mesh = icosphere(5);
    let n = mesh.positions.len();
    for (name, value) in [("red", albedo), ("green", albedo), ("blue", albedo), ("roughness", alpha)] {
        mesh.vertex_properties.push(rmvp_dataset::mesh::VertexProperty {
            name: name.into(),
            kind: rmvp_dataset::mesh::ScalarKind::F32,
            values: vec![value as f64; n],
        });
    }
    let object = Object::new(&mesh, Interface::Dielectric(1.5), lobes).unwrap();
    let cam = camera();
    let view = render_view(&object, &EnvMap::uniform([1.0; 3]), &cam, Settings { spp, seed: 1 }, 0);
    (cam, view)
}

/// The analytic hit of the pixel-centre ray with the unit sphere: (point, depth).
fn sphere_hit(cam: &Camera, i: u32, j: u32) -> Option<(Vector3<f64>, f64)> {
    sphere_hit_at(cam, i as f64 + 0.5, j as f64 + 0.5)
}

/// The mean of the sphere's normals over pixel `(i, j)`'s footprint, normalised, from the rays
/// through the centres of a `FOOTPRINT_SAMPLES` square grid of cells over it.
fn footprint_normal(cam: &Camera, i: u32, j: u32) -> Option<Vector3<f64>> {
    let s = FOOTPRINT_SAMPLES;
    let sum: Vector3<f64> = (0..s * s)
        .filter_map(|c| {
            let (a, b) = ((c % s) as f64 + 0.5, (c / s) as f64 + 0.5);
            sphere_hit_at(cam, i as f64 + a / s as f64, j as f64 + b / s as f64).map(|(p, _)| p)
        })
        .sum();
    (sum.norm() > 0.0).then(|| sum.normalize())
}

/// The analytic hit with the unit sphere of the ray through continuous pixel coordinates
/// `(u, v)`: (point, depth).
fn sphere_hit_at(cam: &Camera, u: f64, v: f64) -> Option<(Vector3<f64>, f64)> {
    let ray = cam.ray(u, v);
    let o = ray.origin.coords;
    let b = o.dot(&ray.direction);
    let disc = b * b - (o.norm_squared() - 1.0);
    (disc >= 0.0).then(|| {
        let p = o + ray.direction * (-b - disc.sqrt());
        (p, cam.world_to_camera(&p.into()).z)
    })
}

#[test]
fn masks_depths_and_normals_match_the_sphere() {
    let (cam, view) = render(Lobes::Plastic, 0.5, 0.1, 8);
    let (mut inside, mut worst_depth, mut worst_normal_deg, mut mask_errors) = (0, 0.0f64, 0.0f64, 0);
    for j in 0..SIZE {
        for i in 0..SIZE {
            let k = (j * SIZE + i) as usize;
            let analytic = sphere_hit(&cam, i, j);
            let masked = view.mask.data()[k] > 0;
            if masked != analytic.is_some() {
                // Only silhouette pixels, partly covered, may differ.
                let near_edge = (-1i32..=1).any(|dj| {
                    (-1i32..=1).any(|di| {
                        sphere_hit(&cam, (i as i32 + di) as u32, (j as i32 + dj) as u32).is_some() != analytic.is_some()
                    })
                });
                assert!(near_edge, "mask differs away from the silhouette at ({i}, {j})");
                mask_errors += 1;
            }
            if let (Some((p, z)), d) = (analytic, view.depth.data()[k]) {
                if d > 0.0 {
                    inside += 1;
                    // The facets sit within their sagitta of the sphere along the normal; a
                    // grazing ray sees that as a depth error of sagitta / cos(theta).
                    let cos_view = p.dot(&-cam.pixel_ray(i, j).direction);
                    worst_depth = worst_depth.max((d as f64 - z).abs() * cos_view);
                    let n = &view.normals.data()[3 * k..3 * k + 3];
                    let p = footprint_normal(&cam, i, j).expect("the centre ray hits");
                    let cos = (n[0] as f64 * p.x + n[1] as f64 * p.y + n[2] as f64 * p.z).clamp(-1.0, 1.0);
                    worst_normal_deg = worst_normal_deg.max(cos.acos().to_degrees());
                }
            }
        }
    }
    assert!(inside > 1000, "{inside}");
    assert!(mask_errors < 60, "{mask_errors} silhouette pixels differ");
    // A level-5 icosphere deviates from the sphere by under 4e-4 (the sagitta of its faces).
    assert!(worst_depth < 4e-4, "depth error along the normal {worst_depth}");
    eprintln!("worst normal error against the footprint's mean: {worst_normal_deg:.3} degrees");
    assert!(worst_normal_deg < 0.5, "normal error {worst_normal_deg} degrees");
}

/// Per object pixel: (normal azimuth in the pixel's Stokes frame, view zenith angle, AoP, DoP).
fn polarization_samples(cam: &Camera, view: &RenderedView) -> Vec<(f64, f64, f64, f64)> {
    let (aop, dop) = view.stokes.aop_dop();
    let mut out = Vec::new();
    for j in 0..SIZE {
        for i in 0..SIZE {
            let k = (j * SIZE + i) as usize;
            let (Some((p, _)), true) = (sphere_hit(cam, i, j), view.mask.data()[k] > 0) else { continue };
            // Stay off the silhouette, where pixels mix normals.
            let all_inside = (-1i32..=1).all(|dj| {
                (-1i32..=1).all(|di| sphere_hit(cam, (i as i32 + di) as u32, (j as i32 + dj) as u32).is_some())
            });
            if !all_inside {
                continue;
            }
            let d = cam.pixel_ray(i, j).direction;
            let (x, y) = cam.stokes_frame(&d);
            let azimuth = p.dot(&y).atan2(p.dot(&x));
            let zenith = p.dot(&-d).clamp(-1.0, 1.0).acos();
            out.push((azimuth, zenith, aop.data()[k] as f64, dop.data()[k] as f64));
        }
    }
    out
}

fn angle_difference_deg(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(PI);
    d.min(PI - d).to_degrees()
}

#[test]
fn diffuse_light_is_polarized_along_the_normal_azimuth_by_fresnel_transmission() {
    let (cam, view) = render(Lobes::Diffuse, 0.8, 0.1, 16);
    let samples = polarization_samples(&cam, &view);
    let mut checked = 0;
    for (azimuth, zenith, aop, dop) in samples {
        let expected = diffuse_dop(zenith as f32, 1.5) as f64;
        assert!((dop - expected).abs() < 0.01 + 0.05 * expected, "zenith {zenith}: DoP {dop} vs {expected}");
        if expected > 0.02 {
            assert!(angle_difference_deg(aop, azimuth) < 2.0, "AoP {aop} vs azimuth {azimuth}");
            checked += 1;
        }
    }
    assert!(checked > 300, "{checked}");
}

#[test]
fn specular_light_is_polarized_across_the_normal_azimuth_by_fresnel_reflection() {
    let (cam, view) = render(Lobes::Specular, 0.0, 0.01, 16);
    let samples = polarization_samples(&cam, &view);
    let (mut aop_errors, mut dop_errors) = (Vec::new(), Vec::new());
    for (azimuth, zenith, aop, dop) in samples {
        let (rs, rp) = fresnel_dielectric(zenith.cos() as f32, 1.5);
        let expected = ((rs - rp) / (rs + rp)) as f64;
        if zenith.to_degrees() < 75.0 {
            dop_errors.push((dop - expected).abs());
        }
        if expected > 0.1 {
            aop_errors.push(angle_difference_deg(aop, azimuth + PI / 2.0));
        }
    }
    // Each sample's half vector scatters around the normal (roughness 0.01), so per-pixel AoP
    // and DoP carry a little Monte Carlo noise.
    let quantile = |v: &mut Vec<f64>, q: f64| {
        v.sort_by(f64::total_cmp);
        v[((v.len() - 1) as f64 * q) as usize]
    };
    assert!(aop_errors.len() > 300, "{}", aop_errors.len());
    let (median, p95) = (quantile(&mut aop_errors, 0.5), quantile(&mut aop_errors, 0.95));
    assert!(median < 0.5 && p95 < 3.0, "AoP - (azimuth + 90 deg): median {median}, p95 {p95}");
    let (median, p95) = (quantile(&mut dop_errors, 0.5), quantile(&mut dop_errors, 0.95));
    assert!(median < 0.01 && p95 < 0.05, "DoP error: median {median}, p95 {p95}");
}

#[test]
fn white_furnace_conserves_energy() {
    // A white Lambertian sphere in a uniform unit environment reflects exactly 1.
    let (_, view) = render(Lobes::Lambertian, 1.0, 0.1, 16);
    let object: Vec<f32> = view
        .stokes
        .s0
        .data()
        .chunks_exact(3)
        .zip(view.mask.data())
        .filter(|(_, &m)| m > 0)
        .map(|(p, _)| p[1])
        .collect();
    let mean = object.iter().sum::<f32>() / object.len() as f32;
    assert!((mean - 1.0).abs() < 0.01, "mean {mean}");
    // Per pixel, Monte Carlo noise at 64 samples only.
    let (_, view) = render(Lobes::Lambertian, 1.0, 0.1, 64);
    let s0 = view.stokes.s0.data();
    assert!(view
        .mask
        .data()
        .iter()
        .enumerate()
        .filter(|(_, &m)| m > 0)
        .all(|(k, _)| (s0[3 * k + 1] - 1.0).abs() < 0.15));
    // The white plastic loses to Fresnel what its diffuse lobe cannot return: never above 1.
    let (_, plastic) = render(Lobes::Plastic, 1.0, 0.1, 16);
    let mean: f32 = plastic
        .stokes
        .s0
        .data()
        .chunks_exact(3)
        .zip(plastic.mask.data())
        .filter(|(_, &m)| m > 0)
        .map(|(p, _)| p[1])
        .sum::<f32>()
        / plastic.mask.data().iter().filter(|&&m| m > 0).count() as f32;
    assert!(mean < 1.0 && mean > 0.8, "plastic mean {mean}");
}

#[test]
fn same_seed_same_bytes_whatever_the_threads() {
    let (_, a) = render(Lobes::Plastic, 0.5, 0.1, 4);
    let b = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| render(Lobes::Plastic, 0.5, 0.1, 4).1);
    assert!(a == b, "renders differ between thread counts");
}

#[test]
fn textured_albedo_is_looked_up_at_the_texture_coordinates() {
    // A quad in the z = 0 plane facing +z, texture coordinates spanning it, under a uniform unit
    // sky: a Lambertian surface then reflects exactly its albedo.
    use rmvp_dataset::mesh::{ScalarKind, VertexProperty};
    let positions = vec![[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]];
    let uv = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let property = |name: &str, k: usize| VertexProperty {
        name: name.into(),
        kind: ScalarKind::F32,
        values: uv.iter().map(|t| t[k]).collect(),
    };
    let mesh = Mesh {
        normals: Some(vec![[0.0, 0.0, 1.0]; 4]),
        positions,
        faces: vec![[0, 1, 2], [0, 2, 3]],
        vertex_properties: vec![property("u", 0), property("v", 1)],
    };
    // Texel (i, j), j counted from the top row: red grows to the right, green downwards.
    let texel = |i: usize, j: usize| [(i + 1) as f32 / 5.0, (j + 1) as f32 / 5.0, 0.5];
    let data = (0..16).flat_map(|k| texel(k % 4, k / 4)).collect();
    let mut object = Object::new(&mesh, Interface::Dielectric(1.5), Lobes::Lambertian).unwrap();
    object.set_albedo_texture(rmvp_dataset::Image::from_vec(4, 4, 3, data).unwrap()).unwrap();
    let cam =
        look_at(rig_intrinsics(SIZE, SIZE), Vector3::new(0.0, 0.0, 6.0), Vector3::zeros(), Vector3::y(), SIZE, SIZE);
    let view = render_view(&object, &EnvMap::uniform([1.0; 3]), &cam, Settings { spp: 64, seed: 2 }, 0);
    assert!(view.stokes.s0.width() == SIZE as usize);
    // Interior texels: at the border the wrapping neighbour breaks the linear ramp.
    for j in 1..3 {
        for i in 1..3 {
            // The texel centre on the quad: u = (i + 0.5) / 4, v = 1 - (j + 0.5) / 4.
            let (u, v) = ((i as f64 + 0.5) / 4.0, 1.0 - (j as f64 + 0.5) / 4.0);
            let p = cam.project(&nalgebra::Point3::new(2.0 * u - 1.0, 2.0 * v - 1.0, 0.0)).unwrap();
            // Average a symmetric 5x5 block: bilinear interpolation is linear around the texel
            // centre, so the mean keeps its value while Monte Carlo noise drops fivefold.
            let (x, y) = (p.x as usize, p.y as usize);
            let mut s0 = [0.0f32; 3];
            for k in 0..25 {
                let px = view.stokes.s0.pixel(x + k % 5 - 2, y + k / 5 - 2);
                (0..3).for_each(|c| s0[c] += px[c] / 25.0);
            }
            let want = texel(i, j);
            assert!((0..3).all(|c| (s0[c] - want[c]).abs() < 0.05), "texel ({i}, {j}): {s0:?} vs {want:?}");
        }
    }
    // A mesh without texture coordinates cannot take a texture.
    let mut plain = Object::new(&icosphere(1), Interface::Dielectric(1.5), Lobes::Plastic).unwrap();
    let err = plain.set_albedo_texture(rmvp_dataset::Image::new(2, 2, 3)).unwrap_err();
    assert!(matches!(err, rmvp_render::Error::NoTextureCoordinates), "{err}");
    let point_cloud = rmvp_dataset::Mesh { faces: Vec::new(), ..icosphere(1) };
    let err = Object::new(&point_cloud, Interface::Dielectric(1.5), Lobes::Plastic).err().unwrap();
    assert!(matches!(err, rmvp_render::Error::NoFaces), "{err}");
}
