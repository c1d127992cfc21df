//! Scenes: calibrated views with their polarization images, plus optional ground truth.

use crate::polarization;
use crate::{Camera, Error, Image, Mesh, Result};
use nalgebra::Matrix4;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// What a view is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Split {
    /// Input to reconstruction.
    Train,
    /// Held out for evaluation (ground truth only).
    Eval,
}

impl std::fmt::Display for Split {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Split::Train => "train",
            Split::Eval => "eval",
        })
    }
}

/// Stokes images `S0, S1, S2` of one view, linear radiance, in the image frame
/// (see [`crate::polarization`]). All three have the same size and channel count (3 for RGB).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stokes {
    /// Total intensity.
    pub s0: Image<f32>,
    /// Horizontal minus vertical.
    pub s1: Image<f32>,
    /// Diagonal minus anti-diagonal.
    pub s2: Image<f32>,
}

impl Stokes {
    /// The Stokes images of four linear images behind polarizers at 0, 45, 90 and 135 degrees
    /// ([`polarization::stokes_from_four`] at every sample); they must agree in size and
    /// channels.
    pub fn from_polarizer_images(images: [&Image<f32>; 4]) -> Result<Self> {
        for (image, deg) in images.iter().zip(polarization::POLARIZER_ANGLES_DEG).skip(1) {
            let what = format!("polarizer images 0 and {deg}");
            images[0].check_same_size(image, &what)?;
            if image.channels() != images[0].channels() {
                return Err(Error::invalid(format!("{what} have different channel counts")));
            }
        }
        let (w, h, c) = (images[0].width(), images[0].height(), images[0].channels());
        let mut s = [Image::new(w, h, c), Image::new(w, h, c), Image::new(w, h, c)];
        for k in 0..w * h * c {
            let v = polarization::stokes_from_four(images.map(|i| i.data()[k]));
            for (component, value) in s.iter_mut().zip(v) {
                component.data_mut()[k] = value;
            }
        }
        let [s0, s1, s2] = s;
        Ok(Stokes { s0, s1, s2 })
    }

    /// Check sizes and finiteness.
    pub fn validate(&self) -> Result<()> {
        for (name, other) in [("S1", &self.s1), ("S2", &self.s2)] {
            self.s0.check_same_size(other, &format!("S0 and {name}"))?;
            if other.channels() != self.s0.channels() {
                return Err(Error::invalid(format!("S0 and {name} have different channel counts")));
            }
        }
        for (name, image) in [("S0", &self.s0), ("S1", &self.s1), ("S2", &self.s2)] {
            if let Some((x, y, c)) = image.first_non_finite() {
                return Err(Error::invalid(format!("{name} is not finite at pixel ({x}, {y}) channel {c}")));
            }
        }
        Ok(())
    }

    /// AoP (radians, `[0, pi)`) and DoP of each pixel's channel-mean Stokes vector (the NeRSP
    /// definition for RGB data), one channel each.
    pub fn aop_dop(&self) -> (Image<f32>, Image<f32>) {
        let (mut aop, mut dop) = (Image::default(), Image::default());
        self.aop_dop_into(&mut aop, &mut dop);
        (aop, dop)
    }

    /// [`Stokes::aop_dop`] into existing images (reusing their buffers), one parallel pass.
    pub fn aop_dop_into(&self, aop: &mut Image<f32>, dop: &mut Image<f32>) {
        let (w, h, c) = (self.s0.width(), self.s0.height(), self.s0.channels());
        aop.ensure_shape(w, h, 1);
        dop.ensure_shape(w, h, 1);
        aop.data_mut().par_chunks_mut(w).zip(dop.data_mut().par_chunks_mut(w)).enumerate().for_each(|(y, (a, d))| {
            let range = y * w * c..(y + 1) * w * c;
            let rows = [&self.s0, &self.s1, &self.s2].map(|s| &s.data()[range.clone()]);
            polarization::aop_dop_row(rows, c, a, d);
        });
    }
}

/// The images behind the four polarizers (0, 45, 90, 135 degrees) as stored 16-bit counts:
/// `count = round(clip(I * scale, 0, 1) * 65535)` with `I` the linear intensity.
#[derive(Clone, Debug, PartialEq)]
pub struct PolarizerImages {
    /// Linear intensity to full-scale factor.
    pub scale: f64,
    /// One image per angle of [`polarization::POLARIZER_ANGLES_DEG`].
    pub images: [Image<u16>; 4],
}

