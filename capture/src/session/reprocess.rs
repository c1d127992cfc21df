//! A session's views computed again from its raw frames: for sessions processed with another
//! polarizer cell than the sensor's ([`rmvp_dataset::session::SessionManifest::read`] refuses
//! them), or after a change to the frame pipeline.
//!
//! The raw frames and dark frames are never touched: they are checked against the manifest,
//! every other file of a view is computed again into `views/NNN.reprocess/` and moved over the
//! old one, and the manifest is written last. An interrupted run leaves the manifest as it
//! was, so running again starts over from the same raw frames.

use super::{list_files, process_view, session_processor, statistics, sync_dir};
use crate::raw::PixelFormat;
use crate::{Error, RawFrame, Result};
use rmvp_dataset::polarization::SENSOR_POLARIZER_CELL;
use rmvp_dataset::session::{FileRecord, SessionManifest, SessionView};
use std::path::Path;

/// What [`reprocess`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct Reprocessed {
    /// Views computed again.
    pub views: usize,
    /// Raw and dark frames checked against the manifest.
    pub raw_files: usize,
}

/// Compute every view of the session in `dir` again from its raw frames, with the sensor's
/// polarizer cell, and record that cell in the manifest.
pub fn reprocess(dir: &Path, progress: bool) -> Result<Reprocessed> {
    let mut manifest = SessionManifest::read_raw(dir)?;
    let manifest_path = dir.join(rmvp_dataset::session::SESSION_FILE);
    let format = PixelFormat::from_name(&manifest.camera.pixel_format)
        .map_err(|e| Error::in_file(&manifest_path, e.to_string()))?;
    let frame_format = (format, manifest.camera.width, manifest.camera.height);
    let exposures = manifest.settings.exposures_us.clone();
    let mut raw_files = 0;
    let mut darks = vec![None; exposures.len()];
    if manifest.settings.dark_frames > 0 {
        for (slot, exposure) in darks.iter_mut().zip(&exposures) {
            let record = manifest.dark.iter().find(|d| d.exposure_us == *exposure).ok_or_else(|| {
                Error::in_file(&manifest_path, format!("lists no dark frame for the exposure of {exposure} us"))
            })?;
            check_unchanged(dir, &record.file)?;
            raw_files += 1;
            *slot = Some(RawFrame::read(&dir.join(&record.file.path), format, 0, 0)?);
        }
    }
    let processor = session_processor();
    let bar = rmvp_dataset::progress::progress_bar(progress, manifest.views.len() as u64, "views");
    let views_dir = dir.join("views");
    for view in &mut manifest.views {
        let folder = view.folder(dir);
        let mut frames = Vec::new();
        for exposure in &exposures {
            let mut burst = Vec::new();
            for k in 0..manifest.settings.average {
                let relative = format!("views/{}/raw/{exposure}us_{k}.raw", view.name);
                let record = view.files.iter().find(|f| f.path == relative).ok_or_else(|| {
                    Error::in_file(&manifest_path, format!("view {} lists no raw frame {relative}", view.name))
                })?;
                burst.push(check_unchanged(dir, record)?);
                raw_files += 1;
            }
            frames.push(burst);
        }
        let source = folder.display().to_string();
        let processed = process_view(&processor, &frames, frame_format, &exposures, &darks, &source)?;
        let staging = views_dir.join(format!("{}.reprocess", view.name));
        if staging.exists() {
            std::fs::remove_dir_all(&staging).map_err(|e| rmvp_dataset::Error::io(&staging, e))?;
        }
        processed.write(&staging, "view")?;
        for file in rmvp_dataset::session::files_under(&staging)? {
            let to = folder.join(&file);
            std::fs::rename(staging.join(&file), &to).map_err(|e| rmvp_dataset::Error::io(&to, e))?;
        }
        std::fs::remove_dir_all(&staging).map_err(|e| rmvp_dataset::Error::io(&staging, e))?;
        sync_dir(&folder)?;
        let (saturated_fraction, mean_dop) = statistics(&processed);
        *view = SessionView { files: list_files(dir, &folder)?, saturated_fraction, mean_dop, ..view.clone() };
        bar.inc(1);
    }
    bar.finish();
    manifest.polarizer_cell = SENSOR_POLARIZER_CELL;
    manifest.write(dir)?;
    Ok(Reprocessed { views: manifest.views.len(), raw_files })
}

/// The bytes of a listed file, refused when they differ from the manifest's record.
fn check_unchanged(dir: &Path, record: &FileRecord) -> Result<Vec<u8>> {
    let path = rmvp_dataset::io::input::inside(dir, &record.path)
        .map_err(|why| Error::in_file(&dir.join(rmvp_dataset::session::SESSION_FILE), why))?;
    let bytes = rmvp_dataset::io::input::read_bytes(&path)?;
    if bytes.len() as u64 != record.bytes || rmvp_dataset::session::sha256_hex(&bytes) != record.sha256 {
        return Err(Error::in_file(
            &path,
            "differs from the session manifest (size or SHA-256): a raw frame was modified or damaged",
        ));
    }
    Ok(bytes)
}
