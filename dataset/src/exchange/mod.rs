//! Other tools' camera files, read and written in rmvp's conventions: COLMAP sparse models
//! ([`colmap`]) and nerfstudio's `transforms.json` ([`nerfstudio`]). (IDR/NeRSP's
//! `cameras.npz` is the NeRSP layout's own, [`crate::layout::nersp`].)

pub mod colmap;
pub mod nerfstudio;
