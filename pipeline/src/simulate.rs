//! A simulated polarized capture of a mesh: rendered Stokes, masks, depth and normals in every
//! view, written in the scene layouts, with a contact sheet and, on request, the raw sensor
//! frames the polarization camera would send.
//!
//! ```text
//! nersp/                 the capture in the NeRSP layout, with gt/ (mesh, env, normals, depth, masks)
//! rmvp/                  the same in our layout
//! camera_normals/NNN.exr normals in each camera's OpenCV frame (N.X N.Y N.Z)
//! contact_sheet.png      per view: S0 preview | AoP (hue) x DoP | normals
//! raw/NNN.raw            with `raw`: BayerRGPolarized12p frames (twice the image size)
//! raw/dark.raw           a black frame of the same sensor (black level, read noise)
//! raw/sensor.json        the frames' [`SensorRecord`]
//! ```

use crate::{Error, Result};
use rmvp_capture::sensor::{SensorModel, SensorRecord, SENSOR_FILE};
use rmvp_capture::PixelFormat;
use rmvp_dataset::io::picture::read_picture;
use rmvp_dataset::io::{exr, png};
use rmvp_dataset::layout::{write_scene, Layout};
use rmvp_dataset::progress::progress_bar;
use rmvp_dataset::visualize::{aop_picture, contact_sheet, downsample, normal_picture, preview, quantile};
use rmvp_dataset::{Image, Mesh, Scene, Split};
use rmvp_render::envmap::procedural_image;
use rmvp_render::pbrdf::{Interface, Lobes};
use rmvp_render::rig::{framing_distance, read_poses, rig_intrinsics, RigKind};
use rmvp_render::{default_mesh, render_view, EnvMap, Object, Settings};
use std::path::{Path, PathBuf};

/// The object fills this fraction of the narrower field of view.
const FRAMING: f64 = 0.85;
/// The normalisation sphere (`scale_mat`) is this much larger than the object's bounding
/// sphere, so that reconstruction's unit sphere encloses it with a margin.
pub(crate) const NORMALIZATION_MARGIN: f64 = 1.1;
/// The widest tile of the contact sheet, pixels.
const SHEET_TILE_WIDTH: usize = 256;

/// What to simulate; [`SimulateOptions::default`] holds every default of `rmvp simulate`.
#[derive(Clone, Debug, PartialEq)]
pub struct SimulateOptions {
    /// Output folder.
    pub output: PathBuf,
    /// Mesh to render (PLY, OBJ or STL); `None`: the built-in "spot".
    pub mesh: Option<PathBuf>,
    /// Number of views (of the rig; a pose list has its own).
    pub views: usize,
    /// Held-out views rendered after the training views (`Split::Eval`, ground truth only):
    /// random directions on the sphere, drawn with another seed than the training rig's.
    pub eval_views: usize,
    /// Where the cameras are.
    pub rig: RigKind,
    /// A JSON pose list replacing the rig ([`rmvp_render::rig::read_poses`]).
    pub poses: Option<PathBuf>,
    /// Image size (even; the rig's intrinsics are scaled to it).
    pub size: (u32, u32),
    /// Samples per pixel.
    pub spp: u32,
    /// Lat-long environment map (EXR, top row +Y); `None`: the built-in studio.
    pub env: Option<PathBuf>,
    /// Albedo texture for meshes with texture coordinates: PNG (sRGB) or EXR (linear RGB).
    pub texture: Option<PathBuf>,
    /// The surface's optics.
    pub interface: Interface,
    /// Also write the raw sensor frames.
    pub raw: bool,
    /// Seed of every random choice (views, samples, noise).
    pub seed: u64,
    /// Layouts to write (each into its own folder, named after it).
    pub layouts: Vec<Layout>,
    /// Show progress bars.
    pub progress: bool,
}

impl Default for SimulateOptions {
    fn default() -> Self {
        Self {
            output: PathBuf::from("simulated"),
            mesh: None,
            views: 6,
            eval_views: 0,
            rig: RigKind::Sphere,
            poses: None,
            size: rmvp_render::rig::SENSOR_SIZE,
            spp: 16,
            env: None,
            texture: None,
            interface: Interface::Dielectric(Interface::DEFAULT_ETA),
            raw: false,
            seed: 0,
            layouts: vec![Layout::Nersp, Layout::Rmvp],
            progress: true,
        }
    }
}

