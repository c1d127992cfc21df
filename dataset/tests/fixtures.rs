//! Our conventions and loaders against the Mitsuba 3 reference scenes in `shared/fixtures`
//! (see its README for the facts checked here).

use nalgebra::{Matrix3x4, Point3};
use rmvp_dataset::io::{exr, npy, png};
use rmvp_dataset::layout::{nersp, read_scene, write_scene, Layout};
use rmvp_dataset::polarization::{aop_to_u16, stokes_from_four};
use rmvp_dataset::{Camera, Mesh, Scene};
use rmvp_testkit::fixture_scenes as fixtures;
use std::path::{Path, PathBuf};

fn png_scale(dir: &Path) -> f64 {
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("gt/cameras.json")).unwrap()).unwrap();
    json["png_scale"].as_f64().unwrap()
}

#[test]
fn aop_from_stokes_matches_the_azimuth_maps_to_the_count() {
    for dir in fixtures() {
        let scene = read_scene(&dir).unwrap();
        for (i, view) in scene.train_views().enumerate() {
            let stored = png::read_png_u16(&dir.join(format!("input_azimuth_maps/{i:04}.png"))).unwrap();
            let (ours, _) = view.stokes.as_ref().unwrap().aop_dop();
            let (mut exact, mut worst) = (0usize, 0i32);
            for (k, &a) in ours.data().iter().enumerate() {
                let diff = (aop_to_u16(a) as i32 - stored.data()[4 * k] as i32).abs();
                // AoP wraps at pi: count 65535 and 0 are neighbours.
                let diff = diff.min(65535 - diff);
                exact += (diff == 0) as usize;
                worst = worst.max(diff);
            }
            let fraction = exact as f64 / ours.data().len() as f64;
            assert!(
                worst <= 1 && fraction > 0.999,
                "{}: view {i}: {fraction} exact, worst {worst} counts",
                dir.display()
            );
        }
    }
}

#[test]
fn stokes_from_polarizer_images_match_the_stored_stokes() {
    for dir in fixtures() {
        let scale = png_scale(&dir) as f32;
        let scene = read_scene(&dir).unwrap();
        for view in scene.train_views() {
            let pol = view.polarized.as_ref().unwrap();
            let s = view.stokes.as_ref().unwrap();
            let (mut checked, mut worst) = (0, 0.0f32);
            for k in 0..s.s0.data().len() {
                let counts = pol.images.each_ref().map(|img| img.data()[k]);
                if counts.contains(&u16::MAX) {
                    continue; // clipped: the PNG cannot hold the intensity
                }
                let i = counts.map(|c| c as f32 / 65535.0 / scale);
                let ours = stokes_from_four(i);
                for (o, t) in ours.iter().zip([s.s0.data()[k], s.s1.data()[k], s.s2.data()[k]]) {
                    worst = worst.max((o - t).abs());
                }
                checked += 1;
            }
            // Each count is within half a count of the truth: S0 and S1, S2 within one count.
            let bound = 1.0 / 65535.0 / scale + 1e-6;
            assert!(checked > s.s0.data().len() * 9 / 10, "too many clipped pixels");
            assert!(worst <= bound, "{}: view {}: worst Stokes error {worst:e} > {bound:e}", dir.display(), view.name);
        }
    }
}

fn world_mats(dir: &Path) -> Vec<Matrix3x4<f64>> {
    let arrays = npy::read_npz::<f64>(&dir.join(nersp::CAMERAS)).unwrap();
    (0..)
        .map_while(|i| arrays.iter().find(|(n, _)| *n == format!("world_mat_{i}")))
        .map(|(_, a)| Matrix3x4::from_row_slice(&a.data[..12]))
        .collect()
}

#[test]
fn decomposed_world_mats_match_the_reference_cameras() {
    for dir in fixtures() {
        let scene = read_scene(&dir).unwrap();
        for (p, view) in world_mats(&dir).iter().zip(scene.train_views()) {
            let camera = Camera::from_projection(p, view.camera.width, view.camera.height).unwrap();
            let reference = &view.camera;
            assert!((camera.k - reference.k).abs().max() < 1e-9 * reference.k.abs().max(), "K of {}", view.name);
            assert!((camera.r - reference.r).abs().max() < 1e-12, "R of {}", view.name);
            assert!((camera.t - reference.t).abs().max() < 1e-12, "t of {}", view.name);
            assert!((camera.r.determinant() - 1.0).abs() < 1e-12);
        }
    }
}

