//! The session manifest (`session.json`): what was captured, with which camera and settings,
//! and a checksum of every file. A view is complete exactly when the manifest lists it.

use crate::camera::{CameraSettings, Identity};
use crate::{Error, Result};
use rmvp_dataset::io::write_bytes_atomically;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::path::Path;

/// Name of the manifest file in a session folder.
pub const MANIFEST_FILE: &str = "session.json";
/// Format tag of the manifest.
pub const MANIFEST_FORMAT: &str = "rmvp-capture-session/1";

/// A capture session.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// [`MANIFEST_FORMAT`].
    pub format: String,
    /// Object name.
    pub object: String,
    /// Views planned.
    pub views_planned: usize,
    /// Creation time (UTC, RFC 3339).
    pub created: String,
    /// Last update (UTC, RFC 3339).
    pub updated: String,
    /// The camera.
    pub camera: CameraRecord,
    /// Acquisition settings.
    pub settings: SessionSettings,
    /// Dark frames, one per exposure time.
    pub dark: Vec<DarkRecord>,
    /// Complete views, in capture order.
    pub views: Vec<ViewRecord>,
    /// Whether all planned views are complete.
    pub complete: bool,
}

/// The camera of a session.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraRecord {
    /// Vendor, model, serial, firmware, transport.
    pub identity: Identity,
    /// Pixel format streamed.
    pub pixel_format: String,
    /// Frame width (sensor pixels).
    pub width: usize,
    /// Frame height (sensor pixels).
    pub height: usize,
    /// GenICam feature values read back after configuration.
    pub features: BTreeMap<String, String>,
}

/// How the session acquires.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SessionSettings {
    /// Camera settings (the exposure is the first of `exposures_us`).
    pub camera: CameraSettings,
    /// Exposure times of each view (several: HDR bracketing), microseconds.
    pub exposures_us: Vec<f64>,
    /// Frames averaged per exposure.
    pub average: usize,
    /// Dark frames averaged per exposure (0: none).
    pub dark_frames: usize,
    /// How views are positioned and started (`interactive`, `timed`, `trigger`, `turntable`).
    pub positioning: String,
    /// What one unit of the Stokes images is.
    pub stokes_unit: String,
}

/// A file of the session.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FileRecord {
    /// Path relative to the session folder.
    pub path: String,
    /// Size in bytes.
    pub bytes: u64,
    /// SHA-256, hexadecimal.
    pub sha256: String,
}

/// The dark frame of one exposure time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DarkRecord {
    /// Exposure time (us).
    pub exposure_us: f64,
    /// Frames averaged.
    pub frames: usize,
    /// Frames the stream lost or failed and that were grabbed again.
    pub dropped_frames: usize,
    /// The mean frame (16-bit PNG mosaic).
    pub file: FileRecord,
}

/// A complete view.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewRecord {
    /// Index in the session (0-based).
    pub index: usize,
    /// Folder name under `views/`.
    pub name: String,
    /// When its first frame was grabbed (UTC, RFC 3339).
    pub captured_at: String,
    /// `DeviceTemperature` when captured (degrees C), if the camera reports it.
    pub temperature_c: Option<f64>,
    /// Frames kept (exposures x average).
    pub frames: usize,
    /// Frames the stream lost or failed and that were grabbed again.
    pub dropped_frames: usize,
    /// Fraction of Stokes pixels with at least one saturated polarizer angle.
    pub saturated_fraction: f64,
    /// Mean DoP over pixels brighter than 5 % of full scale.
    pub mean_dop: f64,
    /// Its files.
    pub files: Vec<FileRecord>,
}

impl Manifest {
    /// Read `DIR/session.json`.
    pub fn read(dir: &Path) -> Result<Self> {
        let path = dir.join(MANIFEST_FILE);
        let text = std::fs::read_to_string(&path).map_err(|e| rmvp_dataset::Error::io(&path, e))?;
        let manifest: Manifest =
            serde_json::from_str(&text).map_err(|e| Error::in_file(&path, format!("not a session manifest: {e}")))?;
        if manifest.format != MANIFEST_FORMAT {
            return Err(Error::in_file(&path, format!("format {:?}, expected {MANIFEST_FORMAT:?}", manifest.format)));
        }
        Ok(manifest)
    }

    /// Write `DIR/session.json` atomically, stamping `updated`.
    pub fn write(&mut self, dir: &Path) -> Result<()> {
        self.updated = utc_now();
        let text = serde_json::to_string_pretty(self).expect("serialisable");
        Ok(write_bytes_atomically(&dir.join(MANIFEST_FILE), text.as_bytes())?)
    }

    /// Check that every listed file exists with its size and checksum.
    pub fn verify(&self, dir: &Path) -> Result<()> {
        let files = self.dark.iter().map(|d| &d.file).chain(self.views.iter().flat_map(|v| &v.files));
        for file in files {
            let actual = FileRecord::of(dir, &file.path)?;
            if actual != *file {
                return Err(Error::in_file(
                    &dir.join(&file.path),
                    "differs from the session manifest (size or SHA-256): the session was modified or damaged",
                ));
            }
        }
        Ok(())
    }
}

impl FileRecord {
    /// Size and SHA-256 of `DIR/relative`.
    pub fn of(dir: &Path, relative: &str) -> Result<Self> {
        let path = dir.join(relative);
        let bytes = std::fs::read(&path).map_err(|e| rmvp_dataset::Error::io(&path, e))?;
        Ok(Self { path: relative.to_string(), bytes: bytes.len() as u64, sha256: sha256_hex(&bytes) })
    }
}

/// SHA-256 of `bytes` in hexadecimal.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

/// The current time, UTC, RFC 3339 with seconds.
pub fn utc_now() -> String {
    let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs()) as i64;
    rfc3339(secs)
}

/// Seconds since 1970 as `YYYY-MM-DDTHH:MM:SSZ` (proleptic Gregorian calendar).
fn rfc3339(secs: i64) -> String {
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z", rem / 3600, rem % 3600 / 60, rem % 60)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_are_rfc3339() {
        assert_eq!(rfc3339(0), "1970-01-01T00:00:00Z");
        assert_eq!(rfc3339(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(rfc3339(1_795_222_861), "2026-11-21T01:01:01Z");
    }

    #[test]
    fn sha256_of_abc() {
        assert_eq!(sha256_hex(b"abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    }
}
