//! Our layout (`rmvp`): a versioned JSON manifest and one folder per view.
//!
//! ```text
//! scene.json                       manifest (format "rmvp-scene", version 1)
//! views/<name>/stokes.exr          S0.R S0.G S0.B S1.R ... (float32; S0 S1 S2 for mono)
//! views/<name>/mask.png            8-bit mask
//! views/<name>/aop.exr dop.exr     AoP (radians, channel "AoP"), DoP (channel "DoP")
//! views/<name>/normal.exr          world-frame ground-truth normals (N.X N.Y N.Z)
//! views/<name>/depth.exr           ground-truth z-depth (Z)
//! views/<name>/polarizer_000.png   16-bit polarizer images (scale in the manifest), 045, 090, 135
//! views/<name>/preview.png         8-bit preview
//! mesh.ply env.exr                 ground-truth mesh and environment map
//! ```

use super::{check_size, read_sized};
use crate::camera::CameraRecord;
use crate::io::{exr, input, json, png, write_bytes_atomically};
use crate::polarization::POLARIZER_ANGLES_DEG;
use crate::{Camera, Error, Image, Mesh, PolarizerImages, Result, Scene, Split, Stokes, View};
use nalgebra::Matrix4;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The index file of this layout.
pub const MANIFEST: &str = "scene.json";
/// The `format` field of the manifest.
pub const FORMAT: &str = "rmvp-scene";
/// The manifest version this code writes and the newest it reads.
pub const VERSION: u32 = 1;

/// The manifest, `scene.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SceneManifest {
    /// Always [`FORMAT`].
    pub format: String,
    /// Layout version, at most [`VERSION`].
    pub version: u32,
    /// Unit sphere to world (IDR `scale_mat`), row-major.
    pub normalization: [[f64; 4]; 4],
    /// Every view.
    pub views: Vec<SceneViewRecord>,
    /// Ground-truth mesh file, relative to the scene folder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mesh: Option<String>,
    /// Environment map file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub env_map: Option<String>,
    /// Provenance (free-form, at most [`json::MAX_FREE_FORM_BYTES`]).
    #[serde(default, skip_serializing_if = "serde_json::Map::is_empty", deserialize_with = "json::free_form")]
    pub metadata: serde_json::Map<String, serde_json::Value>,
}

/// One view in the manifest; file names are relative to the scene folder.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SceneViewRecord {
    /// View name.
    pub name: String,
    /// Train or eval.
    pub split: Split,
    /// Calibration.
    pub camera: CameraRecord,
    /// Verbatim 4x4 projection from the source, row-major.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub projection: Option<[[f64; 4]; 4]>,
    /// Image files.
    #[serde(default)]
    pub files: ViewFiles,
    /// Scale of the polarizer images, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub polarizer_scale: Option<f64>,
}

/// The image files of a view.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct ViewFiles {
    /// Stokes EXR.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stokes: Option<String>,
    /// Mask PNG.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mask: Option<String>,
    /// AoP EXR.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aop: Option<String>,
    /// DoP EXR.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dop: Option<String>,
    /// Normal EXR.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normal: Option<String>,
    /// Depth EXR (channel Z).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth: Option<String>,
    /// Polarizer PNGs at 0, 45, 90, 135 degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub polarizers: Option<[String; 4]>,
    /// Preview PNG.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preview: Option<String>,
}

fn stokes_channels(channels: usize) -> Vec<String> {
    let suffixes: &[&str] = if channels == 1 { &[""] } else { &[".R", ".G", ".B"] };
    ["S0", "S1", "S2"].iter().flat_map(|s| suffixes.iter().map(move |c| format!("{s}{c}"))).collect()
}

fn rows4(m: &Matrix4<f64>) -> [[f64; 4]; 4] {
    [0, 1, 2, 3].map(|i| [0, 1, 2, 3].map(|j| m[(i, j)]))
}

fn from_rows4(r: &[[f64; 4]; 4]) -> Matrix4<f64> {
    Matrix4::from_fn(|i, j| r[i][j])
}

