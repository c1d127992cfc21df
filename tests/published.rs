//! Scenes as the field publishes them, through the commands a researcher runs first: `rmvp
//! dataset info` names the layout, `convert` gives the source's cameras, masks and Stokes, and
//! `recon` trains on it.

use rmvp_dataset::layout::{read_scene, write_scene, Layout};
use rmvp_dataset::{Scene, Split};
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
