//! The specular tilt's physics: where a lobe's light lies beside the mirror direction, and the
//! half vector that light turns the lobe's polarization about.

use crate::engine::vector::dot;

/// The largest shift of the mean lit reflected direction off the mirror direction (radians,
/// about): a lobe's light cannot lean farther than its own width.
pub(super) const MAX_SHIFT: f32 = 0.5;

/// The share of the lit lobe's shift ([`lit_tilt`]) that the model applies. The shift is one
/// bounce of an unshadowed lobe; on Mitsuba's renders that one-bounce prediction, made from the
/// true shape and light, explains the measured off-axis polarization best at 0.34-0.79 of its
/// scale (`docs/benchmarks.md`), the rest being shadowed, interreflected or unpolarized light.
pub(super) const TILT_SHARE: f32 = 0.5;

/// The tilt (across the unit normal `n`, [`tilted`]) of the half vector that reflects the unit
/// view direction `v` into the mean lit direction of a lobe about the mirror direction `r`
/// with variance `rough` under light whose log has gradient `grad_log` at `r`: that mean is
/// `r + rough * grad_log` across `r` (at most [`MAX_SHIFT`] away).
pub(super) fn lit_tilt(n: [f32; 3], v: [f32; 3], r: [f32; 3], rough: f32, grad_log: [f32; 3]) -> [f32; 3] {
    let along = dot(grad_log, r);
    let shift = [0, 1, 2].map(|k| rough * (grad_log[k] - along * r[k]));
    let size = dot(shift, shift).sqrt();
    let cap = if size > MAX_SHIFT { MAX_SHIFT / size } else { 1.0 };
    let mean = [0, 1, 2].map(|k| r[k] + cap * shift[k]);
    let mean_len = dot(mean, mean).sqrt();
    let m = [0, 1, 2].map(|k| v[k] + mean[k] / mean_len);
    let m_along = dot(m, n).max(1e-3);
    [0, 1, 2].map(|k| m[k] / m_along - n[k])
}

/// The specular lobe's tilted half vector (unnormalised): the unit normal `n` plus the part of
/// `tilt` across it.
pub(super) fn tilted(n: [f32; 3], tilt: [f32; 3]) -> [f32; 3] {
    let along = dot(tilt, n);
    [0, 1, 2].map(|k| n[k] + tilt[k] - along * n[k])
}
