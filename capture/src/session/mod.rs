//! Capture sessions: N views of one object, each saved complete or not at all.
//!
//! Three stages run concurrently, joined by bounded queues (two views each): acquisition (this
//! thread: positioning, exposure brackets, K-frame bursts, dropped frames grabbed again),
//! processing (averaging, dark subtraction, HDR merge, demosaicing, Stokes) and writing (files
//! into `views/NNN.partial/`, checksums, rename to `views/NNN/`, then the manifest). A view is
//! complete exactly when `session.json` lists it; `--resume` continues after the last one.
//!
//! The session folder and its manifest are described in [`rmvp_dataset::session`].

pub mod hdr;
pub mod positioning;
pub mod reprocess;
pub mod storage;

use crate::camera::{CameraDevice, CameraOptions, Grab, TriggerSource};
use crate::correction::{mean_frame, subtract_dark};
use crate::pipeline::{FrameProcessor, ProcessedFrame};
use crate::preview::Preview;
use crate::raw::PixelFormat;
use crate::{Error, RawFrame, Result};
use positioning::{LastView, Positioning};
use rmvp_dataset::io::{png, write_bytes_atomically};
use rmvp_dataset::polarization::SENSOR_POLARIZER_CELL;
use rmvp_dataset::session::{
    utc_now, DarkRecord, FileRecord, SessionCamera, SessionManifest, SessionSettings, SessionView, StokesUnit,
    SESSION_FILE, SESSION_FORMAT,
};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Features read back into the manifest after configuration: the camera's state as it
/// captured (those it does not have are left out).
pub const RECORDED_FEATURES: [&str; 26] = [
    "PixelFormat",
    "Width",
    "Height",
    "OffsetX",
    "OffsetY",
    "ReverseX",
    "ReverseY",
    "AdcBitDepth",
    "GammaEnable",
    "BlackLevel",
    "ExposureAuto",
    "ExposureTime",
    "GainAuto",
    "Gain",
    "AcquisitionMode",
    "AcquisitionFrameRateEnable",
    "AcquisitionFrameRate",
    "AcquisitionResultingFrameRate",
    "DeviceLinkThroughputLimit",
    "DeviceLinkCurrentThroughput",
    "DeviceLinkSpeed",
    "TriggerSelector",
    "TriggerMode",
    "TriggerSource",
    "DeviceTemperature",
    "TLParamsLocked",
];

/// Views waiting between two stages.
const QUEUE_DEPTH: usize = 2;

/// What to capture and how.
#[derive(Clone)]
pub struct SessionOptions {
    /// Object name.
    pub object: String,
    /// Views to capture.
    pub views: usize,
    /// Session folder.
    pub dir: PathBuf,
    /// Camera settings (its exposure is replaced by each of `exposures_us`, its trigger by the
    /// positioning's).
    pub camera: CameraOptions,
    /// Exposure times per view, microseconds (several: HDR bracketing).
    pub exposures_us: Vec<f64>,
    /// Frames averaged per exposure.
    pub average: usize,
    /// Dark frames averaged per exposure (0: none).
    pub dark_frames: usize,
    /// How views are positioned.
    pub positioning: Positioning,
    /// Continue an existing session.
    pub resume: bool,
    /// Longest wait for one frame before asking whether the camera is still there.
    pub frame_timeout: Duration,
    /// Live preview to update after each view.
    pub preview: Option<Arc<Preview>>,
    /// Show a progress bar.
    pub progress: bool,
}

impl Default for SessionOptions {
    /// `rmvp capture`'s defaults: 60 views of "object" into `session/`, one 20 ms exposure
    /// ([`CameraOptions::default`]), no averaging, no dark frames, the operator positioning
    /// each view, 5 s for a frame to arrive.
    fn default() -> Self {
        let camera = CameraOptions::default();
        Self {
            object: "object".into(),
            views: 60,
            dir: PathBuf::from("session"),
            exposures_us: vec![camera.exposure_us],
            camera,
            average: 1,
            dark_frames: 0,
            positioning: Positioning::Interactive,
            resume: false,
            frame_timeout: Duration::from_secs(5),
            preview: None,
            progress: true,
        }
    }
}

