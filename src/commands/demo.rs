//! `rmvp demo`: the pipeline on a built-in example.
//!
//! Today the example is one raw frame of the real sensor (2448x2048, BayerRGPolarized12p)
//! synthesised from an analytic scene with known Stokes vectors: a diffusely reflecting
//! dielectric sphere (AoP = normal azimuth, DoP from the Fresnel equations) with painted colour
//! stripes, in front of an unpolarized background. The frame goes through the capture chain
//! (decode, split, demosaic, Stokes, AoP, DoP) and is compared with the truth.

use anyhow::Result;
use rmvp_capture::mosaic::{compose, SensorLayout};
use rmvp_capture::pipeline::aop_picture;
use rmvp_capture::{FrameProcessor, PixelFormat, RawFrame};
use rmvp_dataset::io::{png, write_bytes_atomically};
use rmvp_dataset::polarization::{diffuse_dop, intensity, POLARIZER_ANGLES_DEG};
use rmvp_dataset::visualize::{contact_sheet, downsample, gray_ramp, preview, quantile};
use rmvp_dataset::{Image, Stokes};
use serde_json::json;
use std::f32::consts::PI;
use std::path::PathBuf;

/// Arguments of `rmvp demo`.
#[derive(clap::Args)]
pub struct Args {
    /// Output folder.
    #[arg(short, long, default_value = "demo-out")]
    output: PathBuf,
}

/// Sub-mosaic size of the real sensor (half of 2448x2048).
const WIDTH: usize = 1224;
const HEIGHT: usize = 1024;
const BITS: u8 = 12;
const ETA: f32 = 1.5;

/// The example's true Stokes images (RGB) and object mask at sub-mosaic resolution.
fn example_scene() -> (Stokes, Image<u8>) {
    let (cx, cy, radius) = (WIDTH as f32 / 2.0, HEIGHT as f32 / 2.0, 0.42 * HEIGHT as f32);
    let mut s = [Image::new(WIDTH, HEIGHT, 3), Image::new(WIDTH, HEIGHT, 3), Image::new(WIDTH, HEIGHT, 3)];
    let mut mask = Image::new(WIDTH, HEIGHT, 1);
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            let (dx, dy) = ((x as f32 + 0.5 - cx) / radius, (y as f32 + 0.5 - cy) / radius);
            let r2 = dx * dx + dy * dy;
            let (s0, dop, azimuth) = if r2 < 1.0 {
                mask.pixel_mut(x, y)[0] = 255;
                // Orthographic view of a sphere: normal (dx, dy, -sqrt(1 - r2)) in the camera frame.
                let zenith = r2.sqrt().asin();
                let azimuth = dy.atan2(dx);
                let stripe = 0.5 + 0.5 * (5.0 * (dx + 0.6 * dy) * PI).sin();
                let albedo = [0.85, 0.35 + 0.4 * stripe, 0.25 + 0.2 * (1.0 - stripe)];
                let shade = 0.3 + 0.6 * zenith.cos();
                (albedo.map(|a| a * shade), diffuse_dop(zenith, ETA), azimuth)
            } else {
                ([0.12 + 0.1 * y as f32 / HEIGHT as f32; 3], 0.0, 0.0)
            };
            let linear = [(2.0 * azimuth).cos(), (2.0 * azimuth).sin()];
            s[0].pixel_mut(x, y).copy_from_slice(&s0);
            s[1].pixel_mut(x, y).copy_from_slice(&s0.map(|v| v * dop * linear[0]));
            s[2].pixel_mut(x, y).copy_from_slice(&s0.map(|v| v * dop * linear[1]));
        }
    }
    let [s0, s1, s2] = s;
    (Stokes { s0, s1, s2 }, mask)
}

/// The four polarizer images the sensor sees, as `BITS`-bit counts.
fn polarizer_counts(stokes: &Stokes) -> [Image<u16>; 4] {
    let full = ((1u32 << BITS) - 1) as f32;
    POLARIZER_ANGLES_DEG.map(|deg| {
        let theta = (deg as f32).to_radians();
        let data = (0..stokes.s0.data().len())
            .map(|k| {
                let i = intensity(stokes.s0.data()[k], stokes.s1.data()[k], stokes.s2.data()[k], theta);
                (i.clamp(0.0, 1.0) * full).round() as u16
            })
            .collect();
        Image::from_vec(WIDTH, HEIGHT, 3, data).expect("sized")
    })
}