/// One calibrated view and whatever images it has.
#[derive(Clone, Debug, PartialEq)]
pub struct View {
    /// Unique name (`000`, ...), used for file names.
    pub name: String,
    /// Training input or evaluation only.
    pub split: Split,
    /// Calibration.
    pub camera: Camera,
    /// The 4x4 projection `K [R | t]` exactly as a source file gave it (IDR `world_mat`); kept so
    /// that conversions are bit-exact. It always agrees with `camera` to rounding.
    pub projection: Option<Matrix4<f64>>,
    /// Stokes images.
    pub stokes: Option<Stokes>,
    /// Object mask, 8-bit (0 background, 255 object).
    pub mask: Option<Image<u8>>,
    /// Angle of polarization in radians, one channel.
    pub aop: Option<Image<f32>>,
    /// Degree of polarization, one channel.
    pub dop: Option<Image<f32>>,
    /// Ground-truth world-frame unit normals, 3 channels, 0 outside the object.
    pub normals: Option<Image<f32>>,
    /// Ground-truth depth along the camera's z axis, one channel, 0 outside the object.
    pub depth: Option<Image<f32>>,
    /// The polarizer images the Stokes were computed from.
    pub polarized: Option<PolarizerImages>,
    /// An 8-bit preview picture of S0.
    pub preview: Option<Image<u8>>,
}

impl View {
    /// A view with a camera and nothing else.
    pub fn new(name: impl Into<String>, split: Split, camera: Camera) -> Self {
        Self {
            name: name.into(),
            split,
            camera,
            projection: None,
            stokes: None,
            mask: None,
            aop: None,
            dop: None,
            normals: None,
            depth: None,
            polarized: None,
            preview: None,
        }
    }

    /// `projection` if present, else the one composed from the camera (distortion aside).
    pub fn projection_matrix(&self) -> Matrix4<f64> {
        self.projection.unwrap_or_else(|| {
            let mut m = Matrix4::identity();
            m.fixed_view_mut::<3, 4>(0, 0).copy_from(&self.camera.projection());
            m
        })
    }

    /// This view at 1/`factor` of its size, for training at a lower resolution: the camera
    /// scaled ([`Camera::downscaled`]), Stokes and polarizer images averaged over each block, the
    /// mask set where at least half of its block is, the preview averaged; the AoP and DoP are
    /// dropped (derived again from the averaged Stokes), and so is the ground truth (normals,
    /// depth), which belongs to the full size.
    pub fn downscaled(&self, factor: u32) -> View {
        let f = factor.max(1) as usize;
        let mut view = View::new(self.name.clone(), self.split, self.camera.downscaled(factor));
        view.projection = self.projection.map(|mut p| {
            for c in 0..4 {
                p[(0, c)] /= f as f64;
                p[(1, c)] /= f as f64;
            }
            p
        });
        view.stokes = self.stokes.as_ref().map(|s| Stokes {
            s0: s.s0.block_mean(f),
            s1: s.s1.block_mean(f),
            s2: s.s2.block_mean(f),
        });
        view.mask = self
            .mask
            .as_ref()
            .map(|m| m.map(|v| if v > 127 { 1.0 } else { 0.0 }).block_mean(f).map(|v| if v >= 0.5 { 255 } else { 0 }));
        view.preview = self.preview.as_ref().map(|p| crate::visualize::downsample(p, f));
        view.polarized = self.polarized.as_ref().map(|p| PolarizerImages {
            scale: p.scale,
            images: p.images.each_ref().map(|i| i.map(f32::from).block_mean(f).map(|v| v.round() as u16)),
        });
        view
    }

    /// Check that every image matches the camera's size and holds sane values.
    pub fn validate(&self) -> Result<()> {
        let context = |e: Error| Error::invalid(format!("view {}: {e}", self.name));
        self.camera.validate().map_err(context)?;
        let size = (self.camera.width as usize, self.camera.height as usize);
        let check = |what: &str, got: (usize, usize)| {
            if got != size {
                return Err(Error::invalid(format!(
                    "view {}: {what} is {}x{}, the camera {}x{}",
                    self.name, got.0, got.1, size.0, size.1
                )));
            }
            Ok(())
        };
        if let Some(s) = &self.stokes {
            check("Stokes", s.s0.size())?;
            s.validate().map_err(context)?;
        }
        if let Some(m) = &self.mask {
            check("mask", m.size())?;
        }
        if let Some(a) = &self.aop {
            check("AoP", a.size())?;
        }
        if let Some(d) = &self.dop {
            check("DoP", d.size())?;
        }
        if let Some(d) = &self.depth {
            check("depth map", d.size())?;
        }
        if let Some(p) = &self.polarized {
            for (image, deg) in p.images.iter().zip(polarization::POLARIZER_ANGLES_DEG) {
                check(&format!("polarizer image {deg}"), image.size())?;
            }
        }
        if let Some(n) = &self.normals {
            check("normal map", n.size())?;
            if n.channels() != 3 {
                return Err(Error::invalid(format!(
                    "view {}: normal map has {} channels, not 3",
                    self.name,
                    n.channels()
                )));
            }
            let bad = n.data().chunks_exact(3).position(|v| {
                let len2 = v.iter().map(|x| x * x).sum::<f32>();
                !(len2.is_finite() && (len2 == 0.0 || (len2.sqrt() - 1.0).abs() < 1e-2))
            });
            if let Some(p) = bad {
                return Err(Error::invalid(format!(
                    "view {}: normal at pixel ({}, {}) is neither unit length nor zero",
                    self.name,
                    p % size.0,
                    p / size.0
                )));
            }
        }
        Ok(())
    }
}

