//! Errors of whole jobs: each stage's own, and the job's.

/// Result alias of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What stopped a job.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file or data-model error (names the file).
    #[error(transparent)]
    Dataset(#[from] rmvp_dataset::Error),
    /// Rendering.
    #[error(transparent)]
    Render(#[from] rmvp_render::Error),
    /// Frame processing or the sensor model.
    #[error(transparent)]
    Capture(#[from] rmvp_capture::Error),
    /// Alignment or evaluation.
    #[error(transparent)]
    Align(#[from] rmvp_align::Error),
    /// Reconstruction.
    #[error(transparent)]
    Recon(#[from] rmvp_recon::Error),
    /// An image size the sensor's 2x2 polarizer cells cannot tile.
    #[error("image size {width}x{height}: width and height must be even and at least 4")]
    ImageSize {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
    /// An albedo texture the renderer cannot use.
    #[error("texture {}: {source}", path.display())]
    Texture {
        /// The texture file.
        path: std::path::PathBuf,
        /// Why.
        source: rmvp_render::Error,
    },
    /// An environment map the renderer cannot use.
    #[error("environment map {}: {source}", path.as_ref().map_or("(built-in)".into(), |p| p.display().to_string()))]
    Environment {
        /// The file (`None`: the built-in one).
        path: Option<std::path::PathBuf>,
        /// Why.
        source: rmvp_render::Error,
    },
    /// Calibration, poses or masks.
    #[error(transparent)]
    Calib(#[from] rmvp_calib::Error),
    /// A scene folder given where a capture session is needed.
    #[error("{}: a scene in the {layout} layout, not a capture session: a dataset is built from a session (session.json, posed and masked)", path.display())]
    SceneNotSession {
        /// The folder.
        path: std::path::PathBuf,
        /// The scene's layout.
        layout: &'static str,
    },
    /// A session not yet posed or masked.
    #[error("{}: no {missing}; pose and mask the session first", session.display())]
    Unprepared {
        /// The session.
        session: std::path::PathBuf,
        /// What it lacks.
        missing: &'static str,
    },
    /// A simulated capture with nothing to write.
    #[error("no scene layout to write")]
    NoLayout,
    /// A panorama that cannot be an environment map.
    #[error("panorama {}: {why}", path.display())]
    Panorama {
        /// The file.
        path: std::path::PathBuf,
        /// What is wrong.
        why: String,
    },
    /// A laser scan that does not fit the reference shape.
    #[error("scan {}: {why}", path.display())]
    Scan {
        /// The scan file.
        path: std::path::PathBuf,
        /// What is wrong, with the figures.
        why: String,
    },
    /// An unfinished dataset build in the folder a new one was asked into.
    #[error("{}: an unfinished build is here (done: {done}); resume it to continue", path.display())]
    BuildUnfinished {
        /// The dataset folder.
        path: std::path::PathBuf,
        /// Its finished stages.
        done: String,
    },
    /// A build resumed with options other than those it was started with.
    #[error("{}: was built with other options ({changed}); build again with the same ones, or into another folder", path.display())]
    BuildOptionsChanged {
        /// The dataset folder.
        path: std::path::PathBuf,
        /// Each changed option: `name: recorded -> now`.
        changed: String,
    },
    /// A release's metadata that is missing or malformed (what to give).
    #[error("release metadata: {why}")]
    ReleaseInfo {
        /// What is wrong and what to give.
        why: String,
    },
    /// A dataset or release folder that is there already, or not as expected.
    #[error("{}: {why}", path.display())]
    Folder {
        /// The folder.
        path: std::path::PathBuf,
        /// What is wrong and what to do.
        why: String,
    },
    /// A release that failed verification: every fault, each naming its file.
    #[error("release {}: {} fault(s):\n  {}", path.display(), faults.len(), faults.join("\n  "))]
    Verification {
        /// The release.
        path: std::path::PathBuf,
        /// One line per fault.
        faults: Vec<String>,
    },
    /// A batch plan that cannot run: every fault is found before anything runs or is submitted.
    #[error("{}{}: {why}", path.display(), line.map_or(String::new(), |l| format!(" line {l}")))]
    Plan {
        /// The plan file.
        path: std::path::PathBuf,
        /// The line at fault, when there is one.
        line: Option<usize>,
        /// What is wrong.
        why: String,
    },
    /// A Slurm command that failed.
    #[error("{command}: {why}")]
    Slurm {
        /// The command line.
        command: String,
        /// What it said.
        why: String,
    },
    /// A Slurm command that is not installed.
    #[error("{command}: not found (Slurm's commands are not installed or not on PATH; on Debian: apt-get install slurm-client, or scripts/install-system-deps.sh slurm)")]
    SlurmMissing {
        /// The command.
        command: String,
    },
}
