//! Scene folders on disk: the official NeRSP loader's layout ([`nersp`]) and ours, manifest-based
//! ([`rmvp`]). Both are documented in `docs/formats.md`.

pub mod nersp;
pub mod rmvp;

use crate::{Error, Result, Scene};
use std::path::Path;

/// A scene folder layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Layout {
    /// `cameras.npz`, `s0/ s1/ s2/ mask/ ...` (with the optional `gt/` and `polarized/` extras).
    Nersp,
    /// Ours: `scene.json` and `views/<name>/...`.
    Rmvp,
}

impl Layout {
    /// Recognise the layout of a scene folder by its index file.
    pub fn detect(dir: &Path) -> Result<Self> {
        if dir.join(rmvp::MANIFEST).is_file() {
            Ok(Layout::Rmvp)
        } else if dir.join(nersp::CAMERAS).is_file() {
            Ok(Layout::Nersp)
        } else if !dir.is_dir() {
            Err(Error::io(dir, std::io::Error::new(std::io::ErrorKind::NotFound, "no such scene folder")))
        } else {
            Err(Error::format(dir, format!("not a scene: neither {} nor {} found", rmvp::MANIFEST, nersp::CAMERAS)))
        }
    }

    /// The name used on the command line and in messages.
    pub fn name(self) -> &'static str {
        match self {
            Layout::Nersp => "nersp",
            Layout::Rmvp => "rmvp",
        }
    }
}

/// Read a scene in whichever layout the folder has, and validate it.
pub fn read_scene(dir: &Path) -> Result<Scene> {
    let scene = match Layout::detect(dir)? {
        Layout::Nersp => nersp::read(dir)?,
        Layout::Rmvp => rmvp::read(dir)?,
    };
    scene.validate().map_err(|e| e.in_file(dir))?;
    Ok(scene)
}

/// Validate and write a scene in the given layout; the index file is written last, so a folder
/// whose writing was interrupted is never mistaken for a complete scene.
pub fn write_scene(scene: &Scene, dir: &Path, layout: Layout) -> Result<()> {
    scene.validate()?;
    match layout {
        Layout::Nersp => nersp::write(scene, dir),
        Layout::Rmvp => rmvp::write(scene, dir),
    }
}

/// Copy the scene in `source` (either layout) into `destination` in `layout`; the destination
/// must not exist or be empty. Returns the scene.
pub fn convert_scene(source: &Path, destination: &Path, layout: Layout) -> Result<Scene> {
    let occupied = std::fs::read_dir(destination).is_ok_and(|mut entries| entries.next().is_some());
    if occupied {
        return Err(Error::format(destination, "exists and is not empty; choose a new folder"));
    }
    let scene = read_scene(source)?;
    write_scene(&scene, destination, layout)?;
    Ok(scene)
}

/// An HxW or HxWxC float array as an image.
pub(crate) fn image_from_array(path: &Path, a: crate::io::npy::Array<f32>) -> Result<crate::Image<f32>> {
    let (h, w, c) = match a.shape[..] {
        [h, w] => (h, w, 1),
        [h, w, c] => (h, w, c),
        _ => return Err(Error::format(path, format!("expected an HxW or HxWxC image, shape is {:?}", a.shape))),
    };
    if h == 0 || w == 0 || c == 0 {
        return Err(Error::format(path, format!("empty image: shape {:?}", a.shape)));
    }
    crate::Image::from_vec(w, h, c, a.data).map_err(|e| e.in_file(path))
}

/// An image as an HxWxC array (HxW for one channel).
pub(crate) fn array_from_image(image: &crate::Image<f32>) -> crate::io::npy::Array<f32> {
    let (w, h, c) = (image.width(), image.height(), image.channels());
    let shape = if c == 1 { vec![h, w] } else { vec![h, w, c] };
    crate::io::npy::Array { shape, data: image.data().to_vec() }
}
