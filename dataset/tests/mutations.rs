//! Mutated files against every reader family: truncations, byte flips, forged sizes and counts,
//! inserted bytes and numbers. Each family runs in a child process of this test binary with
//! 1 GiB of data memory (`RLIMIT_DATA`) and a deadline, so that an allocation from a forged size,
//! a hang or a panic fails the test and names the mutation. A mutated file must be refused with
//! an error that names it, or read: never a panic, never more memory, never a hang.

use rmvp_dataset::io::{exr, hdr, npy, picture, png};
use rmvp_dataset::layout::nersp;
use rmvp_dataset::rng::Rng;
use rmvp_dataset::session::SessionManifest;
use rmvp_dataset::Mesh;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

/// Mutations per family.
const MUTATIONS: usize = 200;
/// Data memory a family's child may use.
const MEMORY_LIMIT: u64 = 1 << 30;
/// How long a family's child may take.
const DEADLINE: Duration = Duration::from_secs(90);
/// The variable that makes this binary a child reading one family.
const CHILD: &str = "RMVP_MUTATION_FAMILY";

/// A reader family: its seed file (a valid one) and how to read a file of it.
struct Family {
    name: &'static str,
    file_name: &'static str,
    seed: fn(&Path) -> Vec<u8>,
    read: fn(&Path) -> Result<(), rmvp_dataset::Error>,
    /// Make a mutated file consistent again where its format checks itself (a PNG's header
    /// checksum), so that a forged size reaches the reader as a forger would send it.
    fixup: fn(&mut [u8]),
}

fn no_fixup(_: &mut [u8]) {}

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

fn families() -> Vec<Family> {
    vec![
        Family {
            name: "png",
            file_name: "m.png",
            seed: |_| spot("input_azimuth_maps/0000.png"),
            read: |p| png::read_png(p).map(drop),
            fixup: png_header_crc,
        },
        Family {
            name: "exr",
            file_name: "m.exr",
            seed: |_| spot("gt/normal/000.exr"),
            read: |p| exr::read_exr_channels(p).map(drop),
            fixup: no_fixup,
        },
        Family {
            name: "npy",
            file_name: "m.npy",
            seed: |_| spot("s0/0000.npy"),
            read: |p| npy::read_npy::<f32>(p).map(drop),
            fixup: no_fixup,
        },
        Family {
            name: "npz",
            file_name: "cameras.npz",
            seed: |_| spot("cameras.npz"),
            read: |p| nersp::read_cameras(p).map(drop),
            fixup: no_fixup,
        },
        Family {
            name: "ply-binary",
            file_name: "m.ply",
            seed: |d| small_mesh(d, "seed.ply"),
            read: |p| Mesh::read(p).map(drop),
            fixup: no_fixup,
        },
        Family {
            name: "ply-ascii",
            file_name: "m.ply",
            seed: |d| small_mesh(d, "seed.ascii.ply"),
            read: |p| Mesh::read(p).map(drop),
            fixup: no_fixup,
        },
        Family {
            name: "obj",
            file_name: "m.obj",
            seed: |d| small_mesh(d, "seed.obj"),
            read: |p| Mesh::read(p).map(drop),
            fixup: no_fixup,
        },
        Family {
            name: "jpeg",
            file_name: "m.jpg",
            seed: |_| picture_seed(image::ImageFormat::Jpeg),
            read: |p| picture::read_picture(p).map(drop),
            fixup: no_fixup,
        },
        Family {
            name: "tiff",
            file_name: "m.tif",
            seed: |_| picture_seed(image::ImageFormat::Tiff),
            read: |p| picture::read_picture(p).map(drop),
            fixup: no_fixup,
        },
        Family { name: "stl", file_name: "m.stl", seed: stl_seed, read: |p| Mesh::read(p).map(drop), fixup: no_fixup },
        Family {
            name: "hdr",
            file_name: "m.hdr",
            seed: hdr_seed,
            read: |p| hdr::read_hdr(p).map(drop),
            fixup: no_fixup,
        },
        Family {
            name: "hdr-flat",
            file_name: "m.hdr",
            seed: |_| flat_hdr_seed(),
            read: |p| hdr::read_hdr(p).map(drop),
            fixup: no_fixup,
        },
        Family {
            name: "session",
            file_name: "session.json",
            seed: |_| include_bytes!("data/session.json").to_vec(),
            read: |p| SessionManifest::read(p.parent().unwrap()).map(drop),
            fixup: no_fixup,
        },
    ]
}

