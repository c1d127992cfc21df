//! A simulated polarization camera that is a real GenICam device: a GigE Vision camera on an
//! address of its own ([`gige`]: any number run side by side on one host) over aravis's fake
//! camera registers, described by our own GenICam XML (`capture/genicam/`: the FLIR Blackfly
//! S BFS-U3-51S5PC-C features rmvp uses, on a 2448x2048 sensor), streaming raw frames that our
//! renderer and sensor model make of an object on a simulated motorised turntable.
//!
//! Clients reach it exactly as they reach the real camera (GigE Vision instead of USB3 Vision:
//! the same GenICam features through aravis). The turntable (`TurntablePosition`,
//! `TurntablePositionReached`) and a lens cap (`LensCap`) are extra features of the simulated
//! rig; frames show the pose the turntable has reached.

mod firmware;
pub mod gige;
pub mod served;

use crate::raw::PixelFormat;
use crate::sensor::SensorModel;
use crate::RawFrame;
use crate::{Error, Result};
use aravis_sys as ffi;
use gige::Registers;
use rmvp_calib::board::BoardOptions;
use rmvp_calib::lab::{calibration_cameras, calibration_parts, lab_environment, LabOptions};
use rmvp_dataset::rng::Rng;
use rmvp_dataset::{Camera, Mesh, Stokes};
use rmvp_render::pbrdf::{Interface, Lobes};
use rmvp_render::rig::{framing_distance, rig_intrinsics, RigKind};
use rmvp_render::{default_mesh, render_view, EnvMap, Object, Part, Settings};
use std::collections::HashMap;
use std::ffi::{c_void, CString};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// The GenICam XML of the simulated camera; `{PIXEL_FORMATS}` stands for its enumeration
/// entries, `{RIG}` for [`RIG_XML`].
const XML_TEMPLATE: &str = include_str!("../genicam/simulated-bfs-u3-51s5pc.xml");
/// The simulated rig's own features (turntable, lens cap), in every description it serves.
const RIG_XML: &str = include_str!("../genicam/simulated-rig.xml");

/// Sensor width of the BFS-U3-51S5PC-C (pixels).
pub const SENSOR_WIDTH: usize = 2448;
/// Sensor height of the BFS-U3-51S5PC-C (pixels).
pub const SENSOR_HEIGHT: usize = 2048;
/// Exposure time at which unit radiance fills [`REFERENCE_FILL`] of the full well (us).
pub const REFERENCE_EXPOSURE_US: f64 = 20_000.0;
/// Fraction of the full well that unit rendered radiance fills at [`REFERENCE_EXPOSURE_US`].
pub const REFERENCE_FILL: f64 = 0.5;

/// Register addresses of the simulated camera (bytes into the fake camera's memory). The
/// 0x100-0x30c block is aravis's fake-camera map (it drives streaming); 0x1000 up is ours. They
/// must agree with the XML.
mod register {
    pub const VENDOR_NAME: u32 = 0x48;
    pub const MODEL_NAME: u32 = 0x68;
    pub const FIRMWARE_VERSION: u32 = 0x88;
    pub const WIDTH: u32 = 0x100;
    pub const HEIGHT: u32 = 0x104;
    pub const SENSOR_HEIGHT: u32 = 0x118;
    pub const SENSOR_WIDTH: u32 = 0x11c;
    pub const EXPOSURE_TIME_US: u32 = 0x120;
    pub const ACQUISITION: u32 = 0x124;
    pub const PIXEL_FORMAT: u32 = 0x128;
    pub const FRAME_PERIOD_US: u32 = 0x138;
    pub const EXPOSURE_AUTO: u32 = 0x1000;
    pub const GAIN_AUTO: u32 = 0x1004;
    pub const GAIN_DB: u32 = 0x1008;
    pub const FRAME_RATE_ENABLE: u32 = 0x100c;
    pub const TEMPERATURE_C: u32 = 0x1010;
    pub const TURNTABLE_POSITION: u32 = 0x1014;
    pub const TURNTABLE_REACHED: u32 = 0x1018;
    pub const LENS_CAP: u32 = 0x101c;
    pub const TURNTABLE_POSITIONS: u32 = 0x1020;
    pub const GAMMA_ENABLE: u32 = 0x1024;
    pub const REVERSE_X: u32 = 0x1028;
    pub const REVERSE_Y: u32 = 0x102c;
    pub const ADC_BIT_DEPTH: u32 = 0x1030;
    pub const BLACK_LEVEL_PERCENT: u32 = 0x1034;
    pub const READOUT_LOCKED: u32 = 0x1038;
    pub const LINK_THROUGHPUT_LIMIT: u32 = 0x103c;
    pub const OFFSET_X: u32 = 0x130;
    pub const OFFSET_Y: u32 = 0x134;
}