/// How a session run ended.
#[derive(Clone, Debug, PartialEq)]
pub struct SessionReport {
    /// Views complete in the session.
    pub views_complete: usize,
    /// Views planned.
    pub views_planned: usize,
    /// Views captured by this run.
    pub views_captured: usize,
    /// Frames lost by the stream and grabbed again during this run.
    pub dropped_frames: usize,
}

/// The frames of one view, as grabbed.
struct GrabbedView {
    index: usize,
    captured_at: String,
    temperature_c: Option<f64>,
    turntable_position: Option<i64>,
    /// Per exposure: the frames' bytes.
    frames: Vec<Vec<Vec<u8>>>,
    dropped: usize,
}

/// A processed view on its way to disk.
struct ProcessedView {
    grabbed: GrabbedView,
    processed: ProcessedFrame,
    saturated_fraction: f64,
    mean_dop: f64,
}

/// Run (or resume) a session with `camera`. On any error, every view grabbed before it is still
/// written, the manifest stays consistent, and the error says how to resume.
pub fn capture(camera: &mut CameraDevice, options: &SessionOptions) -> Result<SessionReport> {
    if options.views == 0 || options.exposures_us.is_empty() || options.average == 0 {
        return Err(Error::Unsupported("a session needs at least one view, exposure and frame".into()));
    }
    let dir = options.dir.as_path();
    let mut settings = options.camera.clone();
    settings.exposure_us = options.exposures_us[0];
    settings.trigger = options.positioning.trigger();
    let format = camera.configure(&settings)?;
    let mut manifest = open_manifest(camera, options, &settings, format)?;
    clean_incomplete(dir, &manifest)?;
    manifest.write(dir)?;

    let (darks, dark_dropped) = dark_frames(camera, options, &mut manifest, format)?;
    let start = manifest.views.len();
    let bar = rmvp_dataset::progress::progress_bar(options.progress, options.views as u64, "views");
    bar.set_position(start as u64);
    let last = Mutex::new(LastView { done: start, ..LastView::default() });
    let (to_processing, from_acquisition) = sync_channel::<GrabbedView>(QUEUE_DEPTH);
    let (to_writer, from_processing) = sync_channel::<ProcessedView>(QUEUE_DEPTH);
    // Set when processing or writing fails, so that acquisition stops before the next view.
    let failed = AtomicBool::new(false);
    let (acquired, processed, written) = std::thread::scope(|scope| {
        let frame_format = camera.frame_format();
        let failed = &failed;
        let flag = |result: Result<()>| {
            if result.is_err() {
                failed.store(true, Ordering::Relaxed);
            }
            result
        };
        let processing =
            scope.spawn(move || flag(process_views(from_acquisition, to_writer, frame_format, options, &darks)));
        let (manifest, last, bar) = (&mut manifest, &last, &bar);
        let writing = scope.spawn(move || flag(write_views(from_processing, manifest, options, last, bar)));
        let acquired = acquire_views(camera, to_processing, options, start, last, failed);
        (acquired, processing.join().expect("processing thread"), writing.join().expect("writing thread"))
    });
    bar.finish();
    let complete = manifest.views.len();
    // The acquisition error is the cause when there is one (later stages then stop early).
    let outcome = acquired.and_then(|dropped| processed.and(written).map(|_| dropped));
    match outcome {
        Ok(dropped) => Ok(SessionReport {
            views_complete: complete,
            views_planned: options.views,
            views_captured: complete - start,
            dropped_frames: dark_dropped + dropped,
        }),
        Err(e) => Err(Error::Session { cause: Box::new(e), dir: dir.to_path_buf(), complete, planned: options.views }),
    }
}

