//! `rmvp dataset ...`: datasets and scene folders. `build` makes a dataset of a posed, masked
//! session, `publish` a release of datasets, `verify` checks one; `info` summarises and
//! validates a scene, `check` judges its AoP's handedness, `convert` rewrites it in another
//! layout, `render-normals` ray casts a mesh's ground-truth maps in every view.

use anyhow::{bail, Result};
use rmvp_dataset::handedness::{Handedness, Verdict};
use rmvp_dataset::layout::{convert_scene, read_scene, Layout};
use rmvp_dataset::summary::SceneSummary;
use rmvp_dataset::Mesh;
use rmvp_pipeline::build::{build_dataset, BuildOptions, LengthUnit, PanoramaInput, ScanInput, TrainViews};
use rmvp_pipeline::export::{export_scene, import_rmvp3d, ExportFormat};
use rmvp_pipeline::ground_truth::write_ground_truth_maps;
use rmvp_pipeline::publish::metadata::{Creator, ReleaseInfo};
use rmvp_pipeline::publish::{publish, Archive, PublishOptions};
use rmvp_pipeline::verify::verify;
use rmvp_recon::presets::Preset;
use std::path::PathBuf;

/// The subcommands of `rmvp dataset`.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Build a dataset from a posed, masked capture session (NeRSP layout and ours), with
    /// ground truth from a laser scan and an environment map from a panorama.
    Build(BuildArgs),
    /// Publish built datasets as a release: per-object folders, datasheet, contact sheets,
    /// SHA256SUMS, an optional archive.
    Publish(PublishArgs),
    /// Verify a release: checksums, views, the NeRSP layout, masks and cameras against the scan.
    Verify(VerifyArgs),
    /// Export a scene for other tools: nerfstudio, COLMAP (text model), RMVP3D's or PANDORA's
    /// layout.
    Export(ExportArgs),
    /// Import an RMVP3D object folder as a scene (NeRSP layout or ours).
    Import(ImportArgs),
    /// Summarise and validate a scene folder in any layout (NeRSP, rmvp, RMVP3D, PANDORA).
    Info(InfoArgs),
    /// Convert a scene from any layout into another (NeRSP and rmvp without loss).
    Convert(ConvertArgs),
    /// Check a scene's AoP against its silhouettes: in rmvp's frame, or mirrored (exit status 1).
    Check(CheckArgs),
    /// Ray cast a mesh's normal maps, masks and depths in every view of a scene.
    RenderNormals(RenderNormalsArgs),
}

/// Arguments of `rmvp dataset build`.
#[derive(clap::Args)]
pub struct BuildArgs {
    /// The capture session, posed (`rmvp poses`) and masked (`rmvp masks`).
    session: PathBuf,
    /// The dataset folder: `nersp/` and `rmvp/`.
    #[arg(short, long)]
    output: PathBuf,
    /// Training views: a count, spread over the viewing directions, or names (`000,007,013`).
    #[arg(long, value_parser = str::parse::<TrainViews>, default_value_t = BuildOptions::default().train)]
    train_views: TrainViews,
    /// The camera calibration the poses used (`camera.json`): its figures go in the record.
    #[arg(long)]
    camera: Option<PathBuf>,
    /// A laser scan of the object (PLY, STL or OBJ; any pose): aligned onto a reference
    /// reconstruction from all views, it gives the ground truth (mesh, normals, depth).
    #[arg(long)]
    scan: Option<PathBuf>,
    /// The scan's unit of length (checked where the world is in millimetres).
    #[arg(long, value_enum, default_value_t = LengthUnit::Mm)]
    scan_units: LengthUnit,
    /// An equirectangular panorama (EXR, HDR, PNG, JPEG or TIFF): the environment map, turned into
    /// the world frame.
    #[arg(long)]
    env: Option<PathBuf>,
    /// Turn of the panorama about its up axis after the board's frame, degrees.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    env_yaw: f64,
    /// The reference reconstruction's preset (with --scan).
    #[arg(long, value_enum, default_value_t = BuildOptions::default().reference.preset)]
    reference_preset: Preset,
    /// The reference reconstruction's iterations (default: the preset's).
    #[arg(long)]
    reference_iters: Option<u32>,
    /// The reference mesh's marching grid cells per axis.
    #[arg(long, default_value_t = BuildOptions::default().reference.mesh_res)]
    reference_mesh_res: usize,
    /// Continue an unfinished build in the output folder.
    #[arg(long)]
    resume: bool,
}