/// Smallest angle between two AoPs, in degrees (AoP is periodic in 180 degrees).
fn aop_difference_deg(a: f32, b: f32) -> f32 {
    let d = (a - b).rem_euclid(PI);
    d.min(PI - d).to_degrees()
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let out = &args.output;
    let bar = super::progress(4, "demo");
    bar.set_message("synthesising a 2448x2048 BayerRGPolarized12p frame");
    let (truth, mask) = example_scene();
    let raw = compose(SensorLayout::ColorPolarized, BITS, &polarizer_counts(&truth));
    let format = PixelFormat::BAYER_RG_POLARIZED_12P;
    let raw_path = out.join("frame.raw");
    raw.write(&raw_path, format)?;
    bar.inc(1);

    bar.set_message("decoding, demosaicing, Stokes, AoP, DoP");
    let frame = RawFrame::read(&raw_path, format, 2 * WIDTH, 2 * HEIGHT)?;
    let processed = FrameProcessor::default().process(&frame)?;
    let files = processed.write(out, "frame")?;
    bar.inc(1);

    bar.set_message("comparing with the known Stokes vectors");
    let truth_aop = truth.aop();
    let truth_dop = truth.dop();
    let mut aop_errors = Vec::new();
    let mut aop_error_map = Image::new(WIDTH, HEIGHT, 1);
    let mut s0_errors = Vec::new();
    for k in 0..WIDTH * HEIGHT {
        if mask.data()[k] == 0 {
            continue;
        }
        if truth_dop.data()[k] > 0.05 {
            let e = aop_difference_deg(processed.aop.data()[k], truth_aop.data()[k]);
            aop_errors.push(e);
            aop_error_map.data_mut()[k] = e;
        }
        for c in 0..3 {
            let t = truth.s0.data()[3 * k + c];
            s0_errors.push((processed.estimate.stokes.s0.data()[3 * k + c] - t).abs() / t);
        }
    }
    let dop_errors: Vec<f32> = (0..WIDTH * HEIGHT)
        .filter(|&k| mask.data()[k] != 0)
        .map(|k| (processed.dop.data()[k] - truth_dop.data()[k]).abs())
        .collect();
    bar.inc(1);

    bar.set_message("pictures and report");
    let tiles = [
        preview(&truth.s0),
        preview(&processed.estimate.stokes.s0),
        aop_picture(&truth_aop, &truth_dop),
        aop_picture(&processed.aop, &processed.dop),
        gray_ramp(&processed.dop, 0.0, 0.5),
        gray_ramp(&aop_error_map, 0.0, 5.0),
    ]
    .map(|t| downsample(&t, 4));
    let sheet_path = out.join("contact_sheet.png");
    png::write_png_u8(&sheet_path, &contact_sheet(&tiles, 2))?;
    let report = json!({
        "frame": {"file": "frame.raw", "pixel_format": format.name(), "width": 2 * WIDTH, "height": 2 * HEIGHT},
        "object_pixels": s0_errors.len() / 3,
        "aop_error_deg": {"median": quantile(&aop_errors, 0.5), "p95": quantile(&aop_errors, 0.95), "pixels": aop_errors.len()},
        "dop_abs_error": {"median": quantile(&dop_errors, 0.5), "p95": quantile(&dop_errors, 0.95)},
        "s0_rel_error": {"median": quantile(&s0_errors, 0.5), "p95": quantile(&s0_errors, 0.95)},
        "contact_sheet": "contact_sheet.png",
        "contact_sheet_tiles": ["true S0", "recovered S0", "true AoP (hue) x DoP", "recovered AoP x DoP", "recovered DoP 0..0.5", "AoP error 0..5 deg"],
    });
    let report_path = out.join("report.json");
    write_bytes_atomically(&report_path, serde_json::to_string_pretty(&report)?.as_bytes())?;
    bar.inc(1);
    bar.finish_with_message("done");

    println!("built-in example: diffuse dielectric sphere (eta {ETA}), one 2448x2048 {} frame", format.name());
    println!(
        "  AoP error  median {:.3} deg, 95% {:.3} deg over {} pixels with DoP > 0.05",
        quantile(&aop_errors, 0.5),
        quantile(&aop_errors, 0.95),
        aop_errors.len()
    );
    println!("  DoP error  median {:.4}, 95% {:.4}", quantile(&dop_errors, 0.5), quantile(&dop_errors, 0.95));
    println!(
        "  S0 error   median {:.3}%, 95% {:.3}%",
        100.0 * quantile(&s0_errors, 0.5),
        100.0 * quantile(&s0_errors, 0.95)
    );
    println!("wrote {} and {} more files in {}:", sheet_path.display(), files.len() + 2, out.display());
    println!("  contact_sheet.png: true S0 | recovered S0 / true AoP | recovered AoP / DoP | AoP error");
    println!(
        "  report.json, frame.raw, frame_{{000,045,090,135}}.png, frame_stokes.exr, frame_aop.png, frame_dop.png, ..."
    );
    Ok(())
}
