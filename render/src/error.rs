//! What can go wrong while preparing a scene for rendering.

use std::path::PathBuf;

/// Result alias of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// A rendering input that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file or data-model error (names the file).
    #[error(transparent)]
    Dataset(#[from] rmvp_dataset::Error),
    /// A point cloud where a triangle mesh is needed.
    #[error("cannot render a mesh without faces")]
    NoFaces,
    /// A texture for a mesh without texture coordinates.
    #[error("the mesh has no texture coordinates (u v or s t vertex properties, or OBJ vt)")]
    NoTextureCoordinates,
    /// An albedo texture that is not RGB.
    #[error("an albedo texture must be RGB, this one has {channels} channel(s)")]
    TextureNotRgb {
        /// Channels of the texture.
        channels: usize,
    },
    /// An environment map that is not an RGB image.
    #[error("environment map must be RGB, got {width}x{height}x{channels}")]
    EnvironmentNotRgb {
        /// Width.
        width: usize,
        /// Height.
        height: usize,
        /// Channels.
        channels: usize,
    },
    /// An environment map with a NaN or infinite texel.
    #[error("environment map is not finite at ({x}, {y}) channel {channel}")]
    EnvironmentNotFinite {
        /// Column.
        x: usize,
        /// Row.
        y: usize,
        /// Channel.
        channel: usize,
    },
    /// An entry of a pose list that is not a usable camera.
    #[error("{}: pose {index}: {source}", path.display())]
    BadPose {
        /// The pose list.
        path: PathBuf,
        /// Entry (0-based).
        index: usize,
        /// What is wrong with it.
        source: rmvp_dataset::Error,
    },
}
