//! Unpolarized environment light from a lat-long map, with importance sampling.
//!
//! Directions map to the map as in Mitsuba 3's `envmap` (world +Y up, top row = +Y):
//! `u = atan2(d.x, -d.z) / 2pi` (wrapped to `[0, 1)`), `v = acos(d.y) / pi`; texel `(i, j)` has
//! its centre at `((i + 0.5) / W, (j + 0.5) / H)`. Radiance is interpolated bilinearly (wrapping
//! in u, clamped in v); sampling follows the piecewise-constant luminance times `sin(theta)`.

use crate::math::Vec3;
use crate::{Error, Result};
use rmvp_dataset::Image;
use std::f32::consts::{PI, TAU};

/// An environment map ready for lookups and importance sampling.
pub struct EnvMap {
    width: usize,
    height: usize,
    rgb: Vec<[f32; 3]>,
    /// Cumulative distribution over rows (`height + 1` entries, last = 1).
    row_cdf: Vec<f32>,
    /// Per row, cumulative distribution over columns (`width + 1` entries each).
    col_cdf: Vec<f32>,
    /// Per texel, probability mass.
    texel_pmf: Vec<f32>,
    /// Rows of the rotation from the world frame to the map's frame (+Y up), if not identity.
    to_map: Option<[Vec3; 3]>,
}

