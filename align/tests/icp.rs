//! Alignment with scale against known answers, in the spirit of libpointmatcher's and
//! small_gicp's suites: spot scaled to millimetres is the target.

use nalgebra::{Rotation3, Vector3};
use rmvp_align::icp::{ALIGNED_MESH, ALIGNMENT_FILE};
use rmvp_align::sampling::sample_surface;
use rmvp_align::{align, align_files, Alignment, Error, IcpOptions, Similarity};
use rmvp_dataset::rng::Rng;
use rmvp_dataset::Mesh;

/// The built-in spot, 200 mm across.
fn target() -> Mesh {
    let spot = rmvp_render::default_mesh();
    Mesh { positions: spot.positions.iter().map(|p| p.map(|v| v * 100.0)).collect(), ..spot }
}

fn options() -> IcpOptions {
    IcpOptions { max_scan_points: 10_000, target_samples: 60_000, ..IcpOptions::default() }
}

fn truth(angle_deg: f64, axis: Vector3<f64>, s: f64, t: Vector3<f64>) -> Similarity {
    Similarity {
        r: *Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle_deg.to_radians()).matrix(),
        t,
        s,
    }
}

/// A scan of `target`: surface samples moved by the inverse of `truth` (so that aligning the
/// scan onto the target must find `truth`).
fn scan(target: &Mesh, truth: &Similarity, count: usize, seed: u64) -> Mesh {
    let inverse = truth.inverse();
    let positions = sample_surface(target, count, seed + rmvp_testkit::test_seed())
        .into_iter()
        .map(|p| {
            let q = inverse.apply(&Vector3::from(p.map(|v| v as f64)));
            [q.x as f32, q.y as f32, q.z as f32]
        })
        .collect();
    Mesh { positions, ..Mesh::default() }
}

fn assert_close(found: &Similarity, want: &Similarity, max_deg: f64, max_scale: f64, max_t: f64) {
    let error = found.compose(&want.inverse());
    let (deg, scale, t) = (error.angle_deg(), (found.s / want.s - 1.0).abs(), (found.t - want.t).norm());
    eprintln!("alignment error: rotation {deg:.4} deg, scale {scale:.2e}, translation {t:.4}");
    assert!(
        deg < max_deg && scale < max_scale && t < max_t,
        "rotation off by {deg} deg, scale by {scale}, translation by {t}"
    );
}

#[test]
fn identical_clouds_give_the_identity() {
    // Target and scan are the same points (a cloud with normals): zero residuals.
    let spot = target();
    let cloud = Mesh { faces: Vec::new(), ..spot };
    let found = align(&cloud, &cloud, &options()).unwrap();
    assert_close(&found.transform, &Similarity::identity(), 1e-4, 1e-6, 1e-4);
    assert!(found.rms < 1e-4 && found.inlier_ratio > 0.999, "{found:?}");
}

#[test]
fn a_known_similarity_is_recovered() {
    let target = target();
    let want = truth(20.0, Vector3::new(0.3, 1.0, -0.2), 1.04, Vector3::new(12.0, -7.0, 30.0));
    let found = align(&scan(&target, &want, 40_000, 5), &target, &options()).unwrap();
    assert_close(&found.transform, &want, 0.1, 5e-4, 0.2);
    // Forward and inverse agree: aligning the target onto the scan gives the inverse.
    let scan_surface = Mesh {
        positions: target
            .positions
            .iter()
            .map(|p| {
                let q = want.inverse().apply(&Vector3::from(p.map(|v| v as f64)));
                [q.x as f32, q.y as f32, q.z as f32]
            })
            .collect(),
        normals: None,
        ..target.clone()
    };
    let target_as_scan =
        Mesh { positions: sample_surface(&target, 40_000, 9 + rmvp_testkit::test_seed()), ..Mesh::default() };
    let back = align(&target_as_scan, &scan_surface, &options()).unwrap();
    assert_close(&back.transform.compose(&found.transform), &Similarity::identity(), 0.1, 5e-4, 0.3);
}

