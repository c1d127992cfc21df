//! `rmvp demo`: the pipeline on its built-in example, as far as it exists today.
//!
//! 1. Simulate a capture: six views of the built-in "spot" rendered with polarization
//!    (`rmvp simulate`), and the raw 12-bit frames the sensor would send (with shot and read
//!    noise and a dark frame).
//! 2. Capture processing: every raw frame through decoding, demosaicing, dark subtraction and
//!    Stokes, AoP and DoP estimation.
//! 3. Dataset: the processed views with their cameras and masks as a NeRSP-layout scene, read
//!    back and validated.
//! 4. Report: the captured polarization against the rendered ground truth, as numbers
//!    (`report.json`) and pictures (`contact_sheet.png`).
//! 5. Reconstruction: NeRSP (fast preset) on the captured dataset (`rmvp recon`), evaluated
//!    against the true mesh and normals (`rmvp eval`).

use super::progress;
use super::simulate::{self, simulate};
use anyhow::{Context, Result};
use rmvp_align::{normal_errors, surface_metrics, SurfaceOptions};
use rmvp_capture::sensor::SensorModel;
use rmvp_capture::{FrameProcessor, PixelFormat, RawFrame};
use rmvp_dataset::io::{png, write_bytes_atomically};
use rmvp_dataset::layout::{read_scene, write_scene, Layout};
use rmvp_dataset::visualize::{aop_picture, contact_sheet, downsample, gray_ramp, preview, quantile};
use rmvp_dataset::{Image, Mesh, Scene, View};
use rmvp_recon::reconstruct::{reconstruct, Options, MESH};
use serde_json::json;
use std::f32::consts::PI;
use std::path::PathBuf;

/// Arguments of `rmvp demo`.
#[derive(clap::Args)]
pub struct Args {
    /// Output folder.
    #[arg(short, long, default_value = "demo-out")]
    output: PathBuf,
    /// Image size of the simulated views (the raw frames are twice as large).
    #[arg(long, default_value = "612x512")]
    res: String,
    /// Samples per pixel of the simulation.
    #[arg(long, default_value_t = 16)]
    spp: u32,
    /// Training iterations of the reconstruction (fast preset).
    #[arg(long, default_value_t = 1000)]
    recon_iters: u32,
    /// Marching grid cells per axis of the reconstructed mesh.
    #[arg(long, default_value_t = 192)]
    mesh_res: usize,
}

