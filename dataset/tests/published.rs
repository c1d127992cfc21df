//! Scenes laid out as the field publishes them, built from our own renders exactly as the
//! official loaders read them (`shared/notes/published-layouts.md`).

use rmvp_dataset::io::{npy, png};
use rmvp_dataset::layout::{read_scene, write_scene, Layout};
use rmvp_dataset::{Scene, Split};

#[test]
fn a_nersp_scene_without_mask_folder_takes_its_masks_from_the_azimuth_alpha() {
    let source = rmvp_testkit::fixture("spot_nersp");
    let original = read_scene(&source).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("spot");
    rmvp_testkit::copy_tree(&source, &scene);
    std::fs::remove_dir_all(scene.join("mask")).unwrap();
    let read = read_scene(&scene).unwrap();
    let train: Vec<_> = original.train_views().collect();
    assert_eq!(read.train_views().count(), train.len());
    for (a, b) in read.train_views().zip(&train) {
        assert_eq!(a.mask, b.mask, "view {}: the alpha channel gives the training mask", a.name);
        assert_eq!((&a.stokes, &a.camera), (&b.stokes, &b.camera));
    }

    // Both present and disagreeing: said, naming the mask, the azimuth map and the count.
    let mut mask = train[0].mask.clone().unwrap();
    let flipped = mask.data().iter().position(|&v| v > 127).unwrap();
    let (w, _) = mask.size();
    mask.pixel_mut(flipped % w, flipped / w)[0] = 0;
    let path = scene.join("mask/0000.png");
    png::write_png_u8(&path, &mask).unwrap();
    let err = read_scene(&scene).unwrap_err().to_string();
    assert!(
        err.contains("mask/0000.png: disagrees at 1 pixels with the alpha channel of")
            && err.contains("input_azimuth_maps/0000.png"),
        "{err}"
    );
}

/// The fixture's training views written in `layout`, read back through detection.
fn through(layout: Layout) -> (Scene, Scene, tempfile::TempDir) {
    let source = read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
    let mut train = source.clone();
    train.views.retain(|v| v.split == Split::Train);
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join(layout.name());
    write_scene(&train, &dir, layout).unwrap();
    assert_eq!(Layout::detect(&dir).unwrap(), layout);
    let back = read_scene(&dir).unwrap();
    (train, back, tmp)
}

fn assert_same_cameras_and_masks(a: &Scene, b: &Scene) {
    assert_eq!(a.views.len(), b.views.len());
    assert_eq!(a.normalization, b.normalization);
    for (x, y) in a.views.iter().zip(&b.views) {
        assert!((x.camera.k - y.camera.k).abs().max() < 1e-9, "{}: K", x.name);
        assert!((x.camera.r - y.camera.r).abs().max() < 1e-12, "{}: R", x.name);
        assert!((x.camera.t - y.camera.t).abs().max() < 1e-12, "{}: t", x.name);
        assert_eq!(x.mask, y.mask, "{}: mask", x.name);
    }
}

#[test]
fn an_rmvp3d_original_part_with_one_based_keys_and_mask_folder_reads_as_its_source() {
    let (source, back, tmp) = through(Layout::Rmvp3d);
    assert_same_cameras_and_masks(&source, &back);
    for (x, y) in source.views.iter().zip(&back.views) {
        assert_eq!(x.stokes, y.stokes, "{}: Stokes exactly", x.name);
    }
    // As PolGS reads the release: cameras keyed world_mat_01, world_mat_02, ...
    let dir = tmp.path().join("rmvp3d");
    let cameras = dir.join("cameras.npz");
    let renamed: Vec<_> = npy::read_npz::<f64>(&cameras)
        .unwrap()
        .into_iter()
        .map(|(name, a)| {
            let (stem, k) = name.rsplit_once('_').unwrap();
            (format!("{stem}_{:02}", k.parse::<usize>().unwrap() + 1), a)
        })
        .collect();
    npy::write_npz(&cameras, &renamed).unwrap();
    assert_same_cameras_and_masks(&source, &read_scene(&dir).unwrap());
}

#[test]
fn a_pandora_scene_reads_as_its_source_within_rgbe_precision() {
    let (source, back, tmp) = through(Layout::Pandora);
    assert_same_cameras_and_masks(&source, &back);
    assert_eq!(back.views[0].name, "01");
    for (x, y) in source.views.iter().zip(&back.views) {
        let (a, b) = (x.stokes.as_ref().unwrap(), y.stokes.as_ref().unwrap());
        let scale = a.s0.data().iter().fold(0f32, |m, v| m.max(*v));
        for (p, q) in [(&a.s0, &b.s0), (&a.s1, &b.s1), (&a.s2, &b.s2)] {
            let worst = p.data().iter().zip(q.data()).map(|(u, v)| (u - v).abs()).fold(0f32, f32::max);
            // RGBE rounds each pixel to 1/256 of its largest channel; S1 and S2 differ by two.
            assert!(worst <= 3.0 * scale / 256.0, "{}: Stokes off by {worst} (S0 up to {scale})", x.name);
        }
    }
    // A correction replaces its view's mask.
    let dir = tmp.path().join("pandora");
    let mut corrected = back.views[1].mask.clone().unwrap();
    corrected.data_mut().iter_mut().take(500).for_each(|v| *v = 255 - *v);
    png::write_png_u8(&dir.join("mask_corrections/02.png"), &corrected).unwrap();
    let again = read_scene(&dir).unwrap();
    assert_eq!(again.views[1].mask.as_ref(), Some(&corrected));
    assert_eq!(again.views[0].mask, back.views[0].mask);
}

#[test]
fn a_folder_with_part_of_a_layout_is_told_what_it_lacks() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("half");
    std::fs::create_dir_all(dir.join("images_stokes")).unwrap();
    let err = Layout::detect(&dir).unwrap_err().to_string();
    assert!(err.contains("looks like the RMVP3D or PANDORA layout but has no cameras.npz"), "{err}");
    std::fs::write(dir.join("cameras.npz"), b"").unwrap();
    let err = Layout::detect(&dir).unwrap_err().to_string();
    assert!(
        err.contains("images_stokes: holds neither NNNN.npz archives (RMVP3D) nor NN_s0.hdr files (PANDORA)"),
        "{err}"
    );
    std::fs::remove_dir_all(dir.join("images_stokes")).unwrap();
    std::fs::remove_file(dir.join("cameras.npz")).unwrap();
    std::fs::create_dir_all(dir.join("s0")).unwrap();
    let err = Layout::detect(&dir).unwrap_err().to_string();
    assert!(err.contains("looks like the NeRSP layout but has no cameras.npz"), "{err}");
}
