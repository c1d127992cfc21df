//! `rmvp capture`: a capture session with the polarization camera (or the simulated one), and
//! `rmvp cameras` / `rmvp simulate-camera` around it.

use super::board::BoardArgs;
use anyhow::{Context, Result};
use rmvp_calib::lab::LabOptions;
use rmvp_capture::camera::polarizers::polarizer_evidence;
use rmvp_capture::camera::{controlled_elsewhere, describe, list_devices, CameraDevice, CameraOptions, Control};
use rmvp_capture::preview::{serve, Preview};
use rmvp_capture::session::positioning::Positioning;
use rmvp_capture::session::{capture, check_session_folder, SessionOptions};
use rmvp_capture::simulator::{LeftState, SimulatedCamera, SimulatedSetup, SimulatorOptions};
use rmvp_capture::PixelFormat;
use rmvp_dataset::session::PositioningMode;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

/// Arguments of `rmvp capture`.
#[derive(clap::Args, Clone)]
pub struct Args {
    /// Name of the object (recorded in the manifest).
    #[arg(long)]
    pub object: String,
    /// Views to capture (RMVP3D: about 60 per object).
    #[arg(long, default_value_t = SessionOptions::default().views)]
    pub views: usize,
    /// Session folder.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Camera by serial number, IP address or aravis id (default: the first camera found).
    #[arg(long, conflicts_with = "simulated")]
    pub camera: Option<String>,
    /// Use a simulated camera of its own (GigE Vision on the first free loopback address, the
    /// built-in object on a turntable); any number of them run side by side.
    #[arg(long)]
    pub simulated: bool,
    /// The camera's sensor has on-chip polarizers though it offers no polarized pixel format and
    /// its model is not one of FLIR's polarized ones (without it such a camera is refused).
    #[arg(long)]
    pub polarized_sensor: bool,
    /// Exposure time in microseconds.
    #[arg(long, default_value_t = SessionOptions::default().camera.exposure_us)]
    pub exposure: f64,
    /// Analog gain in dB.
    #[arg(long, default_value_t = SessionOptions::default().camera.gain_db)]
    pub gain: f64,
    /// HDR bracketing: exposure times in microseconds, comma-separated (replaces --exposure).
    #[arg(long, value_delimiter = ',')]
    pub hdr: Vec<f64>,
    /// Frames averaged per exposure.
    #[arg(long, default_value_t = SessionOptions::default().average)]
    pub average: usize,
    /// Dark frames (lens covered) averaged per exposure at the start; 0: none.
    #[arg(long, default_value_t = SessionOptions::default().dark_frames)]
    pub dark: usize,
    /// Continue the session in --output after its last complete view.
    #[arg(long)]
    pub resume: bool,
    /// Pixel format by GenICam name (default: negotiated, BayerRGPolarized12p first).
    #[arg(long, value_parser = str::parse::<PixelFormat>)]
    pub pixel_format: Option<PixelFormat>,
    /// Frame rate in Hz (default: as fast as the exposure allows).
    #[arg(long)]
    pub frame_rate: Option<f64>,
    /// How views start: interactive (Enter), timed, trigger (Line0) or turntable (default:
    /// turntable when the camera has one, else interactive).
    #[arg(long, value_enum)]
    pub mode: Option<PositioningMode>,
    /// Seconds between views in timed mode.
    #[arg(long, default_value_t = Positioning::TIMED_INTERVAL.as_secs_f64())]
    pub interval: f64,
    /// Serve a live preview page on this address (e.g. 127.0.0.1:8642).
    #[arg(long)]
    pub preview: Option<std::net::SocketAddr>,
    /// Simulated camera: object mesh (PLY/OBJ; default: the built-in spot).
    #[arg(long, requires = "simulated")]
    pub mesh: Option<PathBuf>,
    /// Simulated camera: serve a real camera's GenICam description (a FLIR Blackfly S XML
    /// file) instead of rmvp's own.
    #[arg(long, requires = "simulated")]
    pub description: Option<PathBuf>,
    /// Simulated camera: what it looks at.
    #[command(flatten)]
    pub scene: SetupArgs,
    /// Seconds to wait for one frame before checking that the camera is still there.
    #[arg(long, default_value_t = SessionOptions::default().frame_timeout.as_secs_f64())]
    pub frame_timeout: f64,
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    check_session_folder(&args.output, args.resume)?;
    let simulator = if args.simulated {
        let config = SimulatorOptions {
            views: args.views,
            mesh: args.mesh.clone(),
            setup: args.scene.setup(),
            seed: args.scene.seed,
            description: args.description.clone(),
            ..SimulatorOptions::default()
        };
        let camera = SimulatedCamera::start(&config)?;
        eprintln!("started the simulated camera {} on {}", camera.serial, camera.address);
        Some(camera)
    } else {
        None
    };
    let selector = simulator.as_ref().map(|s| s.address.to_string()).or(args.camera.clone());
    let mut camera = CameraDevice::open(selector.as_deref())?;
    let id = camera.identity();
    eprintln!("camera: {} {} serial {} firmware {} ({})", id.vendor, id.model, id.serial, id.firmware, id.protocol);
    let positioning = match args.mode {
        None => Positioning::default_for(&camera),
        Some(mode) => Positioning::new(mode, Duration::from_secs_f64(args.interval)),
    };
    let preview = args.preview.map(|_| Arc::new(Preview::default()));
    let _server = match (args.preview, &preview) {
        (Some(address), Some(preview)) => {
            let server = serve(preview.clone(), address)?;
            eprintln!("live preview: http://{}/", server.address);
            Some(server)
        }
        _ => None,
    };
    let options = SessionOptions {
        object: args.object.clone(),
        views: args.views,
        dir: args.output.clone(),
        camera: CameraOptions {
            pixel_format: args.pixel_format.map(|f| f.name()),
            exposure_us: args.exposure,
            gain_db: args.gain,
            frame_rate: args.frame_rate,
            polarized_sensor: args.polarized_sensor,
            ..CameraOptions::default()
        },
        exposures_us: if args.hdr.is_empty() { vec![args.exposure] } else { args.hdr.clone() },
        average: args.average,
        dark_frames: args.dark,
        positioning,
        resume: args.resume,
        frame_timeout: Duration::from_secs_f64(args.frame_timeout),
        preview,
        progress: true,
    };
    let report = capture(&mut camera, &options)?;
    eprintln!(
        "{} of {} views complete in {} ({} captured now, {} dropped frames grabbed again)",
        report.views_complete,
        report.views_planned,
        args.output.display(),
        report.views_captured,
        report.dropped_frames
    );
    Ok(())
}

