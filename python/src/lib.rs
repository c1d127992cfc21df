//! `rmvp._rmvp`, the native half of the `rmvp` Python package: each function a thin layer over
//! the crates. Scenes cross as dictionaries of numpy arrays (the package's `Scene` and `View`
//! wrap them), options as the JSON of `rmvp recon`'s [`ReconOptions`], errors as the
//! exceptions of `rmvp.errors` by kind, naming the file.

use nalgebra::Matrix4;
use numpy::{IntoPyArray, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use rmvp_capture::demosaic::DemosaicMethod;
use rmvp_capture::{FrameProcessor, PixelFormat, RawFrame};
use rmvp_dataset::camera::CameraRecord;
use rmvp_dataset::layout::{self, Layout};
use rmvp_dataset::mesh::Mesh;
use rmvp_dataset::{Camera, Image, PolarizerImages, Scene, Split, Stokes, View};
use rmvp_recon::options::{ReconOptions, RunControl};
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

/// The kinds of `rmvp.errors`, one class each.
#[derive(Clone, Copy)]
enum Kind {
    /// A file or array that is broken, hostile or not what it should be.
    Input,
    /// A file or folder that does not exist.
    MissingFile,
    /// An option no run can take.
    Option,
    /// Anything else.
    Other,
}

/// The Python exception of `kind` carrying `message` and, where known, the file.
fn error(py: Python<'_>, kind: Kind, message: String, path: Option<&Path>) -> PyErr {
    let class = match kind {
        Kind::Input => "InputError",
        Kind::MissingFile => "MissingFileError",
        Kind::Option => "OptionError",
        Kind::Other => "RmvpError",
    };
    let raised = || -> PyResult<PyErr> {
        let exception = py.import("rmvp.errors")?.getattr(class)?.call1((message.clone(),))?;
        exception.setattr("path", path.map(|p| p.display().to_string()))?;
        Ok(PyErr::from_value(exception))
    };
    raised().unwrap_or_else(|e| e)
}

/// The exception of a dataset error: the kind and the file it names.
fn dataset_error(py: Python<'_>, e: rmvp_dataset::Error) -> PyErr {
    use rmvp_dataset::Error as E;
    let message = e.to_string();
    match &e {
        E::Io { path, source } if source.kind() == std::io::ErrorKind::NotFound => {
            error(py, Kind::MissingFile, message, Some(path))
        }
        E::Io { path, .. } | E::Format { path, .. } | E::ImageTooLarge { path, .. } => {
            error(py, Kind::Input, message, Some(path))
        }
        E::Invalid(_) => error(py, Kind::Input, message, None),
    }
}

/// The exception of a reconstruction error.
fn recon_error(py: Python<'_>, e: rmvp_recon::Error) -> PyErr {
    use rmvp_recon::Error as E;
    let message = e.to_string();
    match e {
        E::Dataset(e) => dataset_error(py, e),
        E::InvalidOption(_) | E::BothCuesOff => error(py, Kind::Option, message, None),
        E::CheckpointSettings { path, .. } => error(py, Kind::Option, message, Some(&path)),
        E::BadCheckpoint { path, .. } => error(py, Kind::Input, message, Some(&path)),
        E::NoSurface | E::Cuda(_) => error(py, Kind::Other, message, None),
        _ => error(py, Kind::Input, message, None),
    }
}

/// The exception of an alignment or evaluation error.
fn align_error(py: Python<'_>, e: rmvp_align::Error) -> PyErr {
    match e {
        rmvp_align::Error::Dataset(e) => dataset_error(py, e),
        other => error(py, Kind::Input, other.to_string(), None),
    }
}

/// The exception of a frame-processing error.
fn capture_error(py: Python<'_>, e: rmvp_capture::Error) -> PyErr {
    match e {
        rmvp_capture::Error::Dataset(e) => dataset_error(py, e),
        rmvp_capture::Error::Unsupported(m) => error(py, Kind::Option, m, None),
        other => error(py, Kind::Input, other.to_string(), None),
    }
}

/// An image as a numpy array, its buffer moved, not copied: `(height, width)` for one channel,
/// `(height, width, channels)` otherwise.
fn image_array<'py, T: numpy::Element + Copy>(py: Python<'py>, image: Image<T>) -> PyResult<Bound<'py, PyAny>> {
    let (w, h) = image.size();
    let c = image.channels();
    let flat = image.into_vec().into_pyarray(py);
    Ok(if c == 1 { flat.reshape([h, w])?.into_any() } else { flat.reshape([h, w, c])?.into_any() })
}

