//! Test support shared by the workspace's test suites: where the reference scenes rendered by
//! Mitsuba 3 are (`shared/fixtures` beside the checkout, or `$RMVP_FIXTURES`).

pub mod mutation;
pub mod results;

use std::path::{Path, PathBuf};

/// The seed that tests whose figures depend on random inputs (noise, samples, a network's
/// start) add to their own: `$RMVP_TEST_SEED`, else 0. The suite runs at 0;
/// `bench/test-margins.sh` runs those tests at other seeds to measure the spread of their
/// figures against their bounds (`docs/design.md`, "Test bounds").
pub fn test_seed() -> u64 {
    match std::env::var("RMVP_TEST_SEED") {
        Ok(text) => text.parse().unwrap_or_else(|_| panic!("RMVP_TEST_SEED={text:?} is not a whole number")),
        Err(_) => 0,
    }
}

/// The fixtures folder: `$RMVP_FIXTURES`, else `shared/fixtures` beside the checkout.
pub fn fixtures_root() -> PathBuf {
    std::env::var_os("RMVP_FIXTURES")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/fixtures"))
}

/// One fixture scene by name (`spot_nersp`, `bunny_nersp`); panics with a clear message when
/// it is missing.
pub fn fixture(name: &str) -> PathBuf {
    let dir = fixtures_root().join(name);
    assert!(dir.is_dir(), "fixture {} missing; set RMVP_FIXTURES", dir.display());
    dir
}

/// The scenes in `root` (its folders with `cameras.npz`), sorted.
fn scenes_in(root: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut scenes = Vec::new();
    for entry in std::fs::read_dir(root)? {
        let path = entry?.path();
        if path.join("cameras.npz").is_file() {
            scenes.push(path);
        }
    }
    scenes.sort();
    Ok(scenes)
}

/// Every fixture scene (folders with `cameras.npz`), sorted; at least the spot and the bunny.
pub fn fixture_scenes() -> Vec<PathBuf> {
    let root = fixtures_root();
    let scenes = scenes_in(&root)
        .unwrap_or_else(|e| panic!("fixtures not found at {} ({e}); set RMVP_FIXTURES", root.display()));
    assert!(scenes.len() >= 2, "expected the spot and bunny fixtures in {}", root.display());
    scenes
}

/// The evaluation scenes rendered by Mitsuba 3: `$RMVP_EVALSET`, else `shared/evalset` beside
/// the checkout.
pub fn evalset_root() -> PathBuf {
    std::env::var_os("RMVP_EVALSET")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/evalset"))
}

/// Every scene rendered by Mitsuba 3 that is at hand, the evaluation set's and the fixtures'
/// (folders with `cameras.npz`), each set sorted; empty where neither folder exists.
pub fn mitsuba_scenes() -> Vec<PathBuf> {
    [evalset_root(), fixtures_root()].iter().filter_map(|root| scenes_in(root).ok()).flatten().collect()
}

/// A real raw frame from outside the project by file name (`shared/real_raw` beside the
/// checkout, or `$RMVP_REAL_RAW`); panics with a clear message when it is missing.
pub fn real_raw(name: &str) -> PathBuf {
    let root = std::env::var_os("RMVP_REAL_RAW")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/real_raw"));
    let path = root.join(name);
    assert!(path.is_file(), "real raw frame {} missing; set RMVP_REAL_RAW", path.display());
    path
}

/// OpenCV's chessboard photographs (`left01.jpg` ... `left14.jpg`: 13 pictures of a board of
/// 10x7 squares, 9x6 inner corners, from a 640x480 camera), sorted, as
/// `scripts/fetch-test-photographs.sh` (run by `./run test`) takes them out of Debian's
/// opencv-doc package.
pub fn opencv_photographs() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/photographs/opencv");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{} ({e}): run scripts/fetch-test-photographs.sh", dir.display()))
        .map(|e| e.expect("readable folder").path())
        .filter(|p| p.extension().is_some_and(|e| e == "jpg"))
        .collect();
    files.sort();
    assert_eq!(files.len(), 13, "OpenCV's 13 chessboard photographs in {}", dir.display());
    files
}

/// An EXIF block (big-endian TIFF, as a JPEG's APP1 segment carries it after `Exif\0\0`) naming
/// a camera: `make` and `model` (each longer than 4 bytes with its terminator) in the first
/// directory, the focal length in the Exif directory it points to.
pub fn exif_block(make: &str, model: &str, focal_mm: u32) -> Vec<u8> {
    assert!(make.len() >= 4 && model.len() >= 4, "short strings are stored inline; not built here");
    let entry = |tag: u16, kind: u16, count: u32, value: u32| {
        [tag.to_be_bytes().as_slice(), &kind.to_be_bytes(), &count.to_be_bytes(), &value.to_be_bytes()].concat()
    };
    let (make_at, model_at) = (8 + 2 + 3 * 12 + 4, 8 + 2 + 3 * 12 + 4 + make.len() as u32 + 1);
    let exif_at = model_at + model.len() as u32 + 1;
    let mut exif = b"MM\0\x2a\0\0\0\x08\0\x03".to_vec();
    exif.extend(entry(0x010f, 2, make.len() as u32 + 1, make_at));
    exif.extend(entry(0x0110, 2, model.len() as u32 + 1, model_at));
    exif.extend(entry(0x8769, 4, 1, exif_at));
    exif.extend([0; 4]);
    for text in [make, model] {
        exif.extend(text.as_bytes());
        exif.push(0);
    }
    exif.extend([0, 1]);
    exif.extend(entry(0x920a, 5, 1, exif_at + 2 + 12 + 4));
    exif.extend([0; 4]);
    exif.extend([focal_mm.to_be_bytes(), 1u32.to_be_bytes()].concat());
    exif
}