/// Mixed into the seed of the held-out views' rig, so that they differ from the training views.
const EVAL_SEED: u64 = 0x5eed_e7a1;

/// The name of the built-in mesh in records.
pub const BUILT_IN_MESH: &str = "spot (built-in)";
/// The folder of the raw frames in a simulation's output.
pub const RAW_FOLDER: &str = "raw";
/// The dark frame among the raw frames.
pub const DARK_FRAME: &str = "dark.raw";
/// The pixel format of simulated raw frames.
pub const RAW_FORMAT: PixelFormat = PixelFormat::BAYER_RG_POLARIZED_12P;

/// Render and write the capture; returns the scene (with its ground truth).
pub fn simulate(options: &SimulateOptions) -> Result<Scene> {
    let (width, height) = options.size;
    if width < 4 || height < 4 || !width.is_multiple_of(2) || !height.is_multiple_of(2) {
        return Err(Error::ImageSize { width, height });
    }
    if options.layouts.is_empty() {
        return Err(Error::NoLayout);
    }
    let (mesh, mesh_name) = match &options.mesh {
        Some(path) => {
            (Mesh::read(path)?, path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default())
        }
        None => (default_mesh(), BUILT_IN_MESH.to_string()),
    };
    let env_image = match &options.env {
        Some(path) => exr::read_exr(path, &["R", "G", "B"])?,
        None => procedural_image(),
    };
    let env = EnvMap::new(&env_image).map_err(|source| Error::Environment { path: options.env.clone(), source })?;
    let mut object = Object::new(&mesh, options.interface, Lobes::Plastic)?;
    if let Some(path) = &options.texture {
        object
            .set_albedo_texture(read_texture(path)?)
            .map_err(|source| Error::Texture { path: path.clone(), source })?;
    }
    let k = rig_intrinsics(width, height);
    let radius = mesh.radius() as f64;
    let distance = framing_distance(&k, width, height, radius, FRAMING);
    let mut cameras = match &options.poses {
        Some(path) => read_poses(path, k, width, height)?,
        None => options.rig.rig(options.views).cameras(k, width, height, distance, options.seed),
    };
    let train_views = cameras.len();
    let eval_seed = options.seed ^ EVAL_SEED;
    cameras.extend(RigKind::Sphere.rig(options.eval_views).cameras(k, width, height, distance, eval_seed));
    let settings = Settings { spp: options.spp, seed: options.seed };
    let bar = progress_bar(options.progress, cameras.len() as u64, "render");
    bar.set_message(format!("{width}x{height}, {} spp", options.spp));
    let renders: Vec<_> = cameras
        .iter()
        .enumerate()
        .map(|(i, camera)| {
            let r = render_view(&object, &env, camera, settings, i as u32);
            bar.inc(1);
            r
        })
        .collect();
    bar.finish();
    // One polarizer-image scale for the capture: its brightest 0.1 % of object pixels clip.
    let object_s0: Vec<f32> = renders
        .iter()
        .flat_map(|r| {
            r.stokes.s0.data().chunks_exact(3).zip(r.mask.data()).filter(|(_, &m)| m > 0).flat_map(|(p, _)| p.to_vec())
        })
        .collect();
    let scale = 1.0 / quantile(&object_s0, 0.999).max(1e-6) as f64;

    let mut tiles = Vec::new();
    let mut scene = Scene::new();
    for (i, (render, camera)) in renders.into_iter().zip(&cameras).enumerate() {
        let (aop, dop) = render.stokes.aop_dop();
        tiles.extend([
            preview(&render.stokes.s0),
            aop_picture(&aop, &dop, Some(&render.mask)),
            normal_picture(&render.normals),
        ]);
        exr::write_exr(
            &options.output.join("camera_normals").join(format!("{i:03}.exr")),
            &camera_frame_normals(&render.normals, camera),
            &["N.X", "N.Y", "N.Z"],
        )?;
        let split = if i < train_views { Split::Train } else { Split::Eval };
        let mut view = render.into_view(format!("{i:03}"), split, camera.clone(), scale);
        if split == Split::Eval {
            // Held out: ground truth (mask, depth, normals) only, as the NeRSP layout keeps it.
            (view.stokes, view.polarized, view.aop, view.dop, view.preview) = (None, None, None, None, None);
        }
        scene.views.push(view);
    }
    scene.normalization = nalgebra::Matrix4::new_scaling(NORMALIZATION_MARGIN * radius);
    scene.mesh = Some(mesh);
    scene.env_map = Some(env_image);
    scene.metadata = serde_json::json!({
        "generator": format!("rmvp simulate {}", env!("CARGO_PKG_VERSION")),
        "mesh": mesh_name,
        "material": match options.interface { Interface::Conductor(..) => "conductor", Interface::Dielectric(_) => "pplastic" },
        "eta": match options.interface { Interface::Dielectric(eta) => Some(eta), Interface::Conductor(..) => None },
        "conductor": match options.interface { Interface::Conductor(n, k) => Some([n, k]), Interface::Dielectric(_) => None },
        "spp": options.spp,
        "eval_views": options.eval_views,
        "seed": options.seed,
        "rig": options.poses.as_ref().map_or_else(|| format!("{:?}", options.rig).to_lowercase(), |p| p.display().to_string()),
        "environment": options.env.as_ref().map_or("built-in".into(), |p| p.display().to_string()),
    })
    .as_object()
    .cloned()
    .expect("object");

    for layout in &options.layouts {
        write_scene(&scene, &options.output.join(layout.name()), *layout)?;
    }
    if options.raw {
        write_raw_frames(&scene, &options.output.join(RAW_FOLDER), options.seed, options.progress)?;
    }
    let tiles: Vec<Image<u8>> = tiles.iter().map(|t| downsample(t, t.width().div_ceil(SHEET_TILE_WIDTH))).collect();
    png::write_png_u8(&options.output.join("contact_sheet.png"), &contact_sheet(&tiles, 3))?;
    Ok(scene)
}