/// A numpy array `(height, width[, channels])` of `T` as an image (`what` names it in errors).
fn array_image<T: numpy::Element + Copy + Default>(
    py: Python<'_>,
    array: &Bound<'_, PyAny>,
    what: &str,
) -> PyResult<Image<T>> {
    let array: PyReadonlyArrayDyn<'_, T> = array.extract().map_err(|_| {
        let want = std::any::type_name::<T>();
        error(py, Kind::Input, format!("{what}: expected a numpy array of {want}"), None)
    })?;
    let shape = array.shape().to_vec();
    let (h, w, c) = match shape[..] {
        [h, w] => (h, w, 1),
        [h, w, c] => (h, w, c),
        _ => {
            return Err(error(py, Kind::Input, format!("{what}: shape {shape:?}, expected (H, W) or (H, W, C)"), None))
        }
    };
    let data: Vec<T> = array.as_array().iter().cloned().collect();
    Image::from_vec(w, h, c, data).map_err(|e| dataset_error(py, e))
}

/// A 2-D numpy array of `f64` from a row-major matrix.
fn matrix<'py, const R: usize, const C: usize>(py: Python<'py>, rows: [[f64; C]; R]) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f64> = rows.iter().flatten().copied().collect();
    Ok(flat.into_pyarray(py).reshape([R, C])?.into_any())
}

/// A numpy array's values as a fixed-size row-major matrix (`what` names it in errors).
fn rows<const R: usize, const C: usize>(
    py: Python<'_>,
    array: &Bound<'_, PyAny>,
    what: &str,
) -> PyResult<[[f64; C]; R]> {
    let array: PyReadonlyArrayDyn<'_, f64> = array
        .extract()
        .map_err(|_| error(py, Kind::Input, format!("{what}: expected a numpy array of float64"), None))?;
    let values: Vec<f64> = array.as_array().iter().copied().collect();
    if values.len() != R * C {
        let shape = array.shape().to_vec();
        return Err(error(py, Kind::Input, format!("{what}: shape {shape:?}, expected ({R}, {C})"), None));
    }
    Ok(std::array::from_fn(|r| std::array::from_fn(|c| values[r * C + c])))
}

/// `dict[key]`, or None where absent or None.
fn item<'py>(dict: &Bound<'py, PyDict>, key: &str) -> PyResult<Option<Bound<'py, PyAny>>> {
    Ok(dict.get_item(key)?.filter(|v| !v.is_none()))
}

/// `dict[key]`, required (`what` names the dictionary in errors).
fn required<'py>(py: Python<'py>, dict: &Bound<'py, PyDict>, key: &str, what: &str) -> PyResult<Bound<'py, PyAny>> {
    item(dict, key)?.ok_or_else(|| error(py, Kind::Input, format!("{what}: no {key:?}"), None))
}

/// A view as a dictionary of numpy arrays (the package's `View`).
fn view_dict<'py>(py: Python<'py>, view: View) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let record = CameraRecord::from(&view.camera);
    d.set_item("name", &view.name)?;
    d.set_item("split", if view.split == Split::Train { "train" } else { "eval" })?;
    d.set_item("K", matrix(py, record.k)?)?;
    d.set_item("R", matrix(py, record.r)?)?;
    d.set_item("t", record.t.to_vec().into_pyarray(py))?;
    d.set_item("width", record.width)?;
    d.set_item("height", record.height)?;
    let distortion = record.distortion.map(|k| vec![k.k1, k.k2, k.p1, k.p2, k.k3].into_pyarray(py));
    d.set_item("distortion", distortion)?;
    if let Some(Stokes { s0, s1, s2 }) = view.stokes {
        d.set_item("s0", image_array(py, s0)?)?;
        d.set_item("s1", image_array(py, s1)?)?;
        d.set_item("s2", image_array(py, s2)?)?;
    }
    for (key, image) in [("aop", view.aop), ("dop", view.dop), ("normals", view.normals), ("depth", view.depth)] {
        if let Some(image) = image {
            d.set_item(key, image_array(py, image)?)?;
        }
    }
    if let Some(mask) = view.mask {
        d.set_item("mask", image_array(py, mask)?)?;
    }
    if let Some(polarized) = view.polarized {
        let (w, h) = polarized.images[0].size();
        let c = polarized.images[0].channels();
        let flat: Vec<u16> = polarized.images.into_iter().flat_map(Image::into_vec).collect();
        let array = flat.into_pyarray(py);
        let array = if c == 1 { array.reshape([4, h, w])?.into_any() } else { array.reshape([4, h, w, c])?.into_any() };
        d.set_item("polarized", array)?;
        d.set_item("polarized_scale", polarized.scale)?;
    }
    if let Some(projection) = view.projection {
        let rows: [[f64; 4]; 4] = std::array::from_fn(|r| std::array::from_fn(|c| projection[(r, c)]));
        d.set_item("projection", matrix(py, rows)?)?;
    }
    Ok(d)
}