/// Numbers a forged size or count is made of.
const FORGED: [u64; 8] = [0, 1 << 20, 1 << 24, 1 << 31, u32::MAX as u64, 100_000, 200_000, u64::MAX];

/// Where a forged field of `width` bytes goes: half the time a 4-byte-aligned offset in the first
/// 64 bytes, else anywhere in the first 512.
fn forged_offset(rng: &mut Rng, len: usize, width: usize) -> usize {
    let room = len.saturating_sub(width).max(1);
    if rng.next_u32().is_multiple_of(2) {
        (4 * (rng.next_u32() as usize % 16)).min(room - 1)
    } else {
        rng.next_u32() as usize % room.min(512)
    }
}

/// Forged fields swept before the random mutations: every 4-byte-aligned offset of the first 64
/// bytes, with 2^20 and 2^24, big- and little-endian (the size fields of binary headers).
const SWEPT: usize = 16 * 4;

/// The `i`-th swept forgery of `seed`, and what it was.
fn sweep(seed: &[u8], i: usize) -> (Vec<u8>, String) {
    let mut bytes = seed.to_vec();
    let at = 4 * (i / 4);
    let value: u32 = if i.is_multiple_of(2) { 1 << 20 } else { 1 << 24 };
    let big_endian = (i / 2).is_multiple_of(2);
    let word = if big_endian { value.to_be_bytes() } else { value.to_le_bytes() };
    if at + 4 <= bytes.len() {
        bytes[at..at + 4].copy_from_slice(&word);
    }
    let order = if big_endian { "big" } else { "little" };
    (bytes, format!("forged {order}-endian {value} at byte {at}"))
}

/// One mutation of `seed`, and what it was.
fn mutate(seed: &[u8], rng: &mut Rng) -> (Vec<u8>, String) {
    let mut bytes = seed.to_vec();
    let at = |rng: &mut Rng, len: usize| (rng.next_u32() as usize) % len.max(1);
    match rng.next_u32() % 6 {
        0 => {
            let keep = at(rng, bytes.len());
            bytes.truncate(keep);
            (bytes, format!("truncated to {keep} bytes"))
        }
        1 => {
            let flips = 1 + rng.next_u32() % 8;
            for _ in 0..flips {
                let i = at(rng, bytes.len());
                bytes[i] ^= 1 << (rng.next_u32() % 8);
            }
            (bytes, format!("{flips} bits flipped"))
        }
        2 => {
            // A forged 32-bit field: sizes and counts live near the start of every format, most
            // at aligned offsets of its first 64 bytes.
            let i = forged_offset(rng, bytes.len(), 4);
            let value = FORGED[(rng.next_u32() as usize) % FORGED.len()] as u32;
            let big_endian = rng.next_u32().is_multiple_of(2);
            let word = if big_endian { value.to_be_bytes() } else { value.to_le_bytes() };
            bytes[i..i + 4].copy_from_slice(&word);
            (bytes, format!("forged 32-bit {value} at byte {i}"))
        }
        3 => {
            // A number in the text replaced by a forged one, NaN or a negative.
            let text_numbers: Vec<usize> =
                (1..bytes.len()).filter(|&i| bytes[i].is_ascii_digit() && !bytes[i - 1].is_ascii_digit()).collect();
            if text_numbers.is_empty() {
                bytes.clear();
                return (bytes, "emptied".into());
            }
            let i = text_numbers[(rng.next_u32() as usize) % text_numbers.len()];
            let end = (i..bytes.len()).find(|&k| !bytes[k].is_ascii_digit()).unwrap_or(bytes.len());
            let choices = ["4294967296", "99999999999999999999", "nan", "-1", "1e308", "0"];
            let by = choices[(rng.next_u32() as usize) % choices.len()];
            bytes.splice(i..end, by.bytes());
            (bytes, format!("number at byte {i} replaced by {by}"))
        }
        4 => {
            let i = at(rng, bytes.len());
            let n = 1 + rng.next_u32() % 64;
            let noise: Vec<u8> = (0..n).map(|_| rng.next_u32() as u8).collect();
            bytes.splice(i..i, noise);
            (bytes, format!("{n} bytes inserted at {i}"))
        }
        _ => {
            // A forged 64-bit field.
            let i = forged_offset(rng, bytes.len(), 8);
            let value = FORGED[(rng.next_u32() as usize) % FORGED.len()];
            bytes[i..i + 8].copy_from_slice(&value.to_le_bytes());
            (bytes, format!("forged 64-bit {value} at byte {i}"))
        }
    }
}

