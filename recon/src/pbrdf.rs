//! NeRSP's polarimetric shading: per-sample Stokes vectors from diffuse and specular radiance
//! with Fresnel degrees of polarization, in the ray's Stokes frame (docs/conventions.md).
//!
//! With `c = n . v` (`v` towards the camera) and `phi` the azimuth of `n` in the ray frame:
//! `S = diffuse [1, rho_d cos 2phi, rho_d sin 2phi] + specular [1, -rho_s cos 2phi, -rho_s sin 2phi]`,
//! `rho_d = (Rs - Rp) / (2 - Rs - Rp)` (transmitted light, AoP = normal azimuth) and
//! `rho_s = (Rs - Rp) / (Rs + Rp)` (reflected light, AoP rotated by 90 degrees).

use crate::engine::vector::dot;

/// Refractive index of the object (NeRSP: 1.5).
pub const ETA: f32 = 1.5;
/// Smallest `n . v` used in the Fresnel terms (grazing and back-facing samples).
pub const MIN_COS: f32 = 1e-3;

/// Fresnel reflectances `(Rs, Rp)` of a dielectric at incidence cosine `c` and their
/// derivatives with respect to `c`.
pub fn fresnel(c: f32) -> ((f32, f32), (f32, f32)) {
    let e2 = ETA * ETA;
    let g = (e2 - 1.0 + c * c).sqrt();
    let dg = c / g;
    let a = (c - g) / (c + g);
    let da = 2.0 * (g - c * dg) / ((c + g) * (c + g));
    let b = (e2 * c - g) / (e2 * c + g);
    let db = 2.0 * e2 * (g - c * dg) / ((e2 * c + g) * (e2 * c + g));
    ((a * a, b * b), (2.0 * a * da, 2.0 * b * db))
}

/// Degrees of polarization `(rho_d, rho_s)` at `n . v = c` (clamped to `[MIN_COS, 1]`) and
/// their derivatives with respect to `c` (zero where clamped).
pub fn degrees(c: f32) -> ((f32, f32), (f32, f32)) {
    let clamped = !(MIN_COS..=1.0).contains(&c);
    let c = c.clamp(MIN_COS, 1.0);
    let ((rs, rp), (drs, drp)) = fresnel(c);
    let (num, dnum) = (rs - rp, drs - drp);
    let (den_d, dden_d) = (2.0 - rs - rp, -drs - drp);
    let (den_s, dden_s) = (rs + rp, drs + drp);
    let rho_d = num / den_d;
    let rho_s = num / den_s.max(1e-12);
    if clamped {
        return ((rho_d, rho_s), (0.0, 0.0));
    }
    let d_rho_d = (dnum * den_d - num * dden_d) / (den_d * den_d);
    let d_rho_s = (dnum * den_s - num * dden_s) / (den_s * den_s).max(1e-24);
    ((rho_d, rho_s), (d_rho_d, d_rho_s))
}

/// Unpolarized Fresnel transmission out of the surface at `n . v = c` relative to normal
/// incidence, `T(c) / T(1)` with `T = 1 - (Rs + Rp) / 2` (`c` clamped to `[MIN_COS, 1]`), and
/// its derivative with respect to `c` (zero where clamped).
pub fn transmission(c: f32) -> (f32, f32) {
    let clamped = !(MIN_COS..=1.0).contains(&c);
    let ((rs, rp), (drs, drp)) = fresnel(c.clamp(MIN_COS, 1.0));
    // At normal incidence Rs = Rp = ((eta - 1) / (eta + 1))^2.
    let normal = 1.0 - ((ETA - 1.0) / (ETA + 1.0)).powi(2);
    let t = (1.0 - 0.5 * (rs + rp)) / normal;
    (t, if clamped { 0.0 } else { -0.5 * (drs + drp) / normal })
}

/// `(cos 2phi, sin 2phi)` of the azimuth of `n` in the frame `(fx, fy)`, and the gradient of each
/// with respect to `n`. Zero (no polarization) when `n` is along the ray.
pub fn double_azimuth(n: [f32; 3], fx: [f32; 3], fy: [f32; 3]) -> ((f32, f32), ([f32; 3], [f32; 3])) {
    let a = dot(n, fx);
    let b = dot(n, fy);
    let q = a * a + b * b;
    if q < 1e-12 {
        return ((0.0, 0.0), ([0.0; 3], [0.0; 3]));
    }
    let (c2, s2) = ((a * a - b * b) / q, 2.0 * a * b / q);
    // d/da, d/db of (a^2 - b^2)/q and 2ab/q.
    let dc_da = 4.0 * a * b * b / (q * q);
    let dc_db = -4.0 * a * a * b / (q * q);
    let ds_da = 2.0 * b * (b * b - a * a) / (q * q);
    let ds_db = 2.0 * a * (a * a - b * b) / (q * q);
    let dc = [0, 1, 2].map(|k| dc_da * fx[k] + dc_db * fy[k]);
    let ds = [0, 1, 2].map(|k| ds_da * fx[k] + ds_db * fy[k]);
    ((c2, s2), (dc, ds))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn degrees_match_the_textbook_formulas() {
        // Diffuse DoP (Atkinson & Hancock 2006) and specular DoP at 60 degrees, eta = 1.5.
        let theta = 60f32.to_radians();
        let (s, c, n) = (theta.sin(), theta.cos(), ETA);
        let diffuse = (n - 1.0 / n).powi(2) * s * s
            / (2.0 + 2.0 * n * n - (n + 1.0 / n).powi(2) * s * s + 4.0 * c * (n * n - s * s).sqrt());
        let specular = 2.0 * s * s * c * (n * n - s * s).sqrt() / (n * n - s * s - n * n * s * s + 2.0 * s.powi(4));
        let ((rho_d, rho_s), _) = degrees(c);
        assert!((rho_d - diffuse).abs() < 1e-5, "{rho_d} {diffuse}");
        assert!((rho_s - specular).abs() < 1e-5, "{rho_s} {specular}");
        // Brewster's angle: the specular reflection is fully polarized.
        let ((_, rho_b), _) = degrees(ETA.atan().cos());
        assert!((rho_b - 1.0).abs() < 1e-4, "{rho_b}");
    }

    #[test]
    fn transmission_follows_snell_and_fresnel() {
        // Snell's law and the Fresnel equations at 60 degrees, eta = 1.5, relative to normal
        // incidence (R = ((eta - 1) / (eta + 1))^2 there).
        let (ci, n) = (60f32.to_radians().cos(), ETA);
        let ct = (1.0 - (1.0 - ci * ci) / (n * n)).sqrt();
        let rs = ((ci - n * ct) / (ci + n * ct)).powi(2);
        let rp = ((n * ci - ct) / (n * ci + ct)).powi(2);
        let r0 = ((n - 1.0) / (n + 1.0)).powi(2);
        let expected = (1.0 - 0.5 * (rs + rp)) / (1.0 - r0);
        let (t, dt) = transmission(ci);
        assert!((t - expected).abs() < 1e-5, "{t} {expected}");
        assert!((transmission(1.0).0 - 1.0).abs() < 1e-6);
        let h = 1e-3;
        let numeric = (transmission(ci + h).0 - transmission(ci - h).0) / (2.0 * h);
        assert!((dt - numeric).abs() < 1e-3, "{dt} {numeric}");
        // Grazing views dim the diffuse lobe; beyond the clamp nothing changes.
        assert!(transmission(0.1).0 < 0.75 && transmission(-0.5) == (transmission(MIN_COS).0, 0.0));
    }
}
