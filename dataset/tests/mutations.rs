//! Mutated files against every reader family of the dataset crate, through the mutation engine
//! of `rmvp-testkit` (each family in a child process under 2 GiB of address space, its peak
//! memory measured, a deadline): a mutated file is refused with an error that names it, or read;
//! never a panic, never more memory, never a hang.

use rmvp_dataset::exchange::colmap::{ColmapCamera, ColmapImage, ColmapModel};
use rmvp_dataset::exchange::nerfstudio::Transforms;
use rmvp_dataset::io::{exr, hdr, npy, picture, png};
use rmvp_dataset::layout::nersp;
use rmvp_dataset::session::SessionManifest;
use rmvp_dataset::Mesh;
use rmvp_testkit::mutation::{no_fixup, outcome, run_family, Family};
use std::path::Path;

/// A correct checksum for a PNG's header chunk, whatever its fields now say.
fn png_header_crc(bytes: &mut [u8]) {
    if bytes.len() >= 33 && &bytes[12..16] == b"IHDR" {
        let crc = rmvp_testkit::crc32(&bytes[12..29]);
        bytes[29..33].copy_from_slice(&crc.to_be_bytes());
    }
}

fn spot(relative: &str) -> Vec<u8> {
    std::fs::read(rmvp_testkit::fixture("spot_nersp").join(relative)).unwrap()
}

/// The spot's mesh, cut to a few hundred triangles, written in `format` by our writers.
fn small_mesh(dir: &Path, name: &str) -> Vec<u8> {
    let mut mesh = Mesh::read(&rmvp_testkit::fixture("spot_nersp").join("gt/mesh.ply")).unwrap();
    mesh.faces.truncate(300);
    let path = dir.join(name);
    if name.ends_with(".ascii.ply") {
        rmvp_dataset::mesh::ply::write_ply(&path, &mesh, rmvp_dataset::mesh::ply::PlyEncoding::Ascii).unwrap();
    } else {
        mesh.write(&path).unwrap();
    }
    std::fs::read(path).unwrap()
}

fn stl_seed(_: &Path) -> Vec<u8> {
    let mut bytes = vec![0u8; 80];
    let triangles: u32 = 40;
    bytes.extend(triangles.to_le_bytes());
    for t in 0..triangles {
        bytes.extend([0f32, 0.0, 1.0].iter().flat_map(|v| v.to_le_bytes()));
        for k in 0..3 {
            let v = [t as f32, k as f32, (t * k) as f32];
            bytes.extend(v.iter().flat_map(|x| x.to_le_bytes()));
        }
        bytes.extend([0u8, 0]);
    }
    bytes
}

/// The spot's S0 preview as a picture file of `format` (a JPEG with an EXIF block).
fn picture_seed(format: image::ImageFormat) -> Vec<u8> {
    use image::ImageEncoder;
    let picture = image::load_from_memory(&spot("image/0000.png")).unwrap().into_rgb8();
    let mut bytes = Vec::new();
    if format == image::ImageFormat::Jpeg {
        let mut encoder = image::codecs::jpeg::JpegEncoder::new(&mut bytes);
        encoder.set_exif_metadata(rmvp_testkit::exif_block("Acme", "X100 Pro", 35)).unwrap();
        let (w, h) = picture.dimensions();
        encoder.write_image(picture.as_raw(), w, h, image::ExtendedColorType::Rgb8).unwrap();
    } else {
        picture.write_to(&mut std::io::Cursor::new(&mut bytes), format).unwrap();
    }
    bytes
}

/// The spot's preview as a TIFF of 32-bit float RGB samples (linear light).
fn float_tiff_seed() -> Vec<u8> {
    let picture = image::load_from_memory(&spot("image/0000.png")).unwrap().into_rgb32f();
    let mut bytes = Vec::new();
    image::DynamicImage::ImageRgb32F(picture)
        .write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Tiff)
        .unwrap();
    bytes
}

/// The spot's S0 as a Radiance HDR file (run-length scanlines, as our writer stores them).
fn hdr_seed(dir: &Path) -> Vec<u8> {
    let s0 = npy::read_npy::<f32>(&rmvp_testkit::fixture("spot_nersp").join("s0/0000.npy")).unwrap();
    let (h, w) = (s0.shape[0], s0.shape[1]);
    let grey: Vec<f32> = s0.data.chunks(s0.data.len() / (w * h)).map(|p| p[0]).collect();
    let rgb: Vec<f32> = grey.iter().flat_map(|&v| [v, 0.5 * v, 0.25 * v]).collect();
    let path = dir.join("seed.hdr");
    hdr::write_hdr(&path, &rmvp_dataset::Image::from_vec(w, h, 3, rgb).unwrap()).unwrap();
    std::fs::read(&path).unwrap()
}

