//! `rmvp info SCENE [--json]`.

use anyhow::Result;
use rmvp_dataset::layout::{read_scene, Layout};
use rmvp_dataset::{Scene, View};
use serde_json::{json, Value};
use std::path::PathBuf;

/// Arguments of `rmvp info`.
#[derive(clap::Args)]
pub struct Args {
    /// Scene folder (NeRSP or rmvp layout).
    scene: PathBuf,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
}

fn contents(view: &View) -> Vec<&'static str> {
    [
        (view.stokes.is_some(), "stokes"),
        (view.mask.is_some(), "mask"),
        (view.aop.is_some(), "aop"),
        (view.dop.is_some(), "dop"),
        (view.polarized.is_some(), "polarizers"),
        (view.preview.is_some(), "preview"),
        (view.normals.is_some(), "normals"),
        (view.depth.is_some(), "depth"),
    ]
    .into_iter()
    .filter_map(|(present, name)| present.then_some(name))
    .collect()
}

fn summary(scene: &Scene, layout: Layout) -> Value {
    let views: Vec<Value> = scene
        .views
        .iter()
        .map(|v| {
            let c = &v.camera;
            let mask_fraction =
                v.mask.as_ref().map(|m| m.data().iter().filter(|&&x| x > 127).count() as f64 / m.data().len() as f64);
            json!({
                "name": v.name,
                "split": v.split,
                "size": [c.width, c.height],
                "focal_px": [c.k[(0, 0)], c.k[(1, 1)]],
                "center": [c.center().x, c.center().y, c.center().z],
                "mask_fraction": mask_fraction,
                "contents": contents(v),
            })
        })
        .collect();
    let mesh = scene
        .mesh
        .as_ref()
        .map(|m| json!({"vertices": m.positions.len(), "triangles": m.faces.len(), "bounds": m.bounds()}));
    let env = scene.env_map.as_ref().map(|e| json!({"size": [e.width(), e.height()]}));
    json!({
        "layout": layout.name(),
        "views": views,
        "train_views": scene.train_views().count(),
        "normalization": (0..4).map(|i| (0..4).map(|j| scene.normalization[(i, j)]).collect::<Vec<_>>()).collect::<Vec<_>>(),
        "mesh": mesh,
        "env_map": env,
        "metadata": scene.metadata,
        "valid": true,
    })
}

/// Run the command: read and validate the scene, then summarise it. An invalid scene is an error.
pub fn run(args: Args) -> Result<()> {
    let layout = Layout::detect(&args.scene)?;
    let scene = read_scene(&args.scene)?;
    let s = summary(&scene, layout);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&s)?);
        return Ok(());
    }
    println!("scene   {} ({} layout), valid", args.scene.display(), layout.name());
    println!(
        "views   {} ({} train, {} eval)",
        scene.views.len(),
        s["train_views"],
        scene.views.len() as u64 - s["train_views"].as_u64().unwrap_or(0)
    );
    for v in s["views"].as_array().into_iter().flatten() {
        let center: Vec<f64> = serde_json::from_value(v["center"].clone())?;
        let contents: Vec<String> = serde_json::from_value(v["contents"].clone())?;
        println!(
            "  {:<6} {:<5} {}x{}  f {:.1} px  centre ({:+.3}, {:+.3}, {:+.3})  mask {:>5.1}%  {}",
            v["name"].as_str().unwrap_or("?"),
            v["split"].as_str().unwrap_or("?"),
            v["size"][0],
            v["size"][1],
            v["focal_px"][0].as_f64().unwrap_or(0.0),
            center[0],
            center[1],
            center[2],
            v["mask_fraction"].as_f64().map_or(f64::NAN, |f| 100.0 * f),
            contents.join(" ")
        );
    }
    if let Some(m) = &scene.mesh {
        println!("mesh    {} vertices, {} triangles", m.positions.len(), m.faces.len());
    }
    if let Some(e) = &scene.env_map {
        println!("env map {}x{}", e.width(), e.height());
    }
    for (k, v) in &scene.metadata {
        if !v.is_object() {
            println!("meta    {k} = {v}");
        }
    }
    Ok(())
}
