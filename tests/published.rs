//! Scenes as the field publishes them, through the commands a researcher runs first: `rmvp
//! dataset info` names the layout, `convert` gives the source's cameras, masks and Stokes, and
//! `recon` trains on it.

use nalgebra::{Matrix3, UnitQuaternion};
use rmvp_dataset::io::png;
use rmvp_dataset::layout::{read_scene, write_scene, Layout};
use rmvp_dataset::session::VIEW_STOKES;
use rmvp_dataset::{Distortion, Image, Scene, Split, Stokes, View};
use rmvp_pipeline::ground_truth::mask_iou;
use std::path::Path;

mod common;
use common::{fails, ok, s};

/// The spot fixture's training views.
fn spot_training_views() -> Scene {
    let mut scene = read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
    scene.views.retain(|v| v.split == Split::Train);
    scene
}

fn opens_converts_and_reconstructs(layout: Layout, tmp: &Path) {
    let source = spot_training_views();
    let dir = tmp.join(layout.name());
    write_scene(&source, &dir, layout).unwrap();
    if layout == Layout::Nersp {
        // The official loader's complete scene: masks only in the azimuth maps' alpha.
        std::fs::remove_dir_all(dir.join("mask")).unwrap();
        std::fs::remove_dir_all(dir.join("gt")).unwrap();
    }
    let info = ok(&["dataset", "info", s(&dir)]);
    assert!(info.contains(&format!("({} layout), valid", layout.name())), "{info}");

    let converted = tmp.join(format!("{}-as-nersp", layout.name()));
    ok(&["dataset", "convert", s(&dir), s(&converted), "--to", "nersp"]);
    let back = read_scene(&converted).unwrap();
    assert_eq!(back.views.len(), source.views.len());
    for (a, b) in source.views.iter().zip(&back.views) {
        assert!((a.camera.k - b.camera.k).abs().max() < 1e-9 && (a.camera.t - b.camera.t).abs().max() < 1e-12);
        assert_eq!(a.mask, b.mask, "{}: mask", a.name);
        if layout != Layout::Pandora {
            assert_eq!(a.stokes, b.stokes, "{}: Stokes", a.name); // PANDORA's RGBE: its own test
        }
    }

    let out = tmp.join(format!("{}-recon", layout.name()));
    ok(&["recon", s(&dir), "-o", s(&out), "--iters", "4", "--batch", "32", "--mesh-res", "24", "--mesh-only"]);
    let log = std::fs::read_to_string(out.join("log.jsonl")).unwrap();
    assert_eq!(log.lines().count(), 4, "{log}");
}

#[test]
fn published_layouts_open_convert_and_reconstruct() {
    let tmp = tempfile::tempdir().unwrap();
    for layout in [Layout::Nersp, Layout::Rmvp3d, Layout::Pandora] {
        opens_converts_and_reconstructs(layout, tmp.path());
    }
}

#[test]
fn a_folder_with_part_of_a_layout_is_told_what_it_lacks() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("object");
    std::fs::create_dir_all(dir.join("images_stokes")).unwrap();
    std::fs::write(dir.join("images_stokes/01_s0.hdr"), b"").unwrap();
    let err = fails(&["dataset", "info", s(&dir)]);
    assert!(err.contains("looks like the RMVP3D or PANDORA layout but has no cameras.npz"), "{err}");
}

