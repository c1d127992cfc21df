//! What can go wrong in alignment and evaluation.

/// Result alias of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// An alignment or evaluation that cannot be done with the inputs given.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file or data-model error (names the file).
    #[error(transparent)]
    Dataset(#[from] rmvp_dataset::Error),
    /// A mesh the ray caster cannot use.
    #[error(transparent)]
    Render(#[from] rmvp_render::Error),
    /// Too few scan points to align.
    #[error("the scan has {points} points; alignment needs at least 10")]
    TooFewScanPoints {
        /// Points in the scan.
        points: usize,
    },
    /// Points no similarity can be fitted to (all at one place, on one line).
    #[error("the {which} is degenerate: {why}")]
    Degenerate {
        /// `scan` or `target`.
        which: &'static str,
        /// What is wrong, with the figures.
        why: String,
    },
    /// A target without faces or normals: no surface to align to.
    #[error("the target needs faces or vertex normals")]
    TargetWithoutSurface,
    /// A mesh the distance queries cannot be built on.
    #[error("{which} mesh: {message}")]
    BadMesh {
        /// `predicted`, `ground-truth`, `target`.
        which: &'static str,
        /// What the geometry library said.
        message: String,
    },
    /// A mesh without area: nothing to sample.
    #[error("the {which} mesh has no surface area to sample")]
    NoSurfaceArea {
        /// `predicted` or `ground-truth`.
        which: &'static str,
    },
    /// A scene without ground-truth normal maps.
    #[error("the scene has no ground-truth normal maps")]
    NoGroundTruthNormals,
    /// A prediction that covers none of a view's ground-truth pixels.
    #[error("view {view}: the prediction covers no ground-truth pixel")]
    NoCoverage {
        /// The view.
        view: String,
    },
}