/// Refuse a session folder that already holds a session when not resuming, or none when
/// resuming. Needs no camera: the command line asks this before it opens one, so an operator
/// hears about `resume` first.
pub fn check_session_folder(dir: &Path, resume: bool) -> Result<()> {
    let exists = dir.join(SESSION_FILE).exists();
    if !resume && exists {
        let old = SessionManifest::read(dir)?;
        return Err(Error::SessionExists {
            dir: dir.to_path_buf(),
            object: old.object,
            complete: old.views.len(),
            planned: old.views_planned,
        });
    }
    if resume && !exists {
        return Err(Error::NothingToResume { dir: dir.to_path_buf() });
    }
    Ok(())
}

/// Read the manifest to resume, or start a new one; check that a resumed session continues
/// with the same camera and settings.
fn open_manifest(
    camera: &CameraDevice,
    options: &SessionOptions,
    settings: &CameraOptions,
    format: PixelFormat,
) -> Result<SessionManifest> {
    let dir = options.dir.as_path();
    let (_, width, height) = camera.frame_format();
    let features: BTreeMap<String, String> = RECORDED_FEATURES
        .iter()
        .filter(|f| camera.is_available(f))
        .filter_map(|f| camera.feature(f).ok().map(|v| (f.to_string(), v)))
        .collect();
    let stokes_unit = if options.exposures_us.len() > 1 {
        let shortest = options.exposures_us.iter().copied().fold(f64::INFINITY, f64::min);
        StokesUnit::HdrFullScale { shortest_exposure_us: shortest, gain_db: settings.gain_db }
    } else {
        StokesUnit::FullScale { bits: format.bits, exposure_us: options.exposures_us[0], gain_db: settings.gain_db }
    };
    let fresh = SessionManifest {
        format: SESSION_FORMAT.into(),
        object: options.object.clone(),
        views_planned: options.views,
        created: utc_now(),
        updated: utc_now(),
        camera: SessionCamera { identity: camera.identity(), pixel_format: format.name(), width, height, features },
        settings: SessionSettings {
            camera: settings.clone(),
            exposures_us: options.exposures_us.clone(),
            average: options.average,
            dark_frames: options.dark_frames,
            positioning: options.positioning.mode(),
            stokes_unit,
        },
        dark: Vec::new(),
        views: Vec::new(),
        complete: false,
        polarizer_cell: SENSOR_POLARIZER_CELL,
    };
    check_session_folder(dir, options.resume)?;
    if !options.resume {
        std::fs::create_dir_all(dir).map_err(|e| rmvp_dataset::Error::io(dir, e))?;
        return Ok(fresh);
    }
    let mut old = SessionManifest::read(dir)?;
    old.verify(dir)?;
    let mismatch = |what: &str, was: String, now: String| Error::ResumeMismatch {
        dir: dir.to_path_buf(),
        what: what.into(),
        was,
        now,
    };
    if old.object != fresh.object {
        return Err(mismatch("object", old.object, fresh.object));
    }
    if old.camera.identity.serial != fresh.camera.identity.serial {
        return Err(mismatch("camera", old.camera.identity.serial, fresh.camera.identity.serial));
    }
    if old.camera.pixel_format != fresh.camera.pixel_format {
        return Err(mismatch("pixel format", old.camera.pixel_format, fresh.camera.pixel_format));
    }
    let acquisition = |s: &SessionSettings| (s.exposures_us.clone(), s.average, s.dark_frames, s.camera.gain_db);
    if acquisition(&old.settings) != acquisition(&fresh.settings) {
        return Err(mismatch(
            "exposures, averaging, dark frames and gain",
            format!("{:?}", acquisition(&old.settings)),
            format!("{:?}", acquisition(&fresh.settings)),
        ));
    }
    old.views_planned = options.views.max(old.views.len());
    old.complete = old.views.len() >= old.views_planned;
    Ok(old)
}

