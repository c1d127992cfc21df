//! The layout read by the official NeRSP loader, with the `gt/` and `polarized/` extras of
//! `shared/fixtures/README.md`:
//!
//! ```text
//! cameras.npz                  world_mat_i = K[R|t] (4x4), scale_mat_i; training views i = 0..N-1
//! image/0000.png               8-bit preview of S0
//! input_azimuth_maps/0000.png  16-bit RGBA: R = G = B = AoP/pi*65535, A = mask*65535
//! mask/0000.png                8-bit mask (optional: the official loader reads the azimuth
//!                              map's alpha instead, and so do we when it is absent)
//! s0/0000.npy s1/ s2/          float32 HxWx3 Stokes components
//! polarized/0000_000.png ...   16-bit linear images behind polarizers at 0/45/90/135 degrees
//! gt/cameras.json              every view (train and eval) with K, R, t, size; provenance
//! gt/mask/<name>.png           mask of every view
//! gt/normal/<name>.exr         world-frame normals (N.X N.Y N.Z)
//! gt/depth/<name>.exr          z-depth along the camera axis (Z)
//! gt/mesh.ply gt/env.exr       ground-truth mesh and environment map
//! ```

use super::{array_from_image, check_size, image_from_array, read_sized};
use crate::camera::{matrix_from_rows, matrix_rows};
use crate::io::{exr, input, json, npy, png, write_bytes_atomically};
use crate::polarization::{aop_from_u16, aop_to_u16, POLARIZER_ANGLES_DEG};
use crate::{visualize, Camera, Error, Image, Mesh, PolarizerImages, Result, Scene, Split, Stokes, View};
use nalgebra::{Matrix3x4, Matrix4, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The index file of this layout.
pub const CAMERAS: &str = "cameras.npz";
/// The most elements an array of [`CAMERAS`] may have (its matrices are 4x4).
pub const CAMERA_ARRAY_ELEMENTS: u64 = 1024;
/// The ground-truth mesh (world frame).
pub const GT_MESH: &str = "gt/mesh.ply";
const GT_CAMERAS: &str = "gt/cameras.json";
const PNG_SCALE: &str = "png_scale";
const NORMAL_CHANNELS: [&str; 3] = ["N.X", "N.Y", "N.Z"];
const RGB: [&str; 3] = ["R", "G", "B"];

/// One camera of `gt/cameras.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
struct GtCamera {
    name: String,
    split: Split,
    #[serde(rename = "K")]
    k: [[f64; 3]; 3],
    #[serde(rename = "R")]
    r: [[f64; 3]; 3],
    t: [f64; 3],
    width: u32,
    height: u32,
}

impl GtCamera {
    fn camera(&self) -> Camera {
        Camera::new(
            matrix_from_rows(&self.k),
            matrix_from_rows(&self.r),
            Vector3::from(self.t),
            self.width,
            self.height,
        )
    }
}

fn train_file(dir: &Path, folder: &str, index: usize, ext: &str) -> std::path::PathBuf {
    dir.join(folder).join(format!("{index:04}.{ext}"))
}

fn read_matrix4(path: &Path, name: &str, array: &npy::Array<f64>) -> Result<Matrix4<f64>> {
    if array.shape != [4, 4] {
        return Err(Error::format(path, format!("{name} has shape {:?}, expected [4, 4]", array.shape)));
    }
    if let Some(i) = array.data.iter().position(|v| !v.is_finite()) {
        return Err(Error::format(
            path,
            format!("{name} has a non-finite entry ({}) at row {}, column {}", array.data[i], i / 4, i % 4),
        ));
    }
    Ok(Matrix4::from_row_slice(&array.data))
}

/// Read a NeRSP-layout scene.
pub fn read(dir: &Path) -> Result<Scene> {
    let cameras_path = dir.join(CAMERAS);
    let (world_mats, normalization) = read_cameras(&cameras_path)?;
    let count = world_mats.len();

    let gt_path = dir.join(GT_CAMERAS);
    let (gt_cameras, mut metadata) =
        if gt_path.is_file() { read_gt_cameras(&gt_path)? } else { (Vec::new(), serde_json::Map::new()) };
    let png_scale = metadata.remove(PNG_SCALE).and_then(|v| v.as_f64()).unwrap_or(1.0);
    let gt_train: Vec<&GtCamera> = gt_cameras.iter().filter(|c| c.split == Split::Train).collect();
    if !gt_train.is_empty() && gt_train.len() != count {
        return Err(Error::format(&gt_path, format!("{} training cameras, but {CAMERAS} has {count}", gt_train.len())));
    }

    let mut views: Vec<View> = (0..count)
        .into_par_iter()
        .map(|i| read_train_view(dir, i, &world_mats[i], gt_train.get(i).copied(), png_scale))
        .collect::<Result<_>>()?;
    views.extend(
        gt_cameras
            .iter()
            .filter(|c| c.split == Split::Eval)
            .map(|c| View::new(c.name.clone(), Split::Eval, c.camera())),
    );
    views.par_iter_mut().enumerate().try_for_each(|(i, view)| read_ground_truth_images(dir, i, view))?;

    let mesh_path = dir.join(GT_MESH);
    let mesh = mesh_path.is_file().then(|| Mesh::read(&mesh_path)).transpose()?;
    let env_path = dir.join("gt/env.exr");
    let env_map = env_path.is_file().then(|| exr::read_exr(&env_path, &RGB)).transpose()?;
    Ok(Scene { views, normalization, mesh, env_map, metadata })
}

/// The `world_mat_i` (`K [R | t]`, 4x4) of an IDR/NeRSP `cameras.npz`, in order (0-based keys),
/// and the one `scale_mat` they share (identity when absent).
pub fn read_cameras(path: &Path) -> Result<(Vec<Matrix4<f64>>, Matrix4<f64>)> {
    let arrays = read_camera_arrays(path)?;
    let cameras = cameras_by_keys(path, &arrays, (0..).map(|i: usize| i.to_string()))?;
    if cameras.0.is_empty() {
        return Err(Error::format(path, "no world_mat_0"));
    }
    Ok(cameras)
}

/// Every array of a camera file (each at most [`CAMERA_ARRAY_ELEMENTS`]).
pub(crate) fn read_camera_arrays(path: &Path) -> Result<Vec<(String, npy::Array<f64>)>> {
    npy::read_npz_limited::<f64>(path, CAMERA_ARRAY_ELEMENTS)
}

/// `world_mat_<key>` for each key in turn while the file has one, and the `scale_mat_<key>` they
/// share (identity when absent; per-view normalisations are refused). The keys are 0-based
/// indices (NeRSP), 1-based two-digit ones (RMVP3D as PolGS reads it) or file stems (PANDORA).
pub(crate) fn cameras_by_keys(
    path: &Path,
    arrays: &[(String, npy::Array<f64>)],
    keys: impl Iterator<Item = String>,
) -> Result<(Vec<Matrix4<f64>>, Matrix4<f64>)> {
    let lookup = |name: &str| arrays.iter().find(|(n, _)| n == name).map(|(_, a)| a);
    let mut world_mats = Vec::new();
    let mut normalization = None;
    for key in keys {
        let name = format!("world_mat_{key}");
        let Some(array) = lookup(&name) else { break };
        world_mats.push(read_matrix4(path, &name, array)?);
        let scale_name = format!("scale_mat_{key}");
        let scale = match lookup(&scale_name) {
            Some(a) => read_matrix4(path, &scale_name, a)?,
            None => Matrix4::identity(),
        };
        match normalization {
            None => normalization = Some(scale),
            Some(first) if first != scale => {
                return Err(Error::format(
                    path,
                    format!("{scale_name} differs from the first view's scale_mat; per-view normalisations are not supported"),
                ));
            }
            _ => {}
        }
    }
    Ok((world_mats, normalization.unwrap_or_else(Matrix4::identity)))
}

fn read_gt_cameras(path: &Path) -> Result<(Vec<GtCamera>, serde_json::Map<String, serde_json::Value>)> {
    let text = json::read_json_text(path)?;
    let json::RawFields(fields) =
        serde_json::from_str(&text).map_err(|e| Error::format(path, format!("bad JSON: {e}")))?;
    let mut cameras = None;
    let mut metadata = serde_json::Map::new();
    for (key, raw) in fields {
        if key == "cameras" {
            let list: Vec<GtCamera> =
                serde_json::from_str(raw.get()).map_err(|e| Error::format(path, format!("bad camera entry: {e}")))?;
            cameras = Some(list);
        } else {
            let value =
                json::parse_free_form(raw).map_err(|why| Error::format(path, format!("field {key:?}: {why}")))?;
            metadata.insert(key, value);
        }
    }
    let cameras = cameras.ok_or_else(|| Error::format(path, "no \"cameras\" list"))?;
    for camera in &cameras {
        // Names become file names under gt/.
        input::file_name(&camera.name).map_err(|why| Error::format(path, format!("camera {why}")))?;
    }
    Ok((cameras, metadata))
}

fn read_train_view(
    dir: &Path,
    i: usize,
    world_mat: &Matrix4<f64>,
    gt: Option<&GtCamera>,
    png_scale: f64,
) -> Result<View> {
    let read_stokes = |folder: &str| {
        let path = train_file(dir, folder, i, "npy");
        npy::read_npy::<f32>(&path).and_then(|a| image_from_array(&path, a))
    };
    let stokes = Stokes { s0: read_stokes("s0")?, s1: read_stokes("s1")?, s2: read_stokes("s2")? };
    let (w, h) = stokes.s0.size();
    let p: Matrix3x4<f64> = world_mat.fixed_view::<3, 4>(0, 0).into_owned();
    let camera = match gt {
        Some(gt) => {
            let camera = gt.camera();
            let composed = camera.projection();
            let deviation = (composed - p).abs().max() / p.abs().max();
            // Written so that a NaN or infinite world_mat is refused too.
            if deviation.is_nan() || deviation > 1e-9 {
                return Err(Error::format(
                    dir.join(GT_CAMERAS),
                    format!("camera {} disagrees with world_mat_{i} (relative {deviation:.1e})", gt.name),
                ));
            }
            camera
        }
        None => Camera::from_projection(&p, w as u32, h as u32).map_err(|e| e.in_file(dir.join(CAMERAS)))?,
    };
    let name = gt.map_or_else(|| format!("{i:03}"), |g| g.name.clone());
    let mut view = View::new(name, Split::Train, camera);
    view.projection = Some(*world_mat);
    view.stokes = Some(stokes);
    let aop_path = train_file(dir, "input_azimuth_maps", i, "png");
    let (aop, alpha) =
        if aop_path.exists() { read_azimuth_map(&aop_path).map(|(a, m)| (Some(a), m))? } else { (None, None) };
    // Every file of the view has the size of its S0.
    let s0_path = train_file(dir, "s0", i, "npy");
    let sized = |path: &Path, size: (usize, usize)| check_size(path, size, s0_path.display(), (w, h));
    if let Some(aop) = &aop {
        sized(&aop_path, aop.size())?;
    }
    view.aop = aop;
    let mask_path = train_file(dir, "mask", i, "png");
    let mask = training_mask(&mask_path, &aop_path, alpha)?;
    sized(if mask_path.exists() { &mask_path } else { &aop_path }, mask.size())?;
    view.mask = Some(mask);
    let preview_path = train_file(dir, "image", i, "png");
    if preview_path.is_file() {
        view.preview = Some(read_sized(&preview_path, png::read_png_u8, s0_path.display(), (w, h))?);
    }
    let polarizer_path = |deg: u32| dir.join("polarized").join(format!("{i:04}_{deg:03}.png"));
    if polarizer_path(0).is_file() {
        let images: Vec<_> = POLARIZER_ANGLES_DEG
            .iter()
            .map(|&deg| read_sized(&polarizer_path(deg), png::read_png_u16, s0_path.display(), (w, h)))
            .collect::<Result<_>>()?;
        let images = images.try_into().expect("four polarizer angles");
        view.polarized = Some(PolarizerImages { scale: png_scale, images });
    }
    Ok(view)
}

fn read_mask(path: &Path) -> Result<Image<u8>> {
    let mask = png::read_png_u8(path)?;
    Ok(if mask.channels() == 1 { mask } else { mask.channel(0) })
}

/// A training view's mask: `mask/%04d.png` where it exists, else the alpha channel of its azimuth
/// map, which is where the official loader takes it from (it never reads `mask/`). Where both
/// exist they must agree.
fn training_mask(mask_path: &Path, aop_path: &Path, alpha: Option<Image<u8>>) -> Result<Image<u8>> {
    if !mask_path.exists() {
        return alpha.ok_or_else(|| {
            Error::format(mask_path, format!("no mask: no such file, and {} has no alpha channel", aop_path.display()))
        });
    }
    let mask = read_mask(mask_path)?;
    if let Some(alpha) = alpha {
        if alpha.size() == mask.size() {
            let differ = mask.data().iter().zip(alpha.data()).filter(|(m, a)| (**m > 127) != (**a > 127)).count();
            if differ > 0 {
                return Err(Error::format(
                    mask_path,
                    format!(
                        "disagrees at {differ} pixels with the alpha channel of {} (the mask the official loader reads)",
                        aop_path.display()
                    ),
                ));
            }
        }
    }
    Ok(mask)
}

/// AoP from the R channel of an azimuth map (16-bit, 1 to 4 channels), and its alpha channel (2
/// or 4 channels) as an 8-bit mask (non-zero: inside, as the official loader reads it).
fn read_azimuth_map(path: &Path) -> Result<(Image<f32>, Option<Image<u8>>)> {
    let map = png::read_png_u16(path)?;
    if map.channels() >= 3 && map.data().chunks_exact(map.channels()).any(|p| p[0] != p[1] || p[0] != p[2]) {
        return Err(Error::format(path, "azimuth map channels R, G, B differ"));
    }
    let alpha =
        matches!(map.channels(), 2 | 4).then(|| map.channel(map.channels() - 1).map(|a| if a > 0 { 255 } else { 0 }));
    Ok((map.channel(0).map(aop_from_u16), alpha))
}

/// The `gt/` images of a view; `index` is its position (a training view's file number).
fn read_ground_truth_images(dir: &Path, index: usize, view: &mut View) -> Result<()> {
    // The file that sets the view's size: its S0 (training views) or its camera's record.
    let size = (view.camera.width as usize, view.camera.height as usize);
    let reference = match view.split {
        Split::Train => train_file(dir, "s0", index, "npy").display().to_string(),
        Split::Eval => format!("camera {} of {}", view.name, dir.join(GT_CAMERAS).display()),
    };
    let sized = |path: &Path, got: (usize, usize)| check_size(path, got, &reference, size);
    let mask_path = dir.join("gt/mask").join(format!("{}.png", view.name));
    if mask_path.is_file() {
        let mask = read_mask(&mask_path)?;
        sized(&mask_path, mask.size())?;
        match &view.mask {
            Some(existing) if *existing != mask => {
                let train_mask = train_file(dir, "mask", index, "png");
                return Err(Error::format(
                    &train_mask,
                    format!("differs from the ground-truth mask {} (one of the two is damaged)", mask_path.display()),
                ));
            }
            Some(_) => {}
            None => view.mask = Some(mask),
        }
    }
    let normal_path = dir.join("gt/normal").join(format!("{}.exr", view.name));
    if normal_path.is_file() {
        view.normals = Some(read_sized(&normal_path, |p| exr::read_exr(p, &NORMAL_CHANNELS), &reference, size)?);
    }
    let depth_path = dir.join("gt/depth").join(format!("{}.exr", view.name));
    if depth_path.is_file() {
        view.depth = Some(read_sized(&depth_path, |p| exr::read_exr(p, &["Z"]), &reference, size)?);
    }
    Ok(())
}

/// Write a scene in the NeRSP layout. Training views need Stokes and a mask; AoP maps and
/// previews are derived from the Stokes when the view has none.
pub fn write(scene: &Scene, dir: &Path) -> Result<()> {
    let train: Vec<&View> = scene.train_views().collect();
    let scales: Vec<f64> = train.iter().filter_map(|v| v.polarized.as_ref().map(|p| p.scale)).collect();
    if scales.windows(2).any(|w| w[0] != w[1]) {
        return Err(Error::invalid("the NeRSP layout holds one png_scale; views differ"));
    }
    train.par_iter().enumerate().try_for_each(|(i, view)| write_train_view(dir, i, view))?;

    let has_ground_truth =
        scene.views.iter().any(|v| v.split == Split::Eval || v.normals.is_some() || v.depth.is_some())
            || scene.mesh.is_some()
            || scene.env_map.is_some();
    if has_ground_truth {
        scene.views.par_iter().try_for_each(|view| {
            if let Some(mask) = &view.mask {
                png::write_png_u8(&dir.join("gt/mask").join(format!("{}.png", view.name)), mask)?;
            }
            if let Some(normals) = &view.normals {
                exr::write_exr(&dir.join("gt/normal").join(format!("{}.exr", view.name)), normals, &NORMAL_CHANNELS)?;
            }
            if let Some(depth) = &view.depth {
                exr::write_exr(&dir.join("gt/depth").join(format!("{}.exr", view.name)), depth, &["Z"])?;
            }
            Ok::<_, Error>(())
        })?;
        if let Some(mesh) = &scene.mesh {
            mesh.write(&dir.join(GT_MESH))?;
        }
        if let Some(env) = &scene.env_map {
            exr::write_exr(&dir.join("gt/env.exr"), env, &RGB)?;
        }
    }
    let mut json = scene.metadata.clone();
    if let Some(scale) = scales.first() {
        json.insert(PNG_SCALE.into(), (*scale).into());
    }
    let cameras: Vec<GtCamera> = scene
        .views
        .iter()
        .map(|v| GtCamera {
            name: v.name.clone(),
            split: v.split,
            k: matrix_rows(&v.camera.k),
            r: matrix_rows(&v.camera.r),
            t: [v.camera.t.x, v.camera.t.y, v.camera.t.z],
            width: v.camera.width,
            height: v.camera.height,
        })
        .collect();
    json.insert("cameras".into(), serde_json::to_value(cameras).expect("plain data"));
    let text = serde_json::to_string_pretty(&json).expect("plain data");
    write_bytes_atomically(&dir.join(GT_CAMERAS), text.as_bytes())?;

    // The index file last: a folder without it is an incomplete write.
    let keyed = train.iter().enumerate().map(|(i, view)| (i.to_string(), view.projection_matrix()));
    write_cameras(&dir.join(CAMERAS), keyed, &scene.normalization)
}

/// Write a camera file: `world_mat_<key>` and `scale_mat_<key>` (the scene's normalisation) for
/// each `(key, projection)`, row-major as numpy saves them.
pub(crate) fn write_cameras(
    path: &Path,
    keyed: impl Iterator<Item = (String, Matrix4<f64>)>,
    normalization: &Matrix4<f64>,
) -> Result<()> {
    let matrix = |m: &Matrix4<f64>| npy::Array { shape: vec![4, 4], data: m.transpose().as_slice().to_vec() };
    let arrays: Vec<(String, npy::Array<f64>)> = keyed
        .flat_map(|(key, projection)| {
            [(format!("world_mat_{key}"), matrix(&projection)), (format!("scale_mat_{key}"), matrix(normalization))]
        })
        .collect();
    npy::write_npz(path, &arrays)
}

fn write_train_view(dir: &Path, i: usize, view: &View) -> Result<()> {
    let missing = |what: &str| {
        Error::invalid(format!("view {}: the NeRSP layout needs {what} for every training view", view.name))
    };
    let stokes = view.stokes.as_ref().ok_or_else(|| missing("Stokes images"))?;
    let mask = view.mask.as_ref().ok_or_else(|| missing("a mask"))?;
    for (folder, image) in [("s0", &stokes.s0), ("s1", &stokes.s1), ("s2", &stokes.s2)] {
        npy::write_npy(&train_file(dir, folder, i, "npy"), &array_from_image(image))?;
    }
    png::write_png_u8(&train_file(dir, "mask", i, "png"), mask)?;
    let aop = view.aop.clone().unwrap_or_else(|| stokes.aop_dop().0);
    let rgba: Vec<u16> = aop
        .data()
        .iter()
        .zip(mask.data())
        .flat_map(|(&a, &m)| {
            let c = aop_to_u16(a);
            [c, c, c, if m > 127 { u16::MAX } else { 0 }]
        })
        .collect();
    png::write_png_u16(
        &train_file(dir, "input_azimuth_maps", i, "png"),
        &Image::from_vec(aop.width(), aop.height(), 4, rgba)?,
    )?;
    let preview = view.preview.clone().unwrap_or_else(|| visualize::preview(&stokes.s0));
    png::write_png_u8(&train_file(dir, "image", i, "png"), &preview)?;
    if let Some(p) = &view.polarized {
        for (image, deg) in p.images.iter().zip(POLARIZER_ANGLES_DEG) {
            png::write_png_u16(&dir.join("polarized").join(format!("{i:04}_{deg:03}.png")), image)?;
        }
    }
    Ok(())
}
