//! NeRSP's geometric cue: the pi/2-ambiguous AoP of every view that sees a surface point
//! constrains the normal to one of two planes. For a view looking along `d` with AoP `phi` in
//! its ray's Stokes frame `(x_r, y_r)`, the polarization direction is `e = cos(phi) x_r +
//! sin(phi) y_r`; diffuse reflection puts the normal in the plane of `d` and `e` (`n . t = 0`
//! with `t = d x e`), specular reflection in the plane of `d` and `t` (`n . e = 0`). The loss is
//! `(n . t)^2 (n . e)^2` averaged over the views that see the point (sphere tracing the SDF).

use crate::data::{TrainView, TrainingSet};
use crate::engine::vector::{cross, dot};
use crate::model::{Model, ShadingInput};
use crate::ray::unit_sphere_span;
use crate::samples::FieldSamples;
use crate::trace::{sphere_trace, TraceLimits, TraceRay};
use nalgebra::Vector3;
use rmvp_dataset::Camera;

/// The two tangent directions one view gives at a surface point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tangents {
    /// `d x e` (zero for diffuse reflection).
    pub t: [f32; 3],
    /// `e`, the polarization direction (zero for specular reflection).
    pub t_hat: [f32; 3],
}

/// What the geometric cue reads at one surface point.
#[derive(Clone, Debug, PartialEq)]
pub struct PointTangents {
    /// The tangents of every view that sees the point.
    pub views: Vec<Tangents>,
    /// The point's [`correction_share`] of its SDF's curvature.
    pub curvature_share: f32,
}

/// Pixel `k`'s measured `(S0, S1, S2)`, each the mean of its three colour channels.
fn channel_means(view: &TrainView, k: usize) -> [f32; 3] {
    let stokes = &view.stokes[9 * k..9 * k + 9];
    [0, 1, 2].map(|s| stokes[3 * s..3 * s + 3].iter().sum::<f32>() / 3.0)
}

fn normalize(a: [f32; 3]) -> [f32; 3] {
    let l = dot(a, a).sqrt().max(1e-12);
    a.map(|x| x / l)
}

/// The scale `c` of the robust tangent term for an AoP `angle` degrees away from both of a
/// normal's planes (the normal across the ray): the plain term there, `sin^2(2 angle) / 4`;
/// 0 for an angle of 0 (no robust term).
pub fn robust_scale(angle: f32) -> f32 {
    (2.0 * angle.to_radians()).sin().powi(2) / 4.0
}

/// [`robust_scale`] `robust` gated by a point's [`correction_share`] `share`: `robust / share`,
/// so that the term is robust at full scale only where the surface curves strongly and tends to
/// NeRSP's plain term on a flat face. Where the surface curves, the AoPs stray from the
/// normal's planes by what the model does not capture (the light's gradient across the lobe,
/// interreflections); on a face, a view's AoP that disagrees with the others is the cue that
/// turns the face (the Mitsuba fandisk, `docs/benchmarks.md`).
pub fn curved_robust_scale(robust: f32, share: f32) -> f32 {
    if robust > 0.0 {
        robust / share.max(1e-6)
    } else {
        0.0
    }
}