/// A view from the dictionary of [`view_dict`].
fn dict_view(py: Python<'_>, d: &Bound<'_, PyDict>) -> PyResult<View> {
    let name: String = required(py, d, "name", "a view")?.extract()?;
    let what = |field: &str| format!("view {name}: {field}");
    let split = match required(py, d, "split", &name)?.extract::<String>()?.as_str() {
        "train" => Split::Train,
        "eval" => Split::Eval,
        other => return Err(error(py, Kind::Input, format!("view {name}: split {other:?}, not train or eval"), None)),
    };
    let k = rows::<3, 3>(py, &required(py, d, "K", &name)?, &what("K"))?;
    let r = rows::<3, 3>(py, &required(py, d, "R", &name)?, &what("R"))?;
    let t = rows::<1, 3>(py, &required(py, d, "t", &name)?, &what("t"))?[0];
    let width: u32 = required(py, d, "width", &name)?.extract()?;
    let height: u32 = required(py, d, "height", &name)?.extract()?;
    let distortion = match item(d, "distortion")? {
        Some(values) => {
            let [k1, k2, p1, p2, k3] = rows::<1, 5>(py, &values, &what("distortion"))?[0];
            Some(rmvp_dataset::Distortion { k1, k2, p1, p2, k3 })
        }
        None => None,
    };
    let record = CameraRecord { k, r, t, width, height, distortion };
    let camera = Camera::try_from(&record).map_err(|e| {
        let message = format!("view {name}: {e}");
        error(py, Kind::Input, message, None)
    })?;
    let mut view = View::new(name.clone(), split, camera);
    let image = |key: &str| -> PyResult<Option<Image<f32>>> {
        item(d, key)?.map(|a| array_image::<f32>(py, &a, &what(key))).transpose()
    };
    if let (Some(s0), Some(s1), Some(s2)) = (image("s0")?, image("s1")?, image("s2")?) {
        view.stokes = Some(Stokes { s0, s1, s2 });
    }
    view.aop = image("aop")?;
    view.dop = image("dop")?;
    view.normals = image("normals")?;
    view.depth = image("depth")?;
    view.mask = item(d, "mask")?.map(|a| array_image::<u8>(py, &a, &what("mask"))).transpose()?;
    if let Some(array) = item(d, "polarized")? {
        let stacked: PyReadonlyArrayDyn<'_, u16> = array
            .extract()
            .map_err(|_| error(py, Kind::Input, format!("{}: expected uint16", what("polarized")), None))?;
        let shape = stacked.shape().to_vec();
        let (h, w, c) = match shape[..] {
            [4, h, w] => (h, w, 1),
            [4, h, w, c] => (h, w, c),
            _ => {
                let message = format!("{}: shape {shape:?}, expected (4, H, W[, C])", what("polarized"));
                return Err(error(py, Kind::Input, message, None));
            }
        };
        let values: Vec<u16> = stacked.as_array().iter().copied().collect();
        let plane = w * h * c;
        let images: [Image<u16>; 4] = std::array::from_fn(|i| {
            Image::from_vec(w, h, c, values[i * plane..(i + 1) * plane].to_vec()).expect("sized to fit")
        });
        let scale: f64 = required(py, d, "polarized_scale", &name)?.extract()?;
        view.polarized = Some(PolarizerImages { scale, images });
    }
    if let Some(p) = item(d, "projection")? {
        view.projection = Some(Matrix4::from(rows::<4, 4>(py, &p, &what("projection"))?).transpose());
    }
    Ok(view)
}

