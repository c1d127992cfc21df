//! The pictures the detectors look at: each view's S0 of a capture session, or image files, as
//! 8-bit grey-level pictures, with their names.

use crate::Result;
use rayon::prelude::*;
use rmvp_dataset::io::read_linear;
use rmvp_dataset::layout::rmvp::read_stokes;
use rmvp_dataset::session::{SessionManifest, SessionView, SESSION_FILE, VIEW_STOKES};
use rmvp_dataset::visualize::preview;
use rmvp_dataset::{Image, Stokes};
use std::path::{Path, PathBuf};

/// An 8-bit grey picture of linear radiance (1 or 3 channels): the channel mean, exposed and
/// encoded as [`preview`] does (sRGB, the 99.5th percentile at 90 %).
pub fn grey_picture(linear: &Image<f32>) -> Image<u8> {
    let rgb = preview(linear);
    let data = rgb.data().chunks_exact(3).map(|p| ((p[0] as u16 + p[1] as u16 + p[2] as u16) / 3) as u8).collect();
    Image::from_vec(rgb.width(), rgb.height(), 1, data).expect("sized")
}

/// The Stokes images of a session's view.
pub fn read_view_stokes(dir: &Path, view: &SessionView) -> Result<Stokes> {
    Ok(read_stokes(&view.folder(dir).join(VIEW_STOKES))?)
}

/// Whether `path` is a capture session folder.
pub fn is_session(path: &Path) -> bool {
    path.join(SESSION_FILE).is_file()
}

/// Named pictures from a session folder (each view's S0, named after the view) or from image
/// files (PNG 8/16-bit or EXR, named after the file).
pub fn read_pictures(inputs: &[PathBuf]) -> Result<Vec<(String, Image<u8>)>> {
    if let [dir] = inputs {
        if is_session(dir) {
            let manifest = SessionManifest::read(dir)?;
            return manifest
                .views
                .par_iter()
                .map(|view| Ok((view.name.clone(), grey_picture(&read_view_stokes(dir, view)?.s0))))
                .collect();
        }
    }
    inputs
        .par_iter()
        .map(|path| {
            let name =
                path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
            Ok((name, grey_picture(&read_linear(path)?)))
        })
        .collect()
}