/// The ADC depth of each `AdcBitDepth` entry's value (Bit8, Bit10, Bit12).
const ADC_BITS: [u8; 3] = [8, 10, 12];
/// The gamma `GammaEnable` applies: `v -> full (v / full)^GAMMA`.
const GAMMA: f32 = 0.45;
/// FLIR's default USB3 link limit, bytes a second.
const LINK_THROUGHPUT_LIMIT: u32 = 380_000_000;

/// How another program left the camera: the state rmvp must put right (or refuse) before it
/// captures. The default is a camera fresh from its default user set.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LeftState {
    /// `GammaEnable` on: samples no longer linear.
    pub gamma: bool,
    /// `ReverseX` on: the readout mirrored left to right (the mosaic's phase moves).
    pub reverse_x: bool,
    /// `ReverseY` on.
    pub reverse_y: bool,
    /// `OffsetX`: an odd one moves the mosaic's phase.
    pub offset_x: u32,
    /// `AdcBitDepth` at 8 bits under a deeper format.
    pub adc_8_bits: bool,
    /// `ReverseX` and `ReverseY` locked (as on a camera whose readout another setting holds).
    pub readout_locked: bool,
}

/// Pixel formats the simulated (colour) camera can stream, with the codes it reports. BayerRG*
/// carry their PFNC codes; the polarized formats have vendor-specific codes on FLIR cameras, so
/// the simulator uses its own in the PFNC custom range (bit 31) with the right bits-per-pixel
/// byte. rmvp chooses formats by name, never by code.
pub const PIXEL_FORMATS: [(&str, u32); 8] = [
    ("BayerRGPolarized8", 0x8108_0001),
    ("BayerRGPolarized10p", 0x810a_0002),
    ("BayerRGPolarized12p", 0x810c_0003),
    ("BayerRGPolarized16", 0x8110_0004),
    ("BayerRG8", 0x0108_0009),
    ("BayerRG10p", 0x010a_0058),
    ("BayerRG12p", 0x010c_0059),
    ("BayerRG16", 0x0110_002f),
];

/// What the simulated camera shows and how it behaves.
#[derive(Clone, Debug)]
pub struct SimulatorOptions {
    /// Serial number it reports; `None`: `RMVPSIM` and four digits of its address
    /// (`RMVPSIM0001` on 127.0.0.1), unique on the host.
    pub serial: Option<String>,
    /// Where it answers: `lo` for the first loopback address no other camera holds, an IPv4
    /// address, or a network interface's name ([`gige::Endpoint::bind`]).
    pub interface: String,
    /// Object on the turntable (PLY/OBJ); `None`: the built-in "spot".
    pub mesh: Option<PathBuf>,
    /// Turntable poses.
    pub views: usize,
    /// Renderer samples per pixel.
    pub spp: u32,
    /// Seed of the views' random streams and of the sensor noise.
    pub seed: u64,
    /// Names of the pixel formats offered (from [`PIXEL_FORMATS`]), in the camera's order.
    pub pixel_formats: Vec<String>,
    /// Shot and read noise on (off: every frame of a pose is the same, which is also fastest).
    pub noise: bool,
    /// Fraction of GVSP packets the camera drops on purpose (0 to 1): frames then arrive
    /// incomplete, as on a congested link.
    pub lost_packet_ratio: f64,
    /// What stands in front of the camera.
    pub setup: SimulatedSetup,
    /// How the camera was left by another program.
    pub left: LeftState,
    /// A real camera's GenICam description to serve instead of rmvp's own (a FLIR Blackfly S
    /// file, [`served`]).
    pub description: Option<PathBuf>,
}

