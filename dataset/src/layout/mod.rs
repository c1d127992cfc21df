//! Scene folders on disk: the official NeRSP loader's layout ([`nersp`]), ours, manifest-based
//! ([`rmvp`]), and two more as the field publishes them: RMVP3D's original part ([`rmvp3d`]) and
//! PANDORA's ([`pandora`]). Each is documented in `docs/formats.md`; each is read and written.
//!
//! **Stokes scale.** Every layout's Stokes images are kept as they are stored: rmvp halves
//! nothing. The official NeRSP loader multiplies `s0/ s1/ s2/` (and PolGS the RMVP3D archives
//! and PANDORA's files) by 0.5 on load; PolGS reads SMVP3D's `s0/` arrays unhalved. A constant
//! factor only rescales the reflectance the reconstruction fits (its albedo and specular
//! weights), never the geometry, and keeping the stored values makes every conversion between
//! layouts exact. The one transformation is PANDORA's shift: it stores `S0 + S1` and `S0 + S2`,
//! read back as `S1` and `S2`.

pub mod nersp;
pub mod pandora;
pub mod rmvp;
pub mod rmvp3d;

use crate::{Error, Image, Result, Scene};
use std::fmt::Display;
use std::path::Path;

/// Refuse an image read from `path` whose size (`got`, width and height) is not `expected`, the
/// size of `reference` (the file or record that sets the view's size), naming both.
fn check_size(path: &Path, got: (usize, usize), reference: impl Display, expected: (usize, usize)) -> Result<()> {
    if got != expected {
        let why = format!("is {}x{}, but {reference} is {}x{}", got.0, got.1, expected.0, expected.1);
        return Err(Error::format(path, why));
    }
    Ok(())
}

/// Read the image at `path` with `read`, refused by [`check_size`] when it is not `expected`.
fn read_sized<T: Copy>(
    path: &Path,
    read: impl FnOnce(&Path) -> Result<Image<T>>,
    reference: impl Display,
    expected: (usize, usize),
) -> Result<Image<T>> {
    let image = read(path)?;
    check_size(path, image.size(), reference, expected)?;
    Ok(image)
}

/// A scene folder layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Layout {
    /// `cameras.npz`, `s0/ s1/ s2/ mask/ ...` (with the optional `gt/` and `polarized/` extras).
    Nersp,
    /// Ours: `scene.json` and `views/<name>/...`.
    Rmvp,
    /// RMVP3D's original part: `cameras.npz`, `images_stokes/NNNN.npz`, `mask/`.
    Rmvp3d,
    /// PANDORA's: `cameras.npz` keyed by stem, `images_stokes/NN_s0.hdr` (shifted Stokes), `mask/`.
    Pandora,
}

impl Layout {
    /// Every layout, in the order of [`Layout::name`]'s documentation.
    pub const ALL: [Layout; 4] = [Layout::Nersp, Layout::Rmvp, Layout::Rmvp3d, Layout::Pandora];

    /// Recognise the layout of a scene folder by its files: `scene.json` (ours), else
    /// `cameras.npz` with `images_stokes/` of `NNNN.npz` archives (RMVP3D) or `NN_s0.hdr` files
    /// (PANDORA), else `cameras.npz` (NeRSP). A folder that has part of a layout is told which
    /// file of which layout it lacks.
    pub fn detect(dir: &Path) -> Result<Self> {
        let stokes = dir.join(rmvp3d::STOKES_FOLDER);
        if dir.join(rmvp::MANIFEST).is_file() {
            Ok(Layout::Rmvp)
        } else if dir.join(nersp::CAMERAS).is_file() {
            if !stokes.is_dir() {
                Ok(Layout::Nersp)
            } else if pandora::recognise(dir) {
                Ok(Layout::Pandora)
            } else if rmvp3d::recognise(dir) {
                Ok(Layout::Rmvp3d)
            } else {
                Err(Error::format(
                    &stokes,
                    "holds neither NNNN.npz archives (RMVP3D) nor NN_s0.hdr files (PANDORA): no Stokes images",
                ))
            }
        } else if !dir.is_dir() {
            Err(Error::io(dir, std::io::Error::new(std::io::ErrorKind::NotFound, "no such scene folder")))
        } else if stokes.is_dir() || dir.join("s0").is_dir() {
            let which = if stokes.is_dir() { "RMVP3D or PANDORA" } else { "NeRSP" };
            Err(Error::format(dir, format!("looks like the {which} layout but has no {}", nersp::CAMERAS)))
        } else {
            Err(Error::format(dir, format!("not a scene: neither {} nor {} found", rmvp::MANIFEST, nersp::CAMERAS)))
        }
    }

    /// The name used on the command line and in messages.
    pub fn name(self) -> &'static str {
        match self {
            Layout::Nersp => "nersp",
            Layout::Rmvp => "rmvp",
            Layout::Rmvp3d => "rmvp3d",
            Layout::Pandora => "pandora",
        }
    }
}

/// Read a scene in whichever layout the folder has, and validate it.
pub fn read_scene(dir: &Path) -> Result<Scene> {
    let scene = match Layout::detect(dir)? {
        Layout::Nersp => nersp::read(dir)?,
        Layout::Rmvp => rmvp::read(dir)?,
        Layout::Rmvp3d => rmvp3d::read(dir)?,
        Layout::Pandora => pandora::read(dir)?,
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
        Layout::Rmvp3d => rmvp3d::write(scene, dir),
        Layout::Pandora => pandora::write(scene, dir),
    }
}

/// Copy the scene in `source` (either layout) into `destination` in `layout`, its AoP mirrored
/// with `mirror_aop` ([`crate::handedness::mirror_aop`]); the destination must not exist or be
/// empty. Returns the scene.
pub fn convert_scene(source: &Path, destination: &Path, layout: Layout, mirror_aop: bool) -> Result<Scene> {
    let occupied = std::fs::read_dir(destination).is_ok_and(|mut entries| entries.next().is_some());
    if occupied {
        return Err(Error::format(destination, "exists and is not empty; choose a new folder"));
    }
    let mut scene = read_scene(source)?;
    if mirror_aop {
        crate::handedness::mirror_aop(&mut scene);
    }
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