/// A scene as a dictionary (the package's `Scene`): `views`, `normalization` (4x4),
/// `mesh` (`vertices`, `faces`) where the scene has a ground-truth mesh, `metadata` (JSON).
fn scene_dict<'py>(py: Python<'py>, scene: Scene) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let n = scene.normalization;
    let normalization: [[f64; 4]; 4] = std::array::from_fn(|r| std::array::from_fn(|c| n[(r, c)]));
    d.set_item("normalization", matrix(py, normalization)?)?;
    d.set_item("metadata", serde_json::Value::Object(scene.metadata).to_string())?;
    if let Some(mesh) = scene.mesh {
        d.set_item("mesh", mesh_dict(py, &mesh)?)?;
    }
    let views = PyList::empty(py);
    for view in scene.views {
        views.append(view_dict(py, view)?)?;
    }
    d.set_item("views", views)?;
    Ok(d)
}

/// A mesh as `vertices` (n x 3 float32) and `faces` (m x 3 uint32).
fn mesh_dict<'py>(py: Python<'py>, mesh: &Mesh) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let vertices: Vec<f32> = mesh.positions.iter().flatten().copied().collect();
    let faces: Vec<u32> = mesh.faces.iter().flatten().copied().collect();
    d.set_item("vertices", vertices.into_pyarray(py).reshape([mesh.positions.len(), 3])?)?;
    d.set_item("faces", faces.into_pyarray(py).reshape([mesh.faces.len(), 3])?)?;
    Ok(d)
}

/// The scene of the dictionary of [`scene_dict`].
fn dict_scene(py: Python<'_>, d: &Bound<'_, PyDict>) -> PyResult<Scene> {
    let mut scene = Scene::new();
    if let Some(n) = item(d, "normalization")? {
        scene.normalization = Matrix4::from(rows::<4, 4>(py, &n, "the scene's normalization")?).transpose();
    }
    if let Some(text) = item(d, "metadata")? {
        let text: String = text.extract()?;
        scene.metadata = serde_json::from_str(&text)
            .map_err(|e| error(py, Kind::Input, format!("the scene's metadata: {e}"), None))?;
    }
    if let Some(mesh) = item(d, "mesh")? {
        let mesh = mesh.cast::<PyDict>()?;
        let vertices = array_image::<f32>(py, &required(py, mesh, "vertices", "the mesh")?, "the mesh's vertices")?;
        let faces = array_image::<u32>(py, &required(py, mesh, "faces", "the mesh")?, "the mesh's faces")?;
        if vertices.width() != 3 || faces.width() != 3 {
            return Err(error(py, Kind::Input, "the mesh: vertices and faces must be (n, 3)".into(), None));
        }
        let positions = vertices.data().chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect();
        let faces = faces.data().chunks_exact(3).map(|f| [f[0], f[1], f[2]]).collect();
        scene.mesh = Some(Mesh { positions, normals: None, faces, vertex_properties: Vec::new() });
    }
    for view in required(py, d, "views", "the scene")?.try_iter()? {
        scene.views.push(dict_view(py, view?.cast::<PyDict>()?)?);
    }
    scene.validate().map_err(|e| dataset_error(py, e))?;
    Ok(scene)
}

/// A scene given as a folder (read in any layout) or as the dictionary of [`scene_dict`].
fn any_scene(py: Python<'_>, scene: &Bound<'_, PyAny>) -> PyResult<Scene> {
    match scene.cast::<PyDict>() {
        Ok(d) => dict_scene(py, d),
        Err(_) => {
            let dir: PathBuf = scene.extract()?;
            py.detach(|| layout::read_scene(&dir)).map_err(|e| dataset_error(py, e))
        }
    }
}

/// The layout called `name` (`nersp`, `rmvp`, `rmvp3d`, `pandora`).
fn layout_named(py: Python<'_>, name: &str) -> PyResult<Layout> {
    Layout::ALL.into_iter().find(|l| l.name() == name).ok_or_else(|| {
        let names: Vec<&str> = Layout::ALL.iter().map(|l| l.name()).collect();
        error(py, Kind::Option, format!("layout {name:?}: one of {}", names.join(", ")), None)
    })
}

