//! The unit sphere NeRSP/NeuS train in (`scale_mat`): a sphere enclosing the object, found from
//! the masks and poses alone (its visual hull), not from a hand-cleaned point cloud.
//!
//! A guess of the centre (the point nearest to the rays through the masks' centroids) and of
//! the size (the masks' extent at that depth) gives a box; a voxel grid over it is carved by
//! every view whose image it falls in (masks dilated by two pixels, so that the hull contains
//! the object) and, outside its image, by every view whose mask leaves the image's border free
//! (it sees the whole object, so nothing outside its image is the object; a view that cuts the
//! object cannot carve what it does not see); the sphere bounding the voxels left, with a
//! margin, is the normalisation. When the hull touches the box, the box grows and the carving
//! starts again.

use crate::{Error, Result};
use nalgebra::{Matrix3, Matrix4, Point2, Point3, Vector3};
use rayon::prelude::*;
use rmvp_dataset::{Camera, Image};

/// Voxels along each side of the carving grid.
const GRID: usize = 96;
/// The sphere is this much larger than the hull's bounding sphere.
pub const MARGIN: f64 = 1.1;
/// Mask dilation before carving, pixels.
const DILATION: usize = 2;

/// Whether the mask leaves a border of the image free: the view sees the whole object.
fn sees_whole_object(mask: &Image<u8>) -> bool {
    let (w, h) = mask.size();
    let at = |x: usize, y: usize| mask.data()[y * w + x] > 127;
    !((0..w).any(|x| at(x, 0) || at(x, h - 1)) || (0..h).any(|y| at(0, y) || at(w - 1, y)))
}

/// The visual hull's bounding sphere: centre and radius (world units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HullSphere {
    /// Centre.
    pub center: Point3<f64>,
    /// Radius.
    pub radius: f64,
    /// Voxels inside the hull.
    pub voxels: usize,
}

impl HullSphere {
    /// The `scale_mat` of this sphere with [`MARGIN`]: unit sphere to world.
    pub fn scale_mat(&self) -> Matrix4<f64> {
        let mut m = Matrix4::new_scaling(MARGIN * self.radius);
        m[(3, 3)] = 1.0;
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.center.coords);
        m
    }
}

/// The point nearest (least squares) to the rays through the masks' centroids.
fn centroid_rays_point(views: &[(Camera, Image<u8>)]) -> Result<Point3<f64>> {
    let (mut a, mut b) = (Matrix3::zeros(), Vector3::zeros());
    for (camera, mask) in views {
        let (w, _) = mask.size();
        let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
        for (k, &m) in mask.data().iter().enumerate() {
            if m > 127 {
                sx += (k % w) as f64 + 0.5;
                sy += (k / w) as f64 + 0.5;
                n += 1.0;
            }
        }
        if n == 0.0 {
            continue;
        }
        let ray = camera.ray(sx / n, sy / n);
        let projector = Matrix3::identity() - ray.direction * ray.direction.transpose();
        a += projector;
        b += projector * ray.origin.coords;
    }
    let solution = a.try_inverse().ok_or_else(|| {
        Error::MaskInput("the masks do not constrain where the object is (empty, or one view)".into())
    })?;
    Ok(Point3::from(solution * b))
}

