//! The error type of the data model: every error names the file it concerns.

use std::fmt::Display;
use std::path::{Path, PathBuf};

/// Result alias of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What went wrong, and with which file.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The operating system refused an operation on a file.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or folder concerned.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A file was read but its content is not what it should be.
    #[error("{}: {message}", path.display())]
    Format {
        /// The offending file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// An image file that declares more pixels than the limit ([`crate::io::input::max_pixels`]).
    #[error("{}: declares a {width}x{height} image, more than the limit of {limit} pixels", path.display())]
    ImageTooLarge {
        /// The file.
        path: PathBuf,
        /// Its declared width.
        width: u64,
        /// Its declared height.
        height: u64,
        /// The limit, pixels.
        limit: u64,
    },
    /// Data that does not hang together (sizes, counts, values), independent of any file.
    #[error("{0}")]
    Invalid(String),
}

impl Error {
    /// An I/O error on `path`.
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Error::Io { path: path.as_ref().to_path_buf(), source }
    }

    /// A content error in `path`.
    pub fn format(path: impl AsRef<Path>, message: impl Display) -> Self {
        Error::Format { path: path.as_ref().to_path_buf(), message: message.to_string() }
    }

    /// Inconsistent data.
    pub fn invalid(message: impl Display) -> Self {
        Error::Invalid(message.to_string())
    }

    /// Attach a file to an [`Error::Invalid`]; other variants already name one.
    pub fn in_file(self, path: impl AsRef<Path>) -> Self {
        match self {
            Error::Invalid(message) => Error::format(path, message),
            other => other,
        }
    }
}
