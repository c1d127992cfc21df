//! Object masks of a session's views, made offline (no model weights):
//!
//! - `threshold`: S0 against a uniform darker background: Otsu's threshold (or a given one),
//!   opening and closing, the largest component, holes filled;
//! - `difference`: against clean background plates (the empty rig at the same turntable
//!   positions, a session of the same view names): the colour difference, then as above;
//! - `grabcut`: OpenCV's GrabCut on S0's colours, started from the `difference` masks when
//!   background plates are given, else from the `threshold` masks (a band around the first
//!   guess is left to it);
//! - `mesh`: a mesh in the poses' world frame, ray cast in every posed view;
//! - `folder`: hand-made masks (`<view>.png`, or JPEG or TIFF; white is the object).
//!
//! Hand-made corrections (`<view>.png`, JPEG or TIFF, in a corrections folder, as PANDORA keeps
//! `mask_corrections/`) replace any view's mask. Masks are kept in the session (`masks/`) with a
//! report of each view's area and a contact sheet of the masks over S0.

use crate::pictures::read_view_stokes;
use crate::poses::{PoseSet, POSES_FILE};
use crate::{Error, Result};
use opencv::core::{self, Mat, Scalar};
use opencv::imgproc;
use opencv::prelude::*;
use rayon::prelude::*;
use rmvp_dataset::io::json::{read_json, write_json};
use rmvp_dataset::io::picture::{find_picture, read_picture};
use rmvp_dataset::io::png;
use rmvp_dataset::session::SessionManifest;
use rmvp_dataset::visualize::{contact_sheet, downsample, preview, quantile};
use rmvp_dataset::{Image, Mesh, Stokes};
use rmvp_render::pbrdf::{Interface, Lobes};
use rmvp_render::{geometry_maps, Object};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The session's masks folder.
pub const MASKS_FOLDER: &str = "masks";
/// The masks' report in a masks folder.
pub const MASKS_REPORT: &str = "masks.json";
/// The contact sheet in a masks folder.
pub const MASKS_SHEET: &str = "contact_sheet.png";

/// How masks are made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum MaskMethod {
    /// S0 threshold against a uniform background.
    #[default]
    Threshold,
    /// Colour difference against background plates.
    Difference,
    /// OpenCV GrabCut from the threshold (or difference) masks.
    Grabcut,
    /// A mesh ray cast with the session's poses.
    Mesh,
    /// Hand-made masks.
    Folder,
}

/// How masks are made; [`MaskOptions::default`] holds `rmvp masks`' defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct MaskOptions {
    /// The method.
    pub method: MaskMethod,
    /// threshold: S0 level as a fraction of its 99.5th percentile (`None`: Otsu's).
    pub threshold: Option<f64>,
    /// difference: relative colour difference that counts as the object.
    pub difference: f64,
    /// Opening radius (removes specks), pixels.
    pub open_px: u32,
    /// Closing radius (fills cracks), pixels.
    pub close_px: u32,
    /// grabcut: width of the undecided band around the first guess, pixels.
    pub band_px: u32,
    /// grabcut: iterations.
    pub iterations: u32,
    /// difference/grabcut: the background plates (a session with the same view names).
    pub background: Option<PathBuf>,
    /// mesh: the mesh, in the poses' world frame.
    pub mesh: Option<PathBuf>,
    /// folder: the masks.
    pub folder: Option<PathBuf>,
    /// Hand-made masks that replace any view's.
    pub corrections: Option<PathBuf>,
}

impl Default for MaskOptions {
    fn default() -> Self {
        Self {
            method: MaskMethod::Threshold,
            threshold: None,
            difference: 0.25,
            open_px: 2,
            close_px: 8,
            band_px: 15,
            iterations: 5,
            background: None,
            mesh: None,
            folder: None,
            corrections: None,
        }
    }
}

/// One view's mask in the report.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MaskRecord {
    /// The view.
    pub name: String,
    /// Share of the image on the object.
    pub area_fraction: f64,
    /// Whether a hand-made correction replaced the computed mask.
    pub corrected: bool,
}

/// The masks of a session (`masks/masks.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MaskReport {
    /// How they were made.
    pub method: MaskMethod,
    /// Every view.
    pub views: Vec<MaskRecord>,
}

