//! The per-ray and per-sample losses, each with its derivative (the geometric loss is in
//! [`crate::geometric`]). Normalisation by batch counts and weights is left to the caller.

/// Opacity clamp of the mask loss (NeuS).
const CLAMP: f32 = 1e-3;

/// Binary cross-entropy of accumulated `opacity` against the mask; returns (loss, d/d opacity),
/// the derivative zero where the opacity is clamped.
pub fn mask_bce(opacity: f32, inside: bool) -> (f32, f32) {
    let a = opacity.clamp(CLAMP, 1.0 - CLAMP);
    let m = inside as u8 as f32;
    let loss = -(m * a.ln() + (1.0 - m) * (1.0 - a).ln());
    let d = if (CLAMP..=1.0 - CLAMP).contains(&opacity) { -(m / a - (1.0 - m) / (1.0 - a)) } else { 0.0 };
    (loss, d)
}

/// L1 distance; returns (loss, d/d prediction).
pub fn l1(prediction: f32, target: f32) -> (f32, f32) {
    let diff = prediction - target;
    (diff.abs(), diff.signum())
}

/// Eikonal term `(|g| - 1)^2`; returns (loss, d/d g).
pub fn eikonal(g: [f32; 3]) -> (f32, [f32; 3]) {
    let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt().max(1e-8);
    let s = 2.0 * (len - 1.0) / len;
    ((len - 1.0) * (len - 1.0), g.map(|v| s * v))
}

/// Curvature term `|laplacian|`; returns (loss, d/d laplacian).
pub fn curvature(laplacian: f32) -> (f32, f32) {
    (laplacian.abs(), laplacian.signum())
}
