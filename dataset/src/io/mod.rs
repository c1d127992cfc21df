//! File formats, each through a well-kept crate, with errors that name the file.
//!
//! Every writer here writes atomically (see [`atomic`]): a reader never sees half a file, and an
//! interrupted or failed write (a full disk, say) leaves any previous version intact.

pub mod atomic;
pub mod exr;
pub mod npy;
pub mod png;

pub use atomic::{write_atomically, write_bytes_atomically};