/// Arguments of `rmvp reprocess`.
#[derive(clap::Args, Clone)]
pub struct ReprocessArgs {
    /// Session folder.
    pub session: PathBuf,
}

/// Run `rmvp reprocess`.
pub fn reprocess(args: ReprocessArgs) -> Result<()> {
    let done = rmvp_capture::session::reprocess::reprocess(&args.session, true)?;
    eprintln!(
        "{}: {} views computed again from {} raw and dark frames, polarizer cell {}",
        args.session.display(),
        done.views,
        done.raw_files,
        rmvp_dataset::polarization::cell_name(&rmvp_dataset::polarization::SENSOR_POLARIZER_CELL)
    );
    Ok(())
}

/// What a simulated camera looks at.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Setup {
    /// The object alone on a turntable.
    #[default]
    Turntable,
    /// The lab: the object on the calibration board on a textured table, cameras on two rings.
    Lab,
    /// A calibration session: the board alone, moved in front of the camera.
    Calibration,
}

/// The simulated camera's scene.
#[derive(clap::Args, Clone, Debug)]
pub struct SetupArgs {
    /// What the simulated camera looks at.
    #[arg(long, value_enum, default_value_t = Setup::default())]
    pub setup: Setup,
    /// The board of the lab or calibration setup.
    #[command(flatten)]
    pub board: BoardArgs,
    /// Lab setup: no table under the board.
    #[arg(long)]
    pub no_table: bool,
    /// Lab setup: the empty lab (background plates at the same turntable positions).
    #[arg(long)]
    pub no_object: bool,
    /// Seed of the simulated camera's views and noise.
    #[arg(long, default_value_t = SimulatorOptions::default().seed)]
    pub seed: u64,
}

impl SetupArgs {
    /// The simulator's setup.
    pub fn setup(&self) -> SimulatedSetup {
        match self.setup {
            Setup::Turntable => SimulatedSetup::Turntable,
            Setup::Lab => SimulatedSetup::Lab(LabOptions {
                board: self.board.spec(),
                table: !self.no_table,
                object: !self.no_object,
                ..LabOptions::default()
            }),
            Setup::Calibration => SimulatedSetup::Calibration(self.board.spec()),
        }
    }
}

/// Arguments of `rmvp simulate-camera`.
#[derive(clap::Args, Clone)]
pub struct SimulateCameraArgs {
    /// Serial number to answer to (default: RMVPSIM and four digits of its address, e.g.
    /// RMVPSIM0002 on 127.0.0.2).
    #[arg(long)]
    pub serial: Option<String>,
    /// Where to answer: lo (the first loopback address no other camera holds), an IPv4
    /// address, or a network interface's name.
    #[arg(long, default_value_t = SimulatorOptions::default().interface)]
    pub interface: String,
    /// Turntable poses.
    #[arg(long, default_value_t = SimulatorOptions::default().views)]
    pub views: usize,
    /// Object mesh (PLY/OBJ; default: the built-in spot).
    #[arg(long)]
    pub mesh: Option<PathBuf>,
    /// What it looks at.
    #[command(flatten)]
    pub scene: SetupArgs,
    /// Pixel formats offered, comma-separated (default: BayerRGPolarized8/10p/12p/16, BayerRG8/10p/12p/16).
    #[arg(long, value_delimiter = ',', value_parser = str::parse::<PixelFormat>)]
    pub pixel_formats: Vec<PixelFormat>,
    /// Renderer samples per pixel.
    #[arg(long, default_value_t = SimulatorOptions::default().spp)]
    pub spp: u32,
    /// No shot or read noise (every frame of a pose identical; fastest).
    #[arg(long)]
    pub noise_free: bool,
    /// Fraction of stream packets to drop on purpose (frames then arrive incomplete).
    #[arg(long, default_value_t = SimulatorOptions::default().lost_packet_ratio)]
    pub lost_packets: f64,
    /// Start as another program may have left the camera, comma-separated: what rmvp must put
    /// right, or refuse, before it captures.
    #[arg(long, value_enum, value_delimiter = ',')]
    pub left_with: Vec<LeftWith>,
    /// Serve a real camera's GenICam description (a FLIR Blackfly S XML file) instead of
    /// rmvp's own.
    #[arg(long)]
    pub description: Option<PathBuf>,
}