/// World normals turned into the camera's OpenCV frame.
fn camera_frame_normals(normals: &Image<f32>, camera: &rmvp_dataset::Camera) -> Image<f32> {
    let to_camera = camera.r.cast::<f32>();
    let data = normals
        .data()
        .chunks_exact(3)
        .flat_map(|n| {
            let c = to_camera * nalgebra::Vector3::new(n[0], n[1], n[2]);
            [c.x, c.y, c.z]
        })
        .collect();
    Image::from_vec(normals.width(), normals.height(), 3, data).expect("size kept")
}

/// Expose every training view's Stokes on the sensor model (exposure chosen so that the brightest
/// object pixels reach 80 % of full scale) and write `DIR/<view>.raw` (twice the image size),
/// `DIR/dark.raw` (a black frame) and `DIR/sensor.json`.
fn write_raw_frames(scene: &Scene, dir: &Path, seed: u64, progress: bool) -> Result<()> {
    let mut model = SensorModel::default();
    let polarized = scene.views.iter().find_map(|v| v.polarized.as_ref()).expect("rendered views");
    model.exposure = 0.8 * polarized.scale as f32;
    let train = scene.views.iter().filter(|v| v.split == Split::Train).count();
    let bar = progress_bar(progress, train as u64, "raw");
    for (i, view) in scene.views.iter().enumerate().filter(|(_, v)| v.split == Split::Train) {
        let stokes = view.stokes.as_ref().expect("rendered training views have Stokes");
        model.expose(stokes, seed, i as u32).write(&dir.join(format!("{}.raw", view.name)), RAW_FORMAT)?;
        bar.inc(1);
    }
    let (w, h) = (scene.views[0].camera.width as usize, scene.views[0].camera.height as usize);
    model.dark_frame(w, h, seed).write(&dir.join(DARK_FRAME), RAW_FORMAT)?;
    SensorRecord::new(model, RAW_FORMAT, 2 * w, 2 * h).write(&dir.join(SENSOR_FILE))?;
    bar.finish();
    Ok(())
}

/// A linear RGB texture ([`read_picture`]'s rule: 8-bit samples sRGB-decoded, the others linear).
fn read_texture(path: &Path) -> Result<Image<f32>> {
    Ok(read_picture(path)?.pixels.into_linear())
}
