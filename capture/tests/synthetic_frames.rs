//! Full-resolution raw frames synthesised from known Stokes vectors go through the whole chain
//! and come back as those Stokes vectors.

use rmvp_capture::demosaic::DemosaicMethod;
use rmvp_capture::mosaic::{compose, SensorLayout};
use rmvp_capture::{FrameProcessor, PixelFormat, RawFrame};
use rmvp_dataset::polarization::{intensity, POLARIZER_ANGLES_DEG};
use rmvp_dataset::Image;

const W: usize = 1224;
const H: usize = 1024;

/// Per-colour Stokes vectors in 12-bit counts, chosen so that every polarizer intensity is an
/// integer count: the frame holds them without rounding.
const STOKES_RGB: [[f32; 3]; 3] = [[2000.0, 600.0, -400.0], [3000.0, -1000.0, 200.0], [1000.0, 100.0, 300.0]];

fn uniform_angle_images(stokes: &[[f32; 3]], channels: usize) -> [Image<u16>; 4] {
    POLARIZER_ANGLES_DEG.map(|deg| {
        let theta = (deg as f32).to_radians();
        let pixel: Vec<u16> =
            (0..channels).map(|c| intensity(stokes[c][0], stokes[c][1], stokes[c][2], theta).round() as u16).collect();
        Image::from_vec(W, H, channels, pixel.iter().copied().cycle().take(W * H * channels).collect()).unwrap()
    })
}

fn color_frame() -> RawFrame {
    compose(SensorLayout::ColorPolarized, 12, &uniform_angle_images(&STOKES_RGB, 3))
}

fn assert_stokes(frame: &rmvp_capture::ProcessedFrame, truth: &[[f32; 3]], tolerance: f32) {
    let channels = truth.len();
    let images = [&frame.estimate.stokes.s0, &frame.estimate.stokes.s1, &frame.estimate.stokes.s2];
    for (k, image) in images.iter().enumerate() {
        for (i, v) in image.data().iter().enumerate() {
            let expected = truth[i % channels][k] / 4095.0;
            assert!(
                (v - expected).abs() <= tolerance,
                "S{k} channel {} at {}: {v} vs {expected}",
                i % channels,
                i / channels
            );
        }
    }
}

#[test]
fn noise_free_frame_gives_back_the_stokes_vectors_exactly() {
    let raw = color_frame();
    // Through the camera's wire format and back.
    let format = PixelFormat::BAYER_RG_POLARIZED_12P;
    let bytes = raw.encode(format).unwrap();
    assert_eq!(bytes.len(), 2448 * 2048 * 3 / 2);
    let decoded = RawFrame::decode(&bytes, format, 2448, 2048, "synthetic").unwrap();
    for method in [DemosaicMethod::Bilinear, DemosaicMethod::EdgeAware] {
        let processed = FrameProcessor { method, ..Default::default() }.process(&decoded).unwrap();
        assert_eq!(processed.aop.size(), (W, H));
        assert_stokes(&processed, &STOKES_RGB, 1e-6);
    }
}

#[test]
fn bayer_mapping_keeps_red_and_blue_apart() {
    // Light only under the red filters: every output pixel is red, none blue.
    let red_only = [[1000.0, 0.0, 0.0], [0.0; 3], [0.0; 3]];
    let raw = compose(SensorLayout::ColorPolarized, 12, &uniform_angle_images(&red_only, 3));
    let processed = FrameProcessor::default().process(&raw).unwrap();
    let s0 = processed.estimate.stokes.s0.data();
    assert!(s0.chunks_exact(3).all(|p| (p[0] - 1000.0 / 4095.0).abs() < 1e-6 && p[1] == 0.0 && p[2] == 0.0));
    // Sensor pixel (4, 4), like (0, 0), is a red 90-degree pixel: lit alone, it stays red.
    // (Interior, since OpenCV replicates the outermost row and column.)
    let mut raw = compose(SensorLayout::ColorPolarized, 12, &uniform_angle_images(&[[0.0; 3]; 3], 3));
    raw.pixels.pixel_mut(4, 4)[0] = 4000;
    let angle_90 = &FrameProcessor::default().process(&raw).unwrap().angles[2];
    assert_eq!(angle_90.pixel(2, 2), &[4000, 0, 0], "sensor (4, 4) is the red 90-degree pixel");
}

/// A deterministic Gaussian sampler (SplitMix64 and Box-Muller).
struct Gaussian(u64);

