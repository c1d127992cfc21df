//! The polarimetric BRDF of NeRSP/PANDORA (Baek et al. 2018), as Mitsuba 3's `pplastic`:
//!
//! - diffuse: light refracts in (unpolarized transmittance `T+(theta_l)`), scatters (albedo, a
//!   depolarizer) and refracts out, which polarizes it parallel to the plane of the normal and
//!   the view: `albedo / pi * cos(theta_l) * T+(theta_l) * [T+, T- cos 2phi_n, T- sin 2phi_n]`,
//!   `T+- = (T_p +- T_s) / 2` at the view angle;
//! - specular: GGX microfacets reflecting with Fresnel, polarized perpendicular to the plane of
//!   the half vector and the view: `D G / (4 cos(theta_v)) * [R+, -R- cos 2phi_h, -R- sin 2phi_h]`,
//!   `R+- = (R_s +- R_p) / 2` at the angle between light and half vector.
//!
//! `phi_n`, `phi_h` are azimuths in the pixel's Stokes frame
//! ([`rmvp_dataset::Camera::stokes_frame`]), so diffuse AoP = normal azimuth and specular AoP =
//! half-vector azimuth + 90 degrees.

use crate::math::Vec3;
use std::f32::consts::PI;

/// Which reflection lobes a surface has.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Lobes {
    /// Diffuse and specular (Mitsuba `pplastic`).
    #[default]
    Plastic,
    /// The diffuse lobe alone (with its Fresnel transmission).
    Diffuse,
    /// The specular lobe alone.
    Specular,
    /// Ideal Lambertian, unpolarized, no Fresnel (for energy tests).
    Lambertian,
}

/// The interface's optics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Interface {
    /// A dielectric of relative refractive index `eta` (default 1.5).
    Dielectric(f32),
    /// A conductor of complex index `n + i k` (no diffuse lobe).
    Conductor(f32, f32),
}

impl Interface {
    /// The relative refractive index of a dielectric unless told otherwise (glass, plastics).
    pub const DEFAULT_ETA: f32 = 1.5;
}

/// Fresnel intensity reflectances `(R_s, R_p)` of a dielectric (index `eta`) lit from outside.
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> (f32, f32) {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return (1.0, 1.0);
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    (rs * rs, rp * rp)
}

/// Fresnel intensity reflectances `(R_s, R_p)` of a conductor of index `n + i k`.
pub fn fresnel_conductor(cos_i: f32, n: f32, k: f32) -> (f32, f32) {
    let c = cos_i.clamp(1e-6, 1.0);
    let s2 = 1.0 - c * c;
    let t0 = n * n - k * k - s2;
    let a2b2 = (t0 * t0 + 4.0 * n * n * k * k).sqrt();
    let a = (0.5 * (a2b2 + t0)).max(0.0).sqrt();
    let rs = (a2b2 - 2.0 * a * c + c * c) / (a2b2 + 2.0 * a * c + c * c);
    let st = s2 / c; // sin(theta) tan(theta)
    let rp = rs * (a2b2 - 2.0 * a * st + st * st) / (a2b2 + 2.0 * a * st + st * st);
    (rs, rp)
}

/// GGX normal distribution at `cos_h` = n . h.
pub fn ggx_d(cos_h: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let t = cos_h * cos_h * (a2 - 1.0) + 1.0;
    a2 / (PI * t * t)
}

/// Smith masking of GGX for one direction at `cos` to the normal.
pub fn smith_g1(cos: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    2.0 * cos / (cos + (a2 + (1.0 - a2) * cos * cos).sqrt())
}

/// Linear Stokes `(S0, S1, S2)` per colour channel.
pub type StokesRgb = [[f32; 3]; 3];

/// Add `weight[c] * polarization[k]` to Stokes component `k` of channel `c`.
fn add_stokes(s: &mut StokesRgb, weight: [f32; 3], polarization: [f32; 3]) {
    for (row, p) in s.iter_mut().zip(polarization) {
        for (v, w) in row.iter_mut().zip(weight) {
            *v += w * p;
        }
    }
}

/// Surface properties at a shading point.
#[derive(Clone, Copy, Debug)]
pub struct Surface {
    /// Diffuse albedo (RGB).
    pub albedo: [f32; 3],
    /// GGX roughness (alpha).
    pub alpha: f32,
    /// Optics of the interface.
    pub interface: Interface,
    /// Lobes present.
    pub lobes: Lobes,
}

