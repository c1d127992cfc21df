//! Files from anywhere: the rules every reader of rmvp follows, defined here once
//! (`docs/formats.md`, "Files read from anywhere").
//!
//! - **Only regular files are read as data.** [`open_regular`] refuses folders, FIFOs, sockets
//!   and devices before a byte is read, and opens without blocking, so a FIFO put where a file
//!   should be cannot hang a command.
//! - **Paths read from files stay inside their root.** [`inside`] takes a relative path found in
//!   a file (a checksum list, a manifest, a COLMAP model) and gives the path under the root it
//!   is relative to, or an error: it must be relative, `/`-separated, with no `..`, no empty or
//!   `.` component, no backslash, no NUL, and must not lead out of the root through a symbolic
//!   link. [`file_name`] is the rule for a name that becomes one file or folder name (a view's).
//! - **Declared sizes are checked before anything is allocated.** [`check_pixels`] holds image
//!   sizes to [`max_pixels`] (2^28 by default, raised by [`set_max_pixels`], `rmvp
//!   --max-pixels`); text files are read up to [`MAX_TEXT_BYTES`].
//! - **Walks of a tree do not follow symbolic links** ([`files_under`]): a link is listed as
//!   the entry it is, so a loop of links cannot make a walk endless.

use crate::{Error, Result};
use std::fs::{File, Metadata};
use std::io::Read;
use std::os::unix::fs::{FileTypeExt, OpenOptionsExt};
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// The default limit on an image's pixels (width x height): 2^28, a 16384 x 16384 image.
pub const DEFAULT_MAX_PIXELS: u64 = 1 << 28;
/// The largest text file (manifest, checksum list, plan, model) read, in bytes.
pub const MAX_TEXT_BYTES: u64 = 256 << 20;
/// The longest name a view or file may have, in bytes (a Linux file name's limit).
pub const MAX_NAME_BYTES: usize = 255;

static MAX_PIXELS: AtomicU64 = AtomicU64::new(DEFAULT_MAX_PIXELS);

/// The largest image, in pixels, any reader accepts.
pub fn max_pixels() -> u64 {
    MAX_PIXELS.load(Ordering::Relaxed)
}

/// Accept images of up to `pixels` pixels from now on (process-wide).
pub fn set_max_pixels(pixels: u64) {
    MAX_PIXELS.store(pixels.max(1), Ordering::Relaxed);
}

/// Check an image size a file declares (`width x height`) against [`max_pixels`] and refuse an
/// empty one, before its samples are allocated.
pub fn check_pixels(path: &Path, width: u64, height: u64) -> Result<()> {
    let pixels = width.saturating_mul(height);
    if pixels > max_pixels() {
        return Err(Error::ImageTooLarge { path: path.to_path_buf(), width, height, limit: max_pixels() });
    }
    if width == 0 || height == 0 {
        return Err(Error::format(path, format!("declares an empty {width}x{height} image")));
    }
    Ok(())
}

/// The memory decoding one image may take, per pixel [`max_pixels`] allows: 768 MiB by default,
/// enough for a 128-megapixel grey picture or a 40-megapixel picture of 16-bit RGB samples.
pub const DECODING_BYTES_PER_PIXEL: u64 = 3;

/// The most memory, in bytes, decoding one image may take (its file, its samples as decoded
/// and as rmvp keeps them).
pub fn max_decoding_bytes() -> u64 {
    max_pixels().saturating_mul(DECODING_BYTES_PER_PIXEL)
}

/// Check the memory decoding a `width x height` image takes (`bytes`, estimated from its
/// declared size and sample type) against [`max_decoding_bytes`], before anything is allocated.
pub fn check_decoding_bytes(path: &Path, width: u64, height: u64, bytes: u64) -> Result<()> {
    let limit = max_decoding_bytes();
    if bytes > limit {
        let mib = |b: u64| b.div_ceil(1 << 20);
        let why = format!(
            "declares a {width}x{height} image that takes {} MiB to decode, more than the {} MiB one image may \
             take ({DECODING_BYTES_PER_PIXEL} bytes per pixel `--max-pixels` allows)",
            mib(bytes),
            mib(limit)
        );
        return Err(Error::format(path, why));
    }
    Ok(())
}

/// What a file system entry is, in words, when it is not a regular file.
fn not_regular(meta: &Metadata) -> Option<&'static str> {
    let t = meta.file_type();
    Some(if t.is_file() {
        return None;
    } else if t.is_dir() {
        "a folder"
    } else if t.is_fifo() {
        "a named pipe (FIFO)"
    } else if t.is_socket() {
        "a socket"
    } else if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else {
        "not a regular file"
    })
}

fn refuse(path: &Path, meta: &Metadata) -> Result<()> {
    match not_regular(meta) {
        Some(kind) => Err(Error::format(path, format!("is {kind}, not a regular file"))),
        None => Ok(()),
    }
}

