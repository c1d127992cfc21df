//! Errors of frame processing.

use std::path::PathBuf;

/// Result alias of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What went wrong while decoding or processing a frame.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A data-model or file error (names the file).
    #[error(transparent)]
    Dataset(#[from] rmvp_dataset::Error),
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
    /// A session that stopped early: the cause, and where the session stands.
    #[error("{cause}\nsession {dir}: {complete} of {planned} views complete and saved; fix the cause and run the same command with --resume to continue", dir = dir.display())]
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