/// A 6x40 Radiance HDR file with flat scanlines (widths under 8 must be), one old-style run.
fn flat_hdr_seed() -> Vec<u8> {
    let mut bytes = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 40 +X 6\n".to_vec();
    for y in 0..40u8 {
        bytes.extend([y, 2 * y, 100, 130, 1, 1, 1, 2, 7, 8, 9, 128, 200, 3, y, 140, 5, 5, 5, 120]);
    }
    bytes
}

/// A COLMAP model of three OPENCV cameras looking at the origin, with keypoints and points.
fn seed_model() -> ColmapModel {
    let mut model = ColmapModel::default();
    for id in 1..=3u32 {
        let params = vec![600.0, 602.0, 320.5, 240.5, -0.05, 0.01, 0.001, -0.002];
        model.cameras.insert(id, ColmapCamera { model: "OPENCV".into(), width: 640, height: 480, params });
        let angle = id as f64 * 0.4;
        let (s, c) = (angle / 2.0).sin_cos();
        let points2d = (0..20).map(|k| (10.5 + k as f64, 20.25 * k as f64, if k % 3 == 0 { -1 } else { k })).collect();
        model.images.push(ColmapImage {
            id,
            qvec: [c, 0.0, s, 0.0],
            tvec: [0.1, -0.2, 4.0],
            camera_id: id,
            name: format!("{:03}.png", id - 1),
            points2d,
        });
    }
    for k in 0..20u64 {
        model.points.insert(k, [k as f64 * 0.01, -0.02, 0.5]);
    }
    model
}

/// `cameras.bin` of `model`, as COLMAP writes it (OPENCV is model 4).
fn colmap_binary_cameras(model: &ColmapModel) -> Vec<u8> {
    let mut b = (model.cameras.len() as u64).to_le_bytes().to_vec();
    for (id, camera) in &model.cameras {
        b.extend(id.to_le_bytes());
        b.extend(4i32.to_le_bytes());
        b.extend((camera.width as u64).to_le_bytes());
        b.extend((camera.height as u64).to_le_bytes());
        camera.params.iter().for_each(|p| b.extend(p.to_le_bytes()));
    }
    b
}

/// `images.bin` of `model`, as COLMAP writes it.
fn colmap_binary_images(model: &ColmapModel) -> Vec<u8> {
    let mut b = (model.images.len() as u64).to_le_bytes().to_vec();
    for image in &model.images {
        b.extend(image.id.to_le_bytes());
        image.qvec.iter().chain(&image.tvec).for_each(|v| b.extend(v.to_le_bytes()));
        b.extend(image.camera_id.to_le_bytes());
        b.extend(image.name.as_bytes());
        b.push(0);
        b.extend((image.points2d.len() as u64).to_le_bytes());
        for (x, y, id) in &image.points2d {
            b.extend(x.to_le_bytes());
            b.extend(y.to_le_bytes());
            b.extend(id.to_le_bytes());
        }
    }
    b
}