/// The scene in folder `path`, its layout detected, as a dictionary; and the layout's name.
#[pyfunction]
fn read_scene<'py>(py: Python<'py>, path: PathBuf) -> PyResult<(Bound<'py, PyDict>, &'static str)> {
    let (scene, layout) = py
        .detach(|| Layout::detect(&path).and_then(|layout| Ok((layout::read_scene(&path)?, layout))))
        .map_err(|e| dataset_error(py, e))?;
    Ok((scene_dict(py, scene)?, layout.name()))
}

/// Check the `sha256sum`-style listing `root/listing` against the files under `root`: the
/// files that matched and every fault (each naming its file).
#[pyfunction]
fn check_listing(py: Python<'_>, root: PathBuf, listing: &str) -> PyResult<(usize, Vec<String>)> {
    let check =
        py.detach(|| rmvp_dataset::checksums::check_listing(&root, listing)).map_err(|e| dataset_error(py, e))?;
    Ok((check.matched, check.faults))
}

/// Write `scene` (a dictionary or a folder) into `path` in `layout`.
#[pyfunction]
fn write_scene(py: Python<'_>, scene: &Bound<'_, PyAny>, path: PathBuf, layout: &str) -> PyResult<()> {
    let layout = layout_named(py, layout)?;
    let scene = any_scene(py, scene)?;
    py.detach(|| layout::write_scene(&scene, &path, layout)).map_err(|e| dataset_error(py, e))
}

/// Copy the scene in `source` into the new folder `destination` in `layout`, its AoP mirrored
/// with `mirror_aop`.
#[pyfunction]
#[pyo3(signature = (source, destination, layout, mirror_aop=false))]
fn convert(py: Python<'_>, source: PathBuf, destination: PathBuf, layout: &str, mirror_aop: bool) -> PyResult<()> {
    let layout = layout_named(py, layout)?;
    py.detach(|| layout::convert_scene(&source, &destination, layout, mirror_aop))
        .map(drop)
        .map_err(|e| dataset_error(py, e))
}

/// A raw frame file (`.png` mosaic or bare buffer in `pixel_format` and size) as a `(H, W)`
/// uint16 array of samples, and their significant bits.
#[pyfunction]
fn read_raw<'py>(
    py: Python<'py>,
    path: PathBuf,
    pixel_format: &str,
    width: usize,
    height: usize,
) -> PyResult<(Bound<'py, PyAny>, u8)> {
    let format = PixelFormat::from_name(pixel_format).map_err(|e| capture_error(py, e))?;
    let frame = py.detach(|| RawFrame::read(&path, format, width, height)).map_err(|e| capture_error(py, e))?;
    Ok((image_array(py, frame.pixels)?, frame.bits))
}

/// One raw mosaic (`(H, W)` uint16 samples of `pixel_format`'s bits) processed as `rmvp
/// demosaic` does: the four polarizer images, Stokes in units of full scale, AoP, DoP, and the
/// saturated angles per pixel.
#[pyfunction]
#[pyo3(signature = (raw, pixel_format, method=None, saturation_aware=false))]
fn demosaic<'py>(
    py: Python<'py>,
    raw: &Bound<'py, PyAny>,
    pixel_format: &str,
    method: Option<&str>,
    saturation_aware: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let format = PixelFormat::from_name(pixel_format).map_err(|e| capture_error(py, e))?;
    let pixels = array_image::<u16>(py, raw, "the raw frame")?;
    if pixels.channels() != 1 {
        return Err(error(py, Kind::Input, "the raw frame: a mosaic has one channel".into(), None));
    }
    let method = match method {
        None | Some("bilinear") => DemosaicMethod::Bilinear,
        Some("edge-aware") => DemosaicMethod::EdgeAware,
        Some("vng") => DemosaicMethod::Vng,
        Some(other) => {
            let message = format!("method {other:?}: one of bilinear, edge-aware, vng");
            return Err(error(py, Kind::Option, message, None));
        }
    };
    let frame = RawFrame { layout: format.family.layout(), bits: format.bits, pixels };
    if let Some(&max) = frame.pixels.data().iter().max().filter(|&&m| m > frame.full_scale()) {
        let message = format!("the raw frame: sample {max} exceeds {}'s {} bits", format.name(), format.bits);
        return Err(error(py, Kind::Input, message, None));
    }
    let processor = FrameProcessor { method, saturation_aware, ..FrameProcessor::default() };
    let out = py.detach(|| processor.process(&frame)).map_err(|e| capture_error(py, e))?;
    let d = PyDict::new(py);
    let (w, h) = out.angles[0].size();
    let c = out.angles[0].channels();
    let angles: Vec<u16> = out.angles.into_iter().flat_map(Image::into_vec).collect();
    let angles = angles.into_pyarray(py);
    d.set_item(
        "angles",
        if c == 1 { angles.reshape([4, h, w])?.into_any() } else { angles.reshape([4, h, w, c])?.into_any() },
    )?;
    let Stokes { s0, s1, s2 } = out.estimate.stokes;
    d.set_item("s0", image_array(py, s0)?)?;
    d.set_item("s1", image_array(py, s1)?)?;
    d.set_item("s2", image_array(py, s2)?)?;
    d.set_item("aop", image_array(py, out.aop)?)?;
    d.set_item("dop", image_array(py, out.dop)?)?;
    d.set_item("saturated", image_array(py, out.estimate.saturated)?)?;
    d.set_item("bits", out.bits)?;
    Ok(d)
}

