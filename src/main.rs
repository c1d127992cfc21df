//! `rmvp`: polarized multi-view capture, datasets and reconstruction of reflective objects.

mod commands;

use clap::{Parser, Subcommand};

/// Polarized multi-view capture, datasets and NeRSP reconstruction of reflective objects.
#[derive(Parser)]
#[command(name = "rmvp", version, about)]
struct Cli {
    /// Worker threads (default: all cores).
    #[arg(long, global = true)]
    threads: Option<usize>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the pipeline on the built-in example and write a report.
    Demo(commands::demo::Args),
    /// Raw polarization-camera frames to angle images, Stokes, AoP and DoP.
    Demosaic(commands::demosaic::Args),
    /// Four polarizer images (0, 45, 90, 135 degrees) to Stokes, AoP and DoP.
    Stokes(commands::stokes::Args),
    /// Summarise and validate a scene folder (NeRSP or rmvp layout).
    Info(commands::info::Args),
    /// Convert a scene between the NeRSP and rmvp layouts, without loss.
    Convert(commands::convert::Args),
    /// Render a synthetic polarized capture of a mesh (scene folders and optional raw frames).
    Simulate(commands::simulate::Args),
    /// Compare a predicted mesh with the ground truth: Chamfer, F-score, normal error per view.
    Eval(commands::eval::Args),
    /// Ray cast a mesh's normal maps, masks and depths in every view of a scene.
    RenderNormals(commands::render_normals::Args),
    /// Align a scan onto a target mesh by a similarity (ICP with scale).
    Align(commands::align::Args),
    /// Reconstruct a scene with NeRSP: mesh, normal maps, re-rendered Stokes.
    Recon(commands::recon::Args),
    /// Capture a session of polarized views with the camera (or a simulated one).
    Capture(commands::capture::Args),
    /// List the GenICam cameras (USB3 Vision, GigE Vision) aravis finds.
    Cameras,
    /// Run a simulated polarization camera (GigE Vision on loopback) until killed.
    SimulateCamera(commands::capture::SimulateCameraArgs),
}

fn main() {
    let cli = Cli::parse();
    if let Some(n) = cli.threads {
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().expect("thread pool set once");
    }
    let result = match cli.command {
        Command::Demo(args) => commands::demo::run(args),
        Command::Demosaic(args) => commands::demosaic::run(args),
        Command::Stokes(args) => commands::stokes::run(args),
        Command::Info(args) => commands::info::run(args),
        Command::Convert(args) => commands::convert::run(args),
        Command::Simulate(args) => commands::simulate::run(args),
        Command::Eval(args) => commands::eval::run(args),
        Command::RenderNormals(args) => commands::render_normals::run(args),
        Command::Align(args) => commands::align::run(args),
        Command::Recon(args) => commands::recon::run(args),
        Command::Capture(args) => commands::capture::run(args),
        Command::Cameras => commands::capture::cameras(),
        Command::SimulateCamera(args) => commands::capture::simulate_camera(args),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