/// The bounding sphere of the visual hull of `views` (camera and mask each).
pub fn visual_hull_sphere(views: &[(Camera, Image<u8>)]) -> Result<HullSphere> {
    let centre = centroid_rays_point(views)?;
    // Size guess: the largest mask extent, back-projected at the centre's depth.
    let mut half = 0f64;
    for (camera, mask) in views {
        let (w, h) = mask.size();
        let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
        for (k, &m) in mask.data().iter().enumerate() {
            if m > 127 {
                let (x, y) = (k % w, k / w);
                (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
            }
        }
        if x1 < x0 {
            continue;
        }
        let depth = camera.world_to_camera(&centre).z;
        let a = camera.unproject(&Point2::new(x0 as f64, y0 as f64), depth);
        let b = camera.unproject(&Point2::new(x1 as f64 + 1.0, y1 as f64 + 1.0), depth);
        half = half.max((a - b).norm() / 2.0);
    }
    let masks: Vec<Vec<bool>> = views
        .par_iter()
        .map(|(_, m)| {
            let inside: Vec<bool> = m.data().iter().map(|&v| v > 127).collect();
            rmvp_dataset::image::dilate(&inside, m.width(), m.height(), DILATION)
        })
        .collect();
    let whole: Vec<bool> = views.iter().map(|(_, m)| sees_whole_object(m)).collect();
    let mut extent = 1.5 * half.max(1e-9);
    for _ in 0..4 {
        let step = 2.0 * extent / GRID as f64;
        let at = |i: usize| -extent + (i as f64 + 0.5) * step;
        let kept: Vec<(usize, usize, usize)> = (0..GRID * GRID * GRID)
            .into_par_iter()
            .filter_map(|k| {
                let (i, j, l) = (k % GRID, k / GRID % GRID, k / (GRID * GRID));
                let p = centre + Vector3::new(at(i), at(j), at(l));
                let inside = views.iter().zip(&masks).zip(&whole).all(|(((camera, mask), dilated), &whole)| {
                    // Outside a view's image (or behind it): not the object if the view sees
                    // all of it; otherwise this view cannot carve the point.
                    let Some(q) = camera.project(&p) else { return !whole };
                    let (w, h) = mask.size();
                    if q.x < 0.0 || q.y < 0.0 || q.x >= w as f64 || q.y >= h as f64 {
                        return !whole;
                    }
                    dilated[q.y as usize * w + q.x as usize]
                });
                inside.then_some((i, j, l))
            })
            .collect();
        if kept.is_empty() {
            return Err(Error::MaskInput("the masks and poses agree on no point: check the poses".into()));
        }
        let touches = kept.iter().any(|&(i, j, l)| [i, j, l].iter().any(|&v| v == 0 || v == GRID - 1));
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for &(i, j, l) in &kept {
            for (axis, v) in [i, j, l].iter().enumerate() {
                lo[axis] = lo[axis].min(at(*v) - step / 2.0);
                hi[axis] = hi[axis].max(at(*v) + step / 2.0);
            }
        }
        let middle = centre + Vector3::new((lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0, (lo[2] + hi[2]) / 2.0);
        let corner = step * 3f64.sqrt() / 2.0;
        let radius = kept
            .iter()
            .map(|&(i, j, l)| (centre + Vector3::new(at(i), at(j), at(l)) - middle).norm() + corner)
            .fold(0.0, f64::max);
        if !touches {
            return Ok(HullSphere { center: middle, radius, voxels: kept.len() });
        }
        extent *= 1.6;
    }
    Err(Error::MaskInput(
        "the visual hull does not close: the masks leave the object unbounded (too few views?)".into(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rmvp_render::rig::{framing_distance, rig_intrinsics, RigKind};

    /// The mask of a sphere of `radius` at `centre` in `camera` (pixel centres whose ray meets it).
    fn sphere_mask(camera: &Camera, centre: &Point3<f64>, radius: f64) -> Image<u8> {
        let (w, h) = (camera.width, camera.height);
        let data = (0..h)
            .flat_map(|j| (0..w).map(move |i| (i, j)))
            .map(|(i, j)| {
                let ray = camera.pixel_ray(i, j);
                let to_centre = centre - ray.origin;
                let miss = (to_centre - ray.direction * to_centre.dot(&ray.direction)).norm();
                if miss < radius {
                    255
                } else {
                    0
                }
            })
            .collect();
        Image::from_vec(w as usize, h as usize, 1, data).unwrap()
    }

    #[test]
    fn six_turntable_views_bound_a_sphere_tightly() {
        // The demo's rig: two rings at 10 and 35 degrees, and pairs of nearly parallel views
        // whose silhouette cones overlap to infinity behind the object. While views did not
        // carve outside their images, that space was never carved and the hull did not close.
        let (w, h) = (160, 128);
        let k = rig_intrinsics(w, h);
        let (centre, radius) = (Point3::new(0.1, -0.05, 0.2), 0.8);
        let distance = framing_distance(&k, w, h, 1.0, 0.85);
        let views: Vec<(Camera, Image<u8>)> = RigKind::Turntable
            .rig(6)
            .cameras(k, w, h, distance, 0)
            .into_iter()
            .map(|mut camera| {
                // Look at `centre`: move the world by it.
                camera.t -= camera.r * centre.coords;
                let mask = sphere_mask(&camera, &centre, radius);
                (camera, mask)
            })
            .collect();
        let hull = visual_hull_sphere(&views).unwrap();
        assert!((hull.center - centre).norm() < 0.15 * radius, "{hull:?}");
        assert!(hull.radius > radius && hull.radius < 1.6 * radius, "{hull:?}");
    }
}