/// The camera models of a default COLMAP run: name, parameters for a camera whose focal
/// length, principal point and distortion are `f`, `c` and `d` (COLMAP's order), and the
/// distortion rmvp should read from them.
fn colmap_models(f: [f64; 2], c: [f64; 2]) -> Vec<(&'static str, Vec<f64>, Option<Distortion>)> {
    let radial = |k1, k2, p1, p2| Some(Distortion { k1, k2, p1, p2, k3: 0.0 });
    vec![
        ("SIMPLE_PINHOLE", vec![f[0], c[0], c[1]], None),
        ("PINHOLE", vec![f[0], f[1], c[0], c[1]], None),
        ("SIMPLE_RADIAL", vec![f[0], c[0], c[1], -0.3], radial(-0.3, 0.0, 0.0, 0.0)),
        ("RADIAL", vec![f[0], c[0], c[1], -0.3, 0.1], radial(-0.3, 0.1, 0.0, 0.0)),
        ("OPENCV", vec![f[0], f[1], c[0], c[1], -0.25, 0.08, 0.01, -0.008], radial(-0.25, 0.08, 0.01, -0.008)),
    ]
}

/// `image` as a camera with lens distortion `d` sees what the pinhole camera `k` saw: each
/// distorted pixel centre undistorted and looked up bilinearly (masks are thresholded after).
fn distorted(image: &Image<f32>, k: &Matrix3<f64>, d: &Distortion) -> Image<f32> {
    let (w, h, c) = (image.width(), image.height(), image.channels());
    let mut out = Image::new(w, h, c);
    for y in 0..h {
        for x in 0..w {
            let (xd, yd) = ((x as f64 + 0.5 - k[(0, 2)]) / k[(0, 0)], (y as f64 + 0.5 - k[(1, 2)]) / k[(1, 1)]);
            let (xu, yu) = d.undistort(xd, yd);
            let (u, v) = (k[(0, 0)] * xu + k[(0, 2)] - 0.5, k[(1, 1)] * yu + k[(1, 2)] - 0.5);
            let (u, v) = (u.clamp(0.0, (w - 1) as f64), v.clamp(0.0, (h - 1) as f64));
            let (x0, y0) = (u.floor() as usize, v.floor() as usize);
            let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
            let (fx, fy) = ((u - x0 as f64) as f32, (v - y0 as f64) as f32);
            for ch in 0..c {
                let p = |x: usize, y: usize| image.pixel(x, y)[ch];
                out.pixel_mut(x, y)[ch] = (p(x0, y0) * (1.0 - fx) + p(x1, y0) * fx) * (1.0 - fy)
                    + (p(x0, y1) * (1.0 - fx) + p(x1, y1) * fx) * fy;
            }
        }
    }
    out
}

/// A capture session of the spot's training views seen through lens distortion `d` (none:
/// as rendered), with its masks as JPEG files in `masks` (the first view's wrong there and
/// right, as TIFF, in `corrections`).
fn distorted_session(dir: &Path, d: Option<&Distortion>, masks: &Path, corrections: &Path) {
    let source = spot_training_views();
    let (w, h) = source.views[0].stokes.as_ref().unwrap().s0.size();
    let mut manifest: serde_json::Value =
        serde_json::from_str(include_str!("../dataset/tests/data/session.json")).unwrap();
    manifest["camera"]["width"] = w.into();
    manifest["camera"]["height"] = h.into();
    manifest["views_planned"] = source.views.len().into();
    let template = manifest["views"][0].clone();
    let mut views = Vec::new();
    for dir in [masks, corrections] {
        std::fs::create_dir_all(dir).unwrap();
    }
    for (i, view) in source.views.iter().enumerate() {
        let name = format!("{i:03}");
        let mut record = template.clone();
        record["index"] = i.into();
        record["name"] = name.clone().into();
        record["files"] = serde_json::json!([]);
        views.push(record);
        let k = view.camera.k;
        let through = |image: &Image<f32>| d.map_or_else(|| image.clone(), |d| distorted(image, &k, d));
        let stokes = view.stokes.as_ref().unwrap();
        let seen = Stokes { s0: through(&stokes.s0), s1: through(&stokes.s1), s2: through(&stokes.s2) };
        let folder = dir.join("views").join(&name);
        std::fs::create_dir_all(&folder).unwrap();
        rmvp_dataset::layout::rmvp::write_stokes(&folder.join(VIEW_STOKES), &seen).unwrap();
        let mask = through(&view.mask.as_ref().unwrap().map(|v| v as f32 / 255.0));
        let mask = image::GrayImage::from_fn(w as u32, h as u32, |x, y| {
            image::Luma([if mask.pixel(x as usize, y as usize)[0] > 0.5 { 255 } else { 0 }])
        });
        if i == 0 {
            mask.save(corrections.join(format!("{name}.tif"))).unwrap();
            image::GrayImage::new(w as u32, h as u32).save(masks.join(format!("{name}.jpg"))).unwrap();
        } else {
            mask.save(masks.join(format!("{name}.jpg"))).unwrap();
        }
    }
    manifest["views"] = views.into();
    std::fs::write(dir.join("session.json"), serde_json::to_string_pretty(&manifest).unwrap()).unwrap();
}