/// In the child: read every mutation of the family, print one line before each (the last line
/// names the culprit of an abort or a hang) and a summary.
fn child(family: &Family) {
    let dir = tempfile::tempdir().unwrap();
    let seed = (family.seed)(dir.path());
    (family.read)(&{
        let p = dir.path().join(family.file_name);
        std::fs::write(&p, &seed).unwrap();
        p
    })
    .unwrap_or_else(|e| panic!("the seed file of {} does not read: {e}", family.name));
    let mut rng = Rng::for_pixel(39, family.name.len() as u32, family.name.as_bytes()[0] as u64);
    let (mut refused, mut read) = (0, 0);
    let mut panics = Vec::new();
    std::panic::set_hook(Box::new(|_| {}));
    for i in 0..MUTATIONS {
        let (mut bytes, what) = if i < SWEPT { sweep(&seed, i) } else { mutate(&seed, &mut rng) };
        (family.fixup)(&mut bytes);
        let case = dir.path().join(format!("{i}"));
        std::fs::create_dir_all(&case).unwrap();
        let path = case.join(family.file_name);
        std::fs::write(&path, &bytes).unwrap();
        println!("mutation {i}: {what}");
        match std::panic::catch_unwind(|| (family.read)(&path)) {
            Ok(Ok(())) => read += 1,
            Ok(Err(e)) => {
                let message = e.to_string();
                assert!(
                    message.contains(&path.display().to_string()),
                    "mutation {i} ({what}): {message:?} does not name the file"
                );
                refused += 1;
            }
            Err(_) => panics.push(format!("mutation {i} ({what})")),
        }
    }
    println!("summary {}: {MUTATIONS} mutations, {refused} refused, {read} read, {} panics", family.name, panics.len());
    assert!(panics.is_empty(), "panics: {panics:?}");
}

/// In the parent: run the family's child under the memory limit and the deadline.
fn run_family(name: &str) {
    let families = families();
    let family = families.iter().find(|f| f.name == name).unwrap();
    if let Ok(wanted) = std::env::var(CHILD) {
        if wanted == name {
            child(family);
        }
        return;
    }
    let test = format!("{}_family", name.replace('-', "_"));
    let mut command = Command::new(std::env::current_exe().unwrap());
    command.args([test.as_str(), "--exact", "--nocapture", "--test-threads=1"]).env(CHILD, name);
    let started = Instant::now();
    let run = rmvp_testkit::run_limited(&mut command, MEMORY_LIMIT, DEADLINE);
    let lines: Vec<&str> = run.stdout.lines().collect();
    let last = lines.iter().rev().find(|l| l.starts_with("mutation ")).copied().unwrap_or_default();
    let summary = lines.iter().find(|l| l.starts_with("summary ")).copied();
    let stderr = &run.stderr;
    match run.status {
        None => panic!("{name}: hung past {DEADLINE:?} at {last}"),
        Some(s) if !s.success() => panic!("{name}: the reader failed ({s}) at {last}\n{stderr}"),
        Some(_) => {}
    }
    let summary = summary.unwrap_or_else(|| panic!("{name}: no summary\n{}", lines.join("\n")));
    eprintln!("{summary} in {:.1} s", started.elapsed().as_secs_f64());
    assert!(summary.contains(&format!("{MUTATIONS} mutations")) && summary.ends_with(", 0 panics"), "{summary}");
}

#[test]
fn png_family() {
    run_family("png");
}

#[test]
fn jpeg_family() {
    run_family("jpeg");
}

#[test]
fn hdr_family() {
    run_family("hdr");
}

#[test]
fn hdr_flat_family() {
    run_family("hdr-flat");
}

#[test]
fn tiff_family() {
    run_family("tiff");
}

#[test]
fn exr_family() {
    run_family("exr");
}

#[test]
fn npy_family() {
    run_family("npy");
}

#[test]
fn npz_family() {
    run_family("npz");
}

#[test]
fn ply_binary_family() {
    run_family("ply-binary");
}

#[test]
fn ply_ascii_family() {
    run_family("ply-ascii");
}

#[test]
fn obj_family() {
    run_family("obj");
}

#[test]
fn stl_family() {
    run_family("stl");
}

#[test]
fn session_family() {
    run_family("session");
}