/// Smallest angle between two AoPs, in degrees (AoP is periodic in 180 degrees).
fn aop_difference_deg(a: f32, b: f32) -> f32 {
    let d = (a - b).rem_euclid(PI);
    d.min(PI - d).to_degrees()
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let out = &args.output;
    println!("1/5 simulating a capture of spot: 6 views at {}, {} spp, with raw sensor frames", args.res, args.spp);
    let truth = simulate(&simulate::Args {
        output: out.join("simulated"),
        mesh: None,
        views: 6,
        rig: "sphere".into(),
        res: args.res.clone(),
        spp: args.spp,
        env: None,
        texture: None,
        raw: true,
        seed: 0,
        eta: 1.5,
        conductor: None,
        layout: "nersp".into(),
    })?;

    println!("2/5 processing the raw frames (decode, demosaic, dark frame, Stokes, AoP, DoP)");
    let raw_dir = out.join("simulated/raw");
    let sensor: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(raw_dir.join("sensor.json"))?)?;
    let (width, height) =
        (sensor["width"].as_u64().context("width")? as usize, sensor["height"].as_u64().context("height")? as usize);
    let model: SensorModel = serde_json::from_value(sensor["model"].clone())?;
    let format = PixelFormat::BAYER_RG_POLARIZED_12P;
    let processor = FrameProcessor {
        dark: Some(RawFrame::read(&raw_dir.join("dark.raw"), format, width, height)?),
        ..Default::default()
    };
    let mut captured = Scene { mesh: None, env_map: None, ..truth.clone() };
    let bar = progress(truth.views.len() as u64, "process");
    for view in &mut captured.views {
        let frame = RawFrame::read(&raw_dir.join(format!("{}.raw", view.name)), format, width, height)?;
        let processed = processor.process(&frame)?;
        let gain = 1.0 / model.stokes_gain();
        let mut stokes = processed.estimate.stokes;
        for image in [&mut stokes.s0, &mut stokes.s1, &mut stokes.s2] {
            image.data_mut().iter_mut().for_each(|v| *v *= gain);
        }
        *view = View {
            aop: Some(processed.aop),
            dop: Some(processed.dop),
            stokes: Some(stokes),
            polarized: None,
            preview: None,
            normals: None,
            depth: None,
            ..view.clone()
        };
        bar.inc(1);
    }
    bar.finish();

    println!("3/5 writing the captured dataset (NeRSP layout) and validating it");
    let dataset_dir = out.join("captured");
    write_scene(&captured, &dataset_dir, Layout::Nersp)?;
    let reread = read_scene(&dataset_dir)?;

    println!("4/5 comparing the captured polarization with the rendered ground truth");
    let (mut aop_errors, mut s0_errors, mut tiles) = (Vec::new(), Vec::new(), Vec::new());
    for (t, c) in truth.views.iter().zip(&reread.views) {
        let (ts, cs) = (t.stokes.as_ref().context("truth")?, c.stokes.as_ref().context("captured")?);
        let ((taop, tdop), (caop, cdop)) = (ts.aop_dop(), cs.aop_dop());
        let mask = t.mask.as_ref().context("mask")?;
        let mut error_map = Image::new(mask.width(), mask.height(), 1);
        for k in 0..mask.data().len() {
            if mask.data()[k] == 0 {
                continue;
            }
            if tdop.data()[k] > 0.05 {
                let e = aop_difference_deg(caop.data()[k], taop.data()[k]);
                aop_errors.push(e);
                error_map.data_mut()[k] = e;
            }
            let (a, b) = (cs.s0.data()[3 * k + 1], ts.s0.data()[3 * k + 1]);
            if b > 0.05 {
                s0_errors.push((a - b).abs() / b);
            }
        }
        let factor = mask.width().div_ceil(256);
        tiles.extend(
            [preview(&ts.s0), preview(&cs.s0), aop_picture(&caop, &cdop, Some(mask)), gray_ramp(&error_map, 0.0, 10.0)]
                .map(|tile| downsample(&tile, factor)),
        );
    }
    let sheet_path = out.join("contact_sheet.png");
    png::write_png_u8(&sheet_path, &contact_sheet(&tiles, 4))?;
    println!("5/5 reconstructing the captured dataset (NeRSP, fast preset, {} iterations)", args.recon_iters);
    let recon_dir = out.join("recon");
    let options = Options { iterations: Some(args.recon_iters), mesh_resolution: args.mesh_res, ..Options::default() };
    let bar = progress(args.recon_iters as u64, "recon");
    let started = std::time::Instant::now();
    reconstruct(&reread, &recon_dir, &options, |_, trainer| bar.set_position(trainer.iteration as u64))?;
    bar.finish();
    let recon_seconds = started.elapsed().as_secs_f64();
    let predicted = Mesh::read(&recon_dir.join(MESH))?;
    let true_mesh = truth.mesh.as_ref().context("the simulation's mesh")?;
    let surface = surface_metrics(&predicted, true_mesh, &SurfaceOptions::default())?;
    let normals = normal_errors(&predicted, &truth)?;
    let report = json!({
        "simulated": {"views": truth.views.len(), "size": [truth.views[0].camera.width, truth.views[0].camera.height], "spp": args.spp, "layout": "simulated/nersp"},
        "raw_frames": {"pixel_format": format.name(), "width": width, "height": height, "sensor": model},
        "captured_dataset": {"folder": "captured", "layout": "nersp", "views": reread.views.len(), "valid": true},
        "aop_error_deg": {"median": quantile(&aop_errors, 0.5), "p90": quantile(&aop_errors, 0.9), "pixels": aop_errors.len()},
        "s0_rel_error": {"median": quantile(&s0_errors, 0.5), "p90": quantile(&s0_errors, 0.9)},
        "contact_sheet": "contact_sheet.png",
        "contact_sheet_columns": ["rendered S0", "captured S0", "captured AoP (hue) x DoP", "AoP error 0..10 deg"],
        "reconstruction": {
            "folder": "recon", "preset": "fast", "iterations": args.recon_iters, "seconds": recon_seconds,
            "chamfer": surface.chamfer, "f_score": surface.fscore, "normal_mae_deg": normals.mean_mae_deg,
            "comparison": "recon/comparison.png",
        },
    });
    write_bytes_atomically(&out.join("report.json"), serde_json::to_string_pretty(&report)?.as_bytes())?;
    println!(
        "captured vs rendered: AoP error median {:.2} deg (90% {:.2} deg) over {} pixels with DoP > 0.05; S0 error median {:.2}%",
        quantile(&aop_errors, 0.5),
        quantile(&aop_errors, 0.9),
        aop_errors.len(),
        100.0 * quantile(&s0_errors, 0.5)
    );
    println!(
        "reconstruction ({recon_seconds:.0} s): Chamfer {:.4} (object radius 1), F-score {:.3}, normal MAE {:.2} deg over {} views",
        surface.chamfer,
        surface.fscore,
        normals.mean_mae_deg,
        normals.views.len()
    );
    println!("wrote {}:", out.display());
    println!("  contact_sheet.png  per view: rendered S0 | captured S0 | captured AoP x DoP | AoP error");
    println!("  report.json        the figures above");
    println!("  simulated/         ground truth (NeRSP layout with gt/) and raw/ sensor frames");
    println!("  captured/          the dataset built from the raw frames (NeRSP layout)");
    println!("  recon/             mesh.ply, normals/, stokes/, comparison.png (input | rendered S0, AoP, normals), log.jsonl");
    Ok(())
}