impl EnvMap {
    /// From an RGB (or more channels: the first three are used) lat-long image.
    pub fn new(image: &Image<f32>) -> Result<Self> {
        let (w, h, c) = (image.width(), image.height(), image.channels());
        if c < 3 || w < 1 || h < 1 {
            return Err(Error::EnvironmentNotRgb { width: w, height: h, channels: c });
        }
        if let Some((x, y, ch)) = image.first_non_finite() {
            return Err(Error::EnvironmentNotFinite { x, y, channel: ch });
        }
        let rgb: Vec<[f32; 3]> =
            image.data().chunks_exact(c).map(|p| [p[0].max(0.0), p[1].max(0.0), p[2].max(0.0)]).collect();
        let mut weights = vec![0.0f32; w * h];
        for j in 0..h {
            let sin_theta = (PI * (j as f32 + 0.5) / h as f32).sin();
            for i in 0..w {
                let p = rgb[j * w + i];
                weights[j * w + i] = (0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]) * sin_theta + 1e-12;
            }
        }
        let total: f64 = weights.iter().map(|&x| x as f64).sum();
        let texel_pmf: Vec<f32> = weights.iter().map(|&x| (x as f64 / total) as f32).collect();
        let mut row_cdf = vec![0.0f32; h + 1];
        let mut col_cdf = vec![0.0f32; h * (w + 1)];
        let mut acc = 0.0f64;
        for j in 0..h {
            let row = &texel_pmf[j * w..(j + 1) * w];
            let row_sum: f64 = row.iter().map(|&x| x as f64).sum();
            let mut c = 0.0f64;
            for i in 0..w {
                c += row[i] as f64;
                col_cdf[j * (w + 1) + i + 1] = (c / row_sum) as f32;
            }
            col_cdf[j * (w + 1) + w] = 1.0;
            acc += row_sum;
            row_cdf[j + 1] = acc as f32;
        }
        row_cdf[h] = 1.0;
        Ok(Self { width: w, height: h, rgb, row_cdf, col_cdf, texel_pmf, to_map: None })
    }

    /// A constant environment of radiance `rgb`.
    pub fn uniform(rgb: [f32; 3]) -> Self {
        Self::new(&Image::from_vec(2, 1, 3, [rgb, rgb].concat()).expect("2x1")).expect("finite")
    }

    /// The built-in environment ([`procedural_image`]).
    pub fn procedural() -> Self {
        Self::new(&procedural_image()).expect("finite")
    }

    /// The same light in a world whose directions `d` are `rotation * d` in the map's frame
    /// (the map's +Y up; e.g. a world with +Z up, as a calibration board's frame).
    pub fn with_rotation(mut self, rotation: &nalgebra::Matrix3<f64>) -> Self {
        let row = |i: usize| Vec3::new(rotation[(i, 0)] as f32, rotation[(i, 1)] as f32, rotation[(i, 2)] as f32);
        self.to_map = Some([row(0), row(1), row(2)]);
        self
    }

    /// A world direction in the map's frame.
    fn world_to_map(&self, d: Vec3) -> Vec3 {
        match &self.to_map {
            Some([x, y, z]) => Vec3::new(x.dot(d), y.dot(d), z.dot(d)),
            None => d,
        }
    }

    /// A direction in the map's frame in the world.
    fn map_to_world(&self, d: Vec3) -> Vec3 {
        match &self.to_map {
            Some([x, y, z]) => *x * d.x + *y * d.y + *z * d.z,
            None => d,
        }
    }

    /// Radiance arriving from direction `d` (unit, pointing away from the scene).
    pub fn eval(&self, d: Vec3) -> [f32; 3] {
        let (u, v) = uv(self.world_to_map(d));
        self.eval_uv(u, v)
    }

    /// Radiance and solid-angle density of [`EnvMap::sample`] at direction `d`, in one lookup.
    pub fn eval_and_pdf(&self, d: Vec3) -> ([f32; 3], f32) {
        let d = self.world_to_map(d);
        let (u, v) = uv(d);
        (self.eval_uv(u, v), self.pdf_uv(u, v, d.y))
    }

    /// Bilinearly interpolated radiance at map coordinates `(u, v)`.
    fn eval_uv(&self, u: f32, v: f32) -> [f32; 3] {
        let x = u * self.width as f32 - 0.5;
        let y = (v * self.height as f32 - 0.5).clamp(0.0, (self.height - 1) as f32);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let col = |i: f32| (i as isize).rem_euclid(self.width as isize) as usize;
        let row = |j: f32| (j as usize).min(self.height - 1);
        let at = |i: f32, j: f32| self.rgb[row(j) * self.width + col(i)];
        let (a, b, c, e) = (at(x0, y0), at(x0 + 1.0, y0), at(x0, y0 + 1.0), at(x0 + 1.0, y0 + 1.0));
        [0, 1, 2].map(|k| (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + e[k] * fx) * fy)
    }

    /// This light as a `width x height` lat-long image of world directions: texel `(u, v)`
    /// holds [`EnvMap::eval`] of the world direction the module's mapping gives it (the map
    /// turned into the world frame, e.g. a dataset's `gt/env.exr`).
    pub fn world_image(&self, width: usize, height: usize) -> Image<f32> {
        let mut data = Vec::with_capacity(width * height * 3);
        for j in 0..height {
            for i in 0..width {
                let d = direction((i as f32 + 0.5) / width as f32, (j as f32 + 0.5) / height as f32);
                data.extend(self.eval(d));
            }
        }
        Image::from_vec(width, height, 3, data).expect("sized")
    }

    /// Solid-angle density of [`EnvMap::sample`] at direction `d`.
    pub fn pdf(&self, d: Vec3) -> f32 {
        let d = self.world_to_map(d);
        let (u, v) = uv(d);
        self.pdf_uv(u, v, d.y)
    }

    /// [`EnvMap::pdf`] at map coordinates, `cos_theta` being the direction's y.
    fn pdf_uv(&self, u: f32, v: f32, cos_theta: f32) -> f32 {
        let i = ((u * self.width as f32) as usize).min(self.width - 1);
        let j = ((v * self.height as f32) as usize).min(self.height - 1);
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        if sin_theta <= 1e-6 {
            return 0.0;
        }
        self.texel_pmf[j * self.width + i] * (self.width * self.height) as f32 / (2.0 * PI * PI * sin_theta)
    }

    /// Importance-sample a direction from two uniform numbers: `(direction, pdf, radiance)`.
    pub fn sample(&self, r1: f32, r2: f32) -> (Vec3, f32, [f32; 3]) {
        let j = self.row_cdf.partition_point(|&c| c <= r1).saturating_sub(1).min(self.height - 1);
        let row_pmf = (self.row_cdf[j + 1] - self.row_cdf[j]).max(1e-30);
        let dv = ((r1 - self.row_cdf[j]) / row_pmf).clamp(0.0, 1.0);
        let cdf = &self.col_cdf[j * (self.width + 1)..(j + 1) * (self.width + 1)];
        let i = cdf.partition_point(|&c| c <= r2).saturating_sub(1).min(self.width - 1);
        let du = ((r2 - cdf[i]) / (cdf[i + 1] - cdf[i]).max(1e-30)).clamp(0.0, 1.0);
        let (u, v) = ((i as f32 + du) / self.width as f32, (j as f32 + dv) / self.height as f32);
        let d = direction(u, v);
        (self.map_to_world(d), self.pdf_uv(u, v, d.y), self.eval_uv(u, v))
    }
}

