//! Training data from a scene: per-view targets (Stokes, mask, AoP) and camera rays expressed in
//! the reconstruction's unit sphere (the scene's `scale_mat` maps it to the world).

use crate::ray::Ray;
use crate::{Error, Result};
use nalgebra::{Matrix3, Matrix4, Point3, Vector3};
use rmvp_dataset::{Camera, Scene, Split};

/// Maps between the world and the unit sphere the SDF lives in.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Unit sphere to world (`scale_mat`).
    pub to_world: Matrix4<f64>,
    /// World to unit sphere.
    pub from_world: Matrix4<f64>,
    /// Rotation part of `from_world` (directions, normalised).
    rotation: Matrix3<f64>,
}

impl Frame {
    /// The frame of `scale_mat`, which must be an invertible similarity.
    pub fn new(to_world: Matrix4<f64>) -> Result<Self> {
        let from_world = to_world.try_inverse().ok_or(Error::SingularNormalization)?;
        let linear = from_world.fixed_view::<3, 3>(0, 0).into_owned();
        let scale = linear.determinant().cbrt();
        if scale.abs() < 1e-12 {
            return Err(Error::SingularNormalization);
        }
        Ok(Self { to_world, from_world, rotation: linear / scale })
    }

    /// A world point in the unit frame.
    pub fn point_from_world(&self, p: &Point3<f64>) -> [f32; 3] {
        let q = self.from_world.transform_point(p);
        [q.x as f32, q.y as f32, q.z as f32]
    }

    /// A unit-frame point in the world.
    pub fn point_to_world(&self, p: [f32; 3]) -> Point3<f64> {
        self.to_world.transform_point(&Point3::new(p[0] as f64, p[1] as f64, p[2] as f64))
    }

    /// A world direction in the unit frame (unit length).
    pub fn dir_from_world(&self, d: &Vector3<f64>) -> [f32; 3] {
        let v = (self.rotation * d).normalize();
        [v.x as f32, v.y as f32, v.z as f32]
    }

    /// A unit-frame direction in the world (unit length).
    pub fn dir_to_world(&self, d: [f32; 3]) -> Vector3<f64> {
        (self.rotation.transpose() * Vector3::new(d[0] as f64, d[1] as f64, d[2] as f64)).normalize()
    }

    /// The ray of pixel `(i, j)` of `camera`, clipped to the unit sphere.
    pub fn pixel_ray(&self, camera: &Camera, i: u32, j: u32) -> Option<Ray> {
        let ray = camera.pixel_ray(i, j);
        let (fx, fy) = camera.stokes_frame(&ray.direction);
        Ray::clipped(
            self.point_from_world(&ray.origin),
            self.dir_from_world(&ray.direction),
            self.dir_from_world(&fx),
            self.dir_from_world(&fy),
        )
    }
}

/// One training view.
#[derive(Clone, Debug)]
pub struct TrainView {
    /// The view's name.
    pub name: String,
    /// World camera.
    pub camera: Camera,
    /// Camera centre in the unit frame.
    pub center: [f32; 3],
    /// Stokes targets, 9 per pixel (S0 RGB, S1 RGB, S2 RGB), scaled by [`TrainingSet::stokes_scale`].
    pub stokes: Vec<f32>,
    /// Object mask.
    pub mask: Vec<bool>,
    /// AoP (radians, per-ray frame).
    pub aop: Vec<f32>,
}

impl TrainView {
    /// Image width.
    pub fn width(&self) -> usize {
        self.camera.width as usize
    }
}

/// Everything training reads from a scene.
#[derive(Clone, Debug)]
pub struct TrainingSet {
    /// Training views.
    pub views: Vec<TrainView>,
    /// Unit sphere <-> world.
    pub frame: Frame,
    /// Factor applied to the input Stokes (so that bright object pixels sit near 0.5).
    pub stokes_scale: f32,
    /// Candidate training rays on the object: (view, pixel) in the dilated masks, hitting the
    /// unit sphere.
    pub pool: Vec<(u32, u32)>,
    /// Candidate rays of the background: (view, pixel) outside the dilated masks whose ray
    /// still crosses the unit sphere. Only the mask loss sees them; without them, space that
    /// no object ray passes through is never carved.
    pub background: Vec<(u32, u32)>,
}