/// Read a scene's manifest (`scene.json`) in our layout, its format, version and view names
/// checked; no image is read.
pub fn read_manifest(dir: &Path) -> Result<SceneManifest> {
    let path = dir.join(MANIFEST);
    let text = json::read_json_text(&path)?;
    let manifest: SceneManifest =
        serde_json::from_str(&text).map_err(|e| Error::format(&path, format!("bad manifest: {e}")))?;
    if manifest.format != FORMAT {
        return Err(Error::format(&path, format!("format is {:?}, expected {FORMAT:?}", manifest.format)));
    }
    if manifest.version > VERSION {
        return Err(Error::format(
            &path,
            format!("version {} is newer than this program reads ({VERSION})", manifest.version),
        ));
    }
    for record in &manifest.views {
        input::file_name(&record.name).map_err(|why| Error::format(&path, format!("view {why}")))?;
    }
    Ok(manifest)
}

/// Read a scene in our layout.
pub fn read(dir: &Path) -> Result<Scene> {
    let path = dir.join(MANIFEST);
    let manifest = read_manifest(dir)?;
    let file = |relative: &String| input::inside(dir, relative).map_err(|why| Error::format(&path, why));
    let views = manifest
        .views
        .par_iter()
        .map(|record| read_view(record, &path, &file).map_err(|e| e.in_file(&path)))
        .collect::<Result<_>>()?;
    let mesh = manifest.mesh.as_ref().map(|f| Mesh::read(&file(f)?)).transpose()?;
    let env_map = manifest.env_map.as_ref().map(|f| exr::read_exr(&file(f)?, &["R", "G", "B"])).transpose()?;
    Ok(Scene { views, normalization: from_rows4(&manifest.normalization), mesh, env_map, metadata: manifest.metadata })
}

/// One view of the manifest (`manifest`); `file` resolves a path of the manifest inside the
/// scene folder. Every image has the size of the view's camera.
fn read_view(
    record: &SceneViewRecord,
    manifest: &Path,
    file: &(impl Fn(&String) -> Result<std::path::PathBuf> + Sync),
) -> Result<View> {
    let camera = Camera::try_from(&record.camera).map_err(|e| Error::invalid(format!("view {}: {e}", record.name)))?;
    let size = (camera.width as usize, camera.height as usize);
    let reference = format!("the camera of view {} in {}", record.name, manifest.display());
    let sized = |name: &String, read: fn(&Path) -> Result<Image<f32>>| read_sized(&file(name)?, read, &reference, size);
    let mut view = View::new(record.name.clone(), record.split, camera);
    view.projection = record.projection.as_ref().map(from_rows4);
    let f = &record.files;
    if let Some(name) = &f.stokes {
        let path = file(name)?;
        let stokes = read_stokes(&path)?;
        check_size(&path, stokes.s0.size(), &reference, size)?;
        view.stokes = Some(stokes);
    }
    if let Some(name) = &f.mask {
        view.mask = Some(read_sized(&file(name)?, png::read_png_u8, &reference, size)?);
    }
    if let Some(name) = &f.aop {
        view.aop = Some(sized(name, |p| exr::read_exr(p, &["AoP"]))?);
    }
    if let Some(name) = &f.dop {
        view.dop = Some(sized(name, |p| exr::read_exr(p, &["DoP"]))?);
    }
    if let Some(name) = &f.normal {
        view.normals = Some(sized(name, |p| exr::read_exr(p, &["N.X", "N.Y", "N.Z"]))?);
    }
    if let Some(name) = &f.depth {
        view.depth = Some(sized(name, |p| exr::read_exr(p, &["Z"]))?);
    }
    if let Some(files) = &f.polarizers {
        let images: Vec<_> = files
            .iter()
            .map(|name| read_sized(&file(name)?, png::read_png_u16, &reference, size))
            .collect::<Result<_>>()?;
        let scale = record.polarizer_scale.unwrap_or(1.0);
        view.polarized = Some(PolarizerImages { scale, images: images.try_into().expect("four polarizer angles") });
    }
    if let Some(name) = &f.preview {
        view.preview = Some(read_sized(&file(name)?, png::read_png_u8, &reference, size)?);
    }
    Ok(view)
}

/// Read Stokes images from one EXR file with channels `S0.R S0.G S0.B S1.R ...` (RGB) or
/// `S0 S1 S2` (mono).
pub fn read_stokes(path: &Path) -> Result<Stokes> {
    let (_, _, channels) = exr::read_exr_channels(path)?;
    let per_component = if channels.iter().any(|(n, _)| n == "S0.R") { 3 } else { 1 };
    let names = stokes_channels(per_component);
    let all = exr::read_exr(path, &names.iter().map(String::as_str).collect::<Vec<_>>())?;
    let component = |k: usize| {
        let planes: Vec<Image<f32>> = (0..per_component).map(|c| all.channel(k * per_component + c)).collect();
        interleave(&planes)
    };
    Ok(Stokes { s0: component(0), s1: component(1), s2: component(2) })
}