/// Open `path` for reading as data: a regular file (or a link to one), refused otherwise with
/// what it is, before any read; never blocks on a FIFO.
pub fn open_regular(path: &Path) -> Result<File> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    refuse(path, &meta)?;
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
        .map_err(|e| Error::io(path, e))?;
    // The entry may have been replaced between the two looks: the open file decides.
    refuse(path, &file.metadata().map_err(|e| Error::io(path, e))?)?;
    Ok(file)
}

/// The size in bytes of a regular file, refused like [`open_regular`] otherwise.
pub fn regular_file_size(path: &Path) -> Result<u64> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    refuse(path, &meta)?;
    Ok(meta.len())
}

/// Whether `path` is a regular file (or a link to one); a FIFO, device or folder is not.
pub fn is_regular_file(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| m.file_type().is_file())
}

/// Read a whole regular file of at most `limit` bytes.
pub fn read_bytes_limited(path: &Path, limit: u64) -> Result<Vec<u8>> {
    let file = open_regular(path)?;
    let size = file.metadata().map_err(|e| Error::io(path, e))?.len();
    if size > limit {
        return Err(Error::format(path, format!("is {size} bytes, more than the {limit} this file may have")));
    }
    // Fallibly: a file too large for this process's memory (a sparse file, a tight address
    // space limit) is refused by name instead of aborting the process.
    let mut bytes = Vec::new();
    bytes
        .try_reserve_exact(size as usize)
        .map_err(|_| Error::format(path, format!("is {size} bytes, more than this process can hold in memory")))?;
    file.take(limit.saturating_add(1)).read_to_end(&mut bytes).map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > limit {
        return Err(Error::format(path, format!("grew past the {limit} bytes this file may have while read")));
    }
    Ok(bytes)
}

/// The first `limit` bytes of a regular file (fewer when it is shorter) and the file's length:
/// a header read before the rest is sized from it.
pub fn read_head(path: &Path, limit: u64) -> Result<(Vec<u8>, u64)> {
    let file = open_regular(path)?;
    let size = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut head = Vec::new();
    file.take(limit).read_to_end(&mut head).map_err(|e| Error::io(path, e))?;
    Ok((head, size))
}

/// Read a whole regular file (mesh, raw frame, panorama): its size on disk bounds what is
/// allocated.
pub fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    read_bytes_limited(path, u64::MAX)
}

/// Read a UTF-8 text file of at most [`MAX_TEXT_BYTES`].
pub fn read_text(path: &Path) -> Result<String> {
    read_text_limited(path, MAX_TEXT_BYTES)
}

/// Read a UTF-8 text file of at most `limit` bytes.
pub fn read_text_limited(path: &Path, limit: u64) -> Result<String> {
    let bytes = read_bytes_limited(path, limit)?;
    String::from_utf8(bytes)
        .map_err(|e| Error::format(path, format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to())))
}

/// Why a relative path read from a file breaks the rule, if it does.
fn relative_fault(relative: &str) -> Option<String> {
    let fault = if relative.is_empty() {
        "is empty"
    } else if relative.contains('\0') {
        "contains a NUL byte"
    } else if relative.contains('\\') {
        "contains a backslash (paths use '/')"
    } else if relative.starts_with('/') {
        "is absolute (it must be relative to its folder)"
    } else if relative.split('/').any(|c| c == "..") {
        "climbs out of its folder ('..')"
    } else if relative.split('/').any(|c| c.is_empty() || c == ".") {
        "has an empty or '.' component"
    } else if relative.split('/').any(|c| c.len() > MAX_NAME_BYTES) {
        "has a component longer than 255 bytes"
    } else if relative.chars().any(char::is_control) {
        "contains a control character"
    } else {
        return None;
    };
    Some(format!("path {relative:?} {fault}"))
}

/// Check a relative path read from a file by the rule of [`inside`], without looking at the disk.
pub fn check_relative(relative: &str) -> std::result::Result<(), String> {
    relative_fault(relative).map_or(Ok(()), Err)
}

/// `root/relative` for a relative path read from a file, after the rule of this module: a
/// relative `/`-separated path without `..`, empty or `.` components, backslashes or control
/// characters, that does not lead out of `root` through a symbolic link. The error is the
/// fault in words, for the caller to attach to the file (and line) it came from.
pub fn inside(root: &Path, relative: &str) -> std::result::Result<PathBuf, String> {
    if let Some(fault) = relative_fault(relative) {
        return Err(fault);
    }
    let path = root.join(relative);
    debug_assert!(Path::new(relative).components().all(|c| matches!(c, Component::Normal(_))));
    // Resolve the deepest part that exists: a link on the way may point anywhere.
    let mut existing = path.as_path();
    while std::fs::symlink_metadata(existing).is_err() {
        match existing.parent() {
            Some(p) if p != root && p.starts_with(root) => existing = p,
            _ => return Ok(path),
        }
    }
    if existing == root {
        return Ok(path);
    }
    let (Ok(real), Ok(real_root)) = (existing.canonicalize(), root.canonicalize()) else {
        return Err(format!("path {relative:?} goes through a broken or looping symbolic link"));
    };
    if !real.starts_with(&real_root) {
        return Err(format!("path {relative:?} leads out of its folder through a symbolic link"));
    }
    Ok(path)
}

