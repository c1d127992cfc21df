//! The camera client against the simulated GenICam camera (GigE Vision on a loopback address of
//! its own, our XML over aravis's fake-camera registers): feature round trips, pixel-format negotiation, and frames in every
//! streamed format decoding to exactly what the sensor model makes of the rendered pose.

use rmvp_capture::camera::{CameraDevice, CameraOptions, Control, Grab};
use rmvp_capture::simulator::{
    LeftState, SimulatedCamera, SimulatedScene, SimulatorOptions, SENSOR_HEIGHT, SENSOR_WIDTH,
};
use rmvp_capture::RawFrame;
use std::sync::Mutex;
use std::time::Duration;

/// One simulated camera at a time: each renders and streams at full speed on the machine's
/// cores, and a frame that waits behind another test's is a frame timing out.
static ONE_CAMERA: Mutex<()> = Mutex::new(());

fn config(serial: &str, formats: &[&str]) -> SimulatorOptions {
    let mut config =
        SimulatorOptions { serial: Some(serial.into()), views: 2, noise: false, ..SimulatorOptions::default() };
    if !formats.is_empty() {
        config.pixel_formats = formats.iter().map(|s| s.to_string()).collect();
    }
    config
}

fn next_frame(camera: &mut CameraDevice) -> Vec<u8> {
    for _ in 0..50 {
        match camera.grab(Duration::from_secs(5)).unwrap() {
            Grab::Frame(bytes) => return bytes,
            Grab::Dropped(_) | Grab::Timeout => continue,
        }
    }
    panic!("no complete frame in 50 tries");
}

#[test]
fn features_round_trip() {
    let _turn = ONE_CAMERA.lock().unwrap_or_else(|e| e.into_inner());
    let sim = SimulatedCamera::start(&config("RMVPFEAT01", &[])).unwrap();
    let camera = CameraDevice::open(Some(&sim.address.to_string())).unwrap();
    let id = camera.identity();
    assert_eq!(id.serial, "RMVPFEAT01");
    assert_eq!(id.model, "Simulated BFS-U3-51S5PC-C");
    assert_eq!(id.protocol, "GigEVision");
    assert!(id.firmware.starts_with("rmvp-sim"), "{id:?}");
    assert_eq!((camera.integer("Width").unwrap(), camera.integer("Height").unwrap()), (2448, 2048));

    camera.set_float("ExposureTime", 12_345.0).unwrap();
    assert_eq!(camera.float("ExposureTime").unwrap(), 12_345.0);
    camera.set_float("Gain", 6.5).unwrap();
    assert_eq!(camera.float("Gain").unwrap(), 6.5);
    camera.set_float("AcquisitionFrameRate", 10.0).unwrap();
    assert!((camera.float("AcquisitionFrameRate").unwrap() - 10.0).abs() < 1e-9);
    for (feature, value) in [
        ("ExposureAuto", "Off"),
        ("GainAuto", "Off"),
        ("AcquisitionFrameRateEnable", "true"),
        ("TriggerMode", "On"),
        ("TriggerSource", "Line0"),
        ("PixelFormat", "BayerRGPolarized16"),
        ("PixelFormat", "BayerRG8"),
    ] {
        camera.set_feature(feature, value).unwrap();
        assert_eq!(camera.feature(feature).unwrap(), value, "{feature}");
    }
    let temperature = camera.float("DeviceTemperature").unwrap();
    assert!((30.0..50.0).contains(&temperature), "{temperature}");
    let err = camera.set_feature("PixelFormat", "RGB8").unwrap_err().to_string();
    assert!(err.contains("PixelFormat") && err.contains("RMVPFEAT01"), "{err}");
    assert!(camera.feature("NoSuchFeature").unwrap_err().to_string().contains("has no feature NoSuchFeature"));
}

#[test]
fn every_streamed_format_decodes_to_the_sensor_model() {
    let _turn = ONE_CAMERA.lock().unwrap_or_else(|e| e.into_inner());
    let formats = ["BayerRGPolarized8", "BayerRGPolarized10p", "BayerRGPolarized12p", "BayerRGPolarized16"];
    let config = config("RMVPFMT01", &formats);
    let sim = SimulatedCamera::start(&config).unwrap();
    let truth = SimulatedScene::new(&config).unwrap().render(0);
    let mut camera = CameraDevice::open(Some(&sim.address.to_string())).unwrap();
    let settings = CameraOptions { exposure_us: 15_000.0, gain_db: 3.0, ..CameraOptions::default() };
    for name in formats {
        let format = camera.configure(&CameraOptions { pixel_format: Some(name.into()), ..settings.clone() }).unwrap();
        assert_eq!(format.name(), name);
        camera.start().unwrap();
        let bytes = next_frame(&mut camera);
        camera.stop().unwrap();
        let frame = RawFrame::decode(&bytes, format, SENSOR_WIDTH, SENSOR_HEIGHT, name).unwrap();
        let model = SimulatedScene::sensor(15_000.0, 3.0, format.bits).noise_free();
        let expected = model.digitize(&model.electrons(&truth), 0, 0);
        assert_eq!(frame.pixels, expected.pixels, "{name}");
    }
}

