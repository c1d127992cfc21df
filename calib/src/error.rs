//! What can go wrong between a capture session and posed, masked views.

/// Result alias of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// A calibration, pose or mask step that cannot be done with the inputs given.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file or data-model error (names the file).
    #[error(transparent)]
    Dataset(#[from] rmvp_dataset::Error),
    /// OpenCV reported an error.
    #[error("OpenCV: {0}")]
    OpenCv(#[from] opencv::Error),
    /// A board description that cannot be a board.
    #[error("calibration board: {0}")]
    Board(String),
    /// Images of different sizes in one calibration.
    #[error("images of different sizes cannot be calibrated together: {0}")]
    MixedSizes(String),
    /// Inputs that are neither a capture session nor picture files.
    #[error("{0}")]
    NotPictures(String),
    /// Pictures whose files name different cameras or focal lengths.
    #[error("pictures from different cameras cannot be calibrated together: {0}")]
    MixedCameras(String),
    /// Too few images where the board was found.
    #[error("{usable} image(s) show the board well enough, {needed} are needed; left out: {rejected}")]
    TooFewImages {
        /// Images usable.
        usable: usize,
        /// Images needed.
        needed: usize,
        /// The others, each with its reason.
        rejected: String,
    },
    /// Too few views posed.
    #[error("{posed} view(s) posed, {needed} needed; failed: {failed}")]
    TooFewViews {
        /// Views posed.
        posed: usize,
        /// Views needed.
        needed: usize,
        /// The others, each with its reason.
        failed: String,
    },
    /// A calibration for another image size.
    #[error("the calibration is for {calibrated:?} pixels, the views are {views:?}")]
    SizeMismatch {
        /// The calibration's image size.
        calibrated: (u32, u32),
        /// The views' size.
        views: (u32, u32),
    },
    /// The `colmap` program is not there.
    #[error("the colmap program was not found ({program}): install COLMAP (Debian: apt-get install colmap, or scripts/install-system-deps.sh colmap)")]
    ColmapMissing {
        /// The program asked for.
        program: String,
    },
    /// A COLMAP step that failed.
    #[error("colmap {step} failed ({status}); the end of its log ({log}):\n{tail}")]
    ColmapFailed {
        /// The subcommand.
        step: String,
        /// Its exit status.
        status: String,
        /// Its log file.
        log: String,
        /// The log's last lines.
        tail: String,
    },
    /// A rendering input (a mask mesh) that cannot be used.
    #[error(transparent)]
    Render(#[from] rmvp_render::Error),
    /// A mask method without what it needs, or masks that do not fit the views.
    #[error("masks: {0}")]
    MaskInput(String),
    /// Views that do not constrain the focal length (the board at one orientation).
    #[error("the board has the same orientation in every image ({images}; tilts differ by at most {spread_deg:.1} deg): tilt it between images")]
    Degenerate {
        /// The images.
        images: String,
        /// Largest angle between two board orientations, degrees.
        spread_deg: f64,
    },
}