/// The loss `rho((n.t)^2 (n.t_hat)^2)` averaged over `views`, and its gradient with
/// respect to the (unnormalised) normal `n`; `rho(l) = l` for a `robust` scale of 0, else
/// Geman-McClure's `c l / (l + c)`, which weighs a view whose AoP strays far from the normal's
/// planes less. With `azimuth_only`, each view's gradient keeps only its component that turns
/// `n` about the view's ray.
pub fn tangent_loss(n: [f32; 3], views: &[Tangents], azimuth_only: bool, robust: f32) -> (f32, [f32; 3]) {
    if views.is_empty() {
        return (0.0, [0.0; 3]);
    }
    let len = dot(n, n).sqrt().max(1e-8);
    let u = n.map(|x| x / len);
    let (mut loss, mut du) = (0f32, [0f32; 3]);
    for v in views {
        let (a, b) = (dot(u, v.t), dot(u, v.t_hat));
        let plain = a * a * b * b;
        let (term, slope) = if robust > 0.0 {
            (robust * plain / (plain + robust), (robust / (plain + robust)).powi(2))
        } else {
            (plain, 1.0)
        };
        loss += term;
        let scale = 2.0 * slope;
        let g = [0, 1, 2].map(|k| scale * (a * b * b * v.t[k] + a * a * b * v.t_hat[k]));
        let g = if azimuth_only {
            // The ray is t_hat x t; turning u about it moves it along ray x u.
            let turn = cross(cross(v.t_hat, v.t), u);
            let q = dot(turn, turn);
            if q < 1e-12 {
                [0.0; 3]
            } else {
                let along = dot(g, turn) / q;
                turn.map(|x| along * x)
            }
        } else {
            g
        };
        for k in 0..3 {
            du[k] += g[k];
        }
    }
    let m = views.len() as f32;
    let along = dot(du, u);
    (loss / m, [0, 1, 2].map(|k| (du[k] - u[k] * along) / len / m))
}

/// Visibility tracing starts this far from the surface point.
const START: f32 = 0.02;
/// Visibility tracing: full SDF steps (as trained so far), over-relaxed by 1.6 (a ray leaving
/// a surface at a grazing angle takes a third fewer), at most 48.
const VISIBILITY: TraceLimits =
    TraceLimits { step_scale: 1.0, max_step: f32::INFINITY, max_steps: 48, relaxation: 1.6 };

/// One view of one surface point, for the geometric cue.
struct Query {
    /// The point's index.
    point: usize,
    /// The view's index.
    view: usize,
    /// The pixel the point projects to.
    pixel: usize,
    /// The point.
    origin: [f32; 3],
    /// Unit direction towards the camera.
    dir: [f32; 3],
    /// Depth where the visibility ray leaves the unit sphere.
    exit: f32,
    /// The view's ray towards the point (world frame, unit).
    towards: Vector3<f64>,
    /// That ray and its Stokes frame in the unit frame.
    frame: [[f32; 3]; 3],
}

