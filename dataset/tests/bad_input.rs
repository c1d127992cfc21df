//! Corrupt, truncated, mismatched or missing files give errors that name the file and the fault.

use rmvp_dataset::io::{exr, npy, png};
use rmvp_dataset::layout::read_scene;
use rmvp_dataset::{Image, Mesh};
use std::path::{Path, PathBuf};

fn spot() -> PathBuf {
    rmvp_testkit::fixture("spot_nersp")
}

/// A writable copy of the spot fixture.
fn copy_of_spot() -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("spot");
    rmvp_testkit::copy_tree(&spot(), &dir);
    (tmp, dir)
}

fn truncate(from: &Path, to: &Path) {
    let bytes = std::fs::read(from).unwrap();
    std::fs::write(to, &bytes[..bytes.len() / 2]).unwrap();
}

fn assert_error_names(err: impl std::fmt::Display, file: &Path, words: &[&str]) {
    let message = err.to_string();
    assert!(message.contains(&file.display().to_string()), "{message:?} does not name {}", file.display());
    for w in words {
        assert!(message.contains(w), "{message:?} does not say {w:?}");
    }
}

#[test]
fn truncated_files_are_reported_with_their_name() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = spot();
    let cases = [
        ("mask/0000.png", "t.png"),
        ("gt/normal/000.exr", "t.exr"),
        ("s0/0000.npy", "t.npy"),
        ("gt/mesh.ply", "t.ply"),
        ("cameras.npz", "t.npz"),
    ];
    for (source, name) in cases {
        let path = tmp.path().join(name);
        truncate(&dir.join(source), &path);
        let err = match name {
            "t.png" => png::read_png(&path).map(|_| ()).unwrap_err(),
            "t.exr" => exr::read_exr(&path, &["N.X"]).map(|_| ()).unwrap_err(),
            "t.npy" => npy::read_npy::<f32>(&path).map(|_| ()).unwrap_err(),
            "t.ply" => Mesh::read(&path).map(|_| ()).unwrap_err(),
            _ => npy::read_npz::<f64>(&path).map(|_| ()).unwrap_err(),
        };
        assert_error_names(err, &path, &[]);
    }
}

#[test]
fn ascii_and_binary_ply_round_trip_and_bad_indices_are_caught() {
    let mesh = Mesh::read(&spot().join("gt/mesh.ply")).unwrap();
    assert!(mesh.colors().is_some() && mesh.property("roughness_0").is_some() && mesh.normals.is_some());
    let tmp = tempfile::tempdir().unwrap();
    let ascii = tmp.path().join("ascii.ply");
    rmvp_dataset::mesh::ply::write_ply(&ascii, &mesh, rmvp_dataset::mesh::ply::PlyEncoding::Ascii).unwrap();
    assert!(std::fs::read_to_string(&ascii).unwrap().starts_with("ply\nformat ascii"));
    assert_eq!(Mesh::read(&ascii).unwrap(), mesh);
    let obj = tmp.path().join("m.obj");
    mesh.write(&obj).unwrap();
    let back = Mesh::read(&obj).unwrap();
    assert_eq!((back.positions.len(), back.faces.len()), (mesh.positions.len(), mesh.faces.len()));
    // Texture coordinates survive OBJ both ways.
    let mut textured = mesh.clone();
    let n = textured.positions.len();
    for (name, scale) in [("u", 0.001), ("v", 0.002)] {
        textured.vertex_properties.push(rmvp_dataset::mesh::VertexProperty {
            name: name.into(),
            kind: rmvp_dataset::mesh::ScalarKind::F32,
            values: (0..n).map(|i| ((i as f64 * scale) % 1.0) as f32 as f64).collect(),
        });
    }
    textured.write(&obj).unwrap();
    let back = Mesh::read(&obj).unwrap();
    // tobj numbers vertices by first use in the faces: match them by position.
    let key = |p: &[f32; 3]| p.map(f32::to_bits);
    let original: std::collections::HashMap<_, _> =
        textured.positions.iter().map(key).zip(textured.texcoords().unwrap()).collect();
    let b = back.texcoords().unwrap();
    assert_eq!(b.len(), n);
    assert!(back.positions.iter().zip(&b).all(|(p, q)| {
        let t = original[&key(p)];
        (t[0] - q[0]).abs() < 1e-6 && (t[1] - q[1]).abs() < 1e-6
    }));
    let mut broken = mesh.clone();
    broken.faces[7] = [0, 1, mesh.positions.len() as u32];
    let err = broken.write(&tmp.path().join("b.ply")).unwrap_err().to_string();
    assert!(err.contains("face 7") && err.contains("b.ply"), "{err}");
}

