//! Files whose claims would cost far more than their bytes, and files read with content the
//! reader does not keep: each case runs in a child process under 2 GiB of address space with
//! its peak memory measured ([`rmvp_testkit::limited_case`]); it is refused by name, or read
//! right, within bounds set by the file's size.

use rmvp_dataset::camera::Camera;
use rmvp_dataset::exchange::colmap::ColmapModel;
use rmvp_dataset::exchange::nerfstudio::Transforms;
use rmvp_dataset::io::picture;
use rmvp_dataset::layout::{read_scene, write_scene, Layout};
use rmvp_dataset::Split;
use std::io::Write;
use std::path::Path;

const MIB: u64 = 1 << 20;

/// Write a JSON array of `n` zeros: 2 bytes a number in the file, a tree node of tens of bytes
/// each where a reader keeps it.
fn write_zeros(to: &mut impl Write, n: usize) {
    let chunk = ",0".repeat(1 << 16);
    to.write_all(b"[0").unwrap();
    for _ in 0..(n - 1) >> 16 {
        to.write_all(chunk.as_bytes()).unwrap();
    }
    to.write_all(&chunk.as_bytes()[..2 * ((n - 1) & 0xFFFF)]).unwrap();
    to.write_all(b"]").unwrap();
}

/// Rewrite the JSON object in `path` with `field` (a JSON array of `n` zeros) first.
fn with_zeros_field(path: &Path, field: &str, n: usize) {
    let text = std::fs::read_to_string(path).unwrap();
    let rest = text.trim_start().strip_prefix('{').unwrap();
    let mut file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    write!(file, "{{\"{field}\": ").unwrap();
    write_zeros(&mut file, n);
    write!(file, ",{rest}").unwrap();
}

fn spot_cameras() -> Vec<(String, Option<String>, Camera)> {
    let scene = read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
    scene.train_views().map(|v| (format!("images/{}.png", v.name), None, v.camera.clone())).collect()
}

#[test]
fn a_transforms_file_with_a_large_unknown_field_is_read_without_keeping_it() {
    let peak =
        rmvp_testkit::limited_case("a_transforms_file_with_a_large_unknown_field_is_read_without_keeping_it", || {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("transforms.json");
            let cameras = spot_cameras();
            Transforms::from_cameras(&cameras).write(&path).unwrap();
            // 40 MB of an unknown field.
            with_zeros_field(&path, "exporter_state", 20_000_000);
            let read = Transforms::read(&path).unwrap().cameras(&path).unwrap();
            assert_eq!(read.len(), cameras.len());
            for ((name, camera), (file, _, expected)) in read.iter().zip(&cameras) {
                assert!(file.ends_with(&format!("{name}.png")));
                assert!((camera.k - expected.k).abs().max() < 1e-9 && (camera.t - expected.t).abs().max() < 1e-9);
            }
        });
    // The text itself (40 MB) and little more: a tree of the unknown field would take 16 times.
    assert!(peak < 100 * MIB, "peak {} MiB", peak / MIB);
}

#[test]
fn a_large_free_form_field_in_ground_truth_cameras_is_refused_by_name() {
    rmvp_testkit::limited_case("a_large_free_form_field_in_ground_truth_cameras_is_refused_by_name", || {
        let dir = tempfile::tempdir().unwrap();
        let scene = dir.path().join("spot");
        rmvp_testkit::copy_tree(&rmvp_testkit::fixture("spot_nersp"), &scene);
        let path = scene.join("gt/cameras.json");
        let original = std::fs::read(&path).unwrap();
        // Below the cap: kept as provenance.
        with_zeros_field(&path, "renderer_log", 100_000);
        let read = read_scene(&scene).unwrap();
        assert_eq!(read.metadata["renderer_log"].as_array().unwrap().len(), 100_000);
        // 20 MB: refused, naming the file and the field.
        std::fs::write(&path, &original).unwrap();
        with_zeros_field(&path, "renderer_log", 10_000_000);
        let err = read_scene(&scene).unwrap_err().to_string();
        assert!(err.contains("gt/cameras.json: field \"renderer_log\": a free-form field of 20000001 bytes"), "{err}");
    });
}