#[test]
fn ground_truth_mesh_projects_into_the_masks() {
    for dir in fixtures() {
        let mesh = Mesh::read(&dir.join("gt/mesh.ply")).unwrap();
        let scene = read_scene(&dir).unwrap();
        for (p, view) in world_mats(&dir).iter().zip(scene.train_views()) {
            let camera = Camera::from_projection(p, view.camera.width, view.camera.height).unwrap();
            let mask = view.mask.as_ref().unwrap();
            let inside_dilated = |x: i64, y: i64| {
                (-1..=1).any(|dy| {
                    (-1..=1).any(|dx| {
                        let (u, v) = (x + dx, y + dy);
                        u >= 0
                            && v >= 0
                            && (u as usize) < mask.width()
                            && (v as usize) < mask.height()
                            && mask.pixel(u as usize, v as usize)[0] > 127
                    })
                })
            };
            let hits = mesh
                .positions
                .iter()
                .filter(|p| {
                    let q = camera.project(&Point3::new(p[0] as f64, p[1] as f64, p[2] as f64)).unwrap();
                    inside_dilated(q.x.floor() as i64, q.y.floor() as i64)
                })
                .count();
            let fraction = hits as f64 / mesh.positions.len() as f64;
            assert!(
                fraction >= 0.999,
                "{}: view {}: {:.4} of vertices inside the dilated mask",
                dir.display(),
                view.name,
                fraction
            );
        }
    }
}

/// Compare two files of a scene folder by decoded content, bit for bit.
fn assert_same_content(a: &Path, b: &Path) {
    let ext = a.extension().unwrap().to_str().unwrap();
    match ext {
        "npy" => {
            let (x, y) = (npy::read_npy::<f32>(a).unwrap(), npy::read_npy::<f32>(b).unwrap());
            assert_eq!(x.shape, y.shape, "{}", a.display());
            assert!(x.data.iter().zip(&y.data).all(|(p, q)| p.to_bits() == q.to_bits()), "{}", a.display());
        }
        "npz" => {
            let (x, y) = (npy::read_npz::<f64>(a).unwrap(), npy::read_npz::<f64>(b).unwrap());
            assert_eq!(x.len(), y.len());
            for ((nx, ax), (ny, ay)) in x.iter().zip(&y) {
                assert_eq!(nx, ny);
                assert!(ax.data.iter().zip(&ay.data).all(|(p, q)| p.to_bits() == q.to_bits()), "{} {nx}", a.display());
            }
        }
        "png" => assert_eq!(png::read_png(a).unwrap(), png::read_png(b).unwrap(), "{}", a.display()),
        "exr" => {
            let (x, y) = (exr::read_exr_channels(a).unwrap(), exr::read_exr_channels(b).unwrap());
            assert_eq!((x.0, x.1), (y.0, y.1));
            for ((nx, cx), (ny, cy)) in x.2.iter().zip(&y.2) {
                assert_eq!(nx, ny);
                assert!(cx.iter().zip(cy).all(|(p, q)| p.to_bits() == q.to_bits()), "{} {nx}", a.display());
            }
        }
        "json" => {
            let read =
                |p: &Path| serde_json::from_str::<serde_json::Value>(&std::fs::read_to_string(p).unwrap()).unwrap();
            assert_eq!(read(a), read(b), "{}", a.display());
        }
        "ply" => assert_eq!(Mesh::read(a).unwrap(), Mesh::read(b).unwrap(), "{}", a.display()),
        other => panic!("unexpected file type {other} in {}", a.display()),
    }
}

fn files_below(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            out.extend(files_below(&path));
        } else {
            out.push(path);
        }
    }
    out.sort();
    out
}

#[test]
fn nersp_layout_round_trips_through_ours_bit_exactly() {
    for dir in fixtures() {
        let tmp = tempfile::tempdir().unwrap();
        let (ours, back) = (tmp.path().join("ours"), tmp.path().join("back"));
        let original = read_scene(&dir).unwrap();
        write_scene(&original, &ours, Layout::Rmvp).unwrap();
        assert_eq!(Layout::detect(&ours).unwrap(), Layout::Rmvp);
        let via_ours = read_scene(&ours).unwrap();
        assert!(via_ours == original, "{}: scene changed through our layout", dir.display());
        write_scene(&via_ours, &back, Layout::Nersp).unwrap();
        for file in files_below(&dir) {
            let relative = file.strip_prefix(&dir).unwrap();
            let copy = back.join(relative);
            assert!(copy.is_file(), "{} was not written back", relative.display());
            assert_same_content(&file, &copy);
        }
        assert_eq!(files_below(&back).len(), files_below(&dir).len(), "extra files written");
        let again: Scene = read_scene(&back).unwrap();
        assert!(again == original, "{}: scene changed through NeRSP -> rmvp -> NeRSP", dir.display());
        assert!(rmvp_dataset::layout::rmvp::read(&ours).is_ok());
    }
}