/// A state another program may leave a camera in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LeftWith {
    /// Gamma on (`GammaEnable`).
    Gamma,
    /// The readout mirrored left to right (`ReverseX`).
    ReverseX,
    /// The readout mirrored top to bottom (`ReverseY`).
    ReverseY,
    /// `OffsetX` = 1: the mosaic's phase moved by a pixel.
    OddOffset,
    /// An 8-bit ADC (`AdcBitDepth`) under a 12-bit format.
    Adc8,
    /// `ReverseX` and `ReverseY` locked.
    LockedReadout,
}

impl LeftWith {
    /// The simulator's state with all of `list`.
    fn state(list: &[LeftWith]) -> LeftState {
        let has = |w: LeftWith| list.contains(&w);
        LeftState {
            gamma: has(LeftWith::Gamma),
            reverse_x: has(LeftWith::ReverseX),
            reverse_y: has(LeftWith::ReverseY),
            offset_x: u32::from(has(LeftWith::OddOffset)),
            adc_8_bits: has(LeftWith::Adc8),
            readout_locked: has(LeftWith::LockedReadout),
        }
    }
}

/// Run a simulated camera until killed.
pub fn simulate_camera(args: SimulateCameraArgs) -> Result<()> {
    let mut config = SimulatorOptions {
        serial: args.serial,
        interface: args.interface,
        mesh: args.mesh,
        views: args.views,
        spp: args.spp,
        seed: args.scene.seed,
        noise: !args.noise_free,
        lost_packet_ratio: args.lost_packets,
        setup: args.scene.setup(),
        left: LeftWith::state(&args.left_with),
        description: args.description,
        ..SimulatorOptions::default()
    };
    if !args.pixel_formats.is_empty() {
        config.pixel_formats = args.pixel_formats.iter().map(PixelFormat::name).collect();
    }
    let camera = SimulatedCamera::start(&config).context("starting the simulated camera")?;
    eprintln!(
        "simulated camera {} ready on {} (GigE Vision), {} turntable poses; stop with Ctrl-C",
        camera.serial,
        camera.address,
        camera.views()
    );
    loop {
        std::thread::park();
    }
}

/// List the cameras aravis finds.
pub fn cameras() -> Result<()> {
    let devices = list_devices();
    if devices.is_empty() {
        println!("{}", describe(&devices));
    }
    for device in devices {
        println!("{} [{} at {}]", device.id, device.protocol, device.address);
        // An address names one GigE Vision camera where ids may repeat (simulated cameras).
        let selector = if device.protocol == "GigEVision" { &device.address } else { &device.id };
        let (camera, control) = match CameraDevice::open_to_inspect(Some(selector)) {
            Ok(opened) => opened,
            Err(e) => {
                println!("  cannot open: {e}");
                continue;
            }
        };
        // Listing only reads: a capture starting now on this camera must find it free.
        camera.let_go();
        let id = camera.identity();
        println!("  {} {}, serial {}, firmware {}", id.vendor, id.model, id.serial, id.firmware);
        match control {
            Control::Ours => println!("  control: free"),
            Control::Elsewhere(holder) => println!("  control: {}", controlled_elsewhere(holder)),
        }
        let offered = camera.offered_pixel_formats().unwrap_or_default();
        let readable: Vec<&str> =
            offered.iter().filter(|f| f.parse::<PixelFormat>().is_ok()).map(String::as_str).collect();
        println!(
            "  pixel formats rmvp reads: {}",
            if readable.is_empty() { "none".into() } else { readable.join(", ") }
        );
        match polarizer_evidence(&id.model, &offered, false) {
            Ok(evidence) => println!("  polarizers: yes ({evidence})"),
            Err(_) => println!(
                "  polarizers: none seen (no polarized pixel format, not one of FLIR's polarized models): \
                 captured only with --polarized-sensor"
            ),
        }
        for feature in rmvp_capture::session::RECORDED_FEATURES {
            let state = if !camera.is_available(feature) {
                "not available".to_string()
            } else {
                let value = camera.feature(feature).unwrap_or_else(|e| format!("unreadable ({e})"));
                if camera.is_writable(feature) {
                    value
                } else {
                    format!("{value} (read-only now)")
                }
            };
            println!("  {feature:<30} {state}");
        }
    }
    Ok(())
}
