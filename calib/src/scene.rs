//! Posed, masked views of a session as a [`Scene`]: each view's Stokes, its pose and its mask,
//! training views named, and the normalisation from the visual hull.

use crate::masks::MASKS_FOLDER;
use crate::normalization::visual_hull_sphere;
use crate::pictures::read_view_stokes;
use crate::poses::PoseSet;
use crate::{Error, Result};
use rayon::prelude::*;
use rmvp_dataset::io::png;
use rmvp_dataset::session::SessionManifest;
use rmvp_dataset::{Camera, Scene, Split, View};
use std::path::Path;

/// The scene of the session in `dir` with `poses` and the masks in `masks` (`<view>.png`;
/// `None`: the session's `masks/`): every view that has both; those in `train` are training
/// views, the others evaluation views. The normalisation encloses the visual hull.
pub fn posed_scene(dir: &Path, poses: &PoseSet, masks: Option<&Path>, train: &[String]) -> Result<Scene> {
    let manifest = SessionManifest::read(dir)?;
    manifest.require_views(dir)?;
    let masks = masks.map_or_else(|| dir.join(MASKS_FOLDER), Path::to_path_buf);
    let missing: Vec<&String> = train.iter().filter(|t| poses.camera(t).is_none()).collect();
    if !missing.is_empty() {
        return Err(Error::MaskInput(format!("training views without a pose: {missing:?}")));
    }
    let views: Vec<View> = manifest
        .views
        .par_iter()
        .filter_map(|v| poses.camera(&v.name).map(|camera| (v, camera)))
        .map(|(v, camera): (_, Camera)| {
            let split = if train.contains(&v.name) { Split::Train } else { Split::Eval };
            let mut view = View::new(v.name.clone(), split, camera);
            view.stokes = Some(read_view_stokes(dir, v)?);
            view.mask = Some(png::read_png_u8(&masks.join(format!("{}.png", v.name)))?.channel(0));
            Ok(view)
        })
        .collect::<Result<_>>()?;
    let hull: Vec<(Camera, rmvp_dataset::Image<u8>)> =
        views.iter().map(|v| (v.camera.clone(), v.mask.clone().expect("set above"))).collect();
    let sphere = visual_hull_sphere(&hull)?;
    let mut scene = Scene::new();
    scene.views = views;
    scene.normalization = sphere.scale_mat();
    scene.metadata.insert("object".into(), manifest.object.clone().into());
    scene.metadata.insert("poses".into(), serde_json::to_value(poses.method).expect("plain"));
    scene.metadata.insert("world".into(), poses.world.clone().into());
    scene.validate()?;
    Ok(scene)
}