#[test]
fn a_hand_made_mask_of_the_wrong_size_is_named_by_its_file() {
    let tmp = tempfile::tempdir().unwrap();
    let (session, masks, corrections) = (tmp.path().join("session"), tmp.path().join("masks"), tmp.path().join("c"));
    distorted_session(&session, None, &masks, &corrections);
    image::GrayImage::new(1, 1).save(masks.join("005.jpg")).unwrap();
    let out = tmp.path().join("masks-out");
    let err = fails(&["masks", s(&session), "--method", "folder", "--from", s(&masks), "-o", s(&out)]);
    let file = masks.join("005.jpg");
    let named = format!("{}: the mask of view 005 is 1x1, the view's ", file.display());
    assert!(err.contains(&named), "{err}");
    assert_eq!(err.matches("005.jpg").count(), 1, "the file named once: {err}");
}

/// A COLMAP text model of the spot's training cameras, all with one camera of `model`.
fn colmap_model(dir: &Path, model: &str, params: &[f64]) {
    std::fs::create_dir_all(dir).unwrap();
    let source = spot_training_views();
    let (w, h) = (source.views[0].camera.width, source.views[0].camera.height);
    let params: Vec<String> = params.iter().map(|p| format!("{p:.17}")).collect();
    std::fs::write(dir.join("cameras.txt"), format!("1 {model} {w} {h} {}\n", params.join(" "))).unwrap();
    let mut images = String::new();
    for (i, view) in source.views.iter().enumerate() {
        let q = UnitQuaternion::from_matrix(&view.camera.r);
        let t = view.camera.t;
        images += &format!(
            "{} {:.17} {:.17} {:.17} {:.17} {:.17} {:.17} {:.17} 1 {i:03}.png\n\n",
            i + 1,
            q.w,
            q.i,
            q.j,
            q.k,
            t.x,
            t.y,
            t.z
        );
    }
    std::fs::write(dir.join("images.txt"), images).unwrap();
    std::fs::write(dir.join("points3D.txt"), "").unwrap();
}

/// Mean absolute S0 difference over the pixels both masks hold, relative to the mean S0 there.
fn s0_difference(a: &View, b: &View) -> f64 {
    let (sa, sb) = (&a.stokes.as_ref().unwrap().s0, &b.stokes.as_ref().unwrap().s0);
    let (ma, mb) = (a.mask.as_ref().unwrap(), b.mask.as_ref().unwrap());
    let (mut diff, mut level, mut n) = (0.0, 0.0, 0);
    for (p, (x, y)) in sa.data().iter().zip(sb.data()).enumerate() {
        let pixel = p / sa.channels();
        if ma.data()[pixel] > 127 && mb.data()[pixel] > 127 {
            (diff, level, n) = (diff + (x - y).abs() as f64, level + x.abs() as f64, n + 1);
        }
    }
    assert!(n > 100, "{n} pixels in both masks");
    diff / level
}

