//! Other tools' camera files, read and written in rmvp's conventions: COLMAP sparse models
//! ([`colmap`]) and nerfstudio's `transforms.json` ([`nerfstudio`]). (Scene folders as the field
//! publishes them, IDR/NeRSP's `cameras.npz` among them, are layouts: [`crate::layout`].)

pub mod colmap;
pub mod nerfstudio;
