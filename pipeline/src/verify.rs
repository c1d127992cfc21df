//! Verification of a release (`rmvp dataset verify`): every fault is listed, each naming its
//! file and what is wrong.
//!
//! - `SHA256SUMS`: every listed file present with its checksum, no file left unlisted;
//! - `croissant.json` (where there is one): every file it lists present with its SHA-256;
//! - per object: both layouts readable; every view posed, masked, with Stokes of the camera's
//!   size; the NeRSP layout by the official loader's rules (one `image/` and one
//!   `input_azimuth_maps/` file per `world_mat_i`, 0-based, 16-bit RGBA azimuth maps, float32
//!   H x W x 3 Stokes arrays);
//! - with ground truth: each captured mask against the scan's silhouette (IoU at least
//!   [`MIN_MASK_IOU`]), and the scan's vertices projected into each view inside its mask
//!   (at least [`MIN_INSIDE`] of them, within [`MASK_SLACK_PX`]): cameras and scan agree.

use crate::build::{BuildRecord, BUILD_FILE};
use crate::ground_truth::mask_iou;
use crate::publish::CHECKSUMS;
use crate::{Error, Result};
use nalgebra::Point3;
use rmvp_dataset::checksums::{check_listing, without_path};
use rmvp_dataset::io::{input, npy, png};
use rmvp_dataset::layout::{nersp, read_scene, Layout};
use rmvp_dataset::session::sha256_file;
use rmvp_dataset::{Image, Scene};
use std::path::Path;

/// Lowest IoU of a captured mask with the ground-truth silhouette.
pub const MIN_MASK_IOU: f64 = 0.9;
/// Share of the scan's vertices that must project inside each mask.
pub const MIN_INSIDE: f64 = 0.98;
/// Pixels a projected vertex may fall outside a mask.
pub const MASK_SLACK_PX: i64 = 3;
/// Scan vertices checked per view, at most.
const VERTICES_CHECKED: usize = 2000;

/// What a verification found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Verification {
    /// Object folders checked.
    pub objects: Vec<String>,
    /// Files whose checksums matched.
    pub files: usize,
    /// Views checked.
    pub views: usize,
}

/// Verify the release in `release`; `Err(Error::Verification)` lists every fault.
pub fn verify(release: &Path) -> Result<Verification> {
    let mut faults = Vec::new();
    let mut report = Verification::default();
    let listing = match check_listing(release, CHECKSUMS) {
        Ok(listing) => listing,
        Err(e) => return Err(Error::Verification { path: release.to_path_buf(), faults: vec![e.to_string()] }),
    };
    faults.extend(listing.faults);
    report.files = listing.matched;
    let hashes = listing.hashes;
    check_croissant(release, &hashes, &mut faults);
    let mut objects: Vec<String> = std::fs::read_dir(release)
        .map_err(|e| rmvp_dataset::Error::io(release, e))?
        .filter_map(|e| e.ok())
        .filter(|e| e.path().join(BUILD_FILE).is_file())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    objects.sort();
    if objects.is_empty() {
        faults.push(format!("no object folder (a folder with {BUILD_FILE})"));
    }
    for object in &objects {
        report.views += check_object(&release.join(object), object, &mut faults);
    }
    report.objects = objects;
    if faults.is_empty() {
        Ok(report)
    } else {
        Err(Error::Verification { path: release.to_path_buf(), faults })
    }
}