#[test]
fn a_colmap_model_with_millions_of_keypoints_on_one_line_is_refused_after_counting() {
    let peak = rmvp_testkit::limited_case(
        "a_colmap_model_with_millions_of_keypoints_on_one_line_is_refused_after_counting",
        || {
            let dir = tempfile::tempdir().unwrap();
            let model =
                ColmapModel::from_cameras(&spot_cameras().into_iter().map(|(n, _, c)| (n, c)).collect::<Vec<_>>());
            model.write_text(dir.path()).unwrap();
            let images = dir.path().join("images.txt");
            let text = std::fs::read_to_string(&images).unwrap();
            let mut file = std::fs::File::create(&images).unwrap();
            let (header, _) = text.split_once(".png\n").unwrap();
            writeln!(file, "{header}.png").unwrap();
            let keypoints = "0 0 -1 ".repeat(1000);
            for _ in 0..9_000 {
                file.write_all(keypoints.as_bytes()).unwrap();
            }
            file.write_all(b"\n").unwrap();
            drop(file);
            let err = ColmapModel::read(dir.path()).unwrap_err().to_string();
            assert!(err.contains("images.txt: holds more than the 8388608 keypoints"), "{err}");
        },
    );
    // The 63 MB of text, not 24 bytes a keypoint.
    assert!(peak < 160 * MIB, "peak {} MiB", peak / MIB);
}

/// The spot's preview as a JPEG whose frame header declares `size x size`, padded with comment
/// segments to `bytes`.
fn forged_jpeg(size: u16, bytes: usize) -> Vec<u8> {
    let picture = image::open(rmvp_testkit::fixture("spot_nersp").join("image/0000.png")).unwrap().into_rgb8();
    let mut jpeg = Vec::new();
    picture.write_to(&mut std::io::Cursor::new(&mut jpeg), image::ImageFormat::Jpeg).unwrap();
    let sof = jpeg.windows(2).position(|w| w == [0xFF, 0xC0]).unwrap();
    jpeg[sof + 5..sof + 7].copy_from_slice(&size.to_be_bytes());
    jpeg[sof + 7..sof + 9].copy_from_slice(&size.to_be_bytes());
    let mut padded = jpeg[..2].to_vec();
    while padded.len() + jpeg.len() < bytes {
        let n = (bytes - padded.len() - jpeg.len()).clamp(4, 65_000);
        padded.extend([0xFF, 0xFE]);
        padded.extend(((n - 2) as u16).to_be_bytes());
        padded.extend(vec![b' '; n - 4]);
    }
    padded.extend(&jpeg[2..]);
    padded
}

#[test]
fn a_small_jpeg_declaring_a_huge_image_is_refused_before_decoding() {
    rmvp_testkit::limited_case("a_small_jpeg_declaring_a_huge_image_is_refused_before_decoding", || {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("board.jpg");
        std::fs::write(&path, forged_jpeg(16384, 70_000)).unwrap();
        let err = picture::read_picture(&path).unwrap_err().to_string();
        assert!(
            err.contains("board.jpg: declares a 16384x16384 image that its") && err.contains("bytes cannot hold"),
            "{err}"
        );
    });
}

/// A little-endian TIFF of `size x size` RGB 32-bit float samples of one value, deflated, every
/// strip the same bytes stored once (strip offsets may repeat).
fn flat_float_tiff(size: u32) -> Vec<u8> {
    let rows = 256u32;
    let strips = size.div_ceil(rows);
    let raw: Vec<u8> = std::iter::repeat_n(0.25f32.to_le_bytes(), (3 * size * rows) as usize).flatten().collect();
    let mut zlib = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
    zlib.write_all(&raw).unwrap();
    let strip = zlib.finish().unwrap();
    let entries = 11u32;
    let arrays = 8 + 2 + 12 * entries + 4;
    let (bits_at, format_at, offsets_at) = (arrays, arrays + 6, arrays + 12);
    let counts_at = offsets_at + 4 * strips;
    let data_at = counts_at + 4 * strips;
    let mut t = b"II\x2a\0\x08\0\0\0".to_vec();
    t.extend((entries as u16).to_le_bytes());
    let mut entry = |tag: u16, kind: u16, count: u32, value: u32| {
        t.extend(tag.to_le_bytes());
        t.extend(kind.to_le_bytes());
        t.extend(count.to_le_bytes());
        t.extend(value.to_le_bytes());
    };
    let (short, long) = (3, 4);
    entry(256, long, 1, size);
    entry(257, long, 1, size);
    entry(258, short, 3, bits_at);
    entry(259, short, 1, 8);
    entry(262, short, 1, 2);
    entry(273, long, strips, offsets_at);
    entry(277, short, 1, 3);
    entry(278, long, 1, rows);
    entry(279, long, strips, counts_at);
    entry(284, short, 1, 1);
    entry(339, short, 3, format_at);
    t.extend([0; 4]);
    t.extend([32u16, 32, 32, 3, 3, 3].iter().flat_map(|v| v.to_le_bytes()));
    (0..strips).for_each(|_| t.extend(data_at.to_le_bytes()));
    (0..strips).for_each(|_| t.extend((strip.len() as u32).to_le_bytes()));
    t.extend(&strip);
    t
}