/// Arguments of `rmvp dataset publish`.
#[derive(clap::Args)]
pub struct PublishArgs {
    /// Built datasets (`rmvp dataset build`), one object each.
    #[arg(required = true)]
    datasets: Vec<PathBuf>,
    /// The release folder (must not exist).
    #[arg(short, long)]
    output: PathBuf,
    /// The release's metadata from a TOML file (title, version, license, description,
    /// publisher, url, keywords, [[creators]], [[related]]; see `docs/datasets.md`); the
    /// options below replace what it says.
    #[arg(long)]
    info: Option<PathBuf>,
    /// SPDX license identifier of the data (required here or in --info).
    #[arg(long)]
    license: Option<String>,
    /// A creator, "Family, Given[; affiliation[; ORCID]]", in order; at least one here or in
    /// --info.
    #[arg(long = "creator", value_parser = str::parse::<Creator>)]
    creators: Vec<Creator>,
    /// Title (default: "Polarized multi-view dataset of reflective objects").
    #[arg(long)]
    title: Option<String>,
    /// Version of the data (default: 1.0.0).
    #[arg(long)]
    version: Option<String>,
    /// Who publishes it (default: the first creator's affiliation).
    #[arg(long)]
    publisher: Option<String>,
    /// Also write the release as one archive beside it.
    #[arg(long, value_enum)]
    archive: Option<Archive>,
}

/// Arguments of `rmvp dataset export`.
#[derive(clap::Args)]
pub struct ExportArgs {
    /// Scene folder (either layout), e.g. a dataset's `rmvp/`.
    scene: PathBuf,
    /// The layout to write.
    #[arg(long, value_enum)]
    format: ExportFormat,
    /// Output folder (new or empty).
    #[arg(short, long)]
    output: PathBuf,
}

/// Arguments of `rmvp dataset import`.
#[derive(clap::Args)]
pub struct ImportArgs {
    /// An RMVP3D object folder (`cameras.npz`, `images_stokes/`, `masks/`).
    source: PathBuf,
    /// Scene folder to write (new or empty).
    #[arg(short, long)]
    output: PathBuf,
    /// Layout to write.
    #[arg(long = "layout", alias = "to", value_enum, default_value_t = Layout::Rmvp)]
    to: Layout,
}

/// Arguments of `rmvp dataset verify`.
#[derive(clap::Args)]
pub struct VerifyArgs {
    /// The release folder.
    release: PathBuf,
}

/// Arguments of `rmvp dataset info`.
#[derive(clap::Args)]
pub struct InfoArgs {
    /// Scene folder in any layout (detected by its files; printed).
    scene: PathBuf,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
}

/// Arguments of `rmvp dataset convert`.
#[derive(clap::Args)]
pub struct ConvertArgs {
    /// Scene folder to read (any layout).
    source: PathBuf,
    /// Folder to write; must not exist yet, or be empty.
    destination: PathBuf,
    /// Layout to write: `nersp` (the official NeRSP loader's), `rmvp` (ours), `rmvp3d` or
    /// `pandora` (their views with Stokes).
    #[arg(long = "layout", alias = "to", value_enum)]
    to: Layout,
    /// Mirror the AoP (S2 and AoP maps negated, the 45 and 135 degree images exchanged): for
    /// a scene whose AoP `rmvp dataset check` finds mirrored.
    #[arg(long)]
    mirror_aop: bool,
}