/// A name that becomes one file or folder name (a view's name, a task's id): [`inside`]'s rule
/// with a single component, and not starting with '.'.
pub fn file_name(name: &str) -> std::result::Result<&str, String> {
    if let Some(fault) = relative_fault(name) {
        return Err(fault.replacen("path", "name", 1));
    }
    if name.contains('/') {
        return Err(format!("name {name:?} contains '/' (it names one file)"));
    }
    if name.starts_with('.') {
        return Err(format!("name {name:?} starts with '.'"));
    }
    Ok(name)
}

/// Every entry under `dir` that is not a folder (files, and symbolic links as themselves:
/// they are not followed), as `/`-separated paths relative to it, in path order (component by
/// component, as `Path` compares).
pub fn files_under(dir: &Path) -> Result<Vec<String>> {
    let mut files = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).map_err(|e| Error::io(&d, e))? {
            let entry = entry.map_err(|e| Error::io(&d, e))?;
            let kind = entry.file_type().map_err(|e| Error::io(entry.path(), e))?;
            if kind.is_dir() {
                stack.push(entry.path());
            } else {
                files.push(entry.path());
            }
        }
    }
    files.sort();
    Ok(files
        .iter()
        .map(|p| {
            let relative = p.strip_prefix(dir).expect("under dir");
            relative.components().map(|c| c.as_os_str().to_string_lossy()).collect::<Vec<_>>().join("/")
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_paths_from_files_stay_inside_their_root() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("release");
        std::fs::create_dir_all(root.join("obj/nersp")).unwrap();
        std::fs::write(root.join("obj/nersp/a.txt"), b"x").unwrap();
        assert_eq!(inside(&root, "obj/nersp/a.txt").unwrap(), root.join("obj/nersp/a.txt"));
        assert_eq!(inside(&root, "obj/new/b.png").unwrap(), root.join("obj/new/b.png"));
        for (bad, why) in [
            ("../../../../etc/hostname", "'..'"),
            ("obj/../../x", "'..'"),
            ("/dev/zero", "absolute"),
            ("", "empty"),
            ("obj//a", "empty or '.'"),
            ("./a", "empty or '.'"),
            ("a\\..\\b", "backslash"),
            ("a\0b", "NUL"),
            ("a\nb", "control"),
        ] {
            let fault = inside(&root, bad).unwrap_err();
            assert!(fault.contains(why), "{bad:?}: {fault}");
        }
        std::os::unix::fs::symlink("/etc", root.join("obj/out")).unwrap();
        let fault = inside(&root, "obj/out/hostname").unwrap_err();
        assert!(fault.contains("symbolic link"), "{fault}");
        std::os::unix::fs::symlink("nersp", root.join("obj/in")).unwrap();
        assert!(inside(&root, "obj/in/a.txt").is_ok());
        std::os::unix::fs::symlink("loop", root.join("loop")).unwrap();
        assert!(inside(&root, "loop/x").unwrap_err().contains("looping"));
    }

    #[test]
    fn names_are_one_component() {
        assert_eq!(file_name("000").unwrap(), "000");
        for bad in ["../../escape_x", "a/b", ".hidden", "..", ".", "", "a\\b"] {
            assert!(file_name(bad).is_err(), "{bad:?} accepted");
        }
    }

    #[test]
    fn only_regular_files_are_opened_and_walks_do_not_follow_links() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("fifo");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let e = open_regular(&fifo).unwrap_err().to_string();
        assert!(e.contains("named pipe (FIFO), not a regular file"), "{e}");
        let e = read_text(dir.path()).unwrap_err().to_string();
        assert!(e.contains("is a folder"), "{e}");
        assert!(read_bytes(Path::new("/dev/zero")).unwrap_err().to_string().contains("character device"));
        std::os::unix::fs::symlink(".", dir.path().join("a")).unwrap();
        std::os::unix::fs::symlink(".", dir.path().join("b")).unwrap();
        std::fs::write(dir.path().join("file"), b"1").unwrap();
        assert_eq!(files_under(dir.path()).unwrap(), ["a", "b", "fifo", "file"]);
    }

    #[test]
    fn declared_image_sizes_are_bounded() {
        let path = Path::new("big.png");
        assert!(check_pixels(path, 16384, 16384).is_ok());
        let e = check_pixels(path, 200_000, 200_000).unwrap_err().to_string();
        assert!(e.starts_with("big.png: declares a 200000x200000 image, more than the limit"), "{e}");
        assert!(check_pixels(path, 128, 0).unwrap_err().to_string().contains("empty"));
        assert!(check_pixels(path, u64::MAX, 3).is_err());
    }
}
