//! Other tools' files, read and written in rmvp's conventions: COLMAP sparse models
//! ([`colmap`]), nerfstudio's `transforms.json` ([`nerfstudio`]) and RMVP3D's release layout
//! ([`rmvp3d`]). (IDR/NeRSP's `cameras.npz` is the NeRSP layout's own, [`crate::layout::nersp`].)

pub mod colmap;
pub mod nerfstudio;
pub mod rmvp3d;