/// Arguments of `rmvp dataset check`.
#[derive(clap::Args)]
pub struct CheckArgs {
    /// Scene folder in any layout.
    scene: PathBuf,
    /// Print the figures as JSON.
    #[arg(long)]
    json: bool,
}

/// Arguments of `rmvp dataset render-normals`.
#[derive(clap::Args)]
pub struct RenderNormalsArgs {
    /// Mesh in the scene's world frame.
    #[arg(long)]
    mesh: PathBuf,
    /// Scene whose cameras to use (any layout).
    #[arg(required_unless_present = "scene_flag")]
    scene: Option<PathBuf>,
    /// The scene, as a flag (older spelling).
    #[arg(long = "scene", hide = true, conflicts_with = "scene")]
    scene_flag: Option<PathBuf>,
    /// Output folder: `<view>_normal.exr` (world frame, N.X N.Y N.Z), `<view>_normal.png`,
    /// `<view>_mask.png`, `<view>_depth.exr` (Z).
    #[arg(short, long)]
    output: PathBuf,
}

/// Run a `rmvp dataset` subcommand.
pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Build(args) => build(args),
        Command::Publish(args) => {
            let given = ReleaseInfo {
                title: args.title,
                version: args.version,
                license: args.license,
                publisher: args.publisher,
                creators: args.creators,
                ..ReleaseInfo::default()
            };
            let from_file = args.info.as_deref().map(ReleaseInfo::read).transpose()?.unwrap_or_default();
            let options = PublishOptions {
                datasets: args.datasets,
                output: args.output,
                info: from_file.overridden_by(given),
                archive: args.archive,
                progress: true,
            };
            let release = publish(&options)?;
            println!(
                "{} object(s) ({}), {} files, {:.1} MB -> {}",
                release.objects.len(),
                release.objects.join(", "),
                release.files,
                release.bytes as f64 / 1e6,
                options.output.display()
            );
            if let Some(archive) = release.archive {
                println!("archive {}", archive.display());
            }
            Ok(())
        }
        Command::Verify(args) => {
            let report = verify(&args.release)?;
            println!(
                "{}: verified ({} object(s): {}; {} files, {} views)",
                args.release.display(),
                report.objects.len(),
                report.objects.join(", "),
                report.files,
                report.views
            );
            Ok(())
        }
        Command::Export(args) => {
            let scene = read_scene(&args.scene)?;
            export_scene(&scene, &args.output, args.format)?;
            println!(
                "{} views -> {}",
                scene.views.iter().filter(|v| v.stokes.is_some()).count(),
                args.output.display()
            );
            Ok(())
        }
        Command::Import(args) => {
            let scene = import_rmvp3d(&args.source)?;
            rmvp_dataset::layout::write_scene(&scene, &args.output, args.to)?;
            println!("{} views -> {} ({} layout)", scene.views.len(), args.output.display(), args.to.name());
            Ok(())
        }
        Command::Info(args) => info(args),
        Command::Check(args) => check(args),
        Command::Convert(args) => {
            let scene = convert_scene(&args.source, &args.destination, args.to, args.mirror_aop)?;
            println!("{} views -> {} ({} layout)", scene.views.len(), args.destination.display(), args.to.name());
            Ok(())
        }
        Command::RenderNormals(args) => {
            let folder = args.scene.or(args.scene_flag).expect("clap requires one");
            let (mesh, scene) = (Mesh::read(&args.mesh)?, read_scene(&folder)?);
            write_ground_truth_maps(&mesh, &scene, &args.output, true)?;
            println!("{} views -> {}", scene.views.len(), args.output.display());
            Ok(())
        }
    }
}

