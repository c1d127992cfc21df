//! `rmvp simulate`: render a synthetic polarized capture of a mesh.

use anyhow::{bail, Context, Result};
use rmvp_capture::sensor::SensorModel;
use rmvp_capture::PixelFormat;
use rmvp_dataset::io::{exr, png, write_bytes_atomically};
use rmvp_dataset::layout::{write_scene, Layout};
use rmvp_dataset::visualize::{aop_picture, contact_sheet, preview, quantile, srgb_to_linear};
use rmvp_dataset::{Image, Mesh, Scene, Split};
use rmvp_render::envmap::procedural_image;
use rmvp_render::pbrdf::{Interface, Lobes};
use rmvp_render::rig::{framing_distance, read_poses, rig_intrinsics, Rig};
use rmvp_render::{default_mesh, render_view, EnvMap, Object, Settings};
use serde_json::json;
use std::path::PathBuf;

/// Arguments of `rmvp simulate`.
#[derive(clap::Args, Clone)]
pub struct Args {
    /// Output folder: `nersp/` and `rmvp/` scene layouts, `camera_normals/`, `contact_sheet.png`,
    /// and with `--raw` the sensor frames in `raw/`.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Mesh to render (PLY or OBJ); default: the built-in "spot".
    #[arg(long)]
    pub mesh: Option<PathBuf>,
    /// Number of views.
    #[arg(long, default_value_t = 6)]
    pub views: usize,
    /// Camera layout: sphere (sparse random views), turntable (rings), or a JSON pose list file.
    #[arg(long, default_value = "sphere")]
    pub rig: String,
    /// Image size WxH (the rig's intrinsics are scaled to it).
    #[arg(long, default_value = "1224x1024")]
    pub res: String,
    /// Samples per pixel.
    #[arg(long, default_value_t = 16)]
    pub spp: u32,
    /// Albedo texture for meshes with texture coordinates: PNG (sRGB) or EXR (linear RGB).
    #[arg(long)]
    pub texture: Option<PathBuf>,
    /// Lat-long environment map (EXR, top row +Y); default: a built-in studio environment.
    #[arg(long)]
    pub env: Option<PathBuf>,
    /// Also write the raw sensor frames the polarization camera would send.
    #[arg(long)]
    pub raw: bool,
    /// Seed of every random choice (views, samples, noise).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Relative refractive index of the dielectric surface.
    #[arg(long, default_value_t = 1.5)]
    pub eta: f32,
    /// Render a conductor of complex index N + iK instead ("N,K", e.g. gold at 600 nm "0.25,3.0").
    #[arg(long, value_parser = super::parse_numbers::<2>)]
    pub conductor: Option<[f32; 2]>,
    /// Layouts to write: both, nersp or rmvp.
    #[arg(long, default_value = "both")]
    pub layout: String,
}

fn parse_res(res: &str) -> Result<(u32, u32)> {
    let (w, h) = res.split_once('x').context("--res must be WIDTHxHEIGHT, e.g. 1224x1024")?;
    let (w, h): (u32, u32) = (w.parse()?, h.parse()?);
    if w < 4 || h < 4 || w % 2 != 0 || h % 2 != 0 {
        bail!("--res {res}: width and height must be even and at least 4");
    }
    Ok((w, h))
}

/// Run the command; returns the scene it wrote.
pub fn run(args: Args) -> Result<()> {
    simulate(&args).map(|_| ())
}

