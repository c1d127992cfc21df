//! Ground truth from a mesh in a scene's frame: per view, the normal map, mask and depth map
//! that ray casting the mesh gives (what a dataset needs once a scan is aligned to it), in the
//! scene ([`set_ground_truth`]) or as files ([`write_ground_truth_maps`]).

use crate::Result;
use rmvp_dataset::io::{exr, png};
use rmvp_dataset::progress::progress_bar;
use rmvp_dataset::visualize::normal_picture;
use rmvp_dataset::{Image, Mesh, Scene};
use rmvp_render::{geometry_maps, Object};
use std::path::Path;

/// Normals and depth of `mesh` in every view of `scene`, the mesh as the scene's ground truth;
/// returns each view's IoU of its own mask with the mesh's silhouette (0 without a mask), and
/// the view's name.
pub fn set_ground_truth(scene: &mut Scene, mesh: &Mesh) -> Result<Vec<(f64, String)>> {
    let object = Object::geometry(mesh)?;
    let ious = scene
        .views
        .iter_mut()
        .map(|view| {
            let maps = geometry_maps(&object, &view.camera);
            let iou = view.mask.as_ref().map_or(0.0, |m| mask_iou(m, &maps.mask));
            view.normals = Some(maps.normals);
            view.depth = Some(maps.depth);
            (iou, view.name.clone())
        })
        .collect();
    scene.mesh = Some(mesh.clone());
    Ok(ious)
}

/// Intersection over union of two masks (> 127 is inside).
pub fn mask_iou(a: &Image<u8>, b: &Image<u8>) -> f64 {
    let (mut inter, mut union) = (0usize, 0usize);
    for (x, y) in a.data().iter().zip(b.data()) {
        inter += usize::from(*x > 127 && *y > 127);
        union += usize::from(*x > 127 || *y > 127);
    }
    if union == 0 {
        1.0
    } else {
        inter as f64 / union as f64
    }
}

/// Ray cast `mesh` in every view of `scene` and write `DIR/<view>_normal.exr` (world frame,
/// N.X N.Y N.Z), `<view>_normal.png`, `<view>_mask.png` and `<view>_depth.exr` (Z).
pub fn write_ground_truth_maps(mesh: &Mesh, scene: &Scene, dir: &Path, progress: bool) -> Result<()> {
    let object = Object::geometry(mesh)?;
    let bar = progress_bar(progress, scene.views.len() as u64, "normals");
    for view in &scene.views {
        let maps = geometry_maps(&object, &view.camera);
        let file = |suffix: &str| dir.join(format!("{}_{suffix}", view.name));
        exr::write_exr(&file("normal.exr"), &maps.normals, &["N.X", "N.Y", "N.Z"])?;
        png::write_png_u8(&file("normal.png"), &normal_picture(&maps.normals))?;
        png::write_png_u8(&file("mask.png"), &maps.mask)?;
        exr::write_exr(&file("depth.exr"), &maps.depth, &["Z"])?;
        bar.inc(1);
    }
    bar.finish();
    Ok(())
}