#[test]
fn negotiation_falls_back_to_bayer_names() {
    let _turn = ONE_CAMERA.lock().unwrap_or_else(|e| e.into_inner());
    let sim = SimulatedCamera::start(&config("RMVPNEG01", &["BayerRG8", "BayerRG16"])).unwrap();
    let mut camera = CameraDevice::open(Some(&sim.address.to_string())).unwrap();
    let format = camera.configure(&CameraOptions::default()).unwrap();
    assert_eq!(format.name(), "BayerRG16");
    assert_eq!(camera.feature("ExposureAuto").unwrap(), "Off");
    camera.start().unwrap();
    let bytes = next_frame(&mut camera);
    assert_eq!(bytes.len(), SENSOR_WIDTH * SENSOR_HEIGHT * 2);
    let err = camera
        .configure(&CameraOptions { pixel_format: Some("BayerRGPolarized12p".into()), ..CameraOptions::default() })
        .unwrap_err()
        .to_string();
    assert!(err.contains("does not offer pixel format BayerRGPolarized12p"), "{err}");
}

/// `count` frames of one acquisition at `exposure_us`.
fn burst(camera: &mut CameraDevice, exposure_us: f64, count: usize) -> Vec<Vec<u8>> {
    camera.configure(&CameraOptions { exposure_us, ..CameraOptions::default() }).unwrap();
    camera.start().unwrap();
    let frames = (0..count).map(|_| next_frame(camera)).collect();
    camera.stop().unwrap();
    frames
}

#[test]
fn the_sensor_noise_depends_on_the_frames_taken_at_a_setting_not_on_the_stream_before() {
    let _turn = ONE_CAMERA.lock().unwrap_or_else(|e| e.into_inner());
    let noisy = |serial: &str| SimulatorOptions { noise: true, ..config(serial, &[]) };
    let direct = {
        let sim = SimulatedCamera::start(&noisy("RMVPNOISE01")).unwrap();
        let mut camera = CameraDevice::open(Some(&sim.address.to_string())).unwrap();
        burst(&mut camera, 15_000.0, 2)
    };
    let after_another_setting = {
        let sim = SimulatedCamera::start(&noisy("RMVPNOISE02")).unwrap();
        let mut camera = CameraDevice::open(Some(&sim.address.to_string())).unwrap();
        burst(&mut camera, 8_000.0, 3);
        burst(&mut camera, 15_000.0, 2)
    };
    assert_ne!(direct[0], direct[1], "two frames of one setting have their own noise");
    assert!(direct == after_another_setting, "the same setting's frames differ after other frames were streamed");
}

/// One noise-free frame of pose 0 at the default settings, from a camera left as `left`, after
/// `configure`.
fn configured_frame(serial: &str, left: LeftState) -> Result<(RawFrame, CameraDevice, SimulatedCamera), String> {
    let sim = SimulatedCamera::start(&SimulatorOptions { left, ..config(serial, &[]) }).unwrap();
    let mut camera = CameraDevice::open(Some(&sim.address.to_string())).unwrap();
    let format = camera.configure(&CameraOptions::default()).map_err(|e| e.to_string())?;
    camera.start().unwrap();
    let bytes = next_frame(&mut camera);
    camera.stop().unwrap();
    Ok((RawFrame::decode(&bytes, format, SENSOR_WIDTH, SENSOR_HEIGHT, serial).unwrap(), camera, sim))
}