/// Remove what an interrupted run left that the manifest does not list.
fn clean_incomplete(dir: &Path, manifest: &SessionManifest) -> Result<()> {
    let views = dir.join("views");
    let Ok(entries) = std::fs::read_dir(&views) else { return Ok(()) };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if !manifest.views.iter().any(|v| v.name == name) {
            std::fs::remove_dir_all(entry.path()).map_err(|e| rmvp_dataset::Error::io(entry.path(), e))?;
        }
    }
    Ok(())
}

/// The mean dark frame of each exposure: read from the session, or captured now; and the
/// frames dropped (and grabbed again) while capturing them.
fn dark_frames(
    camera: &mut CameraDevice,
    options: &SessionOptions,
    manifest: &mut SessionManifest,
    format: PixelFormat,
) -> Result<(Vec<Option<RawFrame>>, usize)> {
    let dir = options.dir.as_path();
    if options.dark_frames == 0 {
        return Ok((vec![None; options.exposures_us.len()], 0));
    }
    if manifest.dark.len() == options.exposures_us.len() {
        let darks = manifest.dark.iter().map(|d| RawFrame::read(&dir.join(&d.file.path), format, 0, 0).map(Some));
        return Ok((darks.collect::<Result<_>>()?, 0));
    }
    let (_, width, height) = camera.frame_format();
    options.positioning.cap_lens(camera, true)?;
    let mut darks = Vec::new();
    let mut dropped = 0;
    for &exposure in &options.exposures_us {
        let dropped_before = dropped;
        let frames = grab_burst(camera, options, exposure, options.dark_frames, &mut dropped)?;
        let frames: Vec<RawFrame> =
            frames.iter().map(|b| RawFrame::decode(b, format, width, height, camera.name())).collect::<Result<_>>()?;
        let mean = mean_frame(&frames)?;
        let relative = format!("dark/dark_{exposure}us.png");
        png::write_png_u16(&dir.join(&relative), &mean.pixels)?;
        manifest.dark.push(DarkRecord {
            exposure_us: exposure,
            frames: frames.len(),
            dropped_frames: dropped - dropped_before,
            file: FileRecord::of(dir, &relative)?,
        });
        darks.push(Some(mean));
    }
    options.positioning.cap_lens(camera, false)?;
    manifest.write(dir)?;
    Ok((darks, dropped))
}

/// Set the exposure, start, grab `count` complete frames (after one settling frame when free
/// running), stop: frames the stream loses, or that arrive short, are counted in `dropped` and
/// grabbed again.
fn grab_burst(
    camera: &mut CameraDevice,
    options: &SessionOptions,
    exposure_us: f64,
    count: usize,
    dropped: &mut usize,
) -> Result<Vec<Vec<u8>>> {
    camera.set_exposure(exposure_us)?;
    camera.start()?;
    let frames = grab_frames(camera, options, count, dropped)?;
    camera.stop()?;
    Ok(frames)
}

/// [`grab_burst`]'s frames, acquisition running.
fn grab_frames(
    camera: &mut CameraDevice,
    options: &SessionOptions,
    count: usize,
    dropped: &mut usize,
) -> Result<Vec<Vec<u8>>> {
    let (format, width, height) = camera.frame_format();
    let expected = format.frame_bytes(width, height);
    let free_running = options.positioning.trigger() == TriggerSource::FreeRun;
    let mut settle = usize::from(free_running);
    let mut frames = Vec::with_capacity(count);
    let mut failures = 0;
    while frames.len() < count {
        match camera.grab(options.frame_timeout)? {
            Grab::Frame(bytes) if bytes.len() >= expected => {
                if settle > 0 {
                    settle -= 1;
                } else {
                    frames.push(bytes);
                }
                continue;
            }
            Grab::Timeout if !free_running => continue,
            Grab::Frame(_) | Grab::Dropped(_) | Grab::Timeout => {
                *dropped += 1;
                failures += 1;
            }
        }
        if failures > 10 + 2 * count {
            return Err(Error::camera(
                camera.name(),
                format!("{failures} frames lost or incomplete while grabbing {count}: check the cable and bandwidth"),
            ));
        }
    }
    Ok(frames)
}