/// What the simulated camera looks at.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum SimulatedSetup {
    /// The object alone on a motorised turntable (two rings of poses), world frame = the
    /// object's (+Y up).
    #[default]
    Turntable,
    /// The simulated lab: the object on a calibration board on a textured table, the camera on
    /// two rings around it; world frame = the board's (mm, z up). Poses are turntable positions.
    Lab(LabOptions),
    /// A calibration session: the board alone, moved in front of the camera at many tilts
    /// (one pose per turntable position); world frame = the board's.
    Calibration(BoardOptions),
}

impl Default for SimulatorOptions {
    fn default() -> Self {
        Self {
            serial: None,
            interface: "lo".into(),
            mesh: None,
            views: 6,
            spp: 4,
            seed: 0,
            pixel_formats: PIXEL_FORMATS.iter().map(|(n, _)| n.to_string()).collect(),
            noise: true,
            lost_packet_ratio: 0.0,
            setup: SimulatedSetup::Turntable,
            left: LeftState::default(),
            description: None,
        }
    }
}

/// The scene in front of the simulated camera: object, environment and the turntable's poses
/// (as cameras around the object, OpenCV convention, 1224x1024 Stokes pixels: one per 2x2
/// polarizer cell of the sensor).
pub struct SimulatedScene {
    object: Object,
    env: EnvMap,
    /// Camera of each turntable pose.
    pub cameras: Vec<Camera>,
    /// The subject in the world frame (`None` for a calibration session).
    pub subject: Option<Mesh>,
    settings: Settings,
}

impl SimulatedScene {
    /// Build the scene of `config`.
    pub fn new(config: &SimulatorOptions) -> Result<Self> {
        let mesh = match &config.mesh {
            Some(path) => Mesh::read(path)?,
            None => default_mesh(),
        };
        let (w, h) = ((SENSOR_WIDTH / 2) as u32, (SENSOR_HEIGHT / 2) as u32);
        let k = rig_intrinsics(w, h);
        let views = config.views.max(1);
        let interface = Interface::Dielectric(1.5);
        let (parts, env, cameras, subject) = match &config.setup {
            SimulatedSetup::Turntable => {
                let distance = framing_distance(&k, w, h, mesh.radius() as f64, 0.85);
                let cameras = RigKind::Turntable.rig(views).cameras(k, w, h, distance, config.seed);
                (
                    vec![Part::subject(mesh.clone(), interface, Lobes::Plastic)],
                    EnvMap::procedural(),
                    cameras,
                    Some(mesh),
                )
            }
            SimulatedSetup::Lab(setup) => {
                let lab = setup.build(&mesh, interface)?;
                let cameras = setup.cameras(&lab, views, k, w, h);
                let subject = setup.object.then(|| lab.subject.clone());
                (lab.parts, lab_environment(EnvMap::procedural()), cameras, subject)
            }
            SimulatedSetup::Calibration(board) => {
                let cameras = calibration_cameras(board, views, k, w, h, config.seed);
                (calibration_parts(board)?, lab_environment(EnvMap::procedural()), cameras, None)
            }
        };
        Ok(Self {
            object: Object::from_parts(parts)?,
            env,
            cameras,
            subject,
            settings: Settings { spp: config.spp, seed: config.seed },
        })
    }

    /// What the centre ray of every pixel of pose `view` hits: the subject's mask, depth and
    /// normals (the ground truth of that view's geometry).
    pub fn geometry(&self, view: usize) -> rmvp_render::GeometryMaps {
        rmvp_render::geometry_maps(&self.object, &self.cameras[view])
    }