/// For each surface point (unit frame) with its outward normal, the tangents of every training
/// view that sees it (in front of the camera, inside the image and the view's mask, facing the
/// camera and not occluded by the SDF).
/// When the model's specular lobe tilts ([`crate::model::Radiance::off_axis`]), the part of
/// each view's `(S1, S2)` that the tilt predicts, times the point's [`correction_share`], is
/// taken away before the AoP gives the tangents. Each point's [`correction_share`] is returned
/// with its tangents when the tilt or `curvature` asks for it (else 1).
///
/// With a [`ViewSample`], a point that more views face than its `views` is compared with a
/// systematic sample of them (before the occlusion test): every view that faces it is taken
/// with the same chance, so the loss's mean over them is an unbiased estimate of the mean over
/// all, and the sample spreads around the point as the views do.
#[allow(clippy::too_many_arguments)]
pub fn tangents(
    set: &TrainingSet,
    model: &Model,
    params: &[f32],
    level_weight: &[f32],
    points: &[[f32; 3]],
    normals: &[[f32; 3]],
    curvature: bool,
    sample: Option<ViewSample>,
) -> Vec<PointTangents> {
    let (mut queries, mut facing, mut kept) = (Vec::new(), Vec::new(), Vec::new());
    for (pi, (&x, &n)) in points.iter().zip(normals).enumerate() {
        let world = set.frame.point_to_world(x);
        // The views that face the point and see it inside their masks: (view, pixel, towards
        // the camera).
        facing.clear();
        for (vi, view) in set.views.iter().enumerate() {
            let to_camera = normalize([0, 1, 2].map(|k| view.center[k] - x[k]));
            if dot(to_camera, n) <= 0.0 {
                continue;
            }
            let Some(pixel) = view.camera.project(&world) else { continue };
            let (w, h) = (view.camera.width as f64, view.camera.height as f64);
            if !(0.0..w).contains(&pixel.x) || !(0.0..h).contains(&pixel.y) {
                continue;
            }
            let k = pixel.y as usize * view.width() + pixel.x as usize;
            if view.mask[k] {
                facing.push((vi, k, to_camera));
            }
        }
        // Those compared: a systematic sample of them, or every one.
        kept.clear();
        match &sample {
            Some(sample) if sample.views > 0 && facing.len() > sample.views => {
                kept.extend(systematic_sample(facing.len(), sample.views, sample.offsets[pi]))
            }
            _ => kept.extend(0..facing.len()),
        }
        for &(vi, k, to_camera) in kept.iter().map(|&j| &facing[j]) {
            let view = &set.views[vi];
            let towards = (world - view.camera.center()).normalize();
            let (fx, fy) = view.camera.stokes_frame(&towards);
            let (fx, fy) = (set.frame.dir_from_world(&fx), set.frame.dir_from_world(&fy));
            let frame = [set.frame.dir_from_world(&towards), fx, fy];
            // A point inside the unit sphere always leaves it; outside, nothing can occlude it.
            let exit = unit_sphere_span(x, to_camera).map_or(0.0, |(_, far)| far);
            queries.push(Query { point: pi, view: vi, pixel: k, origin: x, dir: to_camera, exit, towards, frame });
        }
    }
    // Batched sphere tracing towards each camera.
    let rays: Vec<TraceRay> =
        queries.iter().map(|q| TraceRay { origin: q.origin, dir: q.dir, start: START, end: q.exit }).collect();
    let hits = sphere_trace(model, params, level_weight, &rays, VISIBILITY);
    let visible: Vec<&Query> = queries.iter().zip(&hits).filter(|(_, hit)| hit.is_none()).map(|(q, _)| q).collect();
    let tilts = model.radiance.tilts();
    let at_points =
        (tilts || curvature).then(|| FieldSamples::infer(model, params, level_weight, points.concat(), CURVATURE_STEP));
    let shares: Vec<f32> = match &at_points {
        Some(field) => field.laplacians.iter().map(|&l| correction_share(l)).collect(),
        None => vec![1.0; points.len()],
    };
    let off_axis = match &at_points {
        Some(field) if tilts => predicted_off_axis(model, params, field, &shares, normals, &visible),
        _ => Vec::new(),
    };
    let mut out: Vec<PointTangents> =
        shares.into_iter().map(|curvature_share| PointTangents { views: Vec::new(), curvature_share }).collect();
    for (i, q) in visible.iter().enumerate() {
        let view = &set.views[q.view];
        let aop = match off_axis.get(i) {
            Some(&off_axis) => {
                let [_, s1, s2] = channel_means(view, q.pixel);
                aop_without(view.aop[q.pixel], s1.hypot(s2), off_axis)
            }
            None => view.aop[q.pixel],
        };
        let (t, e) = aop_tangents(&view.camera, &q.towards, aop);
        out[q.point].views.push(Tangents { t: set.frame.dir_from_world(&t), t_hat: set.frame.dir_from_world(&e) });
    }
    out
}

/// How many of the views that face a surface point the geometric cue compares with it, and
/// where each point's systematic sample starts.
#[derive(Clone, Copy, Debug)]
pub struct ViewSample<'a> {
    /// Views compared with a point, at most (0: every one).
    pub views: usize,
    /// Each point's offset in `[0, 1)`.
    pub offsets: &'a [f32],
}

/// The indices of a systematic sample of `n` of `count` items (`n < count`) at `offset` in
/// `[0, 1)`: `floor((offset + j) count / n)`, rising; each item is in it with chance `n / count`.
fn systematic_sample(count: usize, n: usize, offset: f32) -> impl Iterator<Item = usize> {
    let stride = count as f64 / n as f64;
    (0..n).map(move |j| (((f64::from(offset) + j as f64) * stride) as usize).min(count - 1))
}

