//! `rmvp`: polarized multi-view capture, datasets and reconstruction of reflective objects.
//! The command line only: each subcommand parses its arguments, builds a library's options,
//! calls it and prints.

mod commands;

use clap::{Parser, Subcommand};
use commands::*;

/// Polarized multi-view capture, datasets and NeRSP reconstruction of reflective objects.
#[derive(Parser)]
#[command(name = "rmvp", version, about)]
struct Cli {
    /// Worker threads (default: all cores).
    #[arg(long, global = true)]
    threads: Option<usize>,
    /// Largest image any input file may declare, in pixels (width x height); larger ones are
    /// refused before they are read.
    #[arg(long, global = true, default_value_t = rmvp_dataset::io::input::DEFAULT_MAX_PIXELS)]
    max_pixels: u64,
    /// No progress bars or progress lines.
    #[arg(long, global = true)]
    quiet: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the pipeline on the built-in example and write a report.
    Demo(demo::Args),
    /// Render a synthetic polarized capture of a mesh (scene folders and optional raw frames).
    Simulate(simulate::Args),
    /// Capture a session of polarized views with the camera (or a simulated one).
    Capture(capture::Args),
    /// Compute a capture session's views again from its raw frames (a session processed with
    /// another polarizer cell than the sensor's is refused until then).
    Reprocess(capture::ReprocessArgs),
    /// List the GenICam cameras (USB3 Vision, GigE Vision) aravis finds.
    Cameras,
    /// Run a simulated polarization camera (GigE Vision on loopback) until killed.
    SimulateCamera(capture::SimulateCameraArgs),
    /// Write the calibration board as a page to print (PNG at its true size).
    Board(board::Args),
    /// Camera intrinsics from views of a calibration board (a session or images).
    Calibrate(calibrate::Args),
    /// Camera poses of a session's views: ChArUco board, COLMAP, turntable or imported.
    Poses(poses::Args),
    /// Object masks of a session's views.
    Masks(masks::Args),
    /// Raw polarization-camera frames to angle images, Stokes, AoP and DoP.
    Demosaic(demosaic::Args),
    /// Four polarizer images (0, 45, 90, 135 degrees) to Stokes, AoP and DoP.
    Stokes(stokes::Args),
    /// Datasets: build from a session, publish, verify, export; scene folders: summarise,
    /// convert between layouts, ground-truth maps.
    #[command(subcommand)]
    Dataset(dataset::Command),
    /// Reconstruct a scene with NeRSP: mesh, normal maps, re-rendered Stokes.
    Recon(recon::Args),
    /// A page, report.html: a reconstruction (the mesh in 3D, the losses, the figures, the views), a
    /// built dataset or release (the datasheet, the truth in 3D, the views) or a batch.
    Report(report::Args),
    /// Align a scan onto a target mesh by a similarity (ICP with scale).
    Align(align::Args),
    /// Batches of reconstructions (datasets x variants x seeds) on this machine or on Slurm,
    /// with their results tabulated.
    #[command(subcommand)]
    Batch(batch::Command),
    /// Compare a predicted mesh with the ground truth: Chamfer, F-score, normal error per view.
    Eval(eval::Args),
    /// `rmvp dataset info`.
    #[command(hide = true)]
    Info(dataset::InfoArgs),
    /// `rmvp dataset convert`.
    #[command(hide = true)]
    Convert(dataset::ConvertArgs),
    /// `rmvp dataset render-normals`.
    #[command(hide = true)]
    RenderNormals(dataset::RenderNormalsArgs),
    /// Print the command-line reference (Markdown, `docs/cli.md`) generated from these
    /// definitions.
    #[command(hide = true)]
    CliReference,
}

fn main() {
    let cli = Cli::parse();
    if let Some(n) = cli.threads {
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().expect("thread pool set once");
    }
    rmvp_dataset::io::input::set_max_pixels(cli.max_pixels);
    rmvp_dataset::progress::set_quiet(cli.quiet);
    let result = match cli.command {
        Command::Demo(args) => demo::run(args),
        Command::Simulate(args) => simulate::run(args),
        Command::Capture(args) => capture::run(args),
        Command::Reprocess(args) => capture::reprocess(args),
        Command::Cameras => capture::cameras(),
        Command::SimulateCamera(args) => capture::simulate_camera(args),
        Command::Board(args) => board::run(args),
        Command::Calibrate(args) => calibrate::run(args),
        Command::Poses(args) => poses::run(args),
        Command::Masks(args) => masks::run(args),
        Command::Demosaic(args) => demosaic::run(args),
        Command::Stokes(args) => stokes::run(args),
        Command::Dataset(command) => dataset::run(command),
        Command::Recon(args) => recon::run(args),
        Command::Report(args) => report::run(args),
        Command::Align(args) => align::run(args),
        Command::Eval(args) => eval::run(args),
        Command::Batch(command) => batch::run(command),
        Command::Info(args) => dataset::run(dataset::Command::Info(args)),
        Command::Convert(args) => dataset::run(dataset::Command::Convert(args)),
        Command::RenderNormals(args) => dataset::run(dataset::Command::RenderNormals(args)),
        Command::CliReference => {
            let options = clap_markdown::MarkdownOptions::new().show_footer(false).show_table_of_contents(true);
            print!("{}", clap_markdown::help_markdown_custom::<Cli>(&options));
            Ok(())
        }
    };
    if let Err(e) = result {
        eprintln!("error: {}", describe(&e));
        if let Some(hint) = commands::hint(&e) {
            eprintln!("{hint}");
        }
        std::process::exit(1);
    }
}

/// An error and its causes, each said once: a cause whose words the message already holds (an
/// error that shows its source, then the source itself) is not said again.
fn describe(error: &anyhow::Error) -> String {
    let mut text = error.to_string();
    for cause in error.chain().skip(1) {
        let cause = cause.to_string();
        if !text.contains(&cause) {
            text.push_str(": ");
            text.push_str(&cause);
        }
    }
    text
}