/// Copy the folder tree `from` into `to` (created), every file writable: the fixtures are
/// read-only, and tests damage their copies.
pub fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy_tree(&entry.path(), &target);
        } else {
            std::fs::write(&target, std::fs::read(entry.path()).unwrap()).unwrap();
        }
    }
}

/// CRC-32 as PNG computes it over a chunk's type and data.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
        }
    }
    !crc
}

/// What a process run by [`run_limited`] did.
pub struct Limited {
    /// Its exit status; `None` when it was killed at the deadline.
    pub status: Option<std::process::ExitStatus>,
    /// Its standard output.
    pub stdout: String,
    /// Its standard error.
    pub stderr: String,
    /// The most memory it held at once (its peak resident set), bytes.
    pub peak_bytes: u64,
}

/// The address space a process run by [`run_limited`] may map (`RLIMIT_AS`, which counts
/// `mmap` as well as the heap): a reader that asks for more fails to allocate.
pub const ADDRESS_SPACE_LIMIT: u64 = 2 << 30;
/// The most memory such a process may hold at once, measured (its peak resident set).
pub const PEAK_MEMORY_LIMIT: u64 = 1 << 30;

/// Run `command` with at most [`ADDRESS_SPACE_LIMIT`] of address space and two worker threads
/// (`RAYON_NUM_THREADS`), kill it if it runs past `deadline`, and measure its peak memory.
pub fn run_limited(command: &mut std::process::Command, deadline: std::time::Duration) -> Limited {
    use std::os::unix::process::{CommandExt, ExitStatusExt};
    use std::process::Stdio;
    command.stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped()).env("RAYON_NUM_THREADS", "2");
    // SAFETY: setrlimit is async-signal-safe; nothing else runs between fork and exec.
    unsafe {
        command.pre_exec(|| {
            let limit = libc::rlimit { rlim_cur: ADDRESS_SPACE_LIMIT, rlim_max: ADDRESS_SPACE_LIMIT };
            if libc::setrlimit(libc::RLIMIT_AS, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let started = std::time::Instant::now();
    #[allow(clippy::zombie_processes, reason = "reaped below by wait4, which reports its peak memory")]
    let mut child = command.spawn().unwrap();
    let pid = child.id() as libc::pid_t;
    // Both streams drained while the process runs, so that neither can fill up and block it.
    let (out, err) = (child.stdout.take().unwrap(), child.stderr.take().unwrap());
    let stdout = std::thread::spawn(move || std::io::read_to_string(out).unwrap_or_default());
    let stderr = std::thread::spawn(move || std::io::read_to_string(err).unwrap_or_default());
    // The child is reaped here, with its resource usage: `wait4` reports its peak memory.
    let reap = |options: libc::c_int| {
        let (mut status, mut usage) = (0, unsafe { std::mem::zeroed::<libc::rusage>() });
        // SAFETY: plain out-parameters for a child of this process.
        let reaped = unsafe { libc::wait4(pid, &mut status, options, &mut usage) };
        assert!(reaped >= 0, "wait4: {}", std::io::Error::last_os_error());
        (reaped == pid).then(|| (std::process::ExitStatus::from_raw(status), usage.ru_maxrss as u64 * 1024))
    };
    let (status, peak_bytes) = loop {
        if let Some((status, peak)) = reap(libc::WNOHANG) {
            break (Some(status), peak);
        }
        if started.elapsed() > deadline {
            child.kill().unwrap();
            let (_, peak) = reap(0).expect("the killed child");
            break (None, peak);
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    Limited { status, stdout: stdout.join().unwrap(), stderr: stderr.join().unwrap(), peak_bytes }
}

/// Run the test named `test` of this test binary alone, in a child process with the variable
/// `child` set (which tells it it is the child), under [`run_limited`].
pub fn run_test_in_child(test: &str, child: (&str, &str), deadline: std::time::Duration) -> Limited {
    let mut command = std::process::Command::new(std::env::current_exe().unwrap());
    command.args([test, "--exact", "--nocapture", "--test-threads=1"]).env(child.0, child.1);
    run_limited(&mut command, deadline)
}

/// The variable that makes a test binary a child running one test's body.
const LIMITED_CASE: &str = "RMVP_LIMITED_CASE";

/// Run `body` of the test named `test` in a child process of the test binary, under
/// [`run_limited`] and a 60 s deadline: the test fails if the body fails, hangs, or holds
/// [`PEAK_MEMORY_LIMIT`] or more at once. In that child, run `body`. Returns the peak memory in
/// the parent (0 in the child).
pub fn limited_case(test: &str, body: impl FnOnce()) -> u64 {
    if std::env::var(LIMITED_CASE).as_deref() == Ok(test) {
        body();
        return 0;
    }
    let deadline = std::time::Duration::from_secs(60);
    let run = run_test_in_child(test, (LIMITED_CASE, test), deadline);
    let output = format!("{}\n{}", run.stdout, run.stderr);
    match run.status {
        None => panic!("{test}: still ran after {deadline:?}\n{output}"),
        Some(s) if !s.success() => panic!("{test}: failed ({s})\n{output}"),
        Some(_) => {}
    }
    let peak_mib = run.peak_bytes as f64 / (1 << 20) as f64;
    eprintln!("{test}: peak {peak_mib:.0} MiB");
    assert!(run.peak_bytes < PEAK_MEMORY_LIMIT, "{test}: held {peak_mib:.0} MiB at once");
    run.peak_bytes
}