/// Acquisition stage: position, bracket, grab; hand each view to processing. Returns the
/// frames dropped (and grabbed again).
fn acquire_views(
    camera: &mut CameraDevice,
    to_processing: SyncSender<GrabbedView>,
    options: &SessionOptions,
    start: usize,
    last: &Mutex<LastView>,
    failed: &AtomicBool,
) -> Result<usize> {
    let mut dropped_total = 0;
    for index in start..options.views {
        if failed.load(Ordering::Relaxed) {
            break; // the failing stage reports its error
        }
        if options.positioning == Positioning::Interactive {
            // The operator judges the view just taken (saturation, DoP) before moving on.
            while last.lock().expect("last view").done < index && !failed.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(20));
            }
        }
        let status = last.lock().expect("last view").clone();
        options.positioning.prepare(camera, index, options.views, &status)?;
        let captured_at = utc_now();
        let temperature_c = camera.float("DeviceTemperature").ok();
        let turntable_position = camera.integer("TurntablePositionReached").ok();
        let mut frames = Vec::new();
        let mut dropped = 0;
        for &exposure in &options.exposures_us {
            frames.push(grab_burst(camera, options, exposure, options.average, &mut dropped)?);
        }
        dropped_total += dropped;
        let view = GrabbedView { index, captured_at, temperature_c, turntable_position, frames, dropped };
        if to_processing.send(view).is_err() {
            break; // a later stage failed; its error is reported
        }
    }
    Ok(dropped_total)
}

/// Processing stage: decode, average, subtract darks, merge brackets, compute Stokes.
fn process_views(
    from_acquisition: Receiver<GrabbedView>,
    to_writer: SyncSender<ProcessedView>,
    frame_format: (PixelFormat, usize, usize),
    options: &SessionOptions,
    darks: &[Option<RawFrame>],
) -> Result<()> {
    let processor = session_processor();
    for grabbed in from_acquisition {
        let source = format!("view {}", grabbed.index);
        let processed = process_view(&processor, &grabbed.frames, frame_format, &options.exposures_us, darks, &source)?;
        let (saturated_fraction, mean_dop) = statistics(&processed);
        if to_writer.send(ProcessedView { grabbed, processed, saturated_fraction, mean_dop }).is_err() {
            break;
        }
    }
    Ok(())
}

/// How a session processes its frames: bilinear demosaicing, saturated angles dropped.
fn session_processor() -> FrameProcessor {
    FrameProcessor { saturation_aware: true, ..FrameProcessor::default() }
}

/// One view's frames (per exposure, the bytes of each frame) decoded, averaged, darks
/// subtracted, brackets merged, processed. `source` names the view in errors.
fn process_view(
    processor: &FrameProcessor,
    frames: &[Vec<Vec<u8>>],
    (format, w, h): (PixelFormat, usize, usize),
    exposures_us: &[f64],
    darks: &[Option<RawFrame>],
    source: &str,
) -> Result<ProcessedFrame> {
    let mut means = Vec::new();
    for (frames, dark) in frames.iter().zip(darks) {
        let decoded: Vec<RawFrame> =
            frames.iter().map(|b| RawFrame::decode(b, format, w, h, source)).collect::<Result<_>>()?;
        let mut mean = mean_frame(&decoded)?;
        if let Some(dark) = dark {
            subtract_dark(&mut mean, dark)?;
        }
        means.push(mean);
    }
    let frame = if means.len() > 1 { hdr::merge(&means, exposures_us)? } else { means.remove(0) };
    processor.process(&frame)
}