/// Stokes S0, S1, S2 from four images behind polarizers at 0, 45, 90 and 135 degrees (float32,
/// one shape), and the AoP and DoP of their channel mean.
#[pyfunction]
fn stokes<'py>(
    py: Python<'py>,
    i0: &Bound<'py, PyAny>,
    i45: &Bound<'py, PyAny>,
    i90: &Bound<'py, PyAny>,
    i135: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyDict>> {
    let images = [(i0, "i0"), (i45, "i45"), (i90, "i90"), (i135, "i135")]
        .map(|(a, what)| array_image::<f32>(py, a, what))
        .into_iter()
        .collect::<PyResult<Vec<_>>>()?;
    let stokes = Stokes::from_polarizer_images([&images[0], &images[1], &images[2], &images[3]])
        .map_err(|e| dataset_error(py, e))?;
    let (aop, dop) = stokes.aop_dop();
    let d = PyDict::new(py);
    let Stokes { s0, s1, s2 } = stokes;
    d.set_item("s0", image_array(py, s0)?)?;
    d.set_item("s1", image_array(py, s1)?)?;
    d.set_item("s2", image_array(py, s2)?)?;
    d.set_item("aop", image_array(py, aop)?)?;
    d.set_item("dop", image_array(py, dop)?)?;
    Ok(d)
}

/// The tangents the AoP of each pixel of `view` (a dictionary with its camera and `aop`) gives,
/// as the geometric cue takes them ([`rmvp_recon::geometric::aop_tangents`]): `t = d x e` and
/// the polarization direction `e`, world frame, each `(H, W, 3)` float64.
#[pyfunction]
fn aop_tangents<'py>(py: Python<'py>, view: &Bound<'py, PyDict>) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let view = dict_view(py, view)?;
    let aop = view.aop.ok_or_else(|| error(py, Kind::Input, format!("view {}: no AoP", view.name), None))?;
    let camera = &view.camera;
    let (w, h) = (camera.width as usize, camera.height as usize);
    if aop.size() != (w, h) {
        let message = format!("view {}: the AoP is {:?}, the camera {w}x{h}", view.name, aop.size());
        return Err(error(py, Kind::Input, message, None));
    }
    let (mut t, mut e): (Vec<f64>, Vec<f64>) = (Vec::with_capacity(3 * w * h), Vec::with_capacity(3 * w * h));
    for (k, &angle) in aop.data().iter().enumerate() {
        let ray = camera.pixel_ray((k % w) as u32, (k / w) as u32);
        let (tk, ek) = rmvp_recon::geometric::aop_tangents(camera, &ray.direction, angle);
        t.extend(tk.iter());
        e.extend(ek.iter());
    }
    Ok((t.into_pyarray(py).reshape([h, w, 3])?.into_any(), e.into_pyarray(py).reshape([h, w, 3])?.into_any()))
}