/// The local geometry of a shading evaluation: unit normal, direction to the viewer, and the
/// pixel's Stokes frame.
#[derive(Clone, Copy, Debug)]
pub struct ShadingFrame {
    /// Shading normal.
    pub n: Vec3,
    /// Unit direction towards the camera.
    pub v: Vec3,
    /// Stokes frame x axis.
    pub x: Vec3,
    /// Stokes frame y axis.
    pub y: Vec3,
}

impl ShadingFrame {
    /// `(cos 2phi, sin 2phi)` of the azimuth of `a` in the Stokes frame.
    fn double_azimuth(&self, a: Vec3) -> (f32, f32) {
        let (ax, ay) = (a.dot(self.x), a.dot(self.y));
        let r2 = ax * ax + ay * ay;
        if r2 <= 1e-20 {
            return (0.0, 0.0);
        }
        ((ax * ax - ay * ay) / r2, 2.0 * ax * ay / r2)
    }
}

impl Surface {
    fn has_diffuse(&self) -> bool {
        matches!(self.lobes, Lobes::Plastic | Lobes::Diffuse | Lobes::Lambertian)
            && matches!(self.interface, Interface::Dielectric(_))
    }

    fn has_specular(&self) -> bool {
        matches!(self.lobes, Lobes::Plastic | Lobes::Specular)
    }

    fn reflectance(&self, cos: f32) -> (f32, f32) {
        match self.interface {
            Interface::Dielectric(eta) => fresnel_dielectric(cos, eta),
            Interface::Conductor(n, k) => fresnel_conductor(cos, n, k),
        }
    }

    /// Probability of sampling the specular lobe.
    fn specular_probability(&self) -> f32 {
        match (self.has_specular(), self.has_diffuse()) {
            (true, true) => 1.0 / (1.0 + (self.albedo[0] + self.albedo[1] + self.albedo[2]) / 3.0),
            (true, false) => 1.0,
            _ => 0.0,
        }
    }

    /// Outgoing Stokes towards the viewer per unit radiance arriving from `l` (unit, towards the
    /// light), cosine included: the integrand of the reflection integral.
    pub fn eval(&self, f: &ShadingFrame, l: Vec3) -> StokesRgb {
        let mut s = [[0.0f32; 3]; 3];
        let (cos_v, cos_l) = (f.n.dot(f.v), f.n.dot(l));
        if cos_v <= 0.0 || cos_l <= 0.0 {
            return s;
        }
        if self.has_diffuse() {
            if self.lobes == Lobes::Lambertian {
                add_stokes(&mut s, self.albedo.map(|a| a * cos_l / PI), [1.0, 0.0, 0.0]);
            } else {
                let (rs_l, rp_l) = self.reflectance(cos_l);
                let (rs_v, rp_v) = self.reflectance(cos_v);
                let (t_s, t_p) = (1.0 - rs_v, 1.0 - rp_v);
                let (t_plus, t_minus) = (0.5 * (t_s + t_p), 0.5 * (t_p - t_s));
                let (c2, s2) = f.double_azimuth(f.n);
                let k = cos_l / PI * (1.0 - 0.5 * (rs_l + rp_l));
                add_stokes(&mut s, self.albedo.map(|a| a * k), [t_plus, t_minus * c2, t_minus * s2]);
            }
        }
        if self.has_specular() {
            let h = (l + f.v).normalize();
            let cos_h = f.n.dot(h);
            if cos_h > 0.0 {
                let value = ggx_d(cos_h, self.alpha) * smith_g1(cos_v, self.alpha) * smith_g1(cos_l, self.alpha)
                    / (4.0 * cos_v);
                let (rs, rp) = self.reflectance(l.dot(h));
                let (r_plus, r_minus) = (0.5 * (rs + rp), 0.5 * (rs - rp));
                let (c2, s2) = f.double_azimuth(h);
                add_stokes(&mut s, [value; 3], [r_plus, -r_minus * c2, -r_minus * s2]);
            }
        }
        s
    }