#[test]
fn a_camera_left_with_gamma_a_mirrored_readout_an_odd_offset_or_a_shallow_adc_is_put_right() {
    let _turn = ONE_CAMERA.lock().unwrap_or_else(|e| e.into_inner());
    let (fresh, _, _) = configured_frame("RMVPLEFT01", LeftState::default()).unwrap();
    let left = LeftState {
        gamma: true,
        reverse_x: true,
        reverse_y: true,
        offset_x: 1,
        adc_8_bits: true,
        ..LeftState::default()
    };
    let (frame, camera, _sim) = configured_frame("RMVPLEFT02", left).unwrap();
    assert_eq!(frame.pixels, fresh.pixels, "the same frame as from a camera fresh from its defaults");
    for (feature, value) in
        [("GammaEnable", "false"), ("ReverseX", "false"), ("ReverseY", "false"), ("AdcBitDepth", "Bit12")]
    {
        assert_eq!(camera.feature(feature).unwrap(), value, "{feature}");
    }
    assert_eq!(camera.integer("OffsetX").unwrap() % 4, 0);

    // The simulator does apply each of them: left alone, the frame is another.
    camera.set_feature("ReverseX", "true").unwrap();
    let mut camera = camera;
    camera.start().unwrap();
    let bytes = next_frame(&mut camera);
    camera.stop().unwrap();
    let format = rmvp_capture::PixelFormat::BAYER_RG_POLARIZED_12P;
    let mirrored = RawFrame::decode(&bytes, format, SENSOR_WIDTH, SENSOR_HEIGHT, "mirrored").unwrap();
    let row = |f: &RawFrame, y: usize| f.pixels.data()[y * SENSOR_WIDTH..(y + 1) * SENSOR_WIDTH].to_vec();
    let mut reversed = row(&fresh, 1000);
    reversed.reverse();
    assert_eq!(row(&mirrored, 1000), reversed, "ReverseX mirrors each row");
}

#[test]
fn a_mirrored_readout_that_is_locked_is_refused_by_name() {
    let _turn = ONE_CAMERA.lock().unwrap_or_else(|e| e.into_inner());
    let left = LeftState { reverse_x: true, readout_locked: true, ..LeftState::default() };
    let err = configured_frame("RMVPLOCK01", left).map(|_| ()).unwrap_err();
    assert!(err.contains("RMVPLOCK01") && err.contains("ReverseX") && err.contains("locked"), "{err}");
}

#[test]
fn the_frame_rate_is_set_after_the_exposure_that_bounds_it_and_read_back() {
    let _turn = ONE_CAMERA.lock().unwrap_or_else(|e| e.into_inner());
    let sim = SimulatedCamera::start(&config("RMVPRATE01", &[])).unwrap();
    let mut camera = CameraDevice::open(Some(&sim.address.to_string())).unwrap();
    // Left enabled at 70 frames/s by another program: an exposure of 20 ms still goes through.
    camera.set_feature("AcquisitionFrameRateEnable", "true").unwrap();
    camera.set_float("AcquisitionFrameRate", 70.0).unwrap();
    let settings = CameraOptions { exposure_us: 20_000.0, frame_rate: Some(40.0), ..CameraOptions::default() };
    camera.configure(&settings).unwrap();
    assert!((camera.float("AcquisitionResultingFrameRate").unwrap() - 40.0).abs() < 1e-6);
    // At 20 ms no more than 50 frames a second.
    let err = camera.configure(&CameraOptions { frame_rate: Some(60.0), ..settings }).unwrap_err().to_string();
    assert!(err.contains("60 frames/s") && err.contains("at most 50.000"), "{err}");
}

/// The real FLIR descriptions of `shared/genicam`.
fn flir_descriptions() -> Vec<std::path::PathBuf> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/genicam");
    let mut files: Vec<_> = std::fs::read_dir(&root)
        .unwrap_or_else(|e| panic!("{}: {e}", root.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "xml"))
        .collect();
    files.sort();
    assert_eq!(files.len(), 2, "{files:?}");
    files
}