impl MaskReport {
    /// Read a report.
    pub fn read(path: &Path) -> Result<Self> {
        Ok(read_json(path, "a mask report")?)
    }
}

fn mat_u8(image: &Image<u8>) -> Result<Mat> {
    let mat = Mat::from_slice(image.data())?;
    Ok(mat.reshape(image.channels() as i32, image.height() as i32)?.try_clone()?)
}

fn image_u8(mat: &Mat, width: usize, height: usize) -> Result<Image<u8>> {
    Ok(Image::from_vec(width, height, 1, mat.data_bytes()?.to_vec())?)
}

/// 255 where `keep`, else 0.
fn binary(image: &Image<f32>, keep: impl Fn(f32) -> bool) -> Image<u8> {
    image.map(|v| if keep(v) { 255 } else { 0 })
}

/// Opening and closing with discs, the largest component, and its holes filled.
pub fn clean(mask: &Image<u8>, open_px: u32, close_px: u32) -> Result<Image<u8>> {
    let (w, h) = mask.size();
    let mut mat = mat_u8(mask)?;
    for (op, radius) in [(imgproc::MORPH_OPEN, open_px), (imgproc::MORPH_CLOSE, close_px)] {
        if radius == 0 {
            continue;
        }
        let side = 2 * radius as i32 + 1;
        let kernel = imgproc::get_structuring_element(
            imgproc::MORPH_ELLIPSE,
            core::Size::new(side, side),
            core::Point::new(-1, -1),
        )?;
        let mut out = Mat::default();
        imgproc::morphology_ex(
            &mat,
            &mut out,
            op,
            &kernel,
            core::Point::new(-1, -1),
            1,
            core::BORDER_CONSTANT,
            Scalar::all(0.0),
        )?;
        mat = out;
    }
    let (mut labels, mut stats, mut centroids) = (Mat::default(), Mat::default(), Mat::default());
    let n = imgproc::connected_components_with_stats(&mat, &mut labels, &mut stats, &mut centroids, 8, core::CV_32S)?;
    let largest = (1..n).max_by_key(|&l| *stats.at_2d::<i32>(l, imgproc::CC_STAT_AREA).unwrap_or(&0));
    let Some(largest) = largest else { return Ok(Image::new(w, h, 1)) };
    let labels: &[i32] = labels.data_typed()?;
    let mut object: Vec<u8> = labels.iter().map(|&l| if l == largest { 255 } else { 0 }).collect();
    // Holes: background pixels not connected to the image border.
    let mut reached = vec![false; w * h];
    let mut stack: Vec<usize> =
        (0..w).flat_map(|x| [x, (h - 1) * w + x]).chain((0..h).flat_map(|y| [y * w, y * w + w - 1])).collect();
    while let Some(k) = stack.pop() {
        if reached[k] || object[k] != 0 {
            continue;
        }
        reached[k] = true;
        let (x, y) = (k % w, k / w);
        if x > 0 {
            stack.push(k - 1);
        }
        if x + 1 < w {
            stack.push(k + 1);
        }
        if y > 0 {
            stack.push(k - w);
        }
        if y + 1 < h {
            stack.push(k + w);
        }
    }
    for (o, r) in object.iter_mut().zip(&reached) {
        if !r {
            *o = 255;
        }
    }
    Ok(Image::from_vec(w, h, 1, object)?)
}

/// The threshold mask of S0: its channel mean above `level` (a fraction of the 99.5th
/// percentile) or Otsu's threshold, cleaned.
pub fn threshold_mask(s0: &Image<f32>, level: Option<f64>, options: &MaskOptions) -> Result<Image<u8>> {
    let grey = s0.channel_mean();
    let white = quantile(grey.data(), 0.995).max(1e-12);
    let raw = match level {
        Some(level) => binary(&grey, |v| v as f64 > level * white as f64),
        None => {
            let picture = grey.map(|v| (v / white * 255.0).round().clamp(0.0, 255.0) as u8);
            let mut out = Mat::default();
            imgproc::threshold(
                &mat_u8(&picture)?,
                &mut out,
                0.0,
                255.0,
                imgproc::THRESH_BINARY | imgproc::THRESH_OTSU,
            )?;
            image_u8(&out, grey.width(), grey.height())?
        }
    };
    clean(&raw, options.open_px, options.close_px)
}

