//! The pictures the detectors look at: each view's S0 of a capture session, or image files, as
//! 8-bit grey-level pictures, with their names.
//!
//! Linear light (a session's Stokes, EXR, HDR, 16-bit PNG or TIFF) is exposed and sRGB-encoded
//! by [`grey_picture`]; 8-bit files (PNG, JPEG, TIFF from a phone or a photo camera) are already
//! encoded and are only turned grey ([`grey_of_encoded`]), as OpenCV's own detectors see them.

use crate::{Error, Result};
use rayon::prelude::*;
use rmvp_dataset::io::picture::{read_picture, Pixels};
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

/// The grey level of 8-bit encoded pixels: the first channel of grey (and grey-alpha) images,
/// ITU-R BT.601 luma of RGB(A) in OpenCV's fixed point (`cvtColor(RGB2GRAY)`,
/// `imread(IMREAD_GRAYSCALE)`).
pub fn grey_of_encoded(image: &Image<u8>) -> Image<u8> {
    if image.channels() < 3 {
        return image.channel(0);
    }
    let data = image
        .data()
        .chunks_exact(image.channels())
        .map(|p| ((p[0] as u32 * 4899 + p[1] as u32 * 9617 + p[2] as u32 * 1868 + 8192) >> 14) as u8)
        .collect();
    Image::from_vec(image.width(), image.height(), 1, data).expect("sized")
}

/// Whether `path` is a capture session folder.
pub fn is_session(path: &Path) -> bool {
    path.join(SESSION_FILE).is_file()
}

/// Named pictures from a session folder (each view's S0, named after the view) or from image
/// files (PNG, JPEG, TIFF, EXR or HDR, named after the file). Files whose EXIF blocks name
/// different cameras (or focal lengths) are refused: one calibration is one camera.
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
    if let Some(folder) = inputs.iter().find(|p| p.is_dir()) {
        return Err(Error::NotPictures(format!(
            "{} is a folder but not a capture session (it has no {SESSION_FILE}): give a session \
             or picture files",
            folder.display()
        )));
    }
    let pictures: Vec<(String, Image<u8>, Option<String>)> = inputs
        .par_iter()
        .map(|path| {
            let name =
                path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
            let picture = read_picture(path)?;
            let grey = match &picture.pixels {
                Pixels::Encoded(image) => grey_of_encoded(image),
                Pixels::Linear(image) => grey_picture(image),
            };
            Ok((name, grey, picture.camera))
        })
        .collect::<Result<_>>()?;
    let mut cameras: Vec<(&str, &str)> =
        pictures.iter().filter_map(|(name, _, camera)| Some((camera.as_deref()?, name.as_str()))).collect();
    cameras.sort();
    cameras.dedup_by(|a, b| a.0 == b.0);
    if cameras.len() > 1 {
        let named: Vec<String> = cameras.iter().map(|(camera, name)| format!("{name} is from {camera}")).collect();
        return Err(Error::MixedCameras(named.join("; ")));
    }
    Ok(pictures.into_iter().map(|(name, grey, _)| (name, grey)).collect())
}