#[test]
fn far_starts_converge_through_the_multistart() {
    let target = target();
    for angle in [90.0, 150.0] {
        let want = truth(angle, Vector3::new(1.0, 0.4, 0.2), 0.97, Vector3::new(-20.0, 5.0, 8.0));
        let found = align(&scan(&target, &want, 20_000, 3), &target, &options()).unwrap();
        assert_close(&found.transform, &want, 0.1, 5e-4, 0.3);
    }
}

#[test]
fn cropped_noisy_scans_with_outliers_still_align() {
    let target = target();
    let want = truth(20.0, Vector3::new(-0.2, 1.0, 0.5), 1.04, Vector3::new(5.0, 10.0, -4.0));
    let mut cloud = scan(&target, &want, 40_000, 7);
    // Crop 12 % of the target (the points with the largest x), add 0.3 mm noise and 1 % outliers.
    let inverse = want;
    let mut xs: Vec<f32> =
        cloud.positions.iter().map(|p| inverse.apply(&Vector3::from(p.map(|v| v as f64))).x as f32).collect();
    let mut sorted = xs.clone();
    sorted.sort_by(f32::total_cmp);
    let cut = sorted[(sorted.len() as f64 * 0.88) as usize];
    let mut rng = Rng::for_pixel(11 + rmvp_testkit::test_seed(), 0, 0);
    let kept: Vec<[f32; 3]> = cloud
        .positions
        .drain(..)
        .zip(xs.drain(..))
        .filter(|(_, x)| *x < cut)
        .map(|(p, _)| p.map(|v| v + 0.3 * rng.normal()))
        .collect();
    let outliers = kept.len() / 100;
    let mut positions = kept;
    for _ in 0..outliers {
        positions.push([0, 1, 2].map(|_| (rng.next_f32() - 0.5) * 300.0));
    }
    let found = align(&Mesh { positions, ..Mesh::default() }, &target, &options()).unwrap();
    assert_close(&found.transform, &want, 0.2, 1e-3, 0.5);
    assert!(found.inlier_ratio > 0.95 && found.inlier_ratio < 1.0, "{}", found.inlier_ratio);
}

#[test]
fn a_plane_shifted_along_its_normal_is_a_pure_translation() {
    // A flat 200 mm square; the scan is shifted 3 mm along the normal. Sliding in the plane
    // is unconstrained: the damping must keep it (and rotation and scale) from blowing up.
    let n = 40;
    let mut positions = Vec::new();
    let mut faces = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            positions.push([i as f32 * 200.0 / n as f32 - 100.0, j as f32 * 200.0 / n as f32 - 100.0, 0.0]);
        }
    }
    for j in 0..n {
        for i in 0..n {
            let k = (j * (n + 1) + i) as u32;
            faces.push([k, k + 1, k + n as u32 + 2]);
            faces.push([k, k + n as u32 + 2, k + n as u32 + 1]);
        }
    }
    let plane = Mesh { positions, faces, ..Mesh::default() };
    let scan = Mesh {
        positions: sample_surface(&plane, 10_000, 2).iter().map(|p| [p[0] * 0.98, p[1] * 0.98, p[2] + 3.0]).collect(),
        ..Mesh::default()
    };
    let found = align(&scan, &plane, &IcpOptions { coarse: false, ..options() }).unwrap();
    let t = found.transform;
    assert!((t.t.z + 3.0).abs() < 0.01, "{:?}", t.t);
    assert!(t.angle_deg() < 0.01 && (t.s - 1.0).abs() < 0.03 && t.t.xy().norm() < 2.0, "{t:?}");
}