/// Fraction of pixels with a saturated angle, and mean DoP over pixels above 5 % full scale.
fn statistics(frame: &ProcessedFrame) -> (f64, f64) {
    let saturated = frame.estimate.saturated.data();
    let saturated_fraction = saturated.iter().filter(|&&s| s > 0).count() as f64 / saturated.len().max(1) as f64;
    let s0 = frame.estimate.stokes.s0.data();
    let c = frame.estimate.stokes.s0.channels();
    let (mut sum, mut n) = (0.0, 0usize);
    for (px, &dop) in s0.chunks_exact(c).zip(frame.dop.data()) {
        if px.iter().sum::<f32>() / c as f32 > 0.05 && dop.is_finite() {
            sum += dop as f64;
            n += 1;
        }
    }
    (saturated_fraction, if n > 0 { sum / n as f64 } else { 0.0 })
}

/// Writing stage: files into `views/NNN.partial/`, checksums, rename, manifest.
fn write_views(
    from_processing: Receiver<ProcessedView>,
    manifest: &mut SessionManifest,
    options: &SessionOptions,
    last: &Mutex<LastView>,
    bar: &indicatif::ProgressBar,
) -> Result<()> {
    let dir = options.dir.as_path();
    let views_dir = dir.join("views");
    for view in from_processing {
        let name = format!("{:03}", view.grabbed.index);
        let partial = views_dir.join(format!("{name}.partial"));
        let raw_bytes: usize = view.grabbed.frames.iter().flatten().map(Vec::len).sum();
        let (w, h) = view.processed.aop.size();
        storage::ensure_space(dir, raw_bytes as u64 + (w * h * 80) as u64)?;
        if partial.exists() {
            std::fs::remove_dir_all(&partial).map_err(|e| rmvp_dataset::Error::io(&partial, e))?;
        }
        for (frames, exposure) in view.grabbed.frames.iter().zip(&options.exposures_us) {
            for (k, bytes) in frames.iter().enumerate() {
                write_bytes_atomically(&partial.join(format!("raw/{exposure}us_{k}.raw")), bytes)?;
            }
        }
        view.processed.write(&partial, "view")?;
        let final_dir = views_dir.join(&name);
        std::fs::rename(&partial, &final_dir).map_err(|e| rmvp_dataset::Error::io(&final_dir, e))?;
        sync_dir(&views_dir)?;
        let files = list_files(dir, &final_dir)?;
        let frames = view.grabbed.frames.iter().map(Vec::len).sum();
        manifest.views.push(SessionView {
            index: view.grabbed.index,
            name: name.clone(),
            captured_at: view.grabbed.captured_at.clone(),
            temperature_c: view.grabbed.temperature_c,
            turntable_position: view.grabbed.turntable_position,
            frames,
            dropped_frames: view.grabbed.dropped,
            saturated_fraction: view.saturated_fraction,
            mean_dop: view.mean_dop,
            files,
        });
        manifest.complete = manifest.views.len() >= manifest.views_planned;
        manifest.write(dir)?;
        *last.lock().expect("last view") = LastView {
            done: manifest.views.len(),
            saturated_fraction: view.saturated_fraction,
            mean_dop: view.mean_dop,
        };
        if let Some(preview) = &options.preview {
            preview.update(&view.processed, &name, manifest.views.len(), manifest.views_planned);
        }
        bar.inc(1);
    }
    Ok(())
}

/// Every file under `folder`, with size and checksum, paths relative to `root`, sorted.
fn list_files(root: &Path, folder: &Path) -> Result<Vec<FileRecord>> {
    let prefix = folder.strip_prefix(root).expect("under root").to_string_lossy().into_owned();
    rmvp_dataset::session::files_under(folder)?
        .iter()
        .map(|file| {
            let relative = if prefix.is_empty() { file.clone() } else { format!("{prefix}/{file}") };
            Ok(FileRecord::of(root, &relative)?)
        })
        .collect()
}

/// Flush a folder's entries (a rename) to disk.
fn sync_dir(dir: &Path) -> Result<()> {
    std::fs::File::open(dir).and_then(|f| f.sync_all()).map_err(|e| rmvp_dataset::Error::io(dir, e).into())
}
