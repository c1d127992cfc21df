//! `rmvp demosaic RAW... -o DIR`.

use anyhow::{Context, Result};
use rmvp_capture::correction::mean_frame;
use rmvp_capture::demosaic::DemosaicMethod;
use rmvp_capture::{FrameProcessor, PixelFormat, RawFrame};
use std::path::PathBuf;

/// Arguments of `rmvp demosaic`.
#[derive(clap::Args)]
pub struct Args {
    /// Raw frames: bare buffers as the camera sent them (.raw, .bin) or 8/16-bit grey PNG mosaics.
    #[arg(required = true)]
    raw: Vec<PathBuf>,
    /// Output folder.
    #[arg(short, long)]
    output: PathBuf,
    /// GenICam pixel format of the frames (for PNG mosaics: the sensor and significant bits).
    #[arg(long, value_parser = str::parse::<PixelFormat>, default_value = "BayerRGPolarized12p")]
    pixel_format: PixelFormat,
    /// Frame width in pixels (bare buffers).
    #[arg(long, default_value_t = rmvp_capture::simulator::SENSOR_WIDTH)]
    width: usize,
    /// Frame height in pixels (bare buffers).
    #[arg(long, default_value_t = rmvp_capture::simulator::SENSOR_HEIGHT)]
    height: usize,
    /// Demosaicing (VNG: 8-bit frames only).
    #[arg(long, value_enum, default_value_t = DemosaicMethod::default())]
    method: DemosaicMethod,
    /// Drop saturated polarizer angles from the Stokes estimate.
    #[arg(long)]
    saturation_aware: bool,
    /// Dark frames (same format), averaged and subtracted.
    #[arg(long, num_args = 1..)]
    dark: Vec<PathBuf>,
    /// Colour-correction matrix, nine numbers row by row: "m00,m01,...,m22".
    #[arg(long, value_parser = super::parse_numbers::<9>)]
    ccm: Option<[f32; 9]>,
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let format = args.pixel_format;
    let read = |path: &PathBuf| RawFrame::read(path, format, args.width, args.height);
    let dark = if args.dark.is_empty() {
        None
    } else {
        let frames = args.dark.iter().map(read).collect::<Result<Vec<_>, _>>()?;
        Some(mean_frame(&frames)?)
    };
    let processor = FrameProcessor {
        method: args.method,
        saturation_aware: args.saturation_aware,
        dark,
        color_correction: args.ccm.map(|m| [[m[0], m[1], m[2]], [m[3], m[4], m[5]], [m[6], m[7], m[8]]]),
    };
    let bar = super::progress(args.raw.len() as u64, "demosaic");
    for path in &args.raw {
        bar.set_message(path.display().to_string());
        let frame = read(path)?;
        let processed = processor.process(&frame).with_context(|| format!("processing {}", path.display()))?;
        let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "frame".into());
        processed.write(&args.output, &stem)?;
        let saturated = processed.estimate.saturated.data().iter().filter(|&&n| n > 0).count();
        bar.suspend(|| {
            println!(
                "{}: {}x{} x4, {} pixels with saturated angles, median DoP {:.3}",
                path.display(),
                processed.aop.width(),
                processed.aop.height(),
                saturated,
                rmvp_dataset::visualize::quantile(processed.dop.data(), 0.5)
            )
        });
        bar.inc(1);
    }
    bar.finish_with_message(format!("wrote {}", args.output.display()));
    Ok(())
}
