//! Views without lens distortion: every image resampled onto the pinhole camera of the same
//! intrinsics (what the NeRSP layout, whose `world_mat` holds no distortion, needs). Each output
//! pixel centre is distorted into the source image and sampled there: bilinearly for the
//! Stokes images, at the nearest pixel for the mask.

use rayon::prelude::*;
use rmvp_dataset::{Camera, Image, Stokes, View};

/// Where each pixel of the undistorted image lies in the distorted one (continuous pixel
/// coordinates, rmvp's convention).
fn source_positions(camera: &Camera) -> Vec<(f64, f64)> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let k = &camera.k;
    let d = camera.distortion.expect("called for distorted cameras");
    (0..w * h)
        .into_par_iter()
        .map(|p| {
            let (u, v) = ((p % w) as f64 + 0.5, (p / w) as f64 + 0.5);
            let y = (v - k[(1, 2)]) / k[(1, 1)];
            let x = (u - k[(0, 2)] - k[(0, 1)] * y) / k[(0, 0)];
            let (xd, yd) = d.distort(x, y);
            (k[(0, 0)] * xd + k[(0, 1)] * yd + k[(0, 2)], k[(1, 1)] * yd + k[(1, 2)])
        })
        .collect()
}

fn bilinear(image: &Image<f32>, at: &[(f64, f64)]) -> Image<f32> {
    let (w, h, c) = (image.width(), image.height(), image.channels());
    let data: Vec<f32> = at
        .par_iter()
        .flat_map_iter(|&(u, v)| {
            let (x, y) = ((u - 0.5).clamp(0.0, (w - 1) as f64), (v - 0.5).clamp(0.0, (h - 1) as f64));
            let (x0, y0) = (x.floor() as usize, y.floor() as usize);
            let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
            let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
            (0..c).map(move |ch| {
                let p = |x: usize, y: usize| image.data()[(y * w + x) * c + ch];
                (p(x0, y0) * (1.0 - fx) + p(x1, y0) * fx) * (1.0 - fy) + (p(x0, y1) * (1.0 - fx) + p(x1, y1) * fx) * fy
            })
        })
        .collect();
    Image::from_vec(w, h, c, data).expect("sized")
}

fn nearest(image: &Image<u8>, at: &[(f64, f64)]) -> Image<u8> {
    let (w, h, c) = (image.width(), image.height(), image.channels());
    let data: Vec<u8> = at
        .iter()
        .flat_map(|&(u, v)| {
            let (x, y) = ((u.max(0.0) as usize).min(w - 1), (v.max(0.0) as usize).min(h - 1));
            image.pixel(x, y).to_vec()
        })
        .collect();
    Image::from_vec(w, h, c, data).expect("sized")
}

/// `view` seen by its camera without distortion: Stokes resampled bilinearly, the mask at the
/// nearest pixel, the AoP and DoP dropped (recomputed from the Stokes by whoever needs them).
/// A view without distortion is returned as it is.
pub fn undistort_view(view: &View) -> View {
    if view.camera.distortion.is_none_or(|d| [d.k1, d.k2, d.p1, d.p2, d.k3].iter().all(|&v| v == 0.0)) {
        return view.clone();
    }
    let at = source_positions(&view.camera);
    let mut out = view.clone();
    out.camera.distortion = None;
    out.projection = None;
    out.stokes = view.stokes.as_ref().map(|s| Stokes {
        s0: bilinear(&s.s0, &at),
        s1: bilinear(&s.s1, &at),
        s2: bilinear(&s.s2, &at),
    });
    out.mask = view.mask.as_ref().map(|m| nearest(m, &at));
    out.normals = view.normals.as_ref().map(|n| bilinear(n, &at));
    out.depth = view.depth.as_ref().map(|d| bilinear(d, &at));
    (out.aop, out.dop, out.polarized, out.preview) = (None, None, None, None);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Point3, Vector3};
    use rmvp_dataset::Distortion;

    #[test]
    fn a_point_lands_where_the_pinhole_camera_projects_it() {
        let mut camera = Camera::new(
            Matrix3::new(300.0, 0.0, 80.0, 0.0, 300.0, 60.0, 0.0, 0.0, 1.0),
            Matrix3::identity(),
            Vector3::new(0.0, 0.0, 2.0),
            160,
            120,
        );
        camera.distortion = Some(Distortion { k1: -0.2, k2: 0.05, p1: 0.001, p2: 0.0, k3: 0.0 });
        // A bright dot where the distorted camera sees the point (0.3, 0.2, 0).
        let point = Point3::new(0.3, 0.2, 0.0);
        let seen = camera.project(&point).unwrap();
        let mut mask = Image::new(160, 120, 1);
        mask.pixel_mut(seen.x as usize, seen.y as usize)[0] = 255;
        let mut view = View::new("v", rmvp_dataset::Split::Train, camera.clone());
        view.mask = Some(mask);
        let flat = undistort_view(&view);
        let pinhole = Camera { distortion: None, ..camera };
        let want = pinhole.project(&point).unwrap();
        let m = flat.mask.unwrap();
        let found: Vec<(usize, usize)> =
            (0..160 * 120).filter(|&k| m.data()[k] > 0).map(|k| (k % 160, k / 160)).collect();
        assert!(
            !found.is_empty()
                && found
                    .iter()
                    .all(|&(x, y)| (x as f64 + 0.5 - want.x).abs() <= 1.5 && (y as f64 + 0.5 - want.y).abs() <= 1.5),
            "{found:?} vs {want:?}"
        );
        assert!(flat.camera.distortion.is_none());
    }
}
