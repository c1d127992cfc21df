//! Capture sessions on disk: the manifest (`session.json`) that `rmvp capture` writes, with the
//! camera, its settings and a checksum of every file. A view is complete exactly when the
//! manifest lists it. These are plain records: reading a session needs no camera code.
//!
//! ```text
//! session.json                      manifest (camera, settings, views, SHA-256 of every file)
//! dark/dark_<t>us.png               mean dark frame per exposure time (16-bit mosaic)
//! views/NNN/raw/<t>us_<k>.raw       every frame kept, bytes exactly as the camera sent them
//! views/NNN/view_{000,045,090,135}.png   demosaiced angle images (16-bit, linear)
//! views/NNN/view_stokes.exr         Stokes S0, S1, S2 (RGB), in [`SessionSettings::stokes_unit`]
//! views/NNN/view_{aop,dop}.{exr,png}, view_s0.png   AoP, DoP and a preview
//! ```

use crate::io::input;
use crate::io::json::{free_form, read_json, write_json};
use crate::polarization::{cell_name, PolarizerCell, SENSOR_POLARIZER_CELL, VENDOR_NAMES_AS_IMAGE_ANGLES};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::path::Path;

/// Name of the manifest file in a session folder.
pub const SESSION_FILE: &str = "session.json";
/// Format tag this code writes.
pub const SESSION_FORMAT: &str = "rmvp-capture-session/3";
/// Older format tags this code still reads (`/1` stored the Stokes unit as free text; `/1` and
/// `/2` record no polarizer cell: their views were processed with
/// [`VENDOR_NAMES_AS_IMAGE_ANGLES`]).
const READABLE_FORMATS: [&str; 3] = [SESSION_FORMAT, "rmvp-capture-session/2", "rmvp-capture-session/1"];
/// The Stokes images of a view, relative to its folder.
pub const VIEW_STOKES: &str = "view_stokes.exr";

/// A capture session.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SessionManifest {
    /// [`SESSION_FORMAT`].
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
    pub camera: SessionCamera,
    /// Acquisition settings.
    pub settings: SessionSettings,
    /// Dark frames, one per exposure time.
    pub dark: Vec<DarkRecord>,
    /// Complete views, in capture order.
    pub views: Vec<SessionView>,
    /// Whether all planned views are complete.
    pub complete: bool,
    /// The polarizer cell the views' angle images, Stokes and AoP were computed with
    /// ([`crate::polarization::PolarizerCell`]); sessions that lack it were processed with
    /// [`VENDOR_NAMES_AS_IMAGE_ANGLES`].
    #[serde(default = "processed_before_the_cell_was_recorded")]
    pub polarizer_cell: PolarizerCell,
}

fn processed_before_the_cell_was_recorded() -> PolarizerCell {
    VENDOR_NAMES_AS_IMAGE_ANGLES
}

/// What a camera says it is.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CameraIdentity {
    /// `DeviceVendorName`.
    pub vendor: String,
    /// `DeviceModelName`.
    pub model: String,
    /// `DeviceSerialNumber`.
    pub serial: String,
    /// `DeviceFirmwareVersion` (or `DeviceVersion`).
    pub firmware: String,
    /// Transport: `USB3Vision` or `GigEVision`.
    pub protocol: String,
}

/// The camera of a session.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SessionCamera {
    /// Vendor, model, serial, firmware, transport.
    pub identity: CameraIdentity,
    /// Pixel format streamed.
    pub pixel_format: String,
    /// Frame width (sensor pixels).
    pub width: usize,
    /// Frame height (sensor pixels).
    pub height: usize,
    /// GenICam feature values read back after configuration.
    pub features: BTreeMap<String, String>,
}

/// What starts a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum TriggerSource {
    /// Free running at the frame rate.
    FreeRun,
    /// A pulse on the camera's opto-isolated input `Line0`.
    Line0,
}

/// Acquisition settings, by the FLIR Blackfly S feature names.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraOptions {
    /// Pixel format name; `None`: negotiated by the camera code.
    pub pixel_format: Option<String>,
    /// `ExposureTime` in microseconds (`ExposureAuto=Off`).
    pub exposure_us: f64,
    /// `Gain` in dB (`GainAuto=Off`).
    pub gain_db: f64,
    /// `AcquisitionFrameRate` in Hz (`AcquisitionFrameRateEnable`); `None`: as fast as possible.
    pub frame_rate: Option<f64>,
    /// Trigger of each frame.
    pub trigger: TriggerSource,
    /// The user declared the sensor polarized (`--polarized-sensor`): captured although the
    /// camera offers no polarized format and its model is not a known polarized one.
    #[serde(default)]
    pub polarized_sensor: bool,
}

