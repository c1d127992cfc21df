//! The mesh's connected parts that no training view sees are left out and those the views see
//! kept: the Mitsuba spot fixture's true mesh (world frame) with a small sphere hidden inside
//! its body and one in front of it, seen by its views.

use rmvp_dataset::layout::read_scene;
use rmvp_dataset::Mesh;
use rmvp_recon::data::TrainingSet;
use rmvp_recon::unseen::{meet_parts, unseen_parts, UnseenPart, MIN_SEEN_SHARE};
use rmvp_render::shapes::icosphere;

/// An icosphere of `radius` about `centre`.
fn sphere(centre: [f32; 3], radius: f32) -> Mesh {
    let mut mesh = icosphere(3);
    mesh.positions.iter_mut().for_each(|p| *p = [0, 1, 2].map(|k| centre[k] + radius * p[k]));
    mesh.normals = None;
    mesh
}

/// `parts` as one mesh, in order.
fn joined(parts: &[&Mesh]) -> Mesh {
    let mut mesh = Mesh { positions: Vec::new(), normals: None, faces: Vec::new(), vertex_properties: Vec::new() };
    for part in parts {
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(&part.positions);
        mesh.faces.extend(part.faces.iter().map(|f| f.map(|v| v + base)));
    }
    mesh
}

#[test]
fn a_part_no_view_sees_is_left_out_and_one_the_views_see_is_kept() {
    let scene = read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
    let set = TrainingSet::from_scene(&scene, 0).unwrap();
    let mut truth = scene.mesh.clone().unwrap();
    truth.normals = None;
    truth.vertex_properties.clear();
    assert_eq!(truth.face_parts().1, 1, "the spot is one part");
    let (lo, hi) = truth.bounds().unwrap();
    let size = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f32::max);

    // Inside the body: the mean of its vertices (seen nowhere, as the figures below assert).
    let centre = {
        let n = truth.positions.len() as f32;
        let sum = truth.positions.iter().fold([0f32; 3], |s, p| [0, 1, 2].map(|k| s[k] + p[k]));
        sum.map(|s| s / n)
    };
    let hidden = sphere(centre, 0.02 * size);
    // In front of the surface that the first view sees at its image's centre, a tenth of the
    // way to the camera.
    let view = &set.views[0];
    let ray = view.camera.pixel_ray(view.camera.width / 2, view.camera.height / 2);
    let bvh = rmvp_render::bvh::Bvh::new(&truth.positions, &truth.faces);
    let (o, d) =
        (rmvp_render::math::Vec3::from_f64(&ray.origin.coords), rmvp_render::math::Vec3::from_f64(&ray.direction));
    let hit = bvh.intersect(o, d, 0.0, f32::INFINITY).expect("the first view's centre sees the spot");
    let front = [o.x + 0.9 * hit.t * d.x, o.y + 0.9 * hit.t * d.y, o.z + 0.9 * hit.t * d.z];
    let seen = sphere(front, 0.02 * size);

    let mesh = joined(&[&truth, &hidden, &seen]);
    let (parts, count) = mesh.face_parts();
    assert_eq!(count, 3);
    let met = meet_parts(&mesh, &set, &parts, count);
    println!("object pixels that meet each part first and that cross it: {met:?}");
    // The spot is seen wherever its views look through it but where the sphere in front of it
    // stands; the sphere inside it nowhere, though they look through it; the sphere in front
    // by the first view, from behind the spot by others.
    assert!(met[0].seen > 10_000 && met[0].seen + met[2].seen == met[0].crossed, "{met:?}");
    assert_eq!(met[1].seen, 0);
    assert!(met[1].crossed > 20, "{met:?}");
    assert!(met[2].seen > 0 && met[2].seen < met[2].crossed, "{met:?}");
    assert!(met[2].seen as f64 >= MIN_SEEN_SHARE * met[2].crossed as f64);

    let (kept, record) = unseen_parts(mesh.clone(), &set, false);
    assert_eq!(record.parts, 3);
    assert_eq!(record.pixels, met[0].seen + met[2].seen);
    assert_eq!(record.unseen, [UnseenPart { seen: 0, crossed: met[1].crossed, faces: hidden.faces.len() }]);
    assert!(!record.kept);
    assert_eq!(kept.faces.len(), truth.faces.len() + seen.faces.len());
    assert_eq!(kept.positions.len(), truth.positions.len() + seen.positions.len());
    assert_eq!(kept.positions[..truth.positions.len()], truth.positions[..]);
    assert!(record.summary().unwrap().contains("1 part of 3"), "{:?}", record.summary());

    // Kept on request, and said so.
    let (whole, record) = unseen_parts(mesh.clone(), &set, true);
    assert_eq!(whole, mesh);
    assert!(record.kept && record.unseen.len() == 1);

    // One part alone is never cast, whatever the views see.
    let (alone, record) = unseen_parts(hidden.clone(), &set, false);
    assert_eq!(alone, hidden);
    assert_eq!((record.parts, record.unseen.len()), (1, 0));
}
