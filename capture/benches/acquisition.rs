//! Sustained acquisition from the simulated camera at full resolution (2448x2048
//! BayerRGPolarized12p, GigE Vision on loopback, noise-free frames so that the camera side
//! only copies): frames per second and dropped frames for streaming alone, and for streaming
//! with every frame decoded and processed to Stokes, AoP and DoP on a second thread (bounded
//! queue of two frames). Run with `cargo bench -p rmvp-capture --bench acquisition`; writes
//! `bench/results/acquisition.json`.

use rmvp_capture::camera::{CameraDevice, CameraOptions, Grab};
use rmvp_capture::simulator::{SimulatedCamera, SimulatorOptions, SENSOR_HEIGHT, SENSOR_WIDTH};
use rmvp_capture::{FrameProcessor, ProcessedFrame, RawFrame};
use rmvp_testkit::results::{BenchResult, Table};
use std::sync::mpsc::sync_channel;
use std::time::{Duration, Instant};

const SECONDS: f64 = 8.0;

fn main() {
    if !std::env::args().any(|a| a == "--bench") {
        return; // run by `cargo test --all-targets` (no `--bench`): measure only under `cargo bench`
    }
    let config =
        SimulatorOptions { serial: Some("RMVPBENCH1".into()), views: 1, noise: false, ..SimulatorOptions::default() };
    let sim = SimulatedCamera::start(&config).expect("simulated camera");
    let mut camera = CameraDevice::open(Some(&sim.address.to_string())).expect("open");
    let settings = CameraOptions { frame_rate: Some(75.0), exposure_us: 5_000.0, ..CameraOptions::default() };
    let format = camera.configure(&settings).expect("configure");
    println!("{} at {SENSOR_WIDTH}x{SENSOR_HEIGHT}, asked for 75 frames/s, {SECONDS} s per run", format.name());

    let command = "cargo bench -p rmvp-capture --bench acquisition";
    let mut result = BenchResult::now("Acquisition from the simulated camera", command);
    let mut table = Table::new(&["run", "frames/s", "dropped", "time-outs"]);
    for process in [false, true] {
        camera.start().expect("start");
        let (to_worker, from_camera) = sync_channel::<Vec<u8>>(2);
        let worker = std::thread::spawn(move || {
            let processor = FrameProcessor::default();
            let (mut raw, mut out): (Option<RawFrame>, _) = (None, ProcessedFrame::default());
            let mut n = 0usize;
            for bytes in from_camera {
                if process {
                    let frame = raw.get_or_insert_with(|| {
                        RawFrame::decode(&bytes, format, SENSOR_WIDTH, SENSOR_HEIGHT, "bench").unwrap()
                    });
                    frame.decode_from(&bytes, format, SENSOR_WIDTH, SENSOR_HEIGHT, "bench").unwrap();
                    processor.process_into(frame, &mut out).unwrap();
                }
                n += 1;
            }
            n
        });
        let (mut frames, mut dropped, mut timeouts) = (0usize, 0usize, 0usize);
        let start = Instant::now();
        while start.elapsed().as_secs_f64() < SECONDS {
            match camera.grab(Duration::from_secs(2)).expect("grab") {
                Grab::Frame(bytes) => {
                    frames += 1;
                    to_worker.send(bytes).expect("worker");
                }
                Grab::Dropped(_) => dropped += 1,
                Grab::Timeout => timeouts += 1,
            }
        }
        let elapsed = start.elapsed().as_secs_f64();
        drop(to_worker);
        let handled = worker.join().expect("worker");
        camera.stop().expect("stop");
        let run = if process {
            "stream + decode + Stokes, AoP, DoP on a second thread"
        } else {
            "stream only (grab and copy)"
        };
        let rate = format!("{:.1}", frames as f64 / elapsed);
        println!(
            "{run:<54} {rate:>6} frames/s ({frames} frames in {elapsed:.1} s, {dropped} dropped, {timeouts} time-outs, {handled} handled)"
        );
        if !process {
            let lost = if dropped + timeouts == 0 { "none lost".to_string() } else { format!("{dropped} dropped") };
            result.headline = format!("{} frames/s, {lost}", result.figure("frames_per_second", &rate));
        }
        table.row(vec![run.into(), rate, dropped.to_string(), timeouts.to_string()]);
    }
    result.about = format!(
        "{SENSOR_WIDTH}x{SENSOR_HEIGHT} `{}` frames from the simulated GenICam camera on loopback (9000-byte \
         packets, the size the client's test packets find), 75 frames/s asked, {SECONDS} s a run, camera and \
         client in one process on the same cores.",
        format.name()
    );
    result.tables = vec![table];
    result.write("acquisition");
}