impl Default for CameraOptions {
    fn default() -> Self {
        Self {
            pixel_format: None,
            exposure_us: 20_000.0,
            gain_db: 0.0,
            frame_rate: None,
            trigger: TriggerSource::FreeRun,
            polarized_sensor: false,
        }
    }
}

/// How the object and camera get to each view.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum PositioningMode {
    /// The operator moves the camera and presses Enter.
    Interactive,
    /// The operator moves the camera during a fixed pause.
    Timed,
    /// Each view starts with a pulse on the camera's `Line0` input.
    Trigger,
    /// The rig's motorised turntable turns to each view.
    Turntable,
}

/// What one unit of a session's Stokes images is.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum StokesUnit {
    /// Full scale of one exposure's frame.
    FullScale {
        /// Significant bits of the frame.
        bits: u8,
        /// Exposure time, microseconds.
        exposure_us: f64,
        /// Analog gain, dB.
        gain_db: f64,
    },
    /// Full scale of an HDR-merged frame: the full scale at the shortest exposure.
    HdrFullScale {
        /// The shortest exposure time of the bracket, microseconds.
        shortest_exposure_us: f64,
        /// Analog gain, dB.
        gain_db: f64,
    },
    /// Free text, as sessions of format `/1` stored it.
    Described(String),
}

impl std::fmt::Display for StokesUnit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StokesUnit::FullScale { bits, exposure_us, gain_db } => {
                write!(f, "full scale of the {bits}-bit frame at {exposure_us} us, gain {gain_db} dB")
            }
            StokesUnit::HdrFullScale { shortest_exposure_us, gain_db } => write!(
                f,
                "full scale of the HDR-merged frame: full scale at the shortest exposure, \
                 {shortest_exposure_us} us, gain {gain_db} dB"
            ),
            StokesUnit::Described(text) => f.write_str(text),
        }
    }
}

/// How the session acquires.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SessionSettings {
    /// Camera settings (the exposure is the first of `exposures_us`).
    pub camera: CameraOptions,
    /// Exposure times of each view (several: HDR bracketing), microseconds.
    pub exposures_us: Vec<f64>,
    /// Frames averaged per exposure.
    pub average: usize,
    /// Dark frames averaged per exposure (0: none).
    pub dark_frames: usize,
    /// How views are positioned and started.
    pub positioning: PositioningMode,
    /// What one unit of the Stokes images is.
    #[serde(deserialize_with = "free_form")]
    pub stokes_unit: StokesUnit,
}

/// A file of a session or a release: path, size and checksum.
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
pub struct SessionView {
    /// Index in the session (0-based).
    pub index: usize,
    /// Folder name under `views/`.
    pub name: String,
    /// When its first frame was grabbed (UTC, RFC 3339).
    pub captured_at: String,
    /// `DeviceTemperature` when captured (degrees C), if the camera reports it.
    pub temperature_c: Option<f64>,
    /// The rig's turntable position when captured, if it has a turntable.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub turntable_position: Option<i64>,
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

impl SessionView {
    /// The folder of this view in the session `dir`.
    pub fn folder(&self, dir: &Path) -> std::path::PathBuf {
        dir.join("views").join(&self.name)
    }
}

impl SessionManifest {
    /// Read `DIR/session.json`, refusing a session whose views were processed with another
    /// polarizer cell than the sensor's: its AoP would be mirrored. [`SessionManifest::read_raw`]
    /// reads it anyway, to process its raw frames again (`rmvp reprocess`).
    pub fn read(dir: &Path) -> Result<Self> {
        let manifest = Self::read_raw(dir)?;
        if manifest.polarizer_cell != SENSOR_POLARIZER_CELL {
            return Err(Error::format(
                dir.join(SESSION_FILE),
                format!(
                    "its views were processed with the polarizer cell {} in the image frame, but the sensor's is {} \
                     (its AoP is mirrored, S2 has the wrong sign); its raw frames are right: run `rmvp reprocess {}` \
                     to compute its views again from them",
                    cell_name(&manifest.polarizer_cell),
                    cell_name(&SENSOR_POLARIZER_CELL),
                    dir.display()
                ),
            ));
        }
        Ok(manifest)
    }