#[test]
fn alignment_files_read_back_what_they_wrote() {
    let dir = tempfile::tempdir().unwrap();
    let target = target();
    let want = truth(10.0, Vector3::new(0.0, 1.0, 0.0), 1.02, Vector3::new(3.0, -2.0, 1.0));
    let (scan_path, target_path) = (dir.path().join("scan.ply"), dir.path().join("target.ply"));
    scan(&target, &want, 5_000, 1).write(&scan_path).unwrap();
    target.write(&target_path).unwrap();
    let options = IcpOptions { max_scan_points: 5_000, target_samples: 20_000, ..IcpOptions::default() };
    let found = align_files(&scan_path, &target_path, dir.path(), &options).unwrap();
    let path = dir.path().join(ALIGNMENT_FILE);
    assert_eq!(Alignment::read(&path).unwrap(), found);
    let aligned = Mesh::read(&dir.path().join(ALIGNED_MESH)).unwrap();
    assert_eq!(aligned.positions.len(), 5_000);
    let first = found.transform.apply(&Vector3::from(Mesh::read(&scan_path).unwrap().positions[0].map(|v| v as f64)));
    assert!((Vector3::from(aligned.positions[0].map(|v| v as f64)) - first).norm() < 1e-3);

    // A file whose inverse does not match its forward transform is refused, naming the file.
    let text = std::fs::read_to_string(&path).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json["target_to_scan"]["t"][0] = serde_json::json!(99.0);
    json["target_to_scan"]["matrix"][0][3] = serde_json::json!(99.0);
    std::fs::write(&path, json.to_string()).unwrap();
    let err = Alignment::read(&path).unwrap_err().to_string();
    assert!(err.contains(ALIGNMENT_FILE) && err.contains("not the inverse"), "{err}");

    // Too small a scan is a typed error.
    let tiny = Mesh { positions: vec![[0.0; 3]; 5], ..Mesh::default() };
    assert!(matches!(align(&tiny, &target, &options), Err(Error::TooFewScanPoints { points: 5 })));
}

#[test]
fn a_grown_target_seen_from_above_only_pulls_a_rigid_fit_unless_its_offset_is_fitted() {
    // The target as a reconstruction from views above a table gives it: grown by 0.5 mm along
    // its normals (dilated masks) and without its lowest fifth (never seen). The scan is the
    // true object, whole, at the known scale. A plain rigid fit is pulled up by the grown top
    // (nothing below pulls back); fitting the offset as an unknown removes that pull.
    let spot = target();
    let mut normals = vec![Vector3::<f64>::zeros(); spot.positions.len()];
    for f in &spot.faces {
        let [a, b, c] = f.map(|i| Vector3::from(spot.positions[i as usize].map(|v| v as f64)));
        for i in f {
            normals[*i as usize] += (b - a).cross(&(c - a));
        }
    }
    let grown: Vec<[f32; 3]> = spot
        .positions
        .iter()
        .zip(&normals)
        .map(|(p, n)| (Vector3::from(p.map(|v| v as f64)) + 0.5 * n.normalize()).map(|v| v as f32).into())
        .collect();
    let (lo, hi) = spot.bounds().unwrap();
    let cut = lo[1] + 0.2 * (hi[1] - lo[1]);
    let faces = spot.faces.iter().filter(|f| f.iter().all(|&i| spot.positions[i as usize][1] > cut)).copied().collect();
    let reference = Mesh { positions: grown, faces, normals: None, ..spot.clone() };
    let want = truth(25.0, Vector3::new(0.2, 1.0, -0.4), 1.0, Vector3::new(-30.0, 12.0, 40.0));
    let cloud = scan(&spot, &want, 40_000, 13);
    let initial = truth(0.5, Vector3::new(1.0, 0.0, 1.0), 1.0, Vector3::new(1.0, -1.0, 0.5)).compose(&want);
    let rigid = |fit_offset| {
        let options = IcpOptions { coarse: false, initial, fixed_scale: true, fit_offset, ..options() };
        align(&cloud, &reference, &options).unwrap()
    };
    let centre = Vector3::new(0.0, 0.5 * (lo[1] + hi[1]) as f64, 0.0);
    let centre_error = |a: &Alignment| (a.transform.apply(&want.inverse().apply(&centre)) - centre).norm();
    let (plain, fitted) = (rigid(false), rigid(true));
    assert!(centre_error(&plain) > 0.15 && plain.target_offset == 0.0, "{} {plain:?}", centre_error(&plain));
    assert!(centre_error(&fitted) < 0.02, "centre off by {} mm: {fitted:?}", centre_error(&fitted));
    assert!((fitted.target_offset - 0.5).abs() < 0.05, "offset {}", fitted.target_offset);
    assert_close(&fitted.transform, &want, 0.02, 1e-12, 0.2);
    assert!(fitted.rms < 0.05, "rms from the offset surface {}", fitted.rms);
}
