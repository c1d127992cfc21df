//! `rmvp demosaic RAW... -o DIR`.

use anyhow::{bail, Context, Result};
use clap::ValueEnum;
use rmvp_capture::correction::mean_frame;
use rmvp_capture::demosaic::DemosaicMethod;
use rmvp_capture::mosaic::{bayer_colour_spread, SensorLayout};
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
    /// GenICam pixel format of the frames: the sensor (Polarized* mono IMX250MZR,
    /// BayerRGPolarized* colour IMX250MYR) and the significant bits. Required for PNG mosaics,
    /// which carry no format; bare buffers default to BayerRGPolarized12p.
    #[arg(long, value_parser = str::parse::<PixelFormat>)]
    pixel_format: Option<PixelFormat>,
    /// Frame width in pixels (bare buffers).
    #[arg(long, default_value_t = rmvp_capture::simulator::SENSOR_WIDTH)]
    width: usize,
    /// Frame height in pixels (bare buffers).
    #[arg(long, default_value_t = rmvp_capture::simulator::SENSOR_HEIGHT)]
    height: usize,
    /// Colour demosaicing (VNG: 8-bit frames only; default bilinear). Mono frames are not
    /// demosaiced: giving it for them is refused.
    #[arg(long, value_enum)]
    method: Option<DemosaicMethod>,
    /// Drop saturated polarizer angles from the Stokes estimate.
    #[arg(long)]
    saturation_aware: bool,
    /// Dark frames (same format), averaged and subtracted.
    #[arg(long, num_args = 1..)]
    dark: Vec<PathBuf>,
    /// Colour-correction matrix, nine numbers row by row: "m00,m01,...,m22".
    #[arg(long, value_parser = super::parse_numbers::<9>)]
    ccm: Option<[f32; 9]>,
    /// The frames are a polarization sensor's though their format names a plain one (BayerRG*,
    /// Mono*: FLIR's polarized models offer their bytes under those names too); without it such
    /// frames are refused.
    #[arg(long)]
    polarized_sensor: bool,
}

/// A bare buffer's pixel format when none is given: the colour camera's streaming default.
const DEFAULT_BUFFER_FORMAT: PixelFormat = PixelFormat::BAYER_RG_POLARIZED_12P;

/// Largest spread of the Bayer colours (`bayer_colour_spread`) at which a PNG mosaic given
/// under a colour format is taken for a mono sensor's: real mono frames show 0.1 %, a colour
/// sensor's raw colours tens of percent.
const MONO_COLOUR_SPREAD: f64 = 0.02;

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let is_png = |p: &PathBuf| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png"));
    let format = match (args.pixel_format, args.raw.iter().find(|p| is_png(p))) {
        (Some(format), _) => format,
        (None, Some(png)) => bail!(
            "{}: a PNG mosaic carries no pixel format: give --pixel-format (Polarized8 or Polarized16 for the \
             mono IMX250MZR, BayerRGPolarized8 or BayerRGPolarized16 for the colour IMX250MYR)",
            png.display()
        ),
        (None, None) => DEFAULT_BUFFER_FORMAT,
    };
    if !format.family.names_polarizers() && !args.polarized_sensor {
        bail!(
            "--pixel-format {}: a plain {} sensor's format: its 2x2 cells are {}, not polarizers, and Stokes, AoP \
             and DoP from them would be of light no polarizer saw. A polarization camera's frames are \
             BayerRGPolarized* (colour IMX250MYR) or Polarized* (mono IMX250MZR); pass --polarized-sensor if \
             these come from one that names its format {}*",
            format.name(),
            if format.family.layout() == SensorLayout::MonoPolarized { "mono" } else { "Bayer" },
            if format.family.layout() == SensorLayout::MonoPolarized { "plain pixels" } else { "colour filters" },
            format.name().trim_end_matches(|c: char| c.is_ascii_digit() || c == 'p'),
        );
    }
    let layout = format.family.layout();
    if let (Some(method), SensorLayout::MonoPolarized) = (args.method, layout) {
        bail!(
            "--method {}: {} frames come from the mono sensor and are not demosaiced",
            method.to_possible_value().map_or_else(String::new, |v| v.get_name().to_string()),
            format.name()
        );
    }
    let read = |path: &PathBuf| RawFrame::read(path, format, args.width, args.height);
    let dark = if args.dark.is_empty() {
        None
    } else {
        let frames = args.dark.iter().map(read).collect::<Result<Vec<_>, _>>()?;
        Some(mean_frame(&frames)?)
    };
    let processor = FrameProcessor {
        method: args.method.unwrap_or_default(),
        saturation_aware: args.saturation_aware,
        dark,
        color_correction: args.ccm.map(|m| [[m[0], m[1], m[2]], [m[3], m[4], m[5]], [m[6], m[7], m[8]]]),
    };
    let bar = super::progress(args.raw.len() as u64, "demosaic");
    for path in &args.raw {
        bar.set_message(path.display().to_string());
        let frame = read(path)?;
        if is_png(path) && layout == SensorLayout::ColorPolarized {
            let spread = bayer_colour_spread(&frame);
            if spread < MONO_COLOUR_SPREAD {
                bail!(
                    "{}: a mono mosaic given as {}: its Bayer colours' means differ by only {:.2} % (a colour \
                     sensor's by tens of percent); give --pixel-format Polarized{}",
                    path.display(),
                    format.name(),
                    100.0 * spread,
                    frame.bits
                );
            }
        }
        let processed = processor.process(&frame).with_context(|| format!("processing {}", path.display()))?;
        let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "frame".into());
        processed.write(&args.output, &stem)?;
        if !rmvp_dataset::progress::is_quiet() {
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
        }
        bar.inc(1);
    }
    bar.finish_with_message(format!("wrote {}", args.output.display()));
    Ok(())
}