/// Chromatic distortion (relative) below which a darkened pixel is the object's shadow.
const SHADOW_CHROMA: f32 = 0.1;
/// Change of the linear polarization (S1, S2), relative to S0, that only the object makes.
const POLARIZATION_CHANGE: f32 = 0.08;

/// The difference mask against a background plate (the Stokes of the empty rig at the same
/// pose), shadow-aware (after Horprasert et al. 1999): each pixel's colour `I` is the plate's
/// `E` scaled by a brightness `a = I.E / E.E` plus a chromatic distortion `|I - a E|`. The
/// object is where `|I - E|` exceeds `options.difference` of the plate's brightness (plus 2 %
/// of its white), except where the plate is only darkened (`a < 1`, distortion below
/// `SHADOW_CHROMA`: the object's shadow); and wherever the linear polarization changed by
/// more than `POLARIZATION_CHANGE` of S0 (a shadow darkens, it does not polarize: the
/// object's silhouette, seen at grazing angles, is where it polarizes most). Cleaned.
///
/// A dark part of the object (an unlit belly) over a bright part of the plate (the white
/// border of a board marker) looks exactly like a shadow there and is missed: strips as wide
/// as those borders; the default closing (8 px) fills them (on the simulated lab it raised
/// the lowest view's IoU from 0.967 to 0.982).
pub fn difference_mask(stokes: &Stokes, plate: &Stokes, options: &MaskOptions) -> Result<Image<u8>> {
    let white = quantile(plate.s0.data(), 0.995).max(1e-12);
    let c = stokes.s0.channels();
    let pixels = stokes.s0.data().len() / c;
    let data: Vec<u8> = (0..pixels)
        .map(|p| {
            let range = p * c..(p + 1) * c;
            let (i, e) = (&stokes.s0.data()[range.clone()], &plate.s0.data()[range.clone()]);
            let ee: f32 = e.iter().map(|y| y * y).sum::<f32>().max(1e-20);
            let a = i.iter().zip(e).map(|(x, y)| x * y).sum::<f32>() / ee;
            let distortion: f32 = i.iter().zip(e).map(|(x, y)| (x - a * y) * (x - a * y)).sum::<f32>().sqrt();
            let reference = ee.sqrt() + 0.02 * white;
            let changed: f32 = i.iter().zip(e).map(|(x, y)| (x - y) * (x - y)).sum::<f32>().sqrt() / reference;
            // Dark plate pixels (black ink) carry more noise than colour: a wider floor.
            let shadow = a < 1.0 && distortion / (ee.sqrt() + 0.05 * white) < SHADOW_CHROMA;
            let mean = |image: &Image<f32>| image.data()[range.clone()].iter().sum::<f32>() / c as f32;
            let (d1, d2) = (mean(&stokes.s1) - mean(&plate.s1), mean(&stokes.s2) - mean(&plate.s2));
            let polarized =
                (d1 * d1 + d2 * d2).sqrt() > POLARIZATION_CHANGE * (mean(&stokes.s0).max(0.0) + 0.05 * white);
            if (changed > options.difference as f32 && !shadow) || polarized {
                255
            } else {
                0
            }
        })
        .collect();
    clean(&Image::from_vec(stokes.s0.width(), stokes.s0.height(), 1, data)?, options.open_px, options.close_px)
}