    /// Render pose `view`: linear RGB Stokes at 1224x1024 (the ground truth of that view).
    pub fn render(&self, view: usize) -> Stokes {
        render_view(&self.object, &self.env, &self.cameras[view], self.settings, view as u32).stokes
    }

    /// The sensor at exposure time `exposure_us` and gain `gain_db`, read out at `bits`.
    pub fn sensor(exposure_us: f64, gain_db: f64, bits: u8) -> SensorModel {
        SensorModel {
            bits,
            exposure: (REFERENCE_FILL * exposure_us / REFERENCE_EXPOSURE_US) as f32,
            gain_db: gain_db as f32,
            ..SensorModel::default()
        }
    }
}

/// What a frame is exposed under: the pose, exposure (us), gain (dB, as bits), bits per pixel
/// and whether the lens is capped.
type FrameKey = (usize, u32, u32, u32, bool);

/// The seed of the sensor noise of frames exposed under `key`: frames are numbered within their
/// key, so a session's noise depends on the frames it takes under each setting, not on how many
/// the free-running stream sent before (which depends on timing).
fn noise_seed(seed: u64, key: FrameKey) -> u64 {
    let (pose, exposure_us, gain_bits, bits, capped) = key;
    let stream = pose as u32 | (bits << 24) | (u32::from(capped) << 31);
    let mut rng = Rng::for_pixel(seed, stream, u64::from(exposure_us) | (u64::from(gain_bits) << 32));
    u64::from(rng.next_u32()) << 32 | u64::from(rng.next_u32())
}

/// The last frame's inputs and their noise-free electrons (recomputed when any changes).
#[derive(Default)]
struct ExposureCache {
    key: Option<(FrameKey, Readout)>,
    electrons: Option<Arc<rmvp_dataset::Image<f32>>>,
    noise_free_bytes: Option<Arc<Vec<u8>>>,
}

/// State shared by aravis's streaming thread (the fill callback) and the turntable thread.
struct Shared {
    camera: Arc<Registers>,
    scene: SimulatedScene,
    poses: Mutex<Vec<Option<Arc<Stokes>>>>,
    exposure: Mutex<ExposureCache>,
    /// Frames streamed so far under each key (the number of the next one).
    frames: Mutex<HashMap<FrameKey, u32>>,
    noise: bool,
    seed: u64,
    stop: AtomicBool,
    /// Rendering ahead runs here, at a lower scheduling priority than streaming: a busy
    /// renderer must not starve the thread that sends the frames.
    renderer: rayon::ThreadPool,
    /// Where the camera's settings live and what its firmware keeps current.
    firmware: firmware::Firmware,
    /// The pixel formats it streams, with the codes its description gives them.
    formats: Vec<(String, u32)>,
}

/// What the camera's readout settings do to a frame after the sensor: ADC depth, gamma,
/// mirroring and the offset of the window.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
struct Readout {
    adc_bits: u8,
    gamma: bool,
    reverse_x: bool,
    reverse_y: bool,
    offset_x: u32,
    offset_y: u32,
}

impl Readout {
    /// The frame as this readout delivers it. The window's offset moves the sensor under it
    /// (the frame wraps round: the simulated sensor has no pixels outside it).
    fn apply(&self, raw: &mut RawFrame) {
        let bits = raw.bits;
        let plain = Readout { adc_bits: self.adc_bits, ..Readout::default() };
        if *self == plain && self.adc_bits >= bits.min(12) {
            return;
        }
        let full = raw.full_scale();
        // The sensor model's frames carry at most 12 ADC bits (16-bit frames are its own
        // finer model): a shallower ADC drops the bits below its depth.
        let drop = bits.min(12).saturating_sub(self.adc_bits);
        let (w, h) = raw.pixels.size();
        let source = raw.pixels.clone();
        let (ox, oy) = (self.offset_x as usize % w, self.offset_y as usize % h);
        for y in 0..h {
            for x in 0..w {
                let sx = if self.reverse_x { w - 1 - x } else { x };
                let sy = if self.reverse_y { h - 1 - y } else { y };
                let mut v = source.data()[((sy + oy) % h) * w + (sx + ox) % w];
                if self.gamma {
                    v = (f32::from(full) * (f32::from(v) / f32::from(full)).powf(GAMMA)).round() as u16;
                }
                raw.pixels.data_mut()[y * w + x] = v >> drop << drop;
            }
        }
    }
}