/// Write Stokes images (1 or 3 channels each) to one EXR file, as [`read_stokes`] reads them.
pub fn write_stokes(path: &Path, s: &Stokes) -> Result<()> {
    let per_component = s.s0.channels();
    let planes: Vec<Image<f32>> =
        [&s.s0, &s.s1, &s.s2].iter().flat_map(|img| (0..per_component).map(|c| img.channel(c))).collect();
    let names = stokes_channels(per_component);
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    exr::write_exr(path, &interleave(&planes), &names)
}

/// Interleave single-channel planes of one size into one image.
fn interleave(planes: &[Image<f32>]) -> Image<f32> {
    let (w, h) = planes[0].size();
    let data = (0..w * h).flat_map(|p| planes.iter().map(move |plane| plane.data()[p])).collect();
    Image::from_vec(w, h, planes.len(), data).expect("planes of one size")
}

/// Write a scene in our layout; `scene.json` is written last.
pub fn write(scene: &Scene, dir: &Path) -> Result<()> {
    let views = scene.views.par_iter().map(|view| write_view(dir, view)).collect::<Result<Vec<_>>>()?;
    let mesh =
        scene.mesh.as_ref().map(|m| m.write(&dir.join("mesh.ply")).map(|_| "mesh.ply".to_string())).transpose()?;
    let env_map = scene
        .env_map
        .as_ref()
        .map(|e| exr::write_exr(&dir.join("env.exr"), e, &["R", "G", "B"]).map(|_| "env.exr".to_string()))
        .transpose()?;
    let manifest = SceneManifest {
        format: FORMAT.into(),
        version: VERSION,
        normalization: rows4(&scene.normalization),
        views,
        mesh,
        env_map,
        metadata: scene.metadata.clone(),
    };
    let text = serde_json::to_string_pretty(&manifest).expect("plain data");
    write_bytes_atomically(&dir.join(MANIFEST), text.as_bytes())
}

fn write_view(dir: &Path, view: &View) -> Result<SceneViewRecord> {
    let folder = format!("views/{}", view.name);
    let mut files = ViewFiles::default();
    let put = |name: &str, write: &dyn Fn(&Path) -> Result<()>| -> Result<Option<String>> {
        let relative = format!("{folder}/{name}");
        write(&dir.join(&relative))?;
        Ok(Some(relative))
    };
    if let Some(s) = &view.stokes {
        files.stokes = put("stokes.exr", &|p| write_stokes(p, s))?;
    }
    if let Some(m) = &view.mask {
        files.mask = put("mask.png", &|p| png::write_png_u8(p, m))?;
    }
    if let Some(a) = &view.aop {
        files.aop = put("aop.exr", &|p| exr::write_exr(p, a, &["AoP"]))?;
    }
    if let Some(d) = &view.dop {
        files.dop = put("dop.exr", &|p| exr::write_exr(p, d, &["DoP"]))?;
    }
    if let Some(n) = &view.normals {
        files.normal = put("normal.exr", &|p| exr::write_exr(p, n, &["N.X", "N.Y", "N.Z"]))?;
    }
    if let Some(d) = &view.depth {
        files.depth = put("depth.exr", &|p| exr::write_exr(p, d, &["Z"]))?;
    }
    if let Some(pol) = &view.polarized {
        let mut names = Vec::with_capacity(4);
        for (image, deg) in pol.images.iter().zip(POLARIZER_ANGLES_DEG) {
            names.push(put(&format!("polarizer_{deg:03}.png"), &|p| png::write_png_u16(p, image))?.expect("written"));
        }
        files.polarizers = Some(names.try_into().expect("four angles"));
    }
    if let Some(p) = &view.preview {
        files.preview = put("preview.png", &|path| png::write_png_u8(path, p))?;
    }
    Ok(SceneViewRecord {
        name: view.name.clone(),
        split: view.split,
        camera: CameraRecord::from(&view.camera),
        projection: view.projection.as_ref().map(rows4),
        files,
        polarizer_scale: view.polarized.as_ref().map(|p| p.scale),
    })
}
