//! Hostile and broken input against the `rmvp` binary: each case is refused within seconds,
//! under 2 GiB of address space and 1 GiB of peak memory, with a message that names the file and
//! the fault once, and nothing is written outside the command's own folders.

use rmvp_dataset::io::npy::{self, Array};
use rmvp_dataset::Mesh;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

/// A path as the `&str` an argument list needs.
fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// How long a hostile case may take.
const DEADLINE: Duration = Duration::from_secs(60);

/// Run rmvp under the memory limit and the deadline; returns (success, stderr).
fn run(args: &[&str]) -> (bool, String) {
    let started = Instant::now();
    let mut command = Command::new(env!("CARGO_BIN_EXE_rmvp"));
    let run = rmvp_testkit::run_limited(command.args(args), DEADLINE);
    let status = run.status.unwrap_or_else(|| panic!("rmvp {args:?} still ran after {DEADLINE:?}"));
    let peak_mib = run.peak_bytes >> 20;
    eprintln!("rmvp {args:?} ({:.1} s, peak {peak_mib} MiB): {}", started.elapsed().as_secs_f64(), run.stderr.trim());
    assert!(run.peak_bytes < rmvp_testkit::PEAK_MEMORY_LIMIT, "rmvp {args:?} held {peak_mib} MiB at once");
    (status.success(), run.stderr)
}

/// Run rmvp, expect a refusal that says every one of `words`, once each where asked, and no
/// crash (an abort from memory or a panic).
fn refused(args: &[&str], words: &[&str]) -> String {
    let (success, stderr) = run(args);
    assert!(!success, "rmvp {args:?} should have failed");
    assert!(stderr.starts_with("error: "), "not a clean refusal: {stderr}");
    for bad in ["panicked", "memory allocation", "RUST_BACKTRACE"] {
        assert!(!stderr.contains(bad), "rmvp {args:?} crashed: {stderr}");
    }
    for word in words {
        assert!(stderr.contains(word), "rmvp {args:?}: {stderr:?} does not say {word:?}");
    }
    stderr
}

fn mkfifo(path: &Path) {
    let _ = std::fs::remove_file(path);
    let c = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo {}", path.display());
}

/// A writable copy of the spot fixture.
fn spot_copy(tmp: &Path) -> PathBuf {
    let dir = tmp.join("spot");
    rmvp_testkit::copy_tree(&rmvp_testkit::fixture("spot_nersp"), &dir);
    dir
}

/// A valid PNG whose header's size is replaced by `width x height` (with a correct CRC).
fn forged_png(from: &Path, width: u32, height: u32) -> Vec<u8> {
    let mut bytes = std::fs::read(from).unwrap();
    assert_eq!(&bytes[12..16], b"IHDR");
    bytes[16..20].copy_from_slice(&width.to_be_bytes());
    bytes[20..24].copy_from_slice(&height.to_be_bytes());
    let crc = rmvp_testkit::crc32(&bytes[12..29]);
    bytes[29..33].copy_from_slice(&crc.to_be_bytes());
    bytes
}

/// A valid EXR whose `dataWindow` is replaced by `0 0 size-1 size-1`.
fn forged_exr(from: &Path, size: i32) -> Vec<u8> {
    let mut bytes = std::fs::read(from).unwrap();
    let key = b"dataWindow\0box2i\0";
    let at = bytes.windows(key.len()).position(|w| w == key).expect("a dataWindow") + key.len() + 4;
    for (k, v) in [0, 0, size - 1, size - 1].iter().enumerate() {
        bytes[at + 4 * k..at + 4 * k + 4].copy_from_slice(&v.to_le_bytes());
    }
    bytes
}

/// Every entry under `dir` with its bytes (regular files) or what it is (links, FIFOs), links not
/// followed: a refused command must leave it as it was.
fn snapshot(dir: &Path) -> Vec<(PathBuf, String)> {
    let mut entries = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            let meta = std::fs::symlink_metadata(&path).unwrap();
            let what = if meta.is_dir() {
                stack.push(path.clone());
                "folder".to_string()
            } else if meta.is_file() {
                format!("{:?}", std::fs::read(&path).unwrap())
            } else if meta.file_type().is_symlink() {
                format!("link to {}", std::fs::read_link(&path).unwrap().display())
            } else {
                "special".to_string()
            };
            entries.push((path, what));
        }
    }
    entries.sort();
    entries
}