#[test]
fn a_deflated_float_tiff_that_would_take_gigabytes_to_decode_is_refused() {
    rmvp_testkit::limited_case("a_deflated_float_tiff_that_would_take_gigabytes_to_decode_is_refused", || {
        let dir = tempfile::tempdir().unwrap();
        // The decoder reads such a file right at a small size.
        let small = dir.path().join("small.tif");
        std::fs::write(&small, flat_float_tiff(300)).unwrap();
        let picture = picture::read_picture(&small).unwrap();
        let picture::Pixels::Linear(image) = picture.pixels else { panic!("float samples are linear") };
        assert!(image.size() == (300, 300) && image.data().iter().all(|&v| v == 0.25));
        // 8192 x 8192: 805 MB of samples in about 130 kB.
        let path = dir.path().join("flat.tif");
        let bytes = flat_float_tiff(8192);
        assert!(bytes.len() < 256 << 10, "{}", bytes.len());
        std::fs::write(&path, bytes).unwrap();
        let err = picture::read_picture(&path).unwrap_err().to_string();
        assert!(
            err.contains("flat.tif: declares a 8192x8192 image that takes") && err.contains("MiB to decode"),
            "{err}"
        );
    });
}

#[test]
fn a_pandora_mask_of_another_size_names_both_files() {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
    scene.views.retain(|v| v.split == Split::Train);
    let out = dir.path().join("pandora");
    write_scene(&scene, &out, Layout::Pandora).unwrap();
    let mask = out.join("mask/02.png");
    let small = rmvp_dataset::Image::<u8>::new(64, 64, 1);
    rmvp_dataset::io::png::write_png_u8(&mask, &small).unwrap();
    let err = read_scene(&out).unwrap_err().to_string();
    let s0 = out.join("images_stokes/02_s0.hdr");
    let (w, h) = scene.views[1].stokes.as_ref().unwrap().s0.size();
    assert_eq!(err, format!("{}: is 64x64, but {} is {w}x{h}", mask.display(), s0.display()));
}

#[test]
fn a_sparse_file_of_gigabytes_behind_a_valid_head_is_refused_unread() {
    let peak = rmvp_testkit::limited_case("a_sparse_file_of_gigabytes_behind_a_valid_head_is_refused_unread", || {
        let dir = tempfile::tempdir().unwrap();
        let image = rmvp_dataset::Image::from_vec(16, 16, 3, vec![0.5f32; 16 * 16 * 3]).unwrap();
        let path = dir.path().join("panorama.hdr");
        rmvp_dataset::io::hdr::write_hdr(&path, &image).unwrap();
        assert_eq!(rmvp_dataset::io::hdr::read_hdr(&path).unwrap().size(), (16, 16));
        // The same head and scanlines, then a hole: 1.5 GiB on disk, none of it stored.
        std::fs::OpenOptions::new().write(true).open(&path).unwrap().set_len(3 << 29).unwrap();
        let err = rmvp_dataset::io::hdr::read_hdr(&path).unwrap_err().to_string();
        assert!(err.contains("panorama.hdr: is 1610612736 bytes, more than the"), "{err}");
    });
    assert!(peak < 64 * MIB, "peak {} MiB", peak / MIB);
}