impl TrainingSet {
    /// Collect the train views of `scene` (Stokes and masks required); object rays are drawn
    /// from the masks dilated by `margin` pixels, background rays from the rest of the unit
    /// sphere's footprint.
    pub fn from_scene(scene: &Scene, margin: usize) -> Result<Self> {
        let frame = Frame::new(scene.normalization)?;
        let mut views = Vec::new();
        for view in scene.views.iter().filter(|v| v.split == Split::Train) {
            let missing = |what: &'static str| Error::MissingInput { view: view.name.clone(), what };
            let stokes = view.stokes.as_ref().ok_or_else(|| missing("Stokes images"))?;
            let mask = view.mask.as_ref().ok_or_else(|| missing("mask"))?;
            let (w, h) = stokes.s0.size();
            if stokes.s0.channels() != 3 {
                return Err(Error::StokesNotRgb { view: view.name.clone(), channels: stokes.s0.channels() });
            }
            if (w, h) != (view.camera.width as usize, view.camera.height as usize) {
                return Err(Error::SizeMismatch {
                    view: view.name.clone(),
                    image: (w, h),
                    camera: (view.camera.width as usize, view.camera.height as usize),
                });
            }
            if mask.size() != (w, h) {
                return Err(Error::SizeMismatch { view: view.name.clone(), image: mask.size(), camera: (w, h) });
            }
            if let Some((x, y, channel)) =
                [&stokes.s0, &stokes.s1, &stokes.s2].iter().find_map(|s| s.first_non_finite())
            {
                return Err(Error::NonFiniteInput { view: view.name.clone(), x, y, channel });
            }
            let aop = match &view.aop {
                Some(a) => a.data().to_vec(),
                None => stokes.aop_dop().0.into_vec(),
            };
            let mut target = Vec::with_capacity(9 * w * h);
            for k in 0..w * h {
                for s in [&stokes.s0, &stokes.s1, &stokes.s2] {
                    target.extend_from_slice(&s.data()[3 * k..3 * k + 3]);
                }
            }
            let c = view.camera.center();
            views.push(TrainView {
                name: view.name.clone(),
                camera: view.camera.clone(),
                center: frame.point_from_world(&c),
                stokes: target,
                mask: mask.data().iter().map(|&m| m > 127).collect(),
                aop,
            });
        }
        if views.is_empty() {
            return Err(Error::NoTrainingViews);
        }
        let mut s0: Vec<f32> = views
            .iter()
            .flat_map(|v| {
                v.mask.iter().enumerate().filter(|(_, &m)| m).flat_map(|(k, _)| v.stokes[9 * k..9 * k + 3].to_vec())
            })
            .collect();
        if s0.is_empty() {
            return Err(Error::EmptyMasks);
        }
        let at = (s0.len() as f64 * 0.99) as usize;
        let index = at.min(s0.len() - 1);
        let p99 = *s0.select_nth_unstable_by(index, f32::total_cmp).1;
        let stokes_scale = if p99 > 0.0 { 0.5 / p99 } else { 1.0 };
        for v in &mut views {
            v.stokes.iter_mut().for_each(|x| *x *= stokes_scale);
        }
        let (mut pool, mut background) = (Vec::new(), Vec::new());
        for (vi, v) in views.iter().enumerate() {
            let (w, h) = (v.camera.width as usize, v.camera.height as usize);
            let dilated = rmvp_dataset::image::dilate(&v.mask, w, h, margin);
            for (k, &near_object) in dilated.iter().enumerate() {
                if frame.pixel_ray(&v.camera, (k % w) as u32, (k / w) as u32).is_some() {
                    if near_object { &mut pool } else { &mut background }.push((vi as u32, k as u32));
                }
            }
        }
        Ok(Self { views, frame, stokes_scale, pool, background })
    }

    /// The ray of a pool entry.
    pub fn ray(&self, view: u32, pixel: u32) -> Ray {
        let v = &self.views[view as usize];
        let w = v.width() as u32;
        self.frame.pixel_ray(&v.camera, pixel % w, pixel / w).expect("pool rays hit the sphere")
    }
}
