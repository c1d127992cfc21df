//! Ground truth from a mesh in a scene's frame: per view, the normal map, mask and depth map
//! that ray casting the mesh gives (what a dataset needs once a scan is aligned to it).

use crate::Result;
use rmvp_dataset::io::{exr, png};
use rmvp_dataset::progress::progress_bar;
use rmvp_dataset::visualize::normal_picture;
use rmvp_dataset::{Mesh, Scene};
use rmvp_render::pbrdf::{Interface, Lobes};
use rmvp_render::{geometry_maps, Object};
use std::path::Path;

/// Ray cast `mesh` in every view of `scene` and write `DIR/<view>_normal.exr` (world frame,
/// N.X N.Y N.Z), `<view>_normal.png`, `<view>_mask.png` and `<view>_depth.exr` (Z).
pub fn write_ground_truth_maps(mesh: &Mesh, scene: &Scene, dir: &Path, progress: bool) -> Result<()> {
    let object = Object::new(mesh, Interface::Dielectric(1.5), Lobes::Plastic)?;
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