/// Render and write the capture; returns the scene.
pub fn simulate(args: &Args) -> Result<Scene> {
    let (width, height) = parse_res(&args.res)?;
    let (mesh, mesh_name) = match &args.mesh {
        Some(path) => {
            (Mesh::read(path)?, path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default())
        }
        None => (default_mesh(), "spot (built-in)".to_string()),
    };
    let env_image = match &args.env {
        Some(path) => exr::read_exr(path, &["R", "G", "B"])?,
        None => procedural_image(),
    };
    let env = EnvMap::new(&env_image).with_context(|| format!("environment map {:?}", args.env))?;
    let interface = match &args.conductor {
        Some(nk) => Interface::Conductor(nk[0], nk[1]),
        None => Interface::Dielectric(args.eta),
    };
    let mut object = Object::new(&mesh, interface, Lobes::Plastic)?;
    if let Some(path) = &args.texture {
        object.set_albedo_texture(read_texture(path)?).with_context(|| format!("texture {}", path.display()))?;
    }
    let k = rig_intrinsics(width, height);
    let radius = mesh.radius() as f64;
    let distance = framing_distance(&k, width, height, radius, 0.85);
    let cameras = match args.rig.as_str() {
        "sphere" => Rig::Sphere { views: args.views }.cameras(k, width, height, distance, args.seed),
        "turntable" => Rig::Turntable { views: args.views, elevations: vec![10.0, 35.0] }
            .cameras(k, width, height, distance, args.seed),
        file => read_poses(std::path::Path::new(file), k, width, height)?,
    };
    let settings = Settings { spp: args.spp, seed: args.seed };
    let bar = super::progress(cameras.len() as u64, "render");
    bar.set_message(format!("{width}x{height}, {} spp", args.spp));
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
        let normal_picture = render.normals.map(|v| ((v * 0.5 + 0.5) * 255.0).round() as u8);
        let (aop, dop) = render.stokes.aop_dop();
        tiles.extend([preview(&render.stokes.s0), aop_picture(&aop, &dop, Some(&render.mask)), normal_picture]);
        let to_camera = camera.r.cast::<f32>();
        let camera_normals: Vec<f32> = render
            .normals
            .data()
            .chunks_exact(3)
            .flat_map(|n| {
                let c = to_camera * nalgebra::Vector3::new(n[0], n[1], n[2]);
                [c.x, c.y, c.z]
            })
            .collect();
        let camera_normals = Image::from_vec(render.normals.width(), render.normals.height(), 3, camera_normals)?;
        exr::write_exr(
            &args.output.join("camera_normals").join(format!("{i:03}.exr")),
            &camera_normals,
            &["N.X", "N.Y", "N.Z"],
        )?;
        scene.views.push(render.into_view(format!("{i:03}"), Split::Train, camera.clone(), scale));
    }
    // IDR/NeuS scale_mat: a sphere 10 % larger than the object's bounding sphere about the
    // origin, so that reconstruction's unit sphere encloses it with a margin.
    scene.normalization = nalgebra::Matrix4::new_scaling(1.1 * radius);
    scene.mesh = Some(mesh);
    scene.env_map = Some(env_image);
    scene.metadata = json!({
        "generator": format!("rmvp simulate {}", env!("CARGO_PKG_VERSION")),
        "mesh": mesh_name,
        "material": if args.conductor.is_some() { "conductor" } else { "pplastic" },
        "eta": args.eta,
        "conductor": args.conductor,
        "spp": args.spp,
        "seed": args.seed,
        "rig": args.rig,
        "environment": args.env.as_ref().map_or("built-in".into(), |p| p.display().to_string()),
    })
    .as_object()
    .cloned()
    .expect("object");

    let layouts: &[(Layout, &str)] = match args.layout.as_str() {
        "both" => &[(Layout::Nersp, "nersp"), (Layout::Canonical, "rmvp")],
        "nersp" => &[(Layout::Nersp, "nersp")],
        "rmvp" => &[(Layout::Canonical, "rmvp")],
        other => bail!("unknown --layout {other:?}: both, nersp or rmvp"),
    };
    for (layout, folder) in layouts {
        write_scene(&scene, &args.output.join(folder), *layout)?;
    }
    if args.raw {
        write_raw_frames(&scene, &args.output.join("raw"), args.seed)?;
    }
    let sheet = contact_sheet(&tiles.iter().map(|t| shrink_to(t, 256)).collect::<Vec<_>>(), 3);
    png::write_png_u8(&args.output.join("contact_sheet.png"), &sheet)?;
    println!(
        "rendered {} views of {mesh_name} at {width}x{height}, {} spp -> {}",
        scene.views.len(),
        args.spp,
        args.output.display()
    );
    println!("  contact_sheet.png: per view S0 | AoP (hue) x DoP | normals");
    Ok(scene)
}

/// Expose every view's Stokes on the sensor model (exposure chosen so that the brightest
/// object pixels reach 80 % of full scale) and write `DIR/<view>.raw` (BayerRGPolarized12p,
/// twice the image size), `DIR/dark.raw` (a black frame) and `DIR/sensor.json`.
fn write_raw_frames(scene: &Scene, dir: &std::path::Path, seed: u64) -> Result<()> {
    let mut model = SensorModel::default();
    let polarized = scene.views.iter().filter_map(|v| v.polarized.as_ref()).next().context("no rendered view")?;
    model.exposure = 0.8 * polarized.scale as f32;
    let format = PixelFormat::BAYER_RG_POLARIZED_12P;
    let bar = super::progress(scene.views.len() as u64, "raw");
    for (i, view) in scene.views.iter().enumerate() {
        let stokes = view.stokes.as_ref().context("rendered view without Stokes")?;
        model.expose(stokes, seed, i as u32).write(&dir.join(format!("{}.raw", view.name)), format)?;
        bar.inc(1);
    }
    let (w, h) = (scene.views[0].camera.width as usize, scene.views[0].camera.height as usize);
    model.dark_frame(w, h, seed).write(&dir.join("dark.raw"), format)?;
    let description = json!({
        "pixel_format": format.name(),
        "width": 2 * w,
        "height": 2 * h,
        "model": model,
        "stokes_gain": model.stokes_gain(),
        "note": "processed Stokes (dark frame subtracted) / stokes_gain = rendered Stokes",
    });
    write_bytes_atomically(&dir.join("sensor.json"), serde_json::to_string_pretty(&description)?.as_bytes())?;
    bar.finish_with_message(format!("raw frames in {}", dir.display()));
    Ok(())
}

/// A linear RGB texture: EXR channels R, G, B as they are; PNG samples sRGB-decoded.
fn read_texture(path: &std::path::Path) -> Result<Image<f32>> {
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
        return Ok(exr::read_exr(path, &["R", "G", "B"])?);
    }
    let linear = match png::read_png(path)? {
        png::PngImage::U8(i) => i.map(|v| srgb_to_linear(v as f32 / 255.0)),
        png::PngImage::U16(i) => i.map(|v| srgb_to_linear(v as f32 / 65535.0)),
    };
    if linear.channels() < 3 {
        bail!("{}: an albedo texture must be RGB", path.display());
    }
    Ok(linear)
}

/// Shrink a picture by an integer factor so that its width is at most `max_width`.
fn shrink_to(image: &Image<u8>, max_width: usize) -> Image<u8> {
    rmvp_dataset::visualize::downsample(image, image.width().div_ceil(max_width))
}