    /// Read `DIR/session.json` whatever polarizer cell its views were processed with.
    pub fn read_raw(dir: &Path) -> Result<Self> {
        let path = dir.join(SESSION_FILE);
        let manifest: SessionManifest = read_json(&path, "a session manifest")?;
        if !READABLE_FORMATS.contains(&manifest.format.as_str()) {
            return Err(Error::format(&path, format!("format {:?}, expected {SESSION_FORMAT:?}", manifest.format)));
        }
        manifest.check_names().map_err(|why| Error::format(&path, why))?;
        Ok(manifest)
    }

    /// Refuse a session without a complete view: there is nothing to pose, mask or build.
    pub fn require_views(&self, dir: &Path) -> Result<()> {
        if self.views.is_empty() {
            return Err(Error::format(dir.join(SESSION_FILE), "lists no complete view (capture views first)"));
        }
        Ok(())
    }

    /// Every view name is one file name, no two alike, and every file record a path inside the
    /// session (the rule of [`crate::io::input`]): names and paths from the manifest become
    /// paths on disk.
    fn check_names(&self) -> std::result::Result<(), String> {
        let mut names = std::collections::BTreeSet::new();
        for view in &self.views {
            input::file_name(&view.name).map_err(|why| format!("view {}: {why}", view.index))?;
            if !names.insert(view.name.as_str()) {
                return Err(format!("two views are named {:?}", view.name));
            }
        }
        let files = self.dark.iter().map(|d| &d.file).chain(self.views.iter().flat_map(|v| &v.files));
        for file in files {
            input::check_relative(&file.path)?;
        }
        Ok(())
    }

    /// Write `DIR/session.json` atomically, in the current format, stamping `updated`.
    pub fn write(&mut self, dir: &Path) -> Result<()> {
        self.format = SESSION_FORMAT.into();
        self.updated = utc_now();
        write_json(&dir.join(SESSION_FILE), self)
    }

    /// Check that every listed file exists with its size and checksum.
    pub fn verify(&self, dir: &Path) -> Result<()> {
        let files = self.dark.iter().map(|d| &d.file).chain(self.views.iter().flat_map(|v| &v.files));
        for file in files {
            let actual = FileRecord::of(dir, &file.path)?;
            if actual != *file {
                return Err(Error::format(
                    dir.join(&file.path),
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
        let path = input::inside(dir, relative).map_err(|why| Error::format(dir.join(SESSION_FILE), why))?;
        let (sha256, bytes) = sha256_file(&path)?;
        Ok(Self { path: relative.to_string(), bytes, sha256 })
    }
}

/// SHA-256 of `bytes` in hexadecimal.
pub fn sha256_hex(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

/// SHA-256 (hexadecimal) and size of the file at `path`, read in 1 MiB pieces.
pub fn sha256_file(path: &Path) -> Result<(String, u64)> {
    use std::io::Read;
    let mut file = crate::io::input::open_regular(path)?;
    let (mut hasher, mut buffer, mut size) = (Sha256::new(), vec![0u8; 1 << 20], 0u64);
    loop {
        let n = file.read(&mut buffer).map_err(|e| Error::io(path, e))?;
        if n == 0 {
            break;
        }
        hasher.update(&buffer[..n]);
        size += n as u64;
    }
    Ok((hex(&hasher.finalize()), size))
}

fn hex(digest: &[u8]) -> String {
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

pub use crate::io::input::files_under;

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

    #[test]
    fn stokes_units_round_trip_and_old_text_still_reads() {
        for unit in [
            StokesUnit::FullScale { bits: 12, exposure_us: 20_000.0, gain_db: 0.0 },
            StokesUnit::HdrFullScale { shortest_exposure_us: 4_000.0, gain_db: 1.5 },
            StokesUnit::Described("full scale of the 12-bit frame at 20000 us, gain 0 dB".into()),
        ] {
            let text = serde_json::to_string(&unit).unwrap();
            assert_eq!(serde_json::from_str::<StokesUnit>(&text).unwrap(), unit, "{text}");
        }
        let old: PositioningMode = serde_json::from_str("\"trigger\"").unwrap();
        assert_eq!(old, PositioningMode::Trigger);
    }
}