fn families() -> Vec<Family> {
    vec![
        Family {
            name: "png",
            file_name: "m.png",
            seed: |_| spot("input_azimuth_maps/0000.png"),
            read: |p| outcome(png::read_png(p)),
            fixup: png_header_crc,
        },
        Family {
            name: "exr",
            file_name: "m.exr",
            seed: |_| spot("gt/normal/000.exr"),
            read: |p| outcome(exr::read_exr_channels(p)),
            fixup: no_fixup,
        },
        Family {
            name: "npy",
            file_name: "m.npy",
            seed: |_| spot("s0/0000.npy"),
            read: |p| outcome(npy::read_npy::<f32>(p)),
            fixup: no_fixup,
        },
        Family {
            name: "npz",
            file_name: "cameras.npz",
            seed: |_| spot("cameras.npz"),
            read: |p| outcome(nersp::read_cameras(p)),
            fixup: no_fixup,
        },
        Family {
            name: "ply-binary",
            file_name: "m.ply",
            seed: |d| small_mesh(d, "seed.ply"),
            read: |p| outcome(Mesh::read(p)),
            fixup: no_fixup,
        },
        Family {
            name: "ply-ascii",
            file_name: "m.ply",
            seed: |d| small_mesh(d, "seed.ascii.ply"),
            read: |p| outcome(Mesh::read(p)),
            fixup: no_fixup,
        },
        Family {
            name: "obj",
            file_name: "m.obj",
            seed: |d| small_mesh(d, "seed.obj"),
            read: |p| outcome(Mesh::read(p)),
            fixup: no_fixup,
        },
        Family {
            name: "jpeg",
            file_name: "m.jpg",
            seed: |_| picture_seed(image::ImageFormat::Jpeg),
            read: |p| outcome(picture::read_picture(p)),
            fixup: no_fixup,
        },
        Family {
            name: "tiff",
            file_name: "m.tif",
            seed: |_| picture_seed(image::ImageFormat::Tiff),
            read: |p| outcome(picture::read_picture(p)),
            fixup: no_fixup,
        },
        Family {
            name: "tiff-float",
            file_name: "m.tif",
            seed: |_| float_tiff_seed(),
            read: |p| outcome(picture::read_picture(p)),
            fixup: no_fixup,
        },
        Family { name: "stl", file_name: "m.stl", seed: stl_seed, read: |p| outcome(Mesh::read(p)), fixup: no_fixup },
        Family {
            name: "hdr",
            file_name: "m.hdr",
            seed: hdr_seed,
            read: |p| outcome(hdr::read_hdr(p)),
            fixup: no_fixup,
        },
        Family {
            name: "hdr-flat",
            file_name: "m.hdr",
            seed: |_| flat_hdr_seed(),
            read: |p| outcome(hdr::read_hdr(p)),
            fixup: no_fixup,
        },
        Family {
            name: "session",
            file_name: "session.json",
            seed: |_| include_bytes!("data/session.json").to_vec(),
            read: |p| outcome(SessionManifest::read(p.parent().unwrap())),
            fixup: no_fixup,
        },
        Family {
            name: "colmap-bin",
            file_name: "images.bin",
            seed: |_| colmap_binary_images(&seed_model()),
            read: |p| {
                let dir = p.parent().unwrap();
                std::fs::write(dir.join("cameras.bin"), colmap_binary_cameras(&seed_model())).unwrap();
                outcome(ColmapModel::read(dir))
            },
            fixup: no_fixup,
        },
        Family {
            name: "colmap-text",
            file_name: "images.txt",
            seed: |d| {
                seed_model().write_text(d).unwrap();
                std::fs::read(d.join("images.txt")).unwrap()
            },
            read: |p| {
                let dir = p.parent().unwrap();
                let model = tempfile::tempdir().unwrap();
                seed_model().write_text(model.path()).unwrap();
                for name in ["cameras.txt", "points3D.txt"] {
                    std::fs::copy(model.path().join(name), dir.join(name)).unwrap();
                }
                outcome(ColmapModel::read(dir).and_then(|m| m.cameras(dir)))
            },
            fixup: no_fixup,
        },
        Family {
            name: "transforms",
            file_name: "transforms.json",
            seed: |d| {
                let model = seed_model();
                let cameras = model.cameras(d).unwrap();
                let frames: Vec<_> = cameras.into_iter().map(|(n, c)| (format!("images/{n}"), None, c)).collect();
                let path = d.join("transforms.json");
                Transforms::from_cameras(&frames).write(&path).unwrap();
                std::fs::read(path).unwrap()
            },
            read: |p| outcome(Transforms::read(p).and_then(|t| t.cameras(p))),
            fixup: no_fixup,
        },
    ]
}

#[test]
fn png_family() {
    run_family(&families(), "png");
}

#[test]
fn jpeg_family() {
    run_family(&families(), "jpeg");
}

#[test]
fn hdr_family() {
    run_family(&families(), "hdr");
}

#[test]
fn hdr_flat_family() {
    run_family(&families(), "hdr-flat");
}

#[test]
fn tiff_family() {
    run_family(&families(), "tiff");
}

#[test]
fn exr_family() {
    run_family(&families(), "exr");
}

#[test]
fn npy_family() {
    run_family(&families(), "npy");
}

#[test]
fn npz_family() {
    run_family(&families(), "npz");
}

#[test]
fn ply_binary_family() {
    run_family(&families(), "ply-binary");
}

#[test]
fn ply_ascii_family() {
    run_family(&families(), "ply-ascii");
}

#[test]
fn obj_family() {
    run_family(&families(), "obj");
}

#[test]
fn tiff_float_family() {
    run_family(&families(), "tiff-float");
}

#[test]
fn stl_family() {
    run_family(&families(), "stl");
}

#[test]
fn session_family() {
    run_family(&families(), "session");
}

#[test]
fn colmap_bin_family() {
    run_family(&families(), "colmap-bin");
}

#[test]
fn colmap_text_family() {
    run_family(&families(), "colmap-text");
}

#[test]
fn transforms_family() {
    run_family(&families(), "transforms");
}