fn replace(path: &Path, bytes: &[u8]) {
    let _ = std::fs::remove_file(path);
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn a_release_cannot_make_verify_read_outside_it_or_walk_forever() {
    let tmp = tempfile::tempdir().unwrap();
    let release = tmp.path().join("release");
    std::fs::create_dir_all(release.join("obj")).unwrap();
    std::os::unix::fs::symlink("/etc", release.join("obj/etc")).unwrap();
    std::os::unix::fs::symlink(".", release.join("a")).unwrap();
    std::os::unix::fs::symlink(".", release.join("b")).unwrap();
    std::fs::write(release.join("file.txt"), b"abc").unwrap();
    std::os::unix::fs::symlink("/dev/zero", release.join("zero")).unwrap();
    let hash = "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad";
    let sums = format!(
        "{hash}  file.txt\n{hash}  ../../../../etc/hostname\n{hash}  /dev/zero\n{hash}  obj/etc/hostname\n{hash}  zero\n"
    );
    std::fs::write(release.join("SHA256SUMS"), &sums).unwrap();
    let before = snapshot(tmp.path());
    let stderr = refused(
        &["dataset", "verify", s(&release)],
        &[
            "SHA256SUMS line 2: path \"../../../../etc/hostname\" climbs out of its folder",
            "SHA256SUMS line 3: path \"/dev/zero\" is absolute",
            "SHA256SUMS line 4: path \"obj/etc/hostname\" leads out of its folder through a symbolic link",
            "SHA256SUMS line 5: path \"zero\" leads out of its folder through a symbolic link",
            "a: not listed in SHA256SUMS",
        ],
    );
    assert!(!stderr.contains("file.txt"), "file.txt matches its checksum: {stderr}");
    assert!(snapshot(tmp.path()) == before, "verify changed the release");

    mkfifo(&release.join("SHA256SUMS"));
    refused(&["dataset", "verify", s(&release)], &["SHA256SUMS: is a named pipe (FIFO), not a regular file"]);
}

#[test]
fn fifos_and_forged_sizes_in_a_scene_are_refused_naming_the_file() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = spot_copy(tmp.path());
    let info = |words: &[&str]| refused(&["dataset", "info", s(&scene)], words);

    let s0 = scene.join("s0/0000.npy");
    let kept = std::fs::read(&s0).unwrap();
    mkfifo(&s0);
    info(&["s0/0000.npy: is a named pipe (FIFO), not a regular file"]);
    replace(&s0, &kept);

    let mask = scene.join("mask/0000.png");
    let kept = std::fs::read(&mask).unwrap();
    replace(&mask, &forged_png(&mask_source(), 200_000, 200_000));
    info(&["mask/0000.png: declares a 200000x200000 image, more than the limit of 268435456 pixels", "--max-pixels"]);
    replace(&mask, &kept);

    // A training mask that decodes but is another view's: the damaged file is named, and the
    // copy it disagrees with.
    replace(&mask, &std::fs::read(scene.join("mask/0001.png")).unwrap());
    info(&["mask/0000.png: disagrees at", "pixels with the alpha channel of", "input_azimuth_maps/0000.png"]);
    replace(&mask, &kept);

    let normal = scene.join("gt/normal/000.exr");
    let kept = std::fs::read(&normal).unwrap();
    replace(&normal, &forged_exr(&normal, 100_000));
    info(&["gt/normal/000.exr: "]);
    replace(&normal, &kept);

    // A camera file whose array inflates to 64 MiB: refused from the array's header.
    let cameras = scene.join("cameras.npz");
    let kept = std::fs::read(&cameras).unwrap();
    let big = Array { shape: vec![4096, 2048], data: vec![0f64; 4096 * 2048] };
    std::fs::remove_file(&cameras).unwrap();
    npy::write_npz(&cameras, &[("world_mat_0".to_string(), big)]).unwrap();
    assert!(std::fs::metadata(&cameras).unwrap().len() < 1 << 20);
    info(&["cameras.npz: array world_mat_0: array of shape [4096, 2048] has more than the 1024 elements"]);
    replace(&cameras, &kept);

    // A NaN camera is refused although gt/cameras.json holds a finite one.
    let mut arrays = npy::read_npz::<f64>(&cameras).unwrap();
    arrays.iter_mut().find(|(n, _)| n == "world_mat_0").unwrap().1.data[3] = f64::NAN;
    std::fs::remove_file(&cameras).unwrap();
    npy::write_npz(&cameras, &arrays).unwrap();
    info(&["cameras.npz: world_mat_0 has a non-finite entry (NaN) at row 0, column 3"]);
    replace(&cameras, &kept);

    // Stokes of shape (128, 128, 0): refused by info and convert alike, no panic.
    let empty = Array::<f32> { shape: vec![128, 128, 0], data: Vec::new() };
    for component in ["s0", "s1", "s2"] {
        let path = scene.join(component).join("0000.npy");
        std::fs::remove_file(&path).unwrap();
        npy::write_npy(&path, &empty).unwrap();
    }
    info(&["s0/0000.npy: empty image: shape [128, 128, 0]"]);
    refused(&["dataset", "convert", s(&scene), s(&tmp.path().join("converted")), "--to", "rmvp"], &["empty image"]);
    assert!(!tmp.path().join("converted").exists());
}

