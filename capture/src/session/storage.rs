//! Free-space checks before a view is written, so that a full disk stops the session between
//! views instead of leaving one half-written.

use crate::{Error, Result};
use std::path::Path;

/// Bytes free to this user on the file system holding `dir`.
pub fn free_bytes(dir: &Path) -> Result<u64> {
    use std::os::unix::ffi::OsStrExt;
    let c_path = std::ffi::CString::new(dir.as_os_str().as_bytes())
        .map_err(|_| Error::in_file(dir, "path contains a NUL byte"))?;
    let mut stats: libc::statvfs = unsafe { std::mem::zeroed() };
    // SAFETY: a valid C string and a zeroed out-struct.
    if unsafe { libc::statvfs(c_path.as_ptr(), &mut stats) } != 0 {
        return Err(rmvp_dataset::Error::io(dir, std::io::Error::last_os_error()).into());
    }
    Ok(stats.f_bavail as u64 * stats.f_frsize as u64)
}

/// Fail, naming `dir`, unless `needed` bytes (plus a margin of 64 MiB and 10 %) are free.
pub fn ensure_space(dir: &Path, needed: u64) -> Result<()> {
    let free = free_bytes(dir)?;
    let wanted = needed + needed / 10 + (64 << 20);
    if free < wanted {
        return Err(Error::DiskFull {
            dir: dir.to_path_buf(),
            free_mib: free as f64 / 1048576.0,
            needed_mib: wanted as f64 / 1048576.0,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_view_larger_than_the_disk_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        assert!(free_bytes(dir.path()).unwrap() > 0);
        ensure_space(dir.path(), 1024).unwrap();
        let err = ensure_space(dir.path(), u64::MAX / 4).unwrap_err();
        assert!(matches!(&err, Error::DiskFull { dir: d, .. } if d == dir.path()), "{err}");
        assert!(err.to_string().contains(&dir.path().display().to_string()), "{err}");
    }
}