#[test]
fn colmap_models_of_a_default_run_import_and_the_dataset_is_undistorted() {
    let tmp = tempfile::tempdir().unwrap();
    let source = spot_training_views();
    let k = source.views[0].camera.k;
    assert!(source.views.iter().all(|v| v.camera.k == k), "one camera");
    for (model, params, distortion) in colmap_models([k[(0, 0)], k[(1, 1)]], [k[(0, 2)], k[(1, 2)]]) {
        let dir = tmp.path().join(model);
        let (session, model_dir, masks, corrections) =
            (dir.join("session"), dir.join("sparse/0"), dir.join("masks"), dir.join("corrections"));
        distorted_session(&session, distortion.as_ref(), &masks, &corrections);
        colmap_model(&model_dir, model, &params);
        ok(&["poses", s(&session), "--method", "import", "--from", s(&model_dir), "-o", s(&dir.join("poses.json"))]);
        // The world is named for datasheets without this machine's paths.
        let poses = std::fs::read_to_string(dir.join("poses.json")).unwrap();
        assert!(poses.contains("(sparse/0)") && !poses.contains(s(tmp.path())), "{poses}");
        ok(&[
            "masks",
            s(&session),
            "--method",
            "folder",
            "--from",
            s(&masks),
            "--corrections",
            s(&corrections),
            "-o",
            s(&dir.join("masks-out")),
        ]);
        let dataset = dir.join("dataset");
        ok(&["dataset", "build", s(&session), "-o", s(&dataset), "--train-views", "6"]);
        let built = read_scene(&dataset.join("rmvp")).unwrap();
        // Each view against the source: the dataset's (undistorted) and the session's (as the
        // lens saw it). Mask pixels off (1 - IoU) and relative S0 differences, summed.
        let (mut off, mut off_captured, mut s0, mut s0_captured) = (0.0, 0.0, 0.0, 0.0);
        for (i, (want, got)) in source.views.iter().zip(&built.views).enumerate() {
            let (a, b) = (&want.camera, &got.camera);
            assert!(b.distortion.is_none(), "{model}: the dataset's cameras are pinhole");
            assert!((a.k - b.k).abs().max() < 1e-9 && (a.r - b.r).abs().max() < 1e-9, "{model} view {i}");
            let mut captured = got.clone();
            let folder = session.join("views").join(format!("{i:03}"));
            captured.stokes = Some(rmvp_dataset::layout::rmvp::read_stokes(&folder.join(VIEW_STOKES)).unwrap());
            captured.mask = Some(png::read_png_u8(&session.join("masks").join(format!("{i:03}.png"))).unwrap());
            let mask = want.mask.as_ref().unwrap();
            off += 1.0 - mask_iou(mask, got.mask.as_ref().unwrap());
            off_captured += 1.0 - mask_iou(mask, captured.mask.as_ref().unwrap());
            s0 += s0_difference(want, got);
            s0_captured += s0_difference(want, &captured);
        }
        eprintln!(
            "{model}: mask pixels off {off:.4} (as captured {off_captured:.4}), S0 off {s0:.4} ({s0_captured:.4})"
        );
        match distortion {
            None => assert!(off == 0.0 && s0 < 1e-6, "{model}: {off} {s0}"),
            // Undistorted, the masks fit the true cameras several times better; the Stokes,
            // resampled twice (a blur of their texture), closer too.
            Some(_) => assert!(off < 0.4 * off_captured && s0 < 0.9 * s0_captured, "{model}"),
        }
    }
    // Imported cameras that cannot be this session's are refused by name: two images that would
    // pose one view, a lens that cannot be undone, a nerfstudio camera of another size.
    let dir = tmp.path().join("PINHOLE");
    let (session, model_dir) = (dir.join("session"), dir.join("sparse/0"));
    let import = |from: &Path| {
        fails(&["poses", s(&session), "--method", "import", "--from", s(from), "-o", s(&dir.join("p.json"))])
    };
    let twice = dir.join("twice");
    rmvp_testkit::copy_tree(&model_dir, &twice);
    let images = std::fs::read_to_string(twice.join("images.txt")).unwrap();
    let first = images.lines().next().unwrap().replacen("000.png", "cam1/000.png", 1).replacen("1 ", "99 ", 1);
    std::fs::write(twice.join("images.txt"), format!("{images}{first}\n\n")).unwrap();
    let err = import(&twice);
    assert!(err.contains("000.png and cam1/000.png: both would pose view 000"), "{err}");
    let [f, c] = [source.views[0].camera.k[(0, 0)], source.views[0].camera.k[(0, 2)]];
    for k1 in ["nan", "-1000000"] {
        let lens = dir.join(format!("lens{k1}"));
        colmap_model(&lens, "SIMPLE_RADIAL", &[f, c, c, 0.0]);
        let cameras = std::fs::read_to_string(lens.join("cameras.txt")).unwrap();
        let (head, _) = cameras.trim_end().rsplit_once(' ').unwrap();
        std::fs::write(lens.join("cameras.txt"), format!("{head} {k1}\n")).unwrap();
        let err = import(&lens);
        assert!(err.contains("distortion"), "k1 = {k1}: {err}");
    }
    let exported = dir.join("exported");
    ok(&["dataset", "export", s(&dir.join("dataset/rmvp")), "--format", "nerfstudio", "-o", s(&exported)]);
    let transforms = exported.join("transforms.json");
    let mut json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&transforms).unwrap()).unwrap();
    json["w"] = 4096.into();
    json["h"] = 4096.into();
    std::fs::write(&transforms, serde_json::to_string(&json).unwrap()).unwrap();
    let err = import(&transforms);
    assert!(err.contains("transforms.json") && err.contains("was 4096x4096 pixels"), "{err}");

    // A build stopped before its end (its record says so) resumes only with the options it was
    // started with; each changed one is named, the reference's included.
    let (session, dataset) = (dir.join("session"), dir.join("dataset"));
    let record = dataset.join("build.json");
    let mut json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&record).unwrap()).unwrap();
    json["complete"] = false.into();
    json["stages"].as_array_mut().unwrap().pop();
    std::fs::write(&record, serde_json::to_string(&json).unwrap()).unwrap();
    let build = |extra: &[&str], expect: fn(&[&str]) -> String| {
        let mut args = vec!["dataset", "build", s(&session), "-o", s(&dataset), "--train-views", "6"];
        args.extend_from_slice(extra);
        expect(&args)
    };
    let err = build(&[], fails);
    assert!(err.contains("an unfinished build is here") && err.contains("--resume"), "{err}");
    let err = build(&["--resume", "--reference-mesh-res", "200"], fails);
    assert!(err.contains("other options (reference.mesh_res: 384 -> 200)"), "{err}");
    let err = build(&["--resume", "--reference-iters", "90", "--camera", s(&dir.join("poses.json"))], fails);
    assert!(err.contains("calibration: null -> ") && err.contains("reference.iters: null -> 90"), "{err}");
    build(&["--resume"], ok);
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&record).unwrap()).unwrap();
    assert_eq!(json["complete"], true);
    assert_eq!(json["options"]["reference"]["mesh_res"], 384);

    // A model of the views at another size (COLMAP run on smaller copies) is refused.
    let cameras = std::fs::read_to_string(dir.join("sparse/0/cameras.txt")).unwrap();
    let (w, h) = (source.views[0].camera.width, source.views[0].camera.height);
    let half = cameras.replace(&format!(" {w} {h} "), &format!(" {} {} ", w / 2, h / 2));
    assert_ne!(half, cameras);
    std::fs::write(dir.join("sparse/0/cameras.txt"), half).unwrap();
    let poses = dir.join("half.json");
    let err = fails(&[
        "poses",
        s(&dir.join("session")),
        "--method",
        "import",
        "--from",
        s(&dir.join("sparse/0")),
        "-o",
        s(&poses),
    ]);
    assert!(err.contains(&format!("was {}x{} pixels in COLMAP", w / 2, h / 2)), "{err}");
}