fn mask_source() -> PathBuf {
    rmvp_testkit::fixture("spot_nersp").join("mask/0000.png")
}

/// A session folder whose manifest is the test manifest with its views replaced.
fn session_with_views(dir: &Path, views: &str) -> PathBuf {
    let text = include_str!("../dataset/tests/data/session.json");
    let start = text.find("\"views\": [").unwrap();
    let end = text.find("\"complete\"").unwrap();
    let manifest = format!("{}\"views\": {views},\n  {}", &text[..start], &text[end..]);
    let session = dir.join("deep/er/session");
    std::fs::create_dir_all(&session).unwrap();
    std::fs::write(session.join("session.json"), manifest).unwrap();
    session
}

fn view(name: &str) -> String {
    format!(
        "{{\"index\": 0, \"name\": \"{name}\", \"captured_at\": \"2026-11-20T10:01:00Z\", \"temperature_c\": null, \"frames\": 1, \
         \"dropped_frames\": 0, \"saturated_fraction\": 0.0, \"mean_dop\": 0.1, \"files\": []}}"
    )
}

#[test]
fn session_views_that_would_escape_repeat_or_be_missing_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("masks");
    let escape = session_with_views(tmp.path(), &format!("[{}]", view("../../escape_x")));
    let before = snapshot(tmp.path());
    refused(
        &["masks", s(&escape), "-o", s(&out)],
        &["session.json: view 0: name \"../../escape_x\" climbs out of its folder"],
    );
    assert!(snapshot(tmp.path()) == before, "a refused session changed the folder around it");

    let twice = session_with_views(tmp.path(), &format!("[{}, {}]", view("000"), view("000")));
    refused(&["masks", s(&twice), "-o", s(&out)], &["session.json: two views are named \"000\""]);

    let none = session_with_views(tmp.path(), "[]");
    refused(&["masks", s(&none), "-o", s(&out)], &["session.json: lists no complete view"]);
    assert!(!out.exists());

    // A mask correction named for no view of the session is refused by name, not left unused.
    let two = session_with_views(tmp.path(), &format!("[{}, {}]", view("000"), view("001")));
    let corrections = tmp.path().join("corrections");
    std::fs::create_dir_all(&corrections).unwrap();
    std::fs::copy(mask_source(), corrections.join("007.png")).unwrap();
    let args = ["masks", s(&two), "--method", "threshold", "--corrections", s(&corrections), "-o", s(&out)];
    refused(&args, &["corrections/007.png: a correction for no view of the session"]);
    assert!(!out.exists());
}