/// The files `croissant.json` lists against their contents (`hashes`: the SHA-256 of each file
/// `SHA256SUMS` lists, as read; others are read here).
fn check_croissant(release: &Path, hashes: &std::collections::BTreeMap<String, String>, faults: &mut Vec<String>) {
    use crate::publish::croissant::{listed_files, CROISSANT};
    let path = release.join(CROISSANT);
    if !path.exists() {
        return;
    }
    let listed = rmvp_dataset::io::json::read_json_text(&path)
        .map_err(|e| without_path(&e, &path))
        .and_then(|text| serde_json::from_str::<serde_json::Value>(&text).map_err(|e| e.to_string()))
        .and_then(|value| listed_files(&value));
    let listed = match listed {
        Ok(listed) => listed,
        Err(why) => return faults.push(format!("{CROISSANT}: {why}")),
    };
    for (file, sha256) in listed {
        let actual = match hashes.get(&file) {
            Some(hash) => Ok(hash.clone()),
            None => match input::inside(release, &file) {
                Ok(inside) => sha256_file(&inside).map(|(hash, _)| hash).map_err(|e| without_path(&e, &inside)),
                Err(why) => Err(why),
            },
        };
        match actual {
            Ok(actual) if actual == sha256 => {}
            Ok(_) => faults.push(format!("{CROISSANT}: {file}: sha256 differs from the file (changed or damaged)")),
            Err(why) => faults.push(format!("{CROISSANT}: {file}: {why}")),
        }
    }
}

/// Check one object folder; returns the views checked.
fn check_object(dir: &Path, object: &str, faults: &mut Vec<String>) -> usize {
    let record = match BuildRecord::read(dir) {
        Ok(r) => r,
        Err(e) => {
            faults.push(format!("{object}/{BUILD_FILE}: {e}"));
            return 0;
        }
    };
    check_nersp_files(&dir.join(Layout::Nersp.name()), &format!("{object}/nersp"), record.train.len(), faults);
    let mut views = 0;
    for layout in [Layout::Nersp, Layout::Rmvp] {
        let at = format!("{object}/{}", layout.name());
        let scene = match read_scene(&dir.join(layout.name())) {
            Ok(s) => s,
            Err(e) => {
                faults.push(format!("{at}: not readable: {e}"));
                continue;
            }
        };
        views = views.max(check_scene(&scene, &record, &at, faults));
    }
    views
}

/// The official loader's rules on the NeRSP layout's files.
fn check_nersp_files(dir: &Path, at: &str, train: usize, faults: &mut Vec<String>) {
    let cameras = match npy::read_npz_limited::<f64>(&dir.join(nersp::CAMERAS), nersp::CAMERA_ARRAY_ELEMENTS) {
        Ok(c) => c,
        Err(e) => {
            faults.push(format!("{at}/{}: {e}", nersp::CAMERAS));
            return;
        }
    };
    let worlds = (0..).take_while(|i| cameras.iter().any(|(n, _)| *n == format!("world_mat_{i}"))).count();
    let scales = (0..).take_while(|i| cameras.iter().any(|(n, _)| *n == format!("scale_mat_{i}"))).count();
    if worlds != train || scales != train {
        faults.push(format!(
            "{at}/{}: {worlds} world_mat and {scales} scale_mat (0-based) for {train} training views",
            nersp::CAMERAS
        ));
    }
    let count = |folder: &str| std::fs::read_dir(dir.join(folder)).map_or(0, |d| d.count());
    for folder in ["image", "input_azimuth_maps", "s0", "s1", "s2"] {
        if count(folder) != train {
            faults.push(format!("{at}/{folder}/: {} files for {train} training views", count(folder)));
        }
    }
    for i in 0..train {
        let azimuth = dir.join(format!("input_azimuth_maps/{i:04}.png"));
        match png::read_png(&azimuth) {
            Ok(png::PngImage::U16(image)) if image.channels() == 4 => {}
            Ok(_) => {
                faults.push(format!("{at}/input_azimuth_maps/{i:04}.png: not 16-bit RGBA (the loader's mask is alpha)"))
            }
            Err(e) => faults.push(format!("{at}/input_azimuth_maps/{i:04}.png: {e}")),
        }
        for s in ["s0", "s1", "s2"] {
            match npy::read_npy::<f32>(&dir.join(format!("{s}/{i:04}.npy"))) {
                Ok(a) if a.shape.len() == 3 && a.shape[2] == 3 => {}
                Ok(a) => faults.push(format!("{at}/{s}/{i:04}.npy: shape {:?}, not H x W x 3", a.shape)),
                Err(e) => faults.push(format!("{at}/{s}/{i:04}.npy: {e}")),
            }
        }
    }
}

