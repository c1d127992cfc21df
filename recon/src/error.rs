//! What can stop a reconstruction.

use std::path::PathBuf;

/// Result alias of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An I/O error on `path`.
    pub(crate) fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        rmvp_dataset::Error::io(path, source).into()
    }
}

/// A reconstruction that cannot start, continue or finish.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file or data-model error (names the file).
    #[error(transparent)]
    Dataset(#[from] rmvp_dataset::Error),
    /// An option no training can run with (zero iterations, say).
    #[error("{0}")]
    InvalidOption(String),
    /// Both the photometric and the geometric cue switched off.
    #[error("both cues are off (no_geometric and no_photometric): nothing to train")]
    BothCuesOff,
    /// A `scale_mat` that cannot map the unit sphere.
    #[error("scale_mat is singular or degenerate: the unit sphere cannot be mapped")]
    SingularNormalization,
    /// A scene without training views.
    #[error("the scene has no training views")]
    NoTrainingViews,
    /// A training view without an input it needs.
    #[error("view {view}: no {what}; reconstruction needs Stokes and masks")]
    MissingInput {
        /// The view.
        view: String,
        /// `Stokes images` or `mask`.
        what: &'static str,
    },
    /// Stokes images that are not RGB.
    #[error("view {view}: Stokes must be RGB, these have {channels} channel(s)")]
    StokesNotRgb {
        /// The view.
        view: String,
        /// Their channels.
        channels: usize,
    },
    /// Images whose size is not the camera's.
    #[error("view {view}: images are {}x{} but the camera is {}x{}", image.0, image.1, camera.0, camera.1)]
    SizeMismatch {
        /// The view.
        view: String,
        /// Image size.
        image: (usize, usize),
        /// Camera size.
        camera: (usize, usize),
    },
    /// A NaN or infinite input.
    #[error("view {view}: non-finite Stokes value at pixel ({x}, {y}), channel {channel}")]
    NonFiniteInput {
        /// The view.
        view: String,
        /// Column.
        x: usize,
        /// Row.
        y: usize,
        /// Channel.
        channel: usize,
    },
    /// Masks with no object pixel in any training view.
    #[error("every training mask is empty")]
    EmptyMasks,
    /// A trained SDF without a zero crossing.
    #[error("the trained SDF has no zero crossing inside the unit sphere: no surface to extract")]
    NoSurface,
    /// A checkpoint of a run trained with other options.
    #[error("{}: was written with other options ({changed}); resume with the same ones", path.display())]
    CheckpointSettings {
        /// The checkpoint.
        path: PathBuf,
        /// What changed: each option with its recorded and its new value.
        changed: String,
    },
    /// The GPU path cannot run here (no driver, no NVRTC, no GPU, a field it does not cover) or
    /// failed.
    #[error("CUDA: {0}")]
    Cuda(String),
    /// A checkpoint that cannot be read back.
    #[error("{}: {problem}", path.display())]
    BadCheckpoint {
        /// The checkpoint.
        path: PathBuf,
        /// What is wrong with it.
        problem: String,
    },
}