/// A thread pool for rendering ahead whose threads run at nice 10 (Linux: per thread).
fn background_pool() -> Result<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new()
        .thread_name(|i| format!("simulated camera renderer {i}"))
        .start_handler(|_| {
            // SAFETY: plain system calls on the calling thread.
            unsafe {
                let tid = libc::syscall(libc::SYS_gettid) as libc::id_t;
                libc::setpriority(libc::PRIO_PROCESS, tid, 10);
            }
        })
        .build()
        .map_err(|e| Error::Unsupported(format!("cannot start the simulated camera's renderer: {e}")))
}

impl Shared {
    /// The bytes of the next frame in `format`, from the current registers.
    fn frame(&self, format: PixelFormat) -> Arc<Vec<u8>> {
        let pose = self.camera.read(register::TURNTABLE_REACHED) as usize;
        let exposure_us = self.firmware.exposure_us(&self.camera);
        let gain_db = self.firmware.gain_db(&self.camera);
        let capped = self.camera.read(register::LENS_CAP) != 0;
        let readout = self.firmware.readout(&self.camera);
        let sensor = SimulatedScene::sensor(exposure_us as f64, gain_db as f64, format.bits);
        let key = (pose, exposure_us, gain_db.to_bits(), format.bits as u32, capped);
        let frame = {
            let mut frames = self.frames.lock().expect("frame numbers");
            let next = frames.entry(key).or_insert(0);
            *next += 1;
            *next - 1
        };
        let mut cache = self.exposure.lock().expect("exposure cache");
        if cache.key != Some((key, readout)) {
            let stokes = self.poses.lock().expect("poses")[pose.min(self.scene.cameras.len() - 1)].clone();
            let electrons = match (stokes, capped) {
                (Some(stokes), false) => sensor.electrons(&stokes),
                _ => rmvp_dataset::Image::new(SENSOR_WIDTH, SENSOR_HEIGHT, 1),
            };
            *cache = ExposureCache {
                key: Some((key, readout)),
                electrons: Some(Arc::new(electrons)),
                noise_free_bytes: None,
            };
        }
        if !self.noise {
            if let Some(bytes) = &cache.noise_free_bytes {
                return bytes.clone();
            }
        }
        let electrons = cache.electrons.clone().expect("set above");
        let noise_free = !self.noise;
        drop(cache);
        let model = if noise_free { sensor.noise_free() } else { sensor };
        let mut raw = model.digitize(&electrons, noise_seed(self.seed, key), frame);
        readout.apply(&mut raw);
        let bytes = Arc::new(raw.encode(format).expect("bits match the format"));
        if noise_free {
            self.exposure.lock().expect("exposure cache").noise_free_bytes = Some(bytes.clone());
        }
        bytes
    }

    /// Render `view` unless it is cached.
    fn ensure_rendered(&self, view: usize) {
        if self.poses.lock().expect("poses")[view].is_some() {
            return;
        }
        let stokes = Arc::new(self.renderer.install(|| self.scene.render(view)));
        self.poses.lock().expect("poses")[view] = Some(stokes);
    }

