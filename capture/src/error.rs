//! Errors of frame processing, cameras and capture sessions.

use std::path::PathBuf;

/// Result alias of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What went wrong while decoding or processing a frame.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A data-model or file error (names the file).
    #[error(transparent)]
    Dataset(#[from] rmvp_dataset::Error),
    /// A scene the simulated camera cannot render.
    #[cfg(feature = "acquisition")]
    #[error(transparent)]
    Render(#[from] rmvp_render::Error),
    /// A simulated lab that cannot be built (its board).
    #[cfg(feature = "acquisition")]
    #[error(transparent)]
    Calib(#[from] rmvp_calib::Error),
    /// A frame whose bytes do not match its declared format and size.
    #[error("{source_name}: {message}")]
    Frame {
        /// The file or device the frame came from.
        source_name: String,
        /// What is wrong.
        message: String,
    },
    /// A camera that cannot be opened, configured or read, or that stopped answering.
    #[error("camera {device}: {message}")]
    Camera {
        /// The camera (vendor, model and serial, or how it was asked for).
        device: String,
        /// What went wrong.
        message: String,
    },
    /// A session that stopped early: the cause, and where the session stands (resumable).
    #[error("{cause}\nsession {dir}: {complete} of {planned} views complete and saved; fix the cause and resume the session to continue", dir = dir.display())]
    Session {
        /// What stopped it.
        cause: Box<Error>,
        /// Session folder.
        dir: PathBuf,
        /// Views complete.
        complete: usize,
        /// Views planned.
        planned: usize,
    },
    /// A new session asked for in a folder that already holds one.
    #[error("{}: already holds a session of {object:?} ({complete} of {planned} views)", dir.display())]
    SessionExists {
        /// Session folder.
        dir: PathBuf,
        /// Its object.
        object: String,
        /// Views complete.
        complete: usize,
        /// Views planned.
        planned: usize,
    },
    /// Resuming a folder that holds no session.
    #[error("{}: has no session to resume (no session.json)", dir.display())]
    NothingToResume {
        /// The folder.
        dir: PathBuf,
    },
    /// Resuming a session with another camera or other settings.
    #[error("{}: was captured with {what} {was}; this run has {now}: resume with the same camera and options", dir.display())]
    ResumeMismatch {
        /// Session folder.
        dir: PathBuf,
        /// What differs.
        what: String,
        /// The session's value.
        was: String,
        /// This run's value.
        now: String,
    },
    /// Too little free space for the next view (nothing of it was written).
    #[error("{}: disk full: {free_mib:.0} MiB free, the next view needs about {needed_mib:.0} MiB; free space and resume", dir.display())]
    DiskFull {
        /// The session folder.
        dir: PathBuf,
        /// Free space, MiB.
        free_mib: f64,
        /// Space wanted, MiB.
        needed_mib: f64,
    },
    /// Standard input closed while waiting for the operator.
    #[error("standard input closed while waiting for the operator")]
    OperatorGone,
    /// A processing request that cannot be met (unsupported combination of options).
    #[error("{0}")]
    Unsupported(String),
    /// OpenCV reported an error.
    #[error("OpenCV: {0}")]
    OpenCv(#[from] opencv::Error),
}

impl Error {
    /// A frame error for `source_name` (a file path or a device).
    pub fn frame(source_name: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Frame { source_name: source_name.into(), message: message.into() }
    }

    /// A camera error for `device`.
    pub fn camera(device: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Camera { device: device.into(), message: message.into() }
    }

    /// A frame error for a file.
    pub fn in_file(path: &std::path::Path, message: impl Into<String>) -> Self {
        Self::frame(PathBuf::from(path).display().to_string(), message)
    }
}
