//! The purpose-made differentiable engine: flat parameters, dense networks, hash grid,
//! encodings, Adam and vector helpers, each with a hand-written backward pass checked against finite
//! differences in the tests. Everything works on plain `f32` slices, so that a GPU backend
//! (cudarc + NVRTC kernels) can replace these functions without touching the training loop.

pub mod adam;
pub mod dense;
pub mod encoding;
pub mod hashgrid;
pub mod panel;
pub mod params;
pub mod vector;

pub use adam::{Adam, AdamConfig};
pub use dense::{Activation, Init, Mlp, MlpCache};
pub use hashgrid::HashGrid;
pub use params::{Group, ParamLayout};
