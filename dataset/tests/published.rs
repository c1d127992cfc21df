//! Scenes laid out as the field publishes them, built from our own renders exactly as the
//! official loaders read them (`shared/notes/published-layouts.md`).

use rmvp_dataset::io::png;
use rmvp_dataset::layout::read_scene;
use std::path::Path;

/// A writable copy of a fixture scene.
fn copy(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy(&entry.path(), &target);
        } else {
            std::fs::write(&target, std::fs::read(entry.path()).unwrap()).unwrap();
        }
    }
}

#[test]
fn a_nersp_scene_without_mask_folder_takes_its_masks_from_the_azimuth_alpha() {
    let source = rmvp_testkit::fixture("spot_nersp");
    let original = read_scene(&source).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("spot");
    copy(&source, &scene);
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