/// GrabCut on S0's colours started from `guess`: its interior eroded by `band_px` is surely
/// the object, its exterior dilated by `band_px` surely not, the band between undecided.
pub fn grabcut_mask(s0: &Image<f32>, guess: &Image<u8>, options: &MaskOptions) -> Result<Image<u8>> {
    let (w, h) = guess.size();
    let picture = preview(s0);
    let side = 2 * options.band_px as i32 + 1;
    let kernel = imgproc::get_structuring_element(
        imgproc::MORPH_ELLIPSE,
        core::Size::new(side, side),
        core::Point::new(-1, -1),
    )?;
    let guess_mat = mat_u8(guess)?;
    let (mut inner, mut outer) = (Mat::default(), Mat::default());
    let border = imgproc::morphology_default_border_value()?;
    imgproc::erode(&guess_mat, &mut inner, &kernel, core::Point::new(-1, -1), 1, core::BORDER_CONSTANT, border)?;
    imgproc::dilate(&guess_mat, &mut outer, &kernel, core::Point::new(-1, -1), 1, core::BORDER_CONSTANT, border)?;
    let (inner, outer) = (inner.data_bytes()?.to_vec(), outer.data_bytes()?.to_vec());
    let labels: Vec<u8> = (0..w * h)
        .map(|k| {
            if inner[k] > 0 {
                imgproc::GC_FGD as u8
            } else if outer[k] == 0 {
                imgproc::GC_BGD as u8
            } else if guess.data()[k] > 0 {
                imgproc::GC_PR_FGD as u8
            } else {
                imgproc::GC_PR_BGD as u8
            }
        })
        .collect();
    if !labels.iter().any(|&l| l == imgproc::GC_FGD as u8 || l == imgproc::GC_PR_FGD as u8) {
        return Ok(Image::new(w, h, 1));
    }
    let mut mask = mat_u8(&Image::from_vec(w, h, 1, labels)?)?;
    let (mut background, mut foreground) = (Mat::default(), Mat::default());
    imgproc::grab_cut(
        &mat_u8(&picture)?,
        &mut mask,
        core::Rect::default(),
        &mut background,
        &mut foreground,
        options.iterations as i32,
        imgproc::GC_INIT_WITH_MASK,
    )?;
    let refined: Vec<u8> = mask
        .data_bytes()?
        .iter()
        .map(|&l| if l == imgproc::GC_FGD as u8 || l == imgproc::GC_PR_FGD as u8 { 255 } else { 0 })
        .collect();
    clean(&Image::from_vec(w, h, 1, refined)?, options.open_px, options.close_px)
}

/// A picture of a mask over S0: the object as it is, the background darkened, the outline
/// green; at most 320 pixels wide.
pub fn mask_picture(s0: &Image<f32>, mask: &Image<u8>) -> Image<u8> {
    let mut picture = preview(s0);
    let (w, h) = mask.size();
    let m = mask.data();
    for y in 0..h {
        for x in 0..w {
            let k = y * w + x;
            let inside = m[k] > 127;
            let edge = inside
                && [(x.wrapping_sub(1), y), (x + 1, y), (x, y.wrapping_sub(1)), (x, y + 1)]
                    .iter()
                    .any(|&(u, v)| u >= w || v >= h || m[v * w + u] <= 127);
            let p = picture.pixel_mut(x, y);
            if edge {
                p.copy_from_slice(&[0, 255, 0]);
            } else if !inside {
                p.iter_mut().for_each(|c| *c = (*c as f32 * 0.3) as u8);
            }
        }
    }
    downsample(&picture, w.div_ceil(320))
}

/// Every picture in a corrections folder must be named for a view of the session: a correction
/// for no view (a typo, another session's) is refused by name, not silently left unused.
fn check_corrections(folder: &Path, manifest: &SessionManifest) -> Result<()> {
    let entries = std::fs::read_dir(folder).map_err(|e| rmvp_dataset::Error::io(folder, e))?;
    for entry in entries {
        let path = entry.map_err(|e| rmvp_dataset::Error::io(folder, e))?.path();
        if !rmvp_dataset::io::picture::is_picture(&path) {
            continue;
        }
        let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        if !manifest.views.iter().any(|v| v.name == stem) {
            return Err(Error::MaskInput(format!(
                "{}: a correction for no view of the session (its views are {} to {})",
                path.display(),
                manifest.views.first().map_or("", |v| v.name.as_str()),
                manifest.views.last().map_or("", |v| v.name.as_str())
            )));
        }
    }
    Ok(())
}