#[test]
fn plans_with_impossible_values_loops_or_too_many_tasks_are_refused_at_plan_time() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("spot");
    std::fs::create_dir_all(scene.join("gt")).unwrap();
    std::fs::write(scene.join("cameras.npz"), b"").unwrap();
    std::fs::write(scene.join("gt/mesh.ply"), b"").unwrap();
    let plan = tmp.path().join("batch.toml");
    let head = "datasets = [\"spot\"]\n\n[[variant]]\nname = \"v\"\n";
    for (extra, line, words) in [
        ("options = { iters = 0 }\n", 3, "the number of iterations must be at least 1"),
        ("options = { mesh_res = 0 }\n", 3, "the mesh resolution (marching grid cells per axis) must be at least 1"),
        ("options = { batch = 0 }\n", 3, "the rays per iteration (batch) must be at least 1"),
        (
            "options = { tangent_robust_angle = 60.0 }\n",
            3,
            "the tangent term's robust angle must be a number of degrees from 0 to 45",
        ),
        ("options = { curvature_weight = -0.01 }\n", 3, "the curvature term's weight must be a number of at least 0"),
        (
            "options = { min_sample_weight = 1.5 }\n",
            3,
            "the least weight of a rendered sample must be a number from 0 up to 1",
        ),
        (
            "options = { initial_radius = 1.5 }\n",
            3,
            "the initial sphere's radius must be a number between 0 and 1 (the unit sphere's)",
        ),
        ("\n[evaluation]\nthreshold = nan\n", 0, "[evaluation] threshold must be a finite positive distance, not NaN"),
        ("\n[evaluation]\nmax_samples = 0\n", 0, "[evaluation] max_samples must be at least 1"),
    ] {
        std::fs::write(&plan, format!("{head}{extra}")).unwrap();
        let at = if line > 0 { format!("batch.toml line {line}: ") } else { "batch.toml: ".into() };
        refused(&["batch", "plan", s(&plan)], &[at.as_str(), words]);
    }

    let seeds = |n: usize| (0..n).map(|i| i.to_string()).collect::<Vec<_>>().join(", ");
    let variants: String = (0..50).map(|i| format!("\n[[variant]]\nname = \"v{i}\"\n")).collect();
    std::fs::write(&plan, format!("datasets = [\"spot\"]\nseeds = [{}]\n{variants}", seeds(100_000))).unwrap();
    refused(
        &["batch", "plan", s(&plan)],
        &["1 datasets x 50 variants x 100000 seeds make 5000000 tasks, more than the 100000"],
    );
    // Ten million seeds (20 MB): refused by the file's size, before a TOML document of them is
    // parsed.
    std::fs::write(&plan, format!("datasets = [\"spot\"]\nseeds = [{}0]\n{variants}", "0,".repeat(9_999_999))).unwrap();
    refused(&["batch", "plan", s(&plan)], &["batch.toml: is 2000", "bytes, more than the 1048576 this file may have"]);

    std::os::unix::fs::symlink(".", tmp.path().join("a")).unwrap();
    std::os::unix::fs::symlink(".", tmp.path().join("b")).unwrap();
    std::fs::write(&plan, "datasets = [\"**/nothing*\"]\n\n[[variant]]\nname = \"v\"\n").unwrap();
    refused(&["batch", "plan", s(&plan)], &["matches no folder"]);

    mkfifo(&plan);
    refused(&["batch", "plan", s(&plan)], &["batch.toml: is a named pipe (FIFO), not a regular file"]);
}

#[test]
fn meshes_that_cannot_be_aligned_or_evaluated_are_refused_naming_them() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("aligned");
    let target = rmvp_testkit::fixture("spot_nersp").join("gt/mesh.ply");
    let points = tmp.path().join("points.ply");
    Mesh { positions: vec![[0.25, 0.5, 1.0]; 500], ..Mesh::default() }.write(&points).unwrap();
    refused(
        &["align", "--scan", s(&points), "--to", s(&target), "-o", s(&out)],
        &[&format!("{}: all 500 points coincide: nothing to align", points.display())],
    );
    assert!(!out.exists(), "nothing is written for a refused scan");

    let fifo = tmp.path().join("fifo.ply");
    mkfifo(&fifo);
    refused(
        &["align", "--scan", s(&fifo), "--to", s(&target), "-o", s(&out)],
        &["fifo.ply: is a named pipe (FIFO), not a regular file"],
    );

    let missing = tmp.path().join("missing.ply");
    let stderr = refused(&["align", "--scan", s(&missing), "--to", s(&target), "-o", s(&out)], &["missing.ply"]);
    assert_eq!(stderr.matches("os error 2").count(), 1, "the cause said once: {stderr}");

    // An OBJ that names /dev/zero as its material library reads (materials are never opened).
    let obj = tmp.path().join("tri.obj");
    std::fs::write(&obj, "mtllib /dev/zero\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n")
        .unwrap();
    let (success, stderr) = run(&["eval", "--pred", s(&obj), "--gt", s(&obj), "--max-samples", "2000"]);
    assert!(success, "{stderr}");

    refused(
        &["eval", "--pred", s(&points), "--gt", s(&target)],
        &[&format!("{}: has no triangles: a surface is needed to evaluate", points.display())],
    );
}
