//! `rmvp poses SESSION --method charuco|colmap|turntable|import -o poses.json`
//! ([`rmvp_calib::poses`]).

use super::board::BoardArgs;
use anyhow::{Context, Result};
use rmvp_calib::intrinsics::CameraCalibration;
use rmvp_calib::poses::charuco::CharucoOptions;
use rmvp_calib::poses::colmap::{ColmapOptions, Matcher};
use rmvp_calib::poses::{pose_session, PoseMethod, PoseRequest};
use std::path::PathBuf;

/// Arguments of `rmvp poses`.
#[derive(clap::Args)]
pub struct Args {
    /// The capture session.
    session: PathBuf,
    /// How to find the poses.
    #[arg(long, value_enum)]
    method: PoseMethod,
    /// Where to write the poses (JSON; they are also kept in the session as `poses.json`).
    #[arg(short, long)]
    output: PathBuf,
    /// The camera calibration (`rmvp calibrate`), for charuco and colmap.
    #[arg(long, required_if_eq_any = [("method", "charuco"), ("method", "colmap")])]
    camera: Option<PathBuf>,
    /// charuco: the board under the object.
    #[command(flatten)]
    board: BoardArgs,
    /// charuco: board corners a view needs.
    #[arg(long, default_value_t = CharucoOptions::default().min_corners)]
    min_corners: usize,
    /// Views that must be posed.
    #[arg(long, default_value_t = CharucoOptions::default().min_views)]
    min_views: usize,
    /// colmap: pair selection.
    #[arg(long, value_enum, default_value_t = ColmapOptions::default().matcher)]
    matcher: Matcher,
    /// colmap: views each view is matched with (sequential matcher).
    #[arg(long, default_value_t = ColmapOptions::default().overlap)]
    overlap: usize,
    /// colmap: object masks (`<view>.png`) to paint the object out of feature extraction
    /// (default: the session's masks from `rmvp masks`, if any).
    #[arg(long)]
    masks: Option<PathBuf>,
    /// colmap: SIFT features per image at most (matching time grows with their square).
    #[arg(long, default_value_t = ColmapOptions::default().max_features)]
    max_features: usize,
    /// colmap: the program.
    #[arg(long, default_value_os_t = ColmapOptions::default().program)]
    colmap: PathBuf,
    /// turntable: the rig calibration, a posed session captured at the same turntable positions.
    #[arg(long, required_if_eq("method", "turntable"))]
    rig: Option<PathBuf>,
    /// import: a COLMAP model folder, an IDR/NeRSP cameras.npz or a nerfstudio transforms.json.
    #[arg(long = "from", required_if_eq("method", "import"))]
    source: Option<PathBuf>,
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let calibration = || -> Result<CameraCalibration> {
        let path = args.camera.as_ref().context("--camera is needed")?;
        Ok(CameraCalibration::read(path)?)
    };
    let request = match args.method {
        PoseMethod::Charuco => PoseRequest::Charuco {
            calibration: calibration()?,
            board: args.board.spec(),
            options: CharucoOptions { min_corners: args.min_corners, min_views: args.min_views },
        },
        PoseMethod::Colmap => {
            let session_masks = args.session.join(rmvp_calib::masks::MASKS_FOLDER);
            let masks = args.masks.clone().or_else(|| session_masks.is_dir().then_some(session_masks));
            PoseRequest::Colmap {
                calibration: calibration()?,
                options: ColmapOptions {
                    program: args.colmap.clone(),
                    matcher: args.matcher,
                    overlap: args.overlap,
                    min_views: args.min_views,
                    masks,
                    max_features: args.max_features,
                },
            }
        }
        PoseMethod::Turntable => {
            PoseRequest::Turntable { rig: args.rig.clone().context("--rig is needed")?, min_views: args.min_views }
        }
        PoseMethod::Import => {
            PoseRequest::Import { source: args.source.clone().context("--from is needed")?, min_views: args.min_views }
        }
    };
    let set = pose_session(&args.session, &request, &args.output)?;
    println!("{} views posed ({:?}); world: {}", set.views.len(), set.method, set.world);
    for v in &set.views {
        let residual = v.residual_px.map_or("-".into(), |r| format!("{r:.3} px"));
        println!("  {:<8} residual {residual:>9} over {} points", v.name, v.points);
    }
    for f in &set.failed {
        println!("  {:<8} not posed: {}", f.name, f.reason);
    }
    println!("wrote {}", args.output.display());
    Ok(())
}