/// Reconstruct `scene` (a folder or a dictionary) into `output` with `options` (the JSON of
/// `rmvp recon`'s options by field name). `on_step(report)` is called after every iteration
/// with the step's report as JSON; Ctrl-C (or an exception from `on_step`) stops the run after
/// the iteration under way, checkpointed (continue with `resume`), and is raised. Returns the
/// iterations done and the run's length.
#[pyfunction]
#[pyo3(signature = (scene, output, options, on_step=None, resume=false, stop_after=None))]
fn reconstruct(
    py: Python<'_>,
    scene: &Bound<'_, PyAny>,
    output: PathBuf,
    options: &str,
    on_step: Option<Py<PyAny>>,
    resume: bool,
    stop_after: Option<u32>,
) -> PyResult<(u32, u32)> {
    let options = serde_json::from_str(options)
        .map_err(|e| e.to_string())
        .and_then(ReconOptions::from_recorded)
        .map_err(|e| error(py, Kind::Option, format!("options: {e}"), None))?;
    let scene = any_scene(py, scene)?;
    let control = RunControl { resume, stop_after };
    let mut raised: Option<PyErr> = None;
    let run = py.detach(|| {
        rmvp_recon::reconstruct::reconstruct(&scene, &output, &options, control, |report, _| {
            Python::attach(|py| {
                let called = py.check_signals().and_then(|()| match &on_step {
                    Some(f) => {
                        let json = serde_json::to_string(report).expect("a report serialises");
                        f.call1(py, (json,)).map(drop)
                    }
                    None => Ok(()),
                });
                match called {
                    Ok(()) => ControlFlow::Continue(()),
                    Err(e) => {
                        raised = Some(e);
                        ControlFlow::Break(())
                    }
                }
            })
        })
    });
    let trainer = run.map_err(|e| recon_error(py, e))?;
    if let Some(e) = raised {
        return Err(e);
    }
    Ok((trainer.iteration, trainer.config.iterations))
}

/// Surface figures (accuracy, completeness, Chamfer, F-score) of the mesh file `pred` against
/// `gt`, and with `scene` (a folder with ground-truth normals) the normal error per view; as
/// `rmvp eval --json` writes them.
#[pyfunction]
#[pyo3(signature = (pred, gt, scene=None, error_maps=None))]
fn evaluate(
    py: Python<'_>,
    pred: PathBuf,
    gt: PathBuf,
    scene: Option<PathBuf>,
    error_maps: Option<PathBuf>,
) -> PyResult<String> {
    let run = || -> Result<String, rmvp_align::Error> {
        let read = rmvp_align::surface::read_surface;
        let (pred, gt) = (read(&pred)?, read(&gt)?);
        let scene = scene.map(|dir| layout::read_scene(&dir)).transpose()?;
        let evaluation = rmvp_align::evaluate(&pred, &gt, scene.as_ref(), &rmvp_align::SurfaceOptions::default())?;
        if let Some(dir) = error_maps {
            evaluation.write_error_maps(&dir)?;
        }
        Ok(evaluation.to_json())
    };
    py.detach(run).map_err(|e| align_error(py, e))
}

/// Align the mesh file `scan` onto `target` by a similarity (ICP with scale), as `rmvp align`
/// does, writing the aligned scan and `alignment.json` into `output`; returns that JSON.
#[pyfunction]
fn align(py: Python<'_>, scan: PathBuf, target: PathBuf, output: PathBuf) -> PyResult<String> {
    let run = || -> Result<String, rmvp_align::Error> {
        let alignment = rmvp_align::align_files(&scan, &target, &output, &rmvp_align::IcpOptions::default())?;
        Ok(serde_json::to_string(&alignment).expect("an alignment serialises"))
    };
    py.detach(run).map_err(|e| align_error(py, e))
}

/// The module.
#[pymodule]
fn _rmvp(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(read_scene, m)?)?;
    m.add_function(wrap_pyfunction!(check_listing, m)?)?;
    m.add_function(wrap_pyfunction!(write_scene, m)?)?;
    m.add_function(wrap_pyfunction!(convert, m)?)?;
    m.add_function(wrap_pyfunction!(read_raw, m)?)?;
    m.add_function(wrap_pyfunction!(demosaic, m)?)?;
    m.add_function(wrap_pyfunction!(stokes, m)?)?;
    m.add_function(wrap_pyfunction!(aop_tangents, m)?)?;
    m.add_function(wrap_pyfunction!(reconstruct, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(align, m)?)?;
    Ok(())
}
