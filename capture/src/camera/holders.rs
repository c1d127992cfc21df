//! Which processes hold a device file open: what rmvp names when a USB3 Vision camera is
//! claimed by another application (the kernel lets one program claim a USB interface; the
//! claim itself does not say by whom).

use std::path::{Path, PathBuf};

/// A process holding a file open.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Holder {
    /// Process id.
    pub pid: u32,
    /// Its command name (`/proc/PID/comm`).
    pub command: String,
}

impl std::fmt::Display for Holder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} (pid {})", self.command, self.pid)
    }
}

/// Every process (that this user may inspect) with `path` open, this one excluded.
pub fn holders_of(path: &Path) -> Vec<Holder> {
    let Ok(target) = path.canonicalize() else { return Vec::new() };
    let own = std::process::id();
    let Ok(processes) = std::fs::read_dir("/proc") else { return Vec::new() };
    let mut holders: Vec<Holder> = processes
        .flatten()
        .filter_map(|entry| entry.file_name().to_str()?.parse::<u32>().ok())
        .filter(|&pid| pid != own)
        .filter(|&pid| {
            let Ok(fds) = std::fs::read_dir(format!("/proc/{pid}/fd")) else { return false };
            fds.flatten().any(|fd| std::fs::read_link(fd.path()).is_ok_and(|link| link == target))
        })
        .map(|pid| Holder {
            pid,
            command: std::fs::read_to_string(format!("/proc/{pid}/comm")).unwrap_or_default().trim().to_string(),
        })
        .collect();
    holders.sort_by_key(|h| h.pid);
    holders
}

/// The device node (`/dev/bus/usb/BBB/DDD`) of the USB device whose serial string is
/// `serial` (compared without case), from sysfs.
pub fn usb_device_node(serial: &str) -> Option<PathBuf> {
    let devices = std::fs::read_dir("/sys/bus/usb/devices").ok()?;
    let read = |dir: &Path, name: &str| std::fs::read_to_string(dir.join(name)).ok().map(|s| s.trim().to_string());
    devices.flatten().map(|e| e.path()).find_map(|dir| {
        let found = read(&dir, "serial")?;
        if !found.eq_ignore_ascii_case(serial) {
            return None;
        }
        let bus: u32 = read(&dir, "busnum")?.parse().ok()?;
        let device: u32 = read(&dir, "devnum")?.parse().ok()?;
        Some(PathBuf::from(format!("/dev/bus/usb/{bus:03}/{device:03}")))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_process_holding_a_file_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("device");
        std::fs::write(&path, b"").unwrap();
        // `spawn` returns once the child runs `sleep`, its standard input the file.
        let mut child =
            std::process::Command::new("sleep").arg("30").stdin(std::fs::File::open(&path).unwrap()).spawn().unwrap();
        let holders = holders_of(&path);
        child.kill().unwrap();
        child.wait().unwrap();
        assert_eq!(holders, vec![Holder { pid: child.id(), command: "sleep".into() }]);
        assert!(holders_of(&path).is_empty(), "{:?}", holders_of(&path));
    }
}