    /// Move the turntable when asked, render ahead, and warm the sensor up.
    fn run_turntable(&self) {
        let n = self.scene.cameras.len();
        while !self.stop.load(Ordering::Relaxed) {
            let target = self.camera.read(register::TURNTABLE_POSITION) as usize;
            if target < n && target != self.camera.read(register::TURNTABLE_REACHED) as usize {
                self.ensure_rendered(target);
                self.camera.write(register::TURNTABLE_REACHED, target as u32);
            } else if let Some(next) =
                (0..n).map(|k| (target + k) % n).find(|&v| self.poses.lock().unwrap()[v].is_none())
            {
                self.ensure_rendered(next);
                continue;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Warm the sensor up and keep the firmware's registers current, until stopped.
    fn run_firmware(&self) {
        let start = Instant::now();
        while !self.stop.load(Ordering::Relaxed) {
            self.firmware_tick(start);
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    fn firmware_tick(&self, start: Instant) {
        let minutes = start.elapsed().as_secs_f64() / 60.0;
        self.firmware.set_temperature(&self.camera, 36.0 + 6.0 * (1.0 - (-minutes / 10.0).exp()));
        // SAFETY: valid camera pointer.
        let payload = unsafe { ffi::arv_fake_camera_get_payload(self.camera.0) };
        self.firmware.tick(&self.camera, payload as u64);
    }
}

/// The code of a pixel-format name the simulator streams.
fn format_code(name: &str) -> Option<u32> {
    PIXEL_FORMATS.iter().find(|(n, _)| *n == name).map(|(_, c)| *c)
}

/// aravis's fill callback: write the frame for the current registers into `buffer`.
unsafe extern "C" fn fill_frame(
    buffer: *mut ffi::ArvBuffer,
    data: *mut c_void,
    _exposure_us: u32,
    _gain: u32,
    code: ffi::ArvPixelFormat,
) {
    // SAFETY: `data` is the `Shared` of the running `SimulatedCamera` (see `start`).
    let shared = unsafe { &*(data as *const Shared) };
    let format =
        shared.formats.iter().find(|(_, c)| *c == code).and_then(|(name, _)| PixelFormat::from_name(name).ok());
    let frame = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| format.map(|f| shared.frame(f))));
    // The allocated size is the payload (the received size stays 0 with a custom fill).
    // SAFETY: valid camera pointer.
    let payload = unsafe { ffi::arv_fake_camera_get_payload(shared.camera.0) };
    let mut size = 0usize;
    // SAFETY: `buffer` is the camera's buffer of `payload` bytes (fill_buffer checked).
    let target = unsafe { ffi::arv_buffer_get_data(buffer, &mut size) };
    if target.is_null() {
        return;
    }
    // SAFETY: `target` points to at least `payload` writable bytes.
    let out = unsafe { std::slice::from_raw_parts_mut(target, payload) };
    match frame {
        Ok(Some(bytes)) => {
            let n = bytes.len().min(out.len());
            out[..n].copy_from_slice(&bytes[..n]);
        }
        _ => out.fill(0),
    }
}

/// The GenICam description a simulated camera serves, what its registers start with, and the
/// firmware that drives them.
struct Description {
    xml: String,
    formats: Vec<(String, u32)>,
    /// Register contents (address, bytes) besides the fake camera's own.
    registers: Vec<(u32, Vec<u8>)>,
    firmware: firmware::Firmware,
}

impl Description {
    /// rmvp's own description of the BFS-U3-51S5PC-C's features.
    fn own(config: &SimulatorOptions) -> Self {
        let formats: Vec<(String, u32)> =
            config.pixel_formats.iter().map(|n| (n.clone(), format_code(n).expect("checked"))).collect();
        let entries: String = formats
            .iter()
            .map(|(n, code)| {
                format!("\t\t<EnumEntry Name=\"{n}\" NameSpace=\"Standard\">\n\t\t\t<Value>{code}</Value>\n\t\t</EnumEntry>\n")
            })
            .collect();
        let xml = XML_TEMPLATE.replace("{PIXEL_FORMATS}", &entries).replace("{RIG}", RIG_XML);
        let black = black_level_fraction() as f32;
        let left = &config.left;
        let mut registers: Vec<(u32, Vec<u8>)> = [
            (register::EXPOSURE_AUTO, 2),
            (register::GAIN_AUTO, 2),
            (register::FRAME_RATE_ENABLE, 0),
            (register::READOUT_LOCKED, u32::from(left.readout_locked)),
            (register::LINK_THROUGHPUT_LIMIT, LINK_THROUGHPUT_LIMIT),
        ]
        .into_iter()
        .map(|(address, value)| (address, value.to_be_bytes().to_vec()))
        .collect();
        registers.push((register::BLACK_LEVEL_PERCENT, (100.0 * black).to_be_bytes().to_vec()));
        let strings = [
            (register::VENDOR_NAME, "rmvp"),
            (register::MODEL_NAME, "Simulated BFS-U3-51S5PC-C"),
            (register::FIRMWARE_VERSION, concat!("rmvp-sim ", env!("CARGO_PKG_VERSION"))),
        ];
        registers.extend(strings.map(|(address, text)| (address, [text.as_bytes(), &[0]].concat())));
        Self { xml, formats, registers, firmware: firmware::Firmware::own() }
    }

    /// A real camera's description ([`served`]), offering the formats of `config` it lists.
    fn served(path: &std::path::Path, config: &SimulatorOptions, serial: &str) -> Result<Self> {
        let streamable: Vec<&str> = config.pixel_formats.iter().map(String::as_str).collect();
        let served = served::ServedDescription::load(path, &streamable, RIG_XML)?;
        let firmware = firmware::Firmware::flir(&served).map_err(|e| Error::in_file(path, e.to_string()))?;
        let registers = firmware::flir_defaults(&served, served.pixel_formats[0].1, serial, &config.left);
        Ok(Self { xml: served.xml.clone(), formats: served.pixel_formats.clone(), registers, firmware })
    }
}

/// The sensor model's black level as a fraction of full scale (what `BlackLevel` reports).
fn black_level_fraction() -> f64 {
    f64::from(SimulatedScene::sensor(REFERENCE_EXPOSURE_US, 0.0, 12).dark_offset) / 4095.0
}

/// A running simulated camera; it stops when dropped.
pub struct SimulatedCamera {
    /// The fake camera's registers; released in `Drop`, after every thread using them.
    registers: Arc<Registers>,
    peer: Option<gige::Peer>,
    shared: Arc<Shared>,
    turntable: Option<JoinHandle<()>>,
    firmware: Option<JoinHandle<()>>,
    /// Serial number it reports.
    pub serial: String,
    /// Address it answers on: what to open it by (serials need not be unique on a host).
    pub address: std::net::Ipv4Addr,
}

impl SimulatedCamera {
    /// Render the first pose and start answering on `config.interface`.
    pub fn start(config: &SimulatorOptions) -> Result<Self> {
        let unknown: Vec<_> = config.pixel_formats.iter().filter(|n| format_code(n).is_none()).collect();
        if !unknown.is_empty() || config.pixel_formats.is_empty() {
            return Err(Error::Unsupported(format!(
                "the simulated camera streams {}; asked for {:?}",
                PIXEL_FORMATS.map(|(n, _)| n).join(", "),
                config.pixel_formats
            )));
        }
        let endpoint = gige::Endpoint::bind(&config.interface)?;
        let address = endpoint.address;
        let serial = config.serial.clone().unwrap_or_else(|| {
            let [_, _, high, low] = address.octets();
            format!("RMVPSIM{:04}", u32::from(high) * 256 + u32::from(low))
        });
        let description = match &config.description {
            None => Description::own(config),
            Some(path) => Description::served(path, config, &serial)?,
        };
        let xml = tempfile::Builder::new()
            .prefix("rmvp-simulated-camera")
            .suffix(".xml")
            .tempfile()
            .map_err(|e| Error::Unsupported(format!("cannot write the simulated camera's GenICam file: {e}")))?;
        std::fs::write(xml.path(), &description.xml).map_err(|e| rmvp_dataset::Error::io(xml.path(), e))?;

        let scene = SimulatedScene::new(config)?;
        let n = scene.cameras.len();
        let c_serial = CString::new(serial.as_str()).map_err(|_| Error::Unsupported("serial".into()))?;
        let c_xml = CString::new(xml.path().to_string_lossy().as_bytes()).expect("no NUL in a temp path");
        // SAFETY: valid C strings; aravis copies them (and reads the XML now).
        let fake = unsafe { ffi::arv_fake_camera_new_full(c_serial.as_ptr(), c_xml.as_ptr()) };
        if fake.is_null() {
            return Err(Error::camera(format!("simulated camera {serial}"), "aravis could not make its registers"));
        }
        let camera = Arc::new(Registers(fake));
        for (address, value) in [
            (register::SENSOR_WIDTH, SENSOR_WIDTH as u32),
            (register::SENSOR_HEIGHT, SENSOR_HEIGHT as u32),
            (register::WIDTH, SENSOR_WIDTH as u32),
            (register::HEIGHT, SENSOR_HEIGHT as u32),
            (register::PIXEL_FORMAT, description.formats[0].1),
            (register::FRAME_PERIOD_US, 1_000_000 / 25),
            (register::TURNTABLE_POSITION, 0),
            (register::TURNTABLE_REACHED, 0),
            (register::LENS_CAP, 0),
            (register::TURNTABLE_POSITIONS, n as u32),
        ] {
            camera.write(address, value);
        }
        for (address, bytes) in &description.registers {
            camera.write_memory(*address, bytes);
        }
        description.firmware.start_as(&camera, &config.left);

        let renderer = match background_pool() {
            Ok(pool) => pool,
            Err(e) => {
                // SAFETY: the one reference, used by nothing yet.
                unsafe { aravis::glib::gobject_ffi::g_object_unref(fake.cast()) };
                return Err(e);
            }
        };
        let shared = Arc::new(Shared {
            camera: camera.clone(),
            scene,
            poses: Mutex::new(vec![None; n]),
            exposure: Mutex::default(),
            frames: Mutex::default(),
            noise: config.noise,
            seed: config.seed,
            stop: AtomicBool::new(false),
            renderer,
            firmware: description.firmware,
            formats: description.formats,
        });
        shared.ensure_rendered(0);
        // SAFETY: `shared` lives in the returned value, which stops the peer (and with it the
        // callbacks) before releasing it.
        unsafe {
            ffi::arv_fake_camera_set_fill_pattern(fake, Some(fill_frame), Arc::as_ptr(&shared) as *mut c_void);
        }
        let worker = shared.clone();
        let turntable = std::thread::Builder::new()
            .name("simulated turntable".into())
            .spawn(move || worker.run_turntable())
            .expect("spawn a thread");
        shared.firmware_tick(Instant::now());
        let worker = shared.clone();
        let firmware = std::thread::Builder::new()
            .name("simulated firmware".into())
            .spawn(move || worker.run_firmware())
            .expect("spawn a thread");
        let camera_registers = camera.clone();
        let peer = gige::Peer::start(endpoint, camera, config.lost_packet_ratio);
        Ok(Self {
            registers: camera_registers,
            peer: Some(peer),
            shared,
            turntable: Some(turntable),
            firmware: Some(firmware),
            serial,
            address,
        })
    }

    /// Number of turntable poses.
    pub fn views(&self) -> usize {
        self.shared.scene.cameras.len()
    }

    /// The scene it films: cameras, subject and their geometry.
    pub fn scene(&self) -> &SimulatedScene {
        &self.shared.scene
    }

    /// The noise-free rendering its frames of pose `view` are exposed from (rendered now if
    /// the turntable has not reached it yet): the ground truth of that view's Stokes.
    pub fn rendered(&self, view: usize) -> Arc<Stokes> {
        self.shared.ensure_rendered(view);
        self.shared.poses.lock().expect("poses")[view].clone().expect("rendered above")
    }
}

impl Drop for SimulatedCamera {
    fn drop(&mut self) {
        // The peer first: no frame is filled after it stops.
        drop(self.peer.take());
        self.shared.stop.store(true, Ordering::Relaxed);
        for thread in [self.turntable.take(), self.firmware.take()].into_iter().flatten() {
            let _ = thread.join();
        }
        // SAFETY: every thread using the fake camera has stopped; this is its one reference.
        unsafe { aravis::glib::gobject_ffi::g_object_unref(self.registers.0.cast()) };
    }
}
