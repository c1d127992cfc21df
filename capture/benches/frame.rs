//! One full 2448x2048 BayerRGPolarized12p frame through decode, split, demosaic, Stokes, AoP
//! and DoP: time per stage and frames per second. Run with `cargo bench --bench frame`
//! (or `bench/frame.sh` for the side-by-side comparison with Python and OpenCV).

use rmvp_capture::demosaic::{demosaic, demosaic_into, DemosaicMethod};
use rmvp_capture::mosaic::{compose, split, split_into, SensorLayout};
use rmvp_capture::stokes::{StokesEstimate, StokesEstimator};
use rmvp_capture::{FrameProcessor, PixelFormat, ProcessedFrame, RawFrame};
use rmvp_dataset::Image;
use std::hint::black_box;
use std::time::Instant;

const ROUNDS: usize = 40;

/// Median milliseconds of `ROUNDS` runs of `f` after three warm-up runs.
fn time_ms<T>(mut f: impl FnMut() -> T) -> f64 {
    for _ in 0..3 {
        black_box(f());
    }
    let mut times: Vec<f64> = (0..ROUNDS)
        .map(|_| {
            let start = Instant::now();
            black_box(f());
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[ROUNDS / 2]
}

/// A frame with texture everywhere: pseudo-random 12-bit counts.
fn random_frame() -> RawFrame {
    let mut state = 1u32;
    let angles: [Image<u16>; 4] = std::array::from_fn(|_| {
        let data = (0..1224 * 1024 * 3)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 17;
                state ^= state << 5;
                (state % 4096) as u16
            })
            .collect();
        Image::from_vec(1224, 1024, 3, data).unwrap()
    });
    compose(SensorLayout::ColorPolarized, 12, &angles)
}

fn main() {
    if !std::env::args().any(|a| a == "--bench") {
        return; // run by `cargo test --all-targets` (no `--bench`): measure only under `cargo bench`
    }
    let format = PixelFormat::BAYER_RG_POLARIZED_12P;
    // `RMVP_BENCH_FRAME` (a 12p frame file, as bench/frame.sh passes) or pseudo-random counts.
    let bytes = match std::env::var_os("RMVP_BENCH_FRAME") {
        Some(path) => std::fs::read(&path).expect("RMVP_BENCH_FRAME readable"),
        None => random_frame().encode(format).unwrap(),
    };
    let raw = RawFrame::decode(&bytes, format, 2448, 2048, "bench").unwrap();
    let mut decoded = raw.clone();
    let subs = split(&raw);
    let rgb: [Image<u16>; 4] = subs.clone().map(|s| demosaic(&s, 12, DemosaicMethod::Bilinear).unwrap());
    let estimator = StokesEstimator::new(4095, false);
    let stokes = estimator.estimate(&rgb, 4095).stokes;
    let processor = FrameProcessor::default();
    // Steady state of a stream: every stage writes into buffers reused from frame to frame.
    let mut subs_out: [Image<u16>; 4] = Default::default();
    let mut rgb_out = rgb.clone();
    let mut estimate = StokesEstimate::default();
    let (mut aop, mut dop) = (Image::default(), Image::default());
    let mut frame = ProcessedFrame::default();

    let threads = rayon::current_num_threads();
    println!(
        "frame benchmark: 2448x2048 {} -> 4 x 1224x1024 RGB, {threads} threads, median of {ROUNDS}",
        format.name()
    );
    let stages = [
        ("decode 12p (parallel)", time_ms(|| decoded.decode_from(&bytes, format, 2448, 2048, "bench").unwrap())),
        ("split into 4 sub-mosaics (one fused pass)", time_ms(|| split_into(&raw, &mut subs_out))),
        (
            "demosaic x4 (OpenCV, into rmvp's buffers)",
            time_ms(|| {
                for (s, out) in subs.iter().zip(&mut rgb_out) {
                    demosaic_into(s, 12, DemosaicMethod::Bilinear, out).unwrap();
                }
            }),
        ),
        ("Stokes (vectorised closed form)", time_ms(|| estimator.estimate_into(&rgb, 4095, &mut estimate))),
        ("AoP + DoP, were they a separate pass", time_ms(|| stokes.aop_dop_into(&mut aop, &mut dop))),
    ];
    for (name, ms) in stages {
        println!("  {name:<44} {ms:8.2} ms");
        println!("stage_ms\t{name}\t{ms:.2}");
    }
    let mut stream_raw = raw.clone();
    let total = time_ms(|| {
        stream_raw.decode_from(&bytes, format, 2448, 2048, "bench").unwrap();
        processor.process_into(&stream_raw, &mut frame).unwrap()
    });
    println!("  {:<44} {total:8.2} ms  = {:.1} frames/s", "whole frame (decode + process)", 1e3 / total);
    println!("stage_ms\twhole frame, AoP and DoP fused into the Stokes pass\t{total:.2}");
    println!("rust_ms_per_frame {total:.3}");
}
