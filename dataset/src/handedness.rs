//! Whether a scene's AoP is in rmvp's frame or mirrored, judged from its own views.
//!
//! Along an object's outline the surface normal lies in the image plane, pointing out of the
//! silhouette. Light reflected there is polarized along that normal (diffuse) or across it
//! (specular), so `cos 4 (AoP - azimuth)` is near 1 either way. An AoP measured the other way
//! round (`S2` of the wrong sign: a sensor's polarizers read with the wrong handedness, or a
//! layout whose image y axis points up) is `-AoP`, and then bears no relation to the outline:
//! the mean over a whole outline is near 0. Only the masks and the Stokes images (or AoP maps)
//! are needed, no camera and no reconstruction.

use crate::polarization::{self, AOP_MIN_DOP};
use crate::{Scene, View};
use serde::Serialize;

/// Half width, in pixels, of the box that smooths a mask before its gradient gives the
/// outline's normal; the pixels compared lie within about this distance inside the outline.
/// (On the Mitsuba fixtures, 2 agrees best with the outline: 3 and 5 mix in pixels whose
/// normal already turns towards the camera.)
const SMOOTHING_RADIUS: usize = 2;
/// Least smoothed-mask gradient (per pixel) for a pixel to count as on the outline.
const OUTLINE_GRADIENT: f32 = 0.1;
/// Least mean agreement for a reading to be called right.
const LEAST_AGREEMENT: f64 = 0.2;
/// Least lead of one reading over the other.
const LEAST_LEAD: f64 = 0.2;

/// How one view's AoP agrees with its outline's normals, read as stored and mirrored.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ViewAgreement {
    /// The view's name.
    pub view: String,
    /// Outline pixels compared (polarized above [`AOP_MIN_DOP`]).
    pub pixels: usize,
    /// Mean `cos 4 (AoP - normal azimuth)` as stored.
    pub stored: f64,
    /// The same with the AoP mirrored (`-AoP`).
    pub mirrored: f64,
}

/// Which reading of the AoP the outlines support.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    /// The AoP is in rmvp's frame (from image +x towards +y, down).
    Stored,
    /// The AoP is mirrored: `S2` and the AoP have the wrong sign.
    Mirrored,
    /// Neither reading leads clearly (too few polarized outline pixels, or no relation).
    Undecided,
}

/// The scene's AoP against its outlines.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Handedness {
    /// Which reading holds.
    pub verdict: Verdict,
    /// Outline pixels compared over all views.
    pub pixels: usize,
    /// Mean agreement as stored, over all compared pixels.
    pub stored: f64,
    /// Mean agreement mirrored.
    pub mirrored: f64,
    /// Per view with a mask and polarization.
    pub views: Vec<ViewAgreement>,
}

impl Handedness {
    /// Compare every view that has a mask and Stokes images (or an AoP map).
    pub fn of(scene: &Scene) -> Self {
        let views: Vec<ViewAgreement> = scene.views.iter().filter_map(view_agreement).collect();
        let pixels: usize = views.iter().map(|v| v.pixels).sum();
        let mean = |f: fn(&ViewAgreement) -> f64| {
            views.iter().map(|v| f(v) * v.pixels as f64).sum::<f64>() / pixels.max(1) as f64
        };
        let (stored, mirrored) = (mean(|v| v.stored), mean(|v| v.mirrored));
        let verdict = if stored > LEAST_AGREEMENT && stored > mirrored + LEAST_LEAD {
            Verdict::Stored
        } else if mirrored > LEAST_AGREEMENT && mirrored > stored + LEAST_LEAD {
            Verdict::Mirrored
        } else {
            Verdict::Undecided
        };
        Self { verdict, pixels, stored, mirrored, views }
    }
}

/// Mirror every view's AoP: `S2 -> -S2`, `AoP -> (pi - AoP) mod pi`, the 45 and 135 degree
/// polarizer images exchanged. DoP and S0 are unchanged.
pub fn mirror_aop(scene: &mut Scene) {
    for view in &mut scene.views {
        if let Some(stokes) = &mut view.stokes {
            stokes.s2.data_mut().iter_mut().for_each(|v| *v = -*v);
        }
        if let Some(aop) = &mut view.aop {
            let pi = std::f32::consts::PI;
            aop.data_mut().iter_mut().for_each(|a| *a = if *a > 0.0 { pi - *a } else { 0.0 });
        }
        if let Some(polarized) = &mut view.polarized {
            polarized.images.swap(1, 3);
        }
    }
}