/// A scene: its views and optional ground truth.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Views, training views first by convention.
    pub views: Vec<View>,
    /// The similarity that maps the reconstruction's unit sphere into the world frame
    /// (IDR/NeuS `scale_mat`); identity when the world is already normalised.
    pub normalization: Matrix4<f64>,
    /// Ground-truth mesh in the world frame.
    pub mesh: Option<Mesh>,
    /// Unpolarized lat-long environment map, RGB, top row = +Y.
    pub env_map: Option<Image<f32>>,
    /// Free-form provenance (generator, material, seeds, ...), kept through conversions.
    pub metadata: serde_json::Map<String, serde_json::Value>,
}

impl Scene {
    /// An empty scene with the identity normalisation.
    pub fn new() -> Self {
        Self {
            views: Vec::new(),
            normalization: Matrix4::identity(),
            mesh: None,
            env_map: None,
            metadata: Default::default(),
        }
    }

    /// The training views, in order.
    pub fn train_views(&self) -> impl Iterator<Item = &View> {
        self.views.iter().filter(|v| v.split == Split::Train)
    }

    /// The view called `name`.
    pub fn view(&self, name: &str) -> Option<&View> {
        self.views.iter().find(|v| v.name == name)
    }

    /// The scene with every view at 1/`factor` of its size ([`View::downscaled`]); the mesh,
    /// environment map and provenance are kept.
    pub fn downscaled(&self, factor: u32) -> Scene {
        Scene {
            views: self.views.iter().map(|v| v.downscaled(factor)).collect(),
            normalization: self.normalization,
            mesh: self.mesh.clone(),
            env_map: self.env_map.clone(),
            metadata: self.metadata.clone(),
        }
    }

    /// Check every view, unique names, and the ground truth.
    pub fn validate(&self) -> Result<()> {
        let mut names = std::collections::BTreeSet::new();
        for view in &self.views {
            if !names.insert(view.name.as_str()) {
                return Err(Error::invalid(format!("two views are named {}", view.name)));
            }
            view.validate()?;
        }
        if let Some(mesh) = &self.mesh {
            mesh.validate().map_err(|e| Error::invalid(format!("ground-truth mesh: {e}")))?;
        }
        if let Some(env) = &self.env_map {
            if let Some((x, y, c)) = env.first_non_finite() {
                return Err(Error::invalid(format!("environment map is not finite at ({x}, {y}) channel {c}")));
            }
        }
        if !self.normalization.iter().all(|v| v.is_finite()) || self.normalization.determinant().abs() < 1e-300 {
            return Err(Error::invalid("normalization matrix is singular or not finite"));
        }
        Ok(())
    }
}

impl Default for Scene {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Vector3};

    #[test]
    fn a_downscaled_view_averages_stokes_over_blocks_and_keeps_majority_masks() {
        let k = Matrix3::new(100.0, 0.0, 3.0, 0.0, 100.0, 2.0, 0.0, 0.0, 1.0);
        let mut view = View::new("000", Split::Train, Camera::new(k, Matrix3::identity(), Vector3::z(), 6, 4));
        let ramp = Image::from_vec(6, 4, 3, (0..72).map(|i| i as f32).collect()).unwrap();
        view.stokes = Some(Stokes { s0: ramp.clone(), s1: ramp.map(|v| -v), s2: ramp.map(|v| 2.0 * v) });
        // Block (0, 0) three quarters inside, block (1, 0) a quarter, block (2, 1) half.
        let inside = [(0, 0), (1, 0), (0, 1), (2, 0), (4, 2), (5, 2)];
        let mask = (0..24).map(|p| if inside.contains(&(p % 6, p / 6)) { 255 } else { 0 }).collect();
        view.mask = Some(Image::from_vec(6, 4, 1, mask).unwrap());
        view.projection = Some(view.projection_matrix());
        let small = view.downscaled(2);
        assert_eq!((small.camera.width, small.camera.height), (3, 2));
        let s0 = &small.stokes.as_ref().unwrap().s0;
        // Pixel (1, 1) averages full pixels (2..4, 2..4): indices 14, 15, 20, 21, channel 0.
        let expected = [14.0, 15.0, 20.0, 21.0].map(|p: f32| 3.0 * p).iter().sum::<f32>() / 4.0;
        assert_eq!(s0.pixel(1, 1)[0], expected);
        assert_eq!(small.stokes.as_ref().unwrap().s2.pixel(1, 1)[0], 2.0 * expected);
        assert_eq!(small.mask.as_ref().unwrap().data(), &[255, 0, 0, 0, 0, 255]);
        assert_eq!(small.projection.unwrap().fixed_view::<3, 4>(0, 0), small.camera.projection());
        assert!(small.validate().is_ok());
    }
}