#[test]
fn stl_meshes_are_read_and_bad_ones_reported() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("tet.stl");
    let facet = |n: [f32; 3], v: [[f32; 3]; 3]| {
        let vs: String = v.iter().map(|p| format!("      vertex {} {} {}\n", p[0], p[1], p[2])).collect();
        format!("  facet normal {} {} {}\n    outer loop\n{vs}    endloop\n  endfacet\n", n[0], n[1], n[2])
    };
    let (a, b, c, d) = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
    let text = format!(
        "solid tet\n{}{}{}{}endsolid tet\n",
        facet([0.0, 0.0, -1.0], [a, c, b]),
        facet([0.0, -1.0, 0.0], [a, b, d]),
        facet([-1.0, 0.0, 0.0], [a, d, c]),
        facet([0.577, 0.577, 0.577], [b, c, d])
    );
    std::fs::write(&path, text).unwrap();
    let mesh = Mesh::read(&path).unwrap();
    assert_eq!((mesh.positions.len(), mesh.faces.len()), (4, 4), "vertices merged by position");
    let cut = tmp.path().join("cut.stl");
    truncate(&path, &cut);
    assert_error_names(Mesh::read(&cut).map(|_| ()).unwrap_err(), &cut, &[]);
}

#[test]
fn a_missing_view_file_is_named() {
    let (_tmp, dir) = copy_of_spot();
    let missing = dir.join("s1/0003.npy");
    std::fs::remove_file(&missing).unwrap();
    assert_error_names(read_scene(&dir).unwrap_err(), &missing, &["No such file"]);
}

#[test]
fn a_mask_of_the_wrong_size_names_the_mask_and_the_file_it_disagrees_with() {
    let (_tmp, dir) = copy_of_spot();
    let mask = dir.join("mask/0002.png");
    png::write_png_u8(&mask, &Image::new(64, 64, 1)).unwrap();
    std::fs::remove_file(dir.join("gt/mask/002.png")).unwrap();
    let err = read_scene(&dir).unwrap_err().to_string();
    let s0 = dir.join("s0/0002.npy");
    assert_eq!(err, format!("{}: is 64x64, but {} is 128x128", mask.display(), s0.display()));
}

#[test]
fn nan_in_stokes_is_reported_with_its_pixel() {
    let (_tmp, dir) = copy_of_spot();
    let path = dir.join("s2/0001.npy");
    let mut a = npy::read_npy::<f32>(&path).unwrap();
    a.data[(5 * 128 + 9) * 3 + 1] = f32::NAN;
    npy::write_npy(&path, &a).unwrap();
    let err = read_scene(&dir).unwrap_err().to_string();
    assert!(err.contains("S2 is not finite at pixel (9, 5) channel 1") && err.contains("view 001"), "{err}");
}

#[test]
fn a_folder_that_is_no_scene_is_reported() {
    let tmp = tempfile::tempdir().unwrap();
    let err = read_scene(tmp.path()).unwrap_err().to_string();
    assert!(err.contains("not a scene"), "{err}");
    let err = read_scene(&tmp.path().join("nope")).unwrap_err().to_string();
    assert!(err.contains("nope") && err.contains("no such scene folder"), "{err}");
}

#[test]
fn the_direct_binary_ply_path_agrees_with_the_general_parser() {
    use rmvp_dataset::mesh::ply::{read_ply, read_ply_generic, write_ply, PlyEncoding};
    use rmvp_dataset::mesh::{ScalarKind, VertexProperty};
    // The fixture (written by another program) both ways.
    let path = spot().join("gt/mesh.ply");
    let bytes = std::fs::read(&path).unwrap();
    let generic = read_ply_generic(&mut std::io::Cursor::new(&bytes), &path).unwrap();
    assert_eq!(read_ply(&path).unwrap(), generic);
    // Every scalar type, polygons included, written by us and read by both.
    let kinds = [
        ScalarKind::I8,
        ScalarKind::U8,
        ScalarKind::I16,
        ScalarKind::U16,
        ScalarKind::I32,
        ScalarKind::U32,
        ScalarKind::F32,
        ScalarKind::F64,
    ];
    let mut mesh = generic.clone();
    let n = mesh.positions.len();
    for (k, kind) in kinds.iter().enumerate() {
        let values = (0..n)
            .map(|i| {
                ((i * 7 + k) % 100) as f64
                    - if matches!(kind, ScalarKind::I8 | ScalarKind::I16 | ScalarKind::I32) { 50.0 } else { 0.0 }
            })
            .collect();
        mesh.vertex_properties.push(VertexProperty { name: format!("p{k}"), kind: *kind, values });
    }
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("all.ply");
    write_ply(&out, &mesh, PlyEncoding::Binary).unwrap();
    let bytes = std::fs::read(&out).unwrap();
    assert_eq!(read_ply(&out).unwrap(), mesh);
    assert_eq!(read_ply_generic(&mut std::io::Cursor::new(&bytes), &out).unwrap(), mesh);
    // Cut inside the faces: named, and not a panic.
    std::fs::write(&out, &bytes[..bytes.len() - 5]).unwrap();
    let err = read_ply(&out).unwrap_err().to_string();
    assert!(err.contains("all.ply") && err.contains("truncated"), "{err}");
}