impl Gaussian {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }

    fn sample(&mut self) -> f64 {
        let (u, v) = (self.uniform().max(1e-300), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

#[test]
fn noisy_frame_stays_within_the_injected_noise() {
    const SIGMA: f64 = 8.0; // counts of read noise per sensor pixel
    let mut raw = color_frame();
    let mut rng = Gaussian(7);
    for v in raw.pixels.data_mut() {
        *v = (*v as f64 + SIGMA * rng.sample()).round().clamp(0.0, 4095.0) as u16;
    }
    let processed = FrameProcessor::default().process(&raw).unwrap();
    // Per pixel: S0 averages four samples (sigma), S1 and S2 difference two (sqrt 2 sigma);
    // interpolated pixels only average more. Six sigma bounds every pixel of the frame.
    assert_stokes(&processed, &STOKES_RGB, (6.0 * 2f64.sqrt() * SIGMA / 4095.0) as f32);
    // Frame means: no bias beyond OpenCV's integer rounding of interpolated values (round half
    // up, about +0.15 count per interpolated image, +0.3 in S0 which sums four of them).
    let images = [&processed.estimate.stokes.s0, &processed.estimate.stokes.s1, &processed.estimate.stokes.s2];
    for (k, image) in images.iter().enumerate() {
        for (c, truth) in STOKES_RGB.iter().enumerate() {
            let mean: f64 = image.data().iter().skip(c).step_by(3).map(|&v| v as f64).sum::<f64>() / (W * H) as f64;
            let bound = if k == 0 { 0.4 } else { 0.1 };
            assert!((mean * 4095.0 - truth[k] as f64).abs() < bound, "S{k} channel {c}: mean {}", mean * 4095.0);
        }
    }
}

#[test]
fn mono_sensor_frames_need_no_demosaicing() {
    let truth = [[1800.0, -500.0, 700.0]];
    let raw = compose(SensorLayout::MonoPolarized, 12, &uniform_angle_images(&truth, 1));
    let format = PixelFormat::from_name("Polarized12p").unwrap();
    let decoded = RawFrame::decode(&raw.encode(format).unwrap(), format, 2448, 2048, "mono").unwrap();
    let processed = FrameProcessor::default().process(&decoded).unwrap();
    assert_eq!(processed.estimate.stokes.s0.channels(), 1);
    assert_stokes(&processed, &truth, 1e-6);
    let expected_aop = 0.5 * (700f32).atan2(-500.0);
    assert!(processed.aop.data().iter().all(|a| (a - expected_aop).abs() < 1e-5));
}

#[test]
fn saturation_aware_estimate_recovers_a_clipped_angle() {
    // Red: I0 = 0.5 (S0 + S1) = 4500 counts exceeds the 12-bit range and is clipped to 4095.
    let truth = [[6000.0, 3000.0, 600.0], [2000.0, 0.0, 0.0], [1000.0, 0.0, 100.0]];
    let mut angles = uniform_angle_images(&truth, 3);
    for image in &mut angles {
        image.data_mut().iter_mut().for_each(|v| *v = (*v).min(4095));
    }
    let raw = compose(SensorLayout::ColorPolarized, 12, &angles);
    let aware = FrameProcessor { saturation_aware: true, ..Default::default() }.process(&raw).unwrap();
    assert_stokes(&aware, &truth, 1e-5);
    assert!(aware.estimate.saturated.data().iter().all(|&n| n == 1));
    let naive = FrameProcessor::default().process(&raw).unwrap();
    assert!((naive.estimate.stokes.s1.data()[0] * 4095.0 - 3000.0).abs() > 100.0, "clipping biases the naive S1");
}

#[test]
fn dark_frame_and_color_matrix_apply() {
    let raw = color_frame();
    let mut with_offset = raw.clone();
    with_offset.pixels.data_mut().iter_mut().for_each(|v| *v += 64);
    let mut dark = raw.clone();
    dark.pixels.data_mut().fill(64);
    let swap_rb = [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]];
    let processor = FrameProcessor { dark: Some(dark), color_correction: Some(swap_rb), ..Default::default() };
    let processed = processor.process(&with_offset).unwrap();
    assert_stokes(&processed, &[STOKES_RGB[2], STOKES_RGB[1], STOKES_RGB[0]], 1e-6);
}

#[test]
fn vng_needs_8_bit_frames() {
    let err = FrameProcessor { method: DemosaicMethod::Vng, ..Default::default() }
        .process(&color_frame())
        .unwrap_err()
        .to_string();
    assert!(err.contains("VNG") && err.contains("8-bit"), "{err}");
    let truth = [[200.0, 40.0, -20.0], [120.0, -20.0, 10.0], [60.0, 10.0, 0.0]];
    let raw = compose(SensorLayout::ColorPolarized, 8, &uniform_angle_images(&truth, 3));
    let processed = FrameProcessor { method: DemosaicMethod::Vng, ..Default::default() }.process(&raw).unwrap();
    // VNG is exact on flat colour away from the frame border.
    let s0 = &processed.estimate.stokes.s0;
    for y in 4..H - 4 {
        for x in 4..W - 4 {
            for (c, (v, t)) in s0.pixel(x, y).iter().zip(&truth).enumerate() {
                assert!((v * 255.0 - t[0]).abs() < 1e-3, "({x}, {y}) channel {c}");
            }
        }
    }
}