#[test]
fn real_flir_descriptions_are_served_and_driven_as_the_camera() {
    let _turn = ONE_CAMERA.lock().unwrap_or_else(|e| e.into_inner());
    for (k, path) in flir_descriptions().iter().enumerate() {
        let serial = format!("RMVPFLIR0{k}");
        let left = LeftState { gamma: true, reverse_x: true, ..LeftState::default() };
        let config = SimulatorOptions { description: Some(path.clone()), left, ..config(&serial, &[]) };
        let sim = SimulatedCamera::start(&config).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut camera = CameraDevice::open(Some(&sim.address.to_string())).unwrap();
        eprintln!("{}: {:?}, formats {:?}", path.display(), camera.identity(), camera.offered_pixel_formats().unwrap());
        assert_eq!(camera.identity().serial, serial);
        // The older firmware's description has no polarized formats and names a plain mono
        // Blackfly S: refused, saying why, until the sensor is declared polarized (the
        // simulator stands a polarized one behind it).
        let offered = camera.offered_pixel_formats().unwrap();
        let polarized_sensor = !offered.iter().any(|f| f.contains("Polarized"));
        if polarized_sensor {
            let err = camera.configure(&CameraOptions::default()).unwrap_err().to_string();
            assert!(err.contains("has no polarizers") && err.contains("BFS_U3_51S5"), "{}: {err}", path.display());
        }
        let declared = CameraOptions { polarized_sensor, ..CameraOptions::default() };
        let format = camera.configure(&declared).unwrap();
        for (feature, value) in [("GammaEnable", "false"), ("ReverseX", "false"), ("ExposureAuto", "Off")] {
            assert_eq!(camera.feature(feature).unwrap(), value, "{}: {feature}", path.display());
        }
        camera.start().unwrap();
        let bytes = next_frame(&mut camera);
        camera.stop().unwrap();
        let frame = RawFrame::decode(&bytes, format, SENSOR_WIDTH, SENSOR_HEIGHT, &serial).unwrap();
        let truth = SimulatedScene::new(&config).unwrap().render(0);
        let model = SimulatedScene::sensor(20_000.0, 0.0, format.bits).noise_free();
        assert!(frame.pixels == model.digitize(&model.electrons(&truth), 0, 0).pixels, "{}", path.display());

        // The camera's own locks: the pixel format is locked while the host streams
        // (`TLParamsLocked`), free again after.
        camera.start().unwrap();
        let err = camera.write("PixelFormat", "BayerRG8").unwrap_err().to_string();
        assert!(err.contains("PixelFormat") && err.contains("locked"), "{}: {err}", path.display());
        camera.stop().unwrap();
        camera.write("PixelFormat", &format.name()).unwrap();
        // The frame rate's maximum follows the exposure (the firmware updates it within a few
        // milliseconds of a new exposure): 50 frames/s at 20 ms.
        std::thread::sleep(Duration::from_millis(50));
        let rate = |frame_rate| CameraOptions { frame_rate: Some(frame_rate), ..declared.clone() };
        let err = camera.configure(&rate(60.0)).unwrap_err().to_string();
        assert!(err.contains("at most 50.000"), "{}: {err}", path.display());
        camera.configure(&rate(30.0)).unwrap();
        std::thread::sleep(Duration::from_millis(50));
        let resulting = camera.float("AcquisitionResultingFrameRate").unwrap();
        assert!((resulting - 30.0).abs() < 0.01, "{}: {resulting}", path.display());
    }
}

#[test]
fn a_camera_another_client_controls_is_refused_naming_it_and_free_once_let_go() {
    let _turn = ONE_CAMERA.lock().unwrap_or_else(|e| e.into_inner());
    let sim = SimulatedCamera::start(&config("RMVPCCP01", &[])).unwrap();
    let address = sim.address.to_string();
    let holder = CameraDevice::open(Some(&address)).unwrap();
    let err = CameraDevice::open(Some(&address)).map(|_| ()).unwrap_err().to_string();
    assert!(err.contains("RMVPCCP01") && err.contains("controlled by another application at 127.0.0.1:"), "{err}");
    // Read-only access still works, and says who holds it.
    let (inspected, control) = CameraDevice::open_to_inspect(Some(&address)).unwrap();
    assert!(matches!(control, Control::Elsewhere(Some(a)) if a.ip().is_loopback() && a.port() != 0), "{control:?}");
    assert_eq!(inspected.identity().serial, "RMVPCCP01");
    drop(inspected);
    drop(holder);
    CameraDevice::open(Some(&address)).unwrap();
}

#[test]
fn simulated_cameras_started_together_each_answer_on_an_address_of_their_own() {
    let _turn = ONE_CAMERA.lock().unwrap_or_else(|e| e.into_inner());
    // The same serial on purpose (two suites start the same tests): the addresses tell them apart.
    let cameras: Vec<SimulatedCamera> = std::thread::scope(|scope| {
        let starts: Vec<_> =
            (0..3).map(|_| scope.spawn(|| SimulatedCamera::start(&config("RMVPTWIN01", &[])).unwrap())).collect();
        starts.into_iter().map(|s| s.join().unwrap()).collect()
    });
    let mut addresses: Vec<_> = cameras.iter().map(|c| c.address).collect();
    addresses.sort();
    addresses.dedup();
    assert_eq!(addresses.len(), 3, "{addresses:?}");
    let opened: Vec<CameraDevice> =
        cameras.iter().map(|c| CameraDevice::open(Some(&c.address.to_string())).unwrap()).collect();
    for (camera, sim) in opened.iter().zip(&cameras) {
        assert_eq!(camera.integer("TurntablePositions").unwrap() as usize, sim.views());
    }
    // Without a serial each takes one of its address.
    let own = SimulatedCamera::start(&SimulatorOptions { serial: None, ..config("", &[]) }).unwrap();
    let [_, _, high, low] = own.address.octets();
    assert_eq!(own.serial, format!("RMVPSIM{:04}", u32::from(high) * 256 + u32::from(low)));
    assert_eq!(CameraDevice::open(Some(&own.address.to_string())).unwrap().identity().serial, own.serial);
}