    /// Sample a light direction from the BRDF with three uniform numbers; `None` below the surface.
    pub fn sample(&self, f: &ShadingFrame, r0: f32, r1: f32, r2: f32) -> Option<Vec3> {
        let (t, b) = f.n.basis();
        let l = if r0 < self.specular_probability() {
            let tan2 = self.alpha * self.alpha * r1 / (1.0 - r1).max(1e-12);
            let cos_h = 1.0 / (1.0 + tan2).sqrt();
            let sin_h = (1.0 - cos_h * cos_h).max(0.0).sqrt();
            let phi = 2.0 * PI * r2;
            let h = t * (sin_h * phi.cos()) + b * (sin_h * phi.sin()) + f.n * cos_h;
            h * (2.0 * f.v.dot(h)) - f.v
        } else {
            let r = r1.sqrt();
            let phi = 2.0 * PI * r2;
            t * (r * phi.cos()) + b * (r * phi.sin()) + f.n * (1.0 - r1).max(0.0).sqrt()
        };
        (f.n.dot(l) > 0.0).then_some(l)
    }

    /// Solid-angle density of [`Surface::sample`] at `l`.
    pub fn pdf(&self, f: &ShadingFrame, l: Vec3) -> f32 {
        let cos_l = f.n.dot(l);
        if cos_l <= 0.0 {
            return 0.0;
        }
        let p_spec = self.specular_probability();
        let mut pdf = (1.0 - p_spec) * cos_l / PI;
        if p_spec > 0.0 {
            let h = (l + f.v).normalize();
            let cos_h = f.n.dot(h);
            let vh = f.v.dot(h);
            if cos_h > 0.0 && vh > 0.0 {
                pdf += p_spec * ggx_d(cos_h, self.alpha) * cos_h / (4.0 * vh);
            }
        }
        pdf
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_limits() {
        let (rs, rp) = fresnel_dielectric(1.0, 1.5);
        assert!((rs - 0.04).abs() < 1e-6 && (rp - 0.04).abs() < 1e-6);
        // Brewster's angle: no p reflection.
        let brewster = 1.5f32.atan();
        assert!(fresnel_dielectric(brewster.cos(), 1.5).1 < 1e-7);
        let (rs, rp) = fresnel_dielectric(1e-4, 1.5);
        assert!(rs > 0.999 && rp > 0.99);
        // A conductor with k = 0 is a dielectric.
        for cos in [1.0, 0.7, 0.3] {
            let (a, b) = (fresnel_conductor(cos, 1.5, 0.0), fresnel_dielectric(cos, 1.5));
            assert!((a.0 - b.0).abs() < 1e-5 && (a.1 - b.1).abs() < 1e-5, "{cos}: {a:?} {b:?}");
        }
    }

    #[test]
    fn ggx_is_normalised() {
        // Integral of D(h) cos(theta_h) over the hemisphere is 1.
        for alpha in [0.05f32, 0.2, 0.6] {
            let n = 200_000;
            let mut sum = 0.0f64;
            for i in 0..n {
                let cos = (i as f32 + 0.5) / n as f32;
                sum += (ggx_d(cos, alpha) * cos) as f64 * 2.0 * std::f64::consts::PI / n as f64;
            }
            assert!((sum - 1.0).abs() < 2e-3, "alpha {alpha}: {sum}");
        }
    }

    #[test]
    fn sampling_density_matches_pdf() {
        let surface =
            Surface { albedo: [0.5; 3], alpha: 0.2, interface: Interface::Dielectric(1.5), lobes: Lobes::Plastic };
        let v = Vec3::new(0.3, 0.0, 1.0).normalize();
        let f =
            ShadingFrame { n: Vec3::new(0.0, 0.0, 1.0), v, x: Vec3::new(1.0, 0.0, 0.0), y: Vec3::new(0.0, 1.0, 0.0) };
        // E[g(l) / pdf(l)] over BRDF samples equals the integral of g: take g = 1 on the hemisphere.
        let mut rng = rmvp_dataset::rng::Rng::for_pixel(2, 0, 0);
        let n = 200_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            if let Some(l) = surface.sample(&f, rng.next_f32(), rng.next_f32(), rng.next_f32()) {
                sum += 1.0 / surface.pdf(&f, l) as f64;
            }
        }
        let estimate = sum / n as f64;
        assert!((estimate / (2.0 * std::f64::consts::PI) - 1.0).abs() < 0.03, "{estimate}");
    }
}