/// One view's agreement, if it has a mask and polarization.
fn view_agreement(view: &View) -> Option<ViewAgreement> {
    let mask = view.mask.as_ref()?;
    let (aop, dop) = match (&view.stokes, &view.aop) {
        (Some(stokes), _) => stokes.aop_dop(),
        // An AoP map alone: every pixel counts as polarized.
        (None, Some(aop)) => (aop.clone(), view.dop.clone().unwrap_or_else(|| aop.map(|_| 1.0))),
        _ => return None,
    };
    if aop.size() != mask.size() {
        return None;
    }
    let (w, h) = mask.size();
    let smooth = box_blur(&mask.data().iter().map(|&m| f32::from(u8::from(m >= 128))).collect::<Vec<_>>(), w, h);
    let (mut stored, mut mirrored, mut pixels) = (0.0, 0.0, 0usize);
    for y in 1..h.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            let k = y * w + x;
            if mask.data()[k] < 128 || dop.data()[k] <= AOP_MIN_DOP {
                continue;
            }
            // The outline's outward normal: down the smoothed mask's gradient.
            let gx = smooth[k + 1] - smooth[k - 1];
            let gy = smooth[k + w] - smooth[k - w];
            if gx.hypot(gy) < 2.0 * OUTLINE_GRADIENT {
                continue;
            }
            let azimuth = polarization::atan2(-gy, -gx);
            let a = aop.data()[k];
            stored += f64::from((4.0 * (a - azimuth)).cos());
            mirrored += f64::from((4.0 * (-a - azimuth)).cos());
            pixels += 1;
        }
    }
    let n = pixels.max(1) as f64;
    Some(ViewAgreement { view: view.name.clone(), pixels, stored: stored / n, mirrored: mirrored / n })
}

/// Mean over the `(2r + 1)^2` box around each pixel (clamped at the borders), two passes.
fn box_blur(values: &[f32], w: usize, h: usize) -> Vec<f32> {
    let r = SMOOTHING_RADIUS;
    let pass = |input: &[f32], along_x: bool| -> Vec<f32> {
        let mut out = vec![0.0; input.len()];
        for y in 0..h {
            for x in 0..w {
                let (centre, len) = if along_x { (x, w) } else { (y, h) };
                let (lo, hi) = (centre.saturating_sub(r), (centre + r).min(len - 1));
                let at = |i: usize| if along_x { input[y * w + i] } else { input[i * w + x] };
                out[y * w + x] = (lo..=hi).map(at).sum::<f32>() / (hi - lo + 1) as f32;
            }
        }
        out
    };
    pass(&pass(values, true), false)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Camera, Image, Split, Stokes};

    /// A disc whose outline reflects light polarized tangentially (specular) or radially
    /// (diffuse), with `S2` negated when `mirror`.
    fn disc_view(specular: bool, mirror: bool) -> View {
        let (w, h) = (64, 48);
        let k = nalgebra::Matrix3::new(50.0, 0.0, 32.0, 0.0, 50.0, 24.0, 0.0, 0.0, 1.0);
        let camera = Camera::new(k, nalgebra::Matrix3::identity(), nalgebra::Vector3::new(0.0, 0.0, 3.0), 64, 48);
        let mut view = View::new("000", Split::Train, camera);
        let (cx, cy, r) = (30.0f32, 25.0f32, 15.0f32);
        let mut mask = Image::new(w, h, 1);
        let mut stokes = Stokes { s0: Image::new(w, h, 1), s1: Image::new(w, h, 1), s2: Image::new(w, h, 1) };
        for y in 0..h {
            for x in 0..w {
                let (dx, dy) = (x as f32 + 0.5 - cx, y as f32 + 0.5 - cy);
                if dx.hypot(dy) > r {
                    continue;
                }
                mask.pixel_mut(x, y)[0] = 255;
                let angle = dy.atan2(dx) + if specular { std::f32::consts::FRAC_PI_2 } else { 0.0 };
                let sign = if mirror { -1.0 } else { 1.0 };
                stokes.s0.pixel_mut(x, y)[0] = 1.0;
                stokes.s1.pixel_mut(x, y)[0] = 0.3 * (2.0 * angle).cos();
                stokes.s2.pixel_mut(x, y)[0] = sign * 0.3 * (2.0 * angle).sin();
            }
        }
        view.mask = Some(mask);
        view.stokes = Some(stokes);
        view
    }

    #[test]
    fn a_disc_is_judged_by_its_outline_either_way_it_reflects() {
        for specular in [false, true] {
            for (mirror, verdict) in [(false, Verdict::Stored), (true, Verdict::Mirrored)] {
                let mut scene = Scene::new();
                scene.views.push(disc_view(specular, mirror));
                let judged = Handedness::of(&scene);
                assert_eq!(judged.verdict, verdict, "specular {specular}, mirrored {mirror}: {judged:?}");
                assert!(judged.pixels > 50, "{judged:?}");
            }
        }
    }

    #[test]
    fn mirroring_turns_the_verdict_and_twice_gives_the_scene_back() {
        let mut scene = Scene::new();
        scene.views.push(disc_view(true, false));
        let original = scene.clone();
        mirror_aop(&mut scene);
        assert_eq!(Handedness::of(&scene).verdict, Verdict::Mirrored);
        mirror_aop(&mut scene);
        assert_eq!(scene, original);
    }

    #[test]
    fn unpolarized_views_decide_nothing() {
        let mut view = disc_view(true, false);
        let stokes = view.stokes.as_mut().unwrap();
        stokes.s1.data_mut().fill(0.0);
        stokes.s2.data_mut().fill(0.0);
        let mut scene = Scene::new();
        scene.views.push(view);
        assert_eq!(Handedness::of(&scene).verdict, Verdict::Undecided);
    }
}