/// The two tangent directions (world frame) that the AoP `aop` (radians, in the ray's Stokes
/// frame, [`Camera::stokes_frame`]) of light arriving along `direction` (unit, world) gives:
/// `t = d x e` and `e`, the polarization direction, as [`Tangents`] holds them. On the optical
/// axis `t` is the official NeRSP loader's tangent `r1 sin(aop) - r2 cos(aop)` reversed; off
/// the axis it follows the ray's frame, where that loader keeps the camera's axes.
pub fn aop_tangents(camera: &Camera, direction: &Vector3<f64>, aop: f32) -> (Vector3<f64>, Vector3<f64>) {
    let (x, y) = camera.stokes_frame(direction);
    let (s, c) = f64::from(aop).sin_cos();
    let e = x * c + y * s;
    (direction.cross(&e), e)
}

/// The AoP of a measured linear polarization of angle `aop` (radians) and strength
/// `sqrt(S1^2 + S2^2)` once the part `off_axis = (S1, S2)` is taken away.
pub fn aop_without(aop: f32, strength: f32, off_axis: [f32; 2]) -> f32 {
    let (s, c) = (2.0 * aop).sin_cos();
    0.5 * (strength * s - off_axis[1]).atan2(strength * c - off_axis[0])
}

/// Finite-difference step (unit sphere) of the SDF Laplacian that [`correction_share`] reads:
/// wider than the hash grid's finest cells, so that it measures the shape, not the grid's ripple.
const CURVATURE_STEP: f32 = 0.03;

/// The SDF Laplacian (twice the mean curvature, unit sphere) at which [`correction_share`] is
/// one half: that of a sphere of radius 0.5 (a sphere's is `2 / r`).
const HALF_SHARE_LAPLACIAN: f32 = 4.0;

/// The share of the predicted off-axis polarization taken out of the AoPs at a point whose SDF
/// has Laplacian `laplacian`: `l^2 / (l^2 + HALF_SHARE_LAPLACIAN^2)`. The prediction reads the
/// light's gradient from the specular network along the reflected direction, which is fitted
/// only where neighbouring points reflect different directions; on a flat face each view
/// reflects one direction, the gradient there is the network's guess, and a correction made of
/// it turns sound AoPs (on the Mitsuba fandisk's faces, `docs/benchmarks.md`).
pub fn correction_share(laplacian: f32) -> f32 {
    let l2 = laplacian * laplacian;
    l2 / (l2 + HALF_SHARE_LAPLACIAN * HALF_SHARE_LAPLACIAN)
}