fn build(args: BuildArgs) -> Result<()> {
    let defaults = BuildOptions::default();
    let options = BuildOptions {
        session: args.session,
        output: args.output,
        train: args.train_views,
        calibration: args.camera,
        scan: args.scan.map(|path| ScanInput { path, units: args.scan_units }),
        panorama: args.env.map(|path| PanoramaInput { path, yaw_deg: args.env_yaw }),
        reference: rmvp_recon::options::ReconOptions {
            preset: args.reference_preset,
            iters: args.reference_iters,
            mesh_res: args.reference_mesh_res,
            ..defaults.reference
        },
        resume: args.resume,
        progress: true,
    };
    let record = build_dataset(&options)?;
    println!(
        "{} views ({} training: {}) -> {}/nersp and rmvp",
        record.views.len(),
        record.train.len(),
        record.train.join(" "),
        options.output.display()
    );
    if let Some(scan) = &record.scan {
        println!(
            "scan aligned: scale {:.5} (free fit {:.5}), the reference {:+.4} outside it, median distance {:.4} ({:.3} % \
             of the size), masks IoU mean {:.4}",
            scan.alignment.transform.s,
            scan.free_scale,
            scan.alignment.target_offset,
            scan.alignment.median_distance,
            100.0 * scan.median_distance_relative,
            scan.mask_iou_mean
        );
    }
    for stage in &record.stages {
        println!("  {:<13} {:>8.1} s", stage.name.to_string(), stage.seconds);
    }
    Ok(())
}

fn check(args: CheckArgs) -> Result<()> {
    let scene = read_scene(&args.scene)?;
    let judged = Handedness::of(&scene);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&judged)?);
    } else {
        println!("scene     {}", args.scene.display());
        println!("outlines  {} polarized pixels along the silhouettes of {} views", judged.pixels, judged.views.len());
        println!(
            "agreement cos 4(AoP - outline normal): {:.3} as stored, {:.3} mirrored",
            judged.stored, judged.mirrored
        );
        for v in &judged.views {
            println!("  {:<6} {:>6} pixels  {:+.3} as stored  {:+.3} mirrored", v.view, v.pixels, v.stored, v.mirrored);
        }
    }
    match judged.verdict {
        Verdict::Stored => {
            eprintln!("the AoP is in rmvp's frame (from image +x towards +y, down)");
            Ok(())
        }
        Verdict::Mirrored => bail!(
            "{}: the AoP is mirrored against rmvp's frame (S2 has the wrong sign); `rmvp dataset convert {} NEW \
             --layout LAYOUT --mirror-aop` writes it corrected",
            args.scene.display(),
            args.scene.display()
        ),
        Verdict::Undecided => {
            eprintln!(
                "undecided: too few polarized outline pixels, or the AoP follows neither reading (masks that miss \
                 the object?)"
            );
            Ok(())
        }
    }
}

fn info(args: InfoArgs) -> Result<()> {
    let s = SceneSummary::of_folder(&args.scene)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&s)?);
        return Ok(());
    }
    println!("scene   {} ({} layout), valid", args.scene.display(), s.layout);
    println!("views   {} ({} train, {} eval)", s.views.len(), s.train_views, s.views.len() - s.train_views);
    for v in &s.views {
        println!(
            "  {:<6} {:<5} {}x{}  f {:.1} px  centre ({:+.3}, {:+.3}, {:+.3})  mask {:>5.1}%  {}",
            v.name,
            v.split,
            v.size[0],
            v.size[1],
            v.focal_px[0],
            v.center[0],
            v.center[1],
            v.center[2],
            v.mask_fraction.map_or(f64::NAN, |f| 100.0 * f),
            v.contents.join(" ")
        );
    }
    if let Some(m) = &s.mesh {
        println!("mesh    {} vertices, {} triangles", m.vertices, m.triangles);
    }
    if let Some([w, h]) = s.env_map {
        println!("env map {w}x{h}");
    }
    for (k, v) in &s.metadata {
        if !v.is_object() {
            println!("meta    {k} = {v}");
        }
    }
    Ok(())
}