/// Make the masks of the session in `dir` and keep them in `dir/masks` (and in `output` when
/// another folder), with the report and the contact sheet.
pub fn make_masks(dir: &Path, options: &MaskOptions, output: &Path) -> Result<MaskReport> {
    let manifest = SessionManifest::read(dir)?;
    manifest.require_views(dir)?;
    if let Some(corrections) = &options.corrections {
        check_corrections(corrections, &manifest)?;
    }
    let need = |what: &Option<PathBuf>, name: &str| -> Result<PathBuf> {
        what.clone().ok_or_else(|| Error::MaskInput(format!("the {name} mask method needs its input")))
    };
    let mesh_object = match options.method {
        MaskMethod::Mesh => {
            let mesh = Mesh::read(&need(&options.mesh, "mesh")?)?;
            let object = Object::new(&mesh, Interface::Dielectric(1.5), Lobes::Plastic)?;
            Some((object, PoseSet::read(&dir.join(POSES_FILE))?))
        }
        _ => None,
    };
    let plates = match (options.method, &options.background) {
        (MaskMethod::Difference, None) => {
            return Err(Error::MaskInput("the difference method needs background plates".into()))
        }
        (_, Some(plates)) => Some(SessionManifest::read(plates).map(|m| (plates.clone(), m))?),
        _ => None,
    };
    let made: Vec<(Image<u8>, Image<u8>, MaskRecord)> = manifest
        .views
        .par_iter()
        .map(|view| -> Result<_> {
            let stokes: Stokes = read_view_stokes(dir, view)?;
            let plate = |_: ()| -> Result<Stokes> {
                let (folder, plates) = plates.as_ref().expect("checked");
                let v = plates.views.iter().find(|p| p.name == view.name).ok_or_else(|| {
                    Error::MaskInput(format!("the background plates {} have no view {}", folder.display(), view.name))
                })?;
                read_view_stokes(folder, v)
            };
            // The picture the mask was read from, where it was read from one.
            let mut picture_file = None;
            let mask = match options.method {
                MaskMethod::Threshold => threshold_mask(&stokes.s0, options.threshold, options)?,
                MaskMethod::Difference => difference_mask(&stokes, &plate(())?, options)?,
                MaskMethod::Grabcut => {
                    let guess = match &plates {
                        Some(_) => difference_mask(&stokes, &plate(())?, options)?,
                        None => threshold_mask(&stokes.s0, options.threshold, options)?,
                    };
                    grabcut_mask(&stokes.s0, &guess, options)?
                }
                MaskMethod::Mesh => {
                    let (object, poses) = mesh_object.as_ref().expect("built above");
                    let camera = poses
                        .camera(&view.name)
                        .ok_or_else(|| Error::MaskInput(format!("view {} has no pose in {POSES_FILE}", view.name)))?;
                    geometry_maps(object, &camera).mask
                }
                MaskMethod::Folder => {
                    let folder = need(&options.folder, "folder")?;
                    let path = find_picture(&folder, &view.name).ok_or_else(|| {
                        Error::MaskInput(format!("{} has no picture of view {}", folder.display(), view.name))
                    })?;
                    let mask = read_picture(&path)?.pixels.to_mask();
                    picture_file = Some(path);
                    mask
                }
            };
            let correction = options.corrections.as_ref().and_then(|c| find_picture(c, &view.name));
            let (mask, corrected) = match &correction {
                Some(path) => (read_picture(path)?.pixels.to_mask(), true),
                None => (mask, false),
            };
            if mask.size() != stokes.s0.size() {
                let whose = match (&correction, &picture_file) {
                    (Some(path), _) => format!("{}: the correction", path.display()),
                    (None, Some(path)) => format!("{}: the mask", path.display()),
                    (None, None) => "the mask".to_string(),
                };
                return Err(Error::MaskInput(format!(
                    "{whose} of view {} is {}x{}, the view's {} {}x{}",
                    view.name,
                    mask.width(),
                    mask.height(),
                    view.folder(dir).join(rmvp_dataset::session::VIEW_STOKES).display(),
                    stokes.s0.width(),
                    stokes.s0.height()
                )));
            }
            let area_fraction = mask.data().iter().filter(|&&v| v > 127).count() as f64 / mask.data().len() as f64;
            let picture = mask_picture(&stokes.s0, &mask);
            Ok((mask, picture, MaskRecord { name: view.name.clone(), area_fraction, corrected }))
        })
        .collect::<Result<_>>()?;
    let report = MaskReport { method: options.method, views: made.iter().map(|m| m.2.clone()).collect() };
    let tiles: Vec<Image<u8>> = made.iter().map(|m| m.1.clone()).collect();
    for folder in [dir.join(MASKS_FOLDER), output.to_path_buf()] {
        for (mask, _, record) in &made {
            png::write_png_u8(&folder.join(format!("{}.png", record.name)), mask)?;
        }
        png::write_png_u8(&folder.join(MASKS_SHEET), &contact_sheet(&tiles, 6))?;
        write_json(&folder.join(MASKS_REPORT), &report)?;
        if output == dir.join(MASKS_FOLDER) {
            break;
        }
    }
    Ok(report)
}