/// The model's off-axis `(S1, S2)` ([`crate::model::Radiance::off_axis`]) at each query's point,
/// seen from its view with the given normal, scaled by the point's share (its
/// [`correction_share`]); `at_points` is the field at the points.
fn predicted_off_axis(
    model: &Model,
    params: &[f32],
    at_points: &FieldSamples,
    shares: &[f32],
    normals: &[[f32; 3]],
    queries: &[&Query],
) -> Vec<[f32; 2]> {
    if queries.is_empty() {
        return Vec::new();
    }
    let f = model.config.features;
    let flat: Vec<f32> = queries.iter().flat_map(|q| q.origin).collect();
    let features: Vec<f32> =
        queries.iter().flat_map(|q| at_points.features[f * q.point..f * (q.point + 1)].iter().copied()).collect();
    let normals: Vec<f32> = queries.iter().flat_map(|q| normalize(normals[q.point])).collect();
    let view: Vec<f32> = queries.iter().flat_map(|q| q.dir).collect();
    let frame_x: Vec<f32> = queries.iter().flat_map(|q| q.frame[1]).collect();
    let frame_y: Vec<f32> = queries.iter().flat_map(|q| q.frame[2]).collect();
    let input = ShadingInput {
        points: &flat,
        normals: &normals,
        features: &features,
        view: &view,
        frame_x: &frame_x,
        frame_y: &frame_y,
    };
    let mut off_axis = model.radiance.off_axis(params, &input);
    for (o, q) in off_axis.iter_mut().zip(queries) {
        *o = o.map(|x| x * shares[q.point]);
    }
    off_axis
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Model;

    #[test]
    fn taking_the_off_axis_part_away_returns_the_aop_of_the_rest() {
        // A normal's polarization at 30 degrees plus an off-axis part at -20 degrees.
        let (on, off) = (30f32.to_radians(), -20f32.to_radians());
        let on_axis = [0.2 * (2.0 * on).cos(), 0.2 * (2.0 * on).sin()];
        let off_axis = [0.08 * (2.0 * off).cos(), 0.08 * (2.0 * off).sin()];
        let (s1, s2) = (on_axis[0] + off_axis[0], on_axis[1] + off_axis[1]);
        let measured = 0.5 * s2.atan2(s1);
        assert!((measured - on).abs() > 5f32.to_radians(), "the off-axis part turns the AoP");
        let aop = aop_without(measured, s1.hypot(s2), off_axis);
        assert!((aop - on).abs() < 1e-5, "{} vs 30", aop.to_degrees());
        assert!((aop_without(measured, s1.hypot(s2), [0.0, 0.0]) - measured).abs() < 1e-6);
    }

    #[test]
    fn a_systematic_sample_takes_every_item_with_the_same_chance() {
        for count in 2..=24 {
            for n in 1..count {
                let offsets = 4096;
                let mut taken = vec![0usize; count];
                for k in 0..offsets {
                    let kept: Vec<usize> = systematic_sample(count, n, (k as f32 + 0.5) / offsets as f32).collect();
                    assert_eq!(kept.len(), n);
                    assert!(kept.windows(2).all(|w| w[0] < w[1]) && kept[n - 1] < count, "{kept:?}");
                    kept.iter().for_each(|&i| taken[i] += 1);
                }
                for (i, &t) in taken.iter().enumerate() {
                    let chance = t as f64 / offsets as f64;
                    assert!((chance - n as f64 / count as f64).abs() < 1e-3, "{n} of {count}: item {i} {chance}");
                }
            }
        }
    }

    #[test]
    fn the_correction_is_halved_on_a_sphere_of_radius_one_half_and_gone_on_a_plane() {
        assert_eq!(correction_share(0.0), 0.0);
        assert!((correction_share(2.0 / 0.5) - 0.5).abs() < 1e-6);
        assert_eq!(correction_share(-4.0), correction_share(4.0), "a concave sphere as a convex one");
        assert!(correction_share(2.0 / 0.1) > 0.95);
    }

    #[test]
    fn each_view_is_corrected_by_the_share_of_its_own_point() {
        let mut config = crate::presets::model(crate::presets::Preset::Fast);
        config.grid = Some((4, 12, 8, 32));
        config.specular_tilt = true;
        let model = Model::new(config);
        // Networks perturbed from their start, so that the specular light varies by direction
        // and the field's curvature from point to point.
        let mut params = model.init(3);
        let mut rng = rmvp_dataset::rng::Rng::for_pixel(7, 0, 0);
        params[..model.variance].iter_mut().for_each(|p| *p += 0.1 * rng.normal());
        let levels = vec![1.0; model.field.levels()];
        let points = [[0.45, 0.1, 0.0], [0.0, -0.2, 0.5]];
        let normals = [[1.0, 0.1, 0.0], [0.0, -0.3, 1.0]];
        let query = |point: usize, dir: [f32; 3]| {
            let dir = normalize(dir);
            let fx = normalize(cross([0.0, 1.0, 0.0], dir));
            Query {
                point,
                view: 0,
                pixel: 0,
                origin: points[point],
                dir,
                exit: 1.0,
                towards: Vector3::from(dir.map(|x| -f64::from(x))),
                frame: [dir.map(|x| -x), fx, cross(dir, fx)],
            }
        };
        let queries = [query(1, [0.2, 0.1, 1.0]), query(0, [1.0, 0.3, 0.2]), query(1, [-0.4, 0.0, 1.0])];
        let at_points = FieldSamples::infer(&model, &params, &levels, points.concat(), CURVATURE_STEP);
        let point_shares: Vec<f32> = at_points.laplacians.iter().map(|&l| correction_share(l)).collect();
        let queries: Vec<&Query> = queries.iter().collect();
        let corrected = predicted_off_axis(&model, &params, &at_points, &point_shares, &normals, &queries);
        let mut shares = Vec::new();
        for (q, got) in queries.iter().zip(&corrected) {
            // The same query alone, its field read at its point, without the share.
            let field = FieldSamples::infer(&model, &params, &levels, points[q.point].to_vec(), CURVATURE_STEP);
            let input = ShadingInput {
                points: &points[q.point],
                normals: &normalize(normals[q.point]),
                features: &field.features,
                view: &q.dir,
                frame_x: &q.frame[1],
                frame_y: &q.frame[2],
            };
            let whole = model.radiance.off_axis(&params, &input)[0];
            let share = correction_share(field.laplacians[0]);
            assert!(whole[0].hypot(whole[1]) > 1e-4, "the lobe tilts: {whole:?}");
            for k in 0..2 {
                assert!((got[k] - share * whole[k]).abs() < 1e-6, "{got:?} against {share} x {whole:?}");
            }
            shares.push(share);
        }
        assert!((shares[0] - shares[1]).abs() > 0.01, "the two points' shares differ: {shares:?}");
    }

    /// The tangents of a view along `d` whose AoP points along `e` (both unit, `e` across `d`).
    fn view(d: [f32; 3], e: [f32; 3]) -> Tangents {
        Tangents { t: cross(d, e), t_hat: e }
    }

    #[test]
    fn the_azimuthal_gradient_turns_the_normal_about_the_ray_and_matches_the_loss() {
        let d = normalize([0.2, -0.1, 1.0]);
        let e = normalize(cross(d, [0.3, 1.0, 0.1]));
        let n = normalize([0.5, 0.4, -0.6]);
        let (_, full) = tangent_loss(n, &[view(d, e)], false, 0.0);
        let (_, turning) = tangent_loss(n, &[view(d, e)], true, 0.0);
        // No part of it tilts the normal towards or away from the ray.
        assert!(dot(turning, d).abs() < 1e-6 && dot(turning, n).abs() < 1e-6, "{turning:?}");
        assert!(dot(full, d).abs() > 1e-3, "the full gradient tilts the normal here: {full:?}");
        // Along the turn about the ray, it is the loss's derivative.
        let axis = d;
        let turn = |angle: f32| {
            // Rodrigues' rotation of n about the ray.
            let (s, c) = angle.sin_cos();
            let k = cross(axis, n);
            let along = dot(axis, n) * (1.0 - c);
            [0, 1, 2].map(|i| n[i] * c + k[i] * s + axis[i] * along)
        };
        let h = 1e-2;
        let numeric = (tangent_loss(turn(h), &[view(d, e)], true, 0.0).0
            - tangent_loss(turn(-h), &[view(d, e)], true, 0.0).0)
            / (2.0 * h);
        let analytic = dot(turning, cross(axis, n));
        assert!((numeric - analytic).abs() < 1e-2 * analytic.abs() && analytic.abs() > 1e-3, "{numeric} vs {analytic}");
    }

    #[test]
    fn an_aop_that_says_nothing_pulls_the_normal_nowhere_when_it_turns_it_only() {
        // One view's AoP at evenly spread angles: the mean of what a uniformly random AoP does.
        let d = [0.0, 0.0, 1.0];
        let views: Vec<Tangents> = (0..16)
            .map(|i| (i as f32 + 0.37) * std::f32::consts::PI / 16.0)
            .map(|a| view(d, [a.cos(), a.sin(), 0.0]))
            .collect();
        let n = normalize([0.6, 0.2, -0.7]);
        let (_, full) = tangent_loss(n, &views, false, 0.0);
        let (_, turning) = tangent_loss(n, &views, true, 0.0);
        // NeRSP's gradient descends towards the camera (at -d): n.d falls.
        assert!(dot(full, d) > 1e-2, "{full:?}");
        assert!(turning.iter().all(|g| g.abs() < 1e-6), "{turning:?}");
    }

    #[test]
    fn the_robust_term_is_the_plain_one_near_the_planes_and_flattens_beyond_its_angle() {
        // A view along z whose AoP points along x; a normal across the ray at azimuth `delta`.
        let d = [0.0, 0.0, 1.0];
        let views = [view(d, [1.0, 0.0, 0.0])];
        let at = |delta: f32| [delta.cos(), delta.sin(), 0.0];
        let c = robust_scale(10.0);
        // The plain term at the robust angle is its scale.
        let (plain, _) = tangent_loss(at(10f32.to_radians()), &views, true, 0.0);
        assert!((plain - c).abs() < 1e-6, "{plain} vs {c}");
        assert_eq!(robust_scale(0.0), 0.0);
        let mut ratios = Vec::new();
        for degrees in [0.5f32, 10.0, 30.0] {
            let delta = degrees.to_radians();
            let (plain, plain_grad) = tangent_loss(at(delta), &views, true, 0.0);
            let (robust, robust_grad) = tangent_loss(at(delta), &views, true, c);
            assert!((robust - c * plain / (plain + c)).abs() < 1e-7, "{degrees}: {robust}");
            // Its derivative along the turn, against central differences.
            let h = 1e-3;
            let numeric = (tangent_loss(at(delta + h), &views, true, c).0
                - tangent_loss(at(delta - h), &views, true, c).0)
                / (2.0 * h);
            let analytic = dot(robust_grad, [-delta.sin(), delta.cos(), 0.0]);
            assert!((numeric - analytic).abs() < 2e-2 * analytic.abs(), "{degrees}: {numeric} vs {analytic}");
            let ratio = dot(robust_grad, robust_grad).sqrt() / dot(plain_grad, plain_grad).sqrt();
            let expected = (c / (plain + c)).powi(2);
            assert!((ratio - expected).abs() < 1e-4, "{degrees}: {ratio} vs {expected}");
            ratios.push(ratio);
        }
        // Near the planes the pull is the plain one; at the angle a quarter; at 30 degrees
        // (a stray AoP) under a twentieth.
        assert!(ratios[0] > 0.99 && (ratios[1] - 0.25).abs() < 1e-3 && ratios[2] < 0.05, "{ratios:?}");
    }

    #[test]
    fn the_robust_term_is_plain_on_a_face_and_flattens_stray_aops_on_a_curved_surface() {
        let d = [0.0, 0.0, 1.0];
        let views = [view(d, [1.0, 0.0, 0.0])];
        // A normal 30 degrees from the AoP's planes: a stray AoP.
        let n = [30f32.to_radians().cos(), 30f32.to_radians().sin(), 0.0];
        let c = robust_scale(20.0);
        let (plain, _) = tangent_loss(n, &views, true, 0.0);
        let on = |laplacian: f32| tangent_loss(n, &views, true, curved_robust_scale(c, correction_share(laplacian))).0;
        // A face (no curvature): NeRSP's plain term.
        assert!((on(0.0) - plain).abs() < 1e-4 * plain, "{} vs {plain}", on(0.0));
        // A sphere of radius 0.1 (share near one): nearly the full robust term, well under the plain one.
        let full = c * plain / (plain + c);
        assert!((on(2.0 / 0.1) - full).abs() < 0.05 * full && full < 0.6 * plain, "{} vs {full}", on(2.0 / 0.1));
        // In between, in between, and no robust scale stays the plain term at any curvature.
        assert!(full < on(4.0) && on(4.0) < plain);
        assert_eq!(curved_robust_scale(0.0, 0.5), 0.0);
    }
}