/// The built-in studio-like environment, 256x128 lat-long: a bright sky gradient over a darker
/// floor, a sun and two soft area lights, so that reflective objects show highlights.
pub fn procedural_image() -> Image<f32> {
    let (w, h) = (256usize, 128usize);
    let mut data = Vec::with_capacity(w * h * 3);
    let sun = direction(0.15, 0.25);
    let panels = [direction(0.6, 0.35), direction(0.85, 0.45)];
    for j in 0..h {
        for i in 0..w {
            let d = direction((i as f32 + 0.5) / w as f32, (j as f32 + 0.5) / h as f32);
            let sky =
                if d.y > 0.0 { [0.55 + 0.35 * d.y, 0.65 + 0.3 * d.y, 0.8 + 0.2 * d.y] } else { [0.18, 0.16, 0.14] };
            let mut rgb = sky;
            if d.dot(sun) > 0.995 {
                rgb = [40.0, 36.0, 30.0];
            }
            for p in &panels {
                if d.dot(*p) > 0.97 {
                    rgb = [6.0, 6.0, 6.5];
                }
            }
            data.extend(rgb);
        }
    }
    Image::from_vec(w, h, 3, data).expect("sized")
}

/// Map coordinates of a direction.
fn uv(d: Vec3) -> (f32, f32) {
    let u = rmvp_dataset::polarization::atan2(d.x, -d.z) / TAU;
    (u - u.floor(), d.y.clamp(-1.0, 1.0).acos() / PI)
}

/// The direction at map coordinates `(u, v)`.
fn direction(u: f32, v: f32) -> Vec3 {
    let (sp, cp) = (TAU * u).sin_cos();
    let (st, ct) = (PI * v).sin_cos();
    Vec3::new(sp * st, ct, -cp * st)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rmvp_dataset::rng::Rng;

    #[test]
    fn mapping_round_trips_and_puts_the_top_row_up() {
        for (u, v) in [(0.1, 0.2), (0.7, 0.9), (0.5, 0.5)] {
            let (u2, v2) = uv(direction(u, v));
            assert!((u2 - u).abs() < 1e-5 && (v2 - v).abs() < 1e-5);
        }
        assert!(direction(0.3, 0.0).y > 0.999);
        // Mitsuba: u = 0 looks down -Z, u = 0.25 down +X.
        assert!(direction(0.0, 0.5).z < -0.999 && direction(0.25, 0.5).x > 0.999);
    }

    #[test]
    fn a_rotated_map_looks_up_the_rotated_direction() {
        // Board frame (+Z up) to the map's frame (+Y up): a quarter turn about x.
        let rotation = nalgebra::Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0);
        let (base, turned) = (EnvMap::procedural(), EnvMap::procedural().with_rotation(&rotation));
        let up_in_board = Vec3::new(0.0, 0.0, 1.0);
        assert_eq!(turned.eval(up_in_board), base.eval(Vec3::new(0.0, 1.0, 0.0)));
        let d = Vec3::new(0.3, -0.5, 0.81).normalize();
        let r = Vec3::new(d.x, d.z, -d.y);
        assert_eq!(turned.eval_and_pdf(d), base.eval_and_pdf(r));
        let (sampled, pdf, _) = turned.sample(0.3, 0.7);
        assert!((turned.pdf(sampled) - pdf).abs() <= 1e-3 * pdf);
    }

    #[test]
    fn sampling_density_integrates_to_one_and_matches_pdf() {
        let env = EnvMap::procedural();
        // Monte Carlo estimate of the integral of radiance two ways must agree.
        let mut rng = Rng::for_pixel(1, 0, 0);
        let n = 200_000;
        let (mut importance, mut uniform) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let (d, pdf, radiance) = env.sample(rng.next_f32(), rng.next_f32());
            assert!((pdf - env.pdf(d)).abs() <= 1e-3 * pdf, "{pdf} vs {}", env.pdf(d));
            assert!((radiance[1] - env.eval(d)[1]).abs() <= 1e-3 * radiance[1] + 1e-5);
            importance += (radiance[1] / pdf) as f64;
            let z = 1.0 - 2.0 * rng.next_f32();
            let phi = TAU * rng.next_f32();
            let r = (1.0 - z * z).sqrt();
            uniform += (env.eval(Vec3::new(r * phi.cos(), z, r * phi.sin()))[1] * 4.0 * PI) as f64;
        }
        let (a, b) = (importance / n as f64, uniform / n as f64);
        assert!((a - b).abs() / b < 0.03, "importance {a} vs uniform {b}");
    }
}