/// Views, sizes, split and ground truth of one layout's scene; returns the views checked.
fn check_scene(scene: &Scene, record: &BuildRecord, at: &str, faults: &mut Vec<String>) -> usize {
    let names: Vec<&str> = scene.views.iter().map(|v| v.name.as_str()).collect();
    for missing in record.views.iter().filter(|v| !names.contains(&v.as_str())) {
        faults.push(format!("{at}: view {missing} of {BUILD_FILE} is missing"));
    }
    let train: Vec<&str> = scene.train_views().map(|v| v.name.as_str()).collect();
    if train != record.train.iter().map(String::as_str).collect::<Vec<_>>() {
        faults.push(format!("{at}: training views {train:?}, {BUILD_FILE} says {:?}", record.train));
    }
    let vertices: Vec<Point3<f64>> = scene.mesh.as_ref().map_or_else(Vec::new, |m| {
        let step = m.positions.len().div_ceil(VERTICES_CHECKED).max(1);
        m.positions.iter().step_by(step).map(|p| Point3::from(p.map(|v| v as f64))).collect()
    });
    for view in &scene.views {
        let name = &view.name;
        let size = (view.camera.width as usize, view.camera.height as usize);
        if [view.camera.width, view.camera.height] != record.size {
            faults.push(format!("{at}: view {name} is {}x{}, the dataset {:?}", size.0, size.1, record.size));
        }
        let Some(mask) = &view.mask else {
            faults.push(format!("{at}: view {name} has no mask"));
            continue;
        };
        if mask.size() != size {
            faults.push(format!("{at}: view {name}'s mask is {:?}, its camera {size:?}", mask.size()));
            continue;
        }
        match &view.stokes {
            Some(s) if s.s0.size() == size => {}
            Some(s) => faults.push(format!("{at}: view {name}'s Stokes are {:?}, its camera {size:?}", s.s0.size())),
            None if view.split == rmvp_dataset::Split::Train => faults.push(format!("{at}: view {name} has no Stokes")),
            None => {}
        }
        if let Some(depth) = &view.depth {
            let silhouette = depth.map(|d| if d > 0.0 { 255u8 } else { 0 });
            let iou = mask_iou(mask, &silhouette);
            if iou < MIN_MASK_IOU {
                faults.push(format!(
                    "{at}: view {name}'s mask against the scan's silhouette: IoU {iou:.3} < {MIN_MASK_IOU}"
                ));
            }
        }
        if !vertices.is_empty() {
            let inside = share_inside(&vertices, view, mask);
            if inside < MIN_INSIDE {
                faults.push(format!(
                    "{at}: view {name}: {:.1} % of the scan's vertices project inside its mask (< {:.0} %): camera and \
                     scan disagree",
                    100.0 * inside,
                    100.0 * MIN_INSIDE
                ));
            }
        }
    }
    scene.views.len()
}

/// Share of `points` that project into `view` within [`MASK_SLACK_PX`] of its mask.
fn share_inside(points: &[Point3<f64>], view: &rmvp_dataset::View, mask: &Image<u8>) -> f64 {
    let (w, h) = (mask.width() as i64, mask.height() as i64);
    let near_mask = |x: i64, y: i64| {
        (-MASK_SLACK_PX..=MASK_SLACK_PX).any(|dy| {
            (-MASK_SLACK_PX..=MASK_SLACK_PX).any(|dx| {
                let (u, v) = (x + dx, y + dy);
                u >= 0 && v >= 0 && u < w && v < h && mask.pixel(u as usize, v as usize)[0] > 127
            })
        })
    };
    let inside = points
        .iter()
        .filter(|p| view.camera.project(p).is_some_and(|px| near_mask(px.x.floor() as i64, px.y.floor() as i64)))
        .count();
    inside as f64 / points.len() as f64
}
