//! Ray casting against the 69k-triangle bunny: rmvp-render's BVH and parry3d's, on the same
//! rays, single-threaded. Camera rays (closest hit) from six 256x256 cameras around the mesh,
//! then shadow rays (any hit) from every hit point in random upper-hemisphere directions.
//! Checks that both find the same hits, prints million rays per second.
//!
//! usage: cargo run --release -- MESH.ply

use parry3d::math::Vector;
use parry3d::query::{Ray, RayCast};
use parry3d::shape::TriMesh;
use rmvp_dataset::Mesh;
use rmvp_render::bvh::Bvh;
use rmvp_render::math::Vec3;
use rmvp_render::rig::{framing_distance, rig_intrinsics, Rig};
use rmvp_dataset::rng::Rng;
use std::time::Instant;

fn main() {
    let path = std::env::args().nth(1).expect("usage: bvh-compare MESH.ply");
    let mesh = Mesh::read(std::path::Path::new(&path)).expect("readable mesh");
    let t = Instant::now();
    let ours = Bvh::new(&mesh.positions, &mesh.faces);
    let build_ours = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let vertices: Vec<Vector> = mesh.positions.iter().map(|p| Vector::new(p[0], p[1], p[2])).collect();
    let theirs = TriMesh::new(vertices, mesh.faces.clone()).expect("valid mesh");
    let build_theirs = t.elapsed().as_secs_f64();

    let (w, h) = (256u32, 256u32);
    let k = rig_intrinsics(w, h);
    let cameras = Rig::Sphere { views: 6 }.cameras(k, w, h, framing_distance(&k, w, h, 1.0, 0.85), 0);
    let mut primary = Vec::new();
    for cam in &cameras {
        for j in 0..h {
            for i in 0..w {
                let r = cam.pixel_ray(i, j);
                primary.push((Vec3::from_f64(&r.origin.coords), Vec3::from_f64(&r.direction)));
            }
        }
    }
    let time = |f: &mut dyn FnMut() -> usize| {
        let t = Instant::now();
        let n = f();
        (t.elapsed().as_secs_f64(), n)
    };
    let (ours_primary, ours_hits) =
        time(&mut || primary.iter().filter(|(o, d)| ours.intersect(*o, *d, 0.0, f32::MAX).is_some()).count());
    let (theirs_primary, theirs_hits) = time(&mut || {
        primary
            .iter()
            .filter(|(o, d)| {
                theirs
                    .cast_local_ray(&Ray::new(Vector::new(o.x, o.y, o.z), Vector::new(d.x, d.y, d.z)), f32::MAX, true)
                    .is_some()
            })
            .count()
    });
    // Shadow rays from the hit points, off the surface along the face normal side of the ray.
    let mut rng = Rng::for_pixel(1, 0, 0);
    let shadow: Vec<(Vec3, Vec3)> = primary
        .iter()
        .filter_map(|(o, d)| ours.intersect(*o, *d, 0.0, f32::MAX).map(|hit| *o + *d * (hit.t * 0.9999)))
        .map(|p| {
            let z = rng.next_f32();
            let phi = std::f32::consts::TAU * rng.next_f32();
            let r = (1.0 - z * z).sqrt();
            (p, Vec3::new(r * phi.cos(), z, r * phi.sin()))
        })
        .collect();
    let (ours_shadow, ours_blocked) =
        time(&mut || shadow.iter().filter(|(o, d)| ours.occluded(*o, *d, 0.0, f32::MAX)).count());
    let (theirs_shadow, theirs_blocked) = time(&mut || {
        shadow
            .iter()
            .filter(|(o, d)| {
                theirs.intersects_local_ray(&Ray::new(Vector::new(o.x, o.y, o.z), Vector::new(d.x, d.y, d.z)), f32::MAX)
            })
            .count()
    });
    println!("{} triangles; build: rmvp {:.3} s, parry3d {:.3} s", mesh.faces.len(), build_ours, build_theirs);
    println!(
        "camera rays ({}): rmvp {:.2} Mrays/s, parry3d {:.2} Mrays/s; hits {} vs {}",
        primary.len(),
        primary.len() as f64 / ours_primary / 1e6,
        primary.len() as f64 / theirs_primary / 1e6,
        ours_hits,
        theirs_hits
    );
    println!(
        "shadow rays ({}): rmvp {:.2} Mrays/s, parry3d {:.2} Mrays/s; blocked {} vs {}",
        shadow.len(),
        shadow.len() as f64 / ours_shadow / 1e6,
        shadow.len() as f64 / theirs_shadow / 1e6,
        ours_blocked,
        theirs_blocked
    );
    println!("row\tbuild\t{build_ours:.3} s\t{build_theirs:.3} s");
    let rate = |rays: usize, seconds: f64| format!("{:.2} M rays/s", rays as f64 / seconds / 1e6);
    let (camera, shadows) = (primary.len(), shadow.len());
    println!("row\tcamera rays, closest hit ({camera})\t{}\t{}", rate(camera, ours_primary), rate(camera, theirs_primary));
    println!("row\tshadow rays, any hit ({shadows})\t{}\t{}", rate(shadows, ours_shadow), rate(shadows, theirs_shadow));
}
