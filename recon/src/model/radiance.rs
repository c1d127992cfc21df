//! The radiance networks and their composition through the pBRDF into per-sample Stokes vectors.

use super::tilt::{lit_tilt, tilted, TILT_SHARE};
use super::ModelConfig;
use crate::engine::encoding::{ide, IDE_WIDTH};
use crate::engine::vector::{dot, sigmoid};
use crate::engine::{Activation, Init, Mlp, MlpCache, ParamLayout};
use crate::pbrdf::{degrees, double_azimuth, transmission};
use rmvp_dataset::rng::Rng;

/// Everything the radiance networks see at a batch of `n` samples (row-major `n x k`).
pub struct ShadingInput<'a> {
    /// Sample positions (n x 3).
    pub points: &'a [f32],
    /// Unit normals (n x 3).
    pub normals: &'a [f32],
    /// Field features (n x features).
    pub features: &'a [f32],
    /// Unit directions towards the camera (n x 3).
    pub view: &'a [f32],
    /// The ray's Stokes frame x axis (n x 3).
    pub frame_x: &'a [f32],
    /// The ray's Stokes frame y axis (n x 3).
    pub frame_y: &'a [f32],
}

/// Values per sample of the shaded Stokes vector: S0, S1, S2 for R, G, B.
pub const STOKES: usize = 9;

/// What [`Radiance::shade`] keeps for the backward pass.
#[derive(Default)]
pub struct ShadingCache {
    diffuse_only: bool,
    diffuse: MlpCache,
    roughness: MlpCache,
    specular: MlpCache,
    diffuse_rgb: Vec<f32>,
    specular_rgb: Vec<f32>,
    roughness_value: Vec<f32>,
    ide_jacobian: Vec<[([f32; 3], f32); IDE_WIDTH]>,
    tilt_value: Vec<[f32; 3]>,
    off_axis: Vec<[f32; 2]>,
}

/// The three radiance networks, the specular lobe's polarization scale when it is learned and
/// whether its lobe tilts towards its light.
#[derive(Clone, Debug)]
pub struct Radiance {
    diffuse: Mlp,
    roughness: Mlp,
    specular: Mlp,
    tilt: bool,
    features: usize,
    pub(super) polarization: Option<usize>,
    diffuse_transmission: bool,
}

impl Radiance {
    pub(super) fn new(layout: &mut ParamLayout, config: &ModelConfig) -> Self {
        let (f, h, d) = (config.features, config.color_hidden, config.color_depth);
        Self {
            diffuse: Mlp::new(layout, 6 + f, h, d, 3, Activation::Relu, None),
            roughness: Mlp::new(layout, 3 + f, h, d.min(2), 1, Activation::Relu, None),
            specular: Mlp::new(layout, IDE_WIDTH + 1 + f, h, d, 3, Activation::Relu, None),
            tilt: config.specular_tilt,
            features: f,
            polarization: None,
            diffuse_transmission: config.diffuse_transmission,
        }
    }

    /// The scale of the specular lobe's Fresnel degree of polarization, in [0, 1]: 1 is NeRSP's
    /// dielectric (eta = 1.5); a conductor's reflection is nearly unpolarized (gold: at most
    /// 0.07 where the dielectric reaches 1), which the fixed dielectric could only match by
    /// turning normals towards the camera. Learned, one number per object, when the model has
    /// it; its gradient passes the clamp unchanged, so it can return from beyond [0, 1].
    pub fn specular_polarization(&self, params: &[f32]) -> f32 {
        self.polarization.map_or(1.0, |i| params[i].clamp(0.0, 1.0))
    }

    /// Whether the specular lobe's polarization can turn off the normal
    /// ([`ModelConfig::specular_tilt`]).
    pub fn tilts(&self) -> bool {
        self.tilt
    }

    /// Where the polarization scale sits in the parameter vector, when it is learned.
    pub fn polarization_parameter(&self) -> Option<usize> {
        self.polarization
    }

    /// The learned polarization scale ([`Radiance::specular_polarization`]); `None` when the
    /// model keeps NeRSP's fixed dielectric.
    pub fn learned_polarization(&self, params: &[f32]) -> Option<f32> {
        self.polarization.map(|_| self.specular_polarization(params))
    }

    /// The diffuse lobe's factor at `n . v = c` and its derivative with respect to `c`: 1 and 0
    /// without [`ModelConfig::diffuse_transmission`], else the Fresnel transmission relative to
    /// normal incidence ([`transmission`]).
    fn transmission(&self, c: f32) -> (f32, f32) {
        if self.diffuse_transmission {
            transmission(c)
        } else {
            (1.0, 0.0)
        }
    }

    pub(super) fn init(&self, params: &mut [f32], rng: &mut Rng) {
        for mlp in [&self.diffuse, &self.roughness, &self.specular] {
            mlp.init(params, Init::Default, rng);
        }
    }

    /// Shade `n` samples into Stokes vectors (n x 9), keeping what backward needs in `cache`
    /// when there is one. `diffuse_only` switches the specular lobe off (NeRSP's first
    /// iterations).
    pub fn shade(
        &self,
        params: &[f32],
        s: &ShadingInput,
        diffuse_only: bool,
        cache: Option<&mut ShadingCache>,
    ) -> Vec<f32> {
        self.shade_tilted(params, s, diffuse_only, cache, None)
    }

    /// [`Radiance::shade`] with the lobe's tilts given (`tilts`, one per sample) instead of
    /// read from the light, as the backward pass sees them.
    pub(super) fn shade_tilted(
        &self,
        params: &[f32],
        s: &ShadingInput,
        diffuse_only: bool,
        mut cache: Option<&mut ShadingCache>,
        tilts: Option<&[[f32; 3]]>,
    ) -> Vec<f32> {
        let n = s.points.len() / 3;
        let f = self.features;
        let row3 = |a: &[f32], i: usize| [a[3 * i], a[3 * i + 1], a[3 * i + 2]];
        let mut input = Vec::with_capacity(n * (6 + f));
        for i in 0..n {
            input.extend_from_slice(&s.points[3 * i..3 * i + 3]);
            input.extend_from_slice(&s.normals[3 * i..3 * i + 3]);
            input.extend_from_slice(&s.features[f * i..f * (i + 1)]);
        }
        let diffuse_rgb: Vec<f32> = self
            .diffuse
            .evaluate(params, &input, n, cache.as_deref_mut().map(|c| &mut c.diffuse))
            .iter()
            .map(|&x| sigmoid(x))
            .collect();
        let mut specular_rgb = vec![0f32; 3 * n];
        let (mut roughness_value, mut ide_jacobian, mut tilt_value) = (Vec::new(), Vec::new(), Vec::new());
        if !diffuse_only {
            let mut input = Vec::with_capacity(n * (3 + f));
            for i in 0..n {
                input.extend_from_slice(&s.points[3 * i..3 * i + 3]);
                input.extend_from_slice(&s.features[f * i..f * (i + 1)]);
            }
            roughness_value = self
                .roughness
                .evaluate(params, &input, n, cache.as_deref_mut().map(|c| &mut c.roughness))
                .iter()
                .map(|&x| sigmoid(x))
                .collect();
            let mut input = Vec::with_capacity(n * (IDE_WIDTH + 1 + f));
            // Each sample's reflected view and n . v, which the tilt reads again.
            let mut reflections = Vec::with_capacity(if self.tilt { n } else { 0 });
            for i in 0..n {
                let (nv, v) = (row3(s.normals, i), row3(s.view, i));
                let c = dot(nv, v);
                let reflected = [0, 1, 2].map(|k| 2.0 * c * nv[k] - v[k]);
                let (values, jac) = ide(reflected, roughness_value[i]);
                input.extend_from_slice(&values);
                input.push(c);
                input.extend_from_slice(&s.features[f * i..f * (i + 1)]);
                ide_jacobian.push(jac);
                if self.tilt {
                    reflections.push((reflected, c));
                }
            }
            specular_rgb = self
                .specular
                .evaluate(params, &input, n, cache.as_deref_mut().map(|c| &mut c.specular))
                .iter()
                .map(|&x| sigmoid(x))
                .collect();
            if self.tilt {
                tilt_value = match tilts {
                    Some(tilts) => tilts.to_vec(),
                    None => self.lit_tilts(params, s, &reflections, &roughness_value, &specular_rgb),
                };
            }
        }
        let scale = self.specular_polarization(params);
        let mut stokes = vec![0f32; STOKES * n];
        let mut off_axis = Vec::with_capacity(tilt_value.len());
        for i in 0..n {
            let nv = row3(s.normals, i);
            let c = dot(nv, row3(s.view, i));
            let ((rho_d, rho_s), _) = degrees(c);
            let rho_s = scale * rho_s;
            let (t, _) = self.transmission(c);
            let (fx, fy) = (row3(s.frame_x, i), row3(s.frame_y, i));
            let ((c2, s2), _) = double_azimuth(nv, fx, fy);
            let ((c2h, s2h), _) = match tilt_value.get(i) {
                Some(&tilt) => double_azimuth(tilted(nv, tilt), fx, fy),
                None => ((c2, s2), ([0.0; 3], [0.0; 3])),
            };
            let out = &mut stokes[STOKES * i..STOKES * (i + 1)];
            for ch in 0..3 {
                let (d, sp) = (t * diffuse_rgb[3 * i + ch], specular_rgb[3 * i + ch]);
                out[ch] = d + sp;
                out[3 + ch] = rho_d * d * c2 - rho_s * sp * c2h;
                out[6 + ch] = rho_d * d * s2 - rho_s * sp * s2h;
            }
            if !tilt_value.is_empty() {
                let amplitude = -rho_s * specular_rgb[3 * i..3 * i + 3].iter().sum::<f32>() / 3.0;
                off_axis.push([amplitude * (c2h - c2), amplitude * (s2h - s2)]);
            }
        }
        if let Some(cache) = cache {
            cache.off_axis = off_axis;
            cache.diffuse_only = diffuse_only;
            cache.roughness_value = roughness_value;
            cache.ide_jacobian = ide_jacobian;
            cache.diffuse_rgb = diffuse_rgb;
            cache.specular_rgb = specular_rgb;
            cache.tilt_value = tilt_value;
        }
        stokes
    }

    /// The tilt of each sample's mean lit half vector off the normal, read from the specular
    /// network itself: that network gives the environment filtered by the lobe as a function of
    /// the reflected direction `r`, and for a lobe of variance `rough` about `r` the mean of the
    /// directions it gathers, weighted by their light, is `r + rough * grad log L(r)` (Tweedie's
    /// formula for the heat kernel that the IDE's attenuation is), of which [`TILT_SHARE`] is
    /// applied. The gradient comes from forward differences of the network (channel mean) along
    /// the three axes, projected across `r`; the tilt is held fixed in the backward pass, so it
    /// follows the light the radiance fits and no loss can bend it to excuse a wrong normal.
    /// `reflections` holds each sample's `r` and `n . v`, as the specular network read them.
    fn lit_tilts(
        &self,
        params: &[f32],
        s: &ShadingInput,
        reflections: &[([f32; 3], f32)],
        roughness: &[f32],
        specular_rgb: &[f32],
    ) -> Vec<[f32; 3]> {
        const STEP: f32 = 0.02;
        let n = s.points.len() / 3;
        let f = self.features;
        let row3 = |a: &[f32], i: usize| [a[3 * i], a[3 * i + 1], a[3 * i + 2]];
        let mut input = Vec::with_capacity(3 * n * (IDE_WIDTH + 1 + f));
        for (i, &(r, c)) in reflections.iter().enumerate() {
            for axis in 0..3 {
                let mut w = r;
                w[axis] += STEP;
                let (values, _) = ide(w, roughness[i]);
                input.extend_from_slice(&values);
                input.push(c);
                input.extend_from_slice(&s.features[f * i..f * (i + 1)]);
            }
        }
        let shifted = self.specular.evaluate(params, &input, 3 * n, None);
        (0..n)
            .map(|i| {
                let (nv, v, r) = (row3(s.normals, i), row3(s.view, i), reflections[i].0);
                let here = specular_rgb[3 * i..3 * i + 3].iter().sum::<f32>() / 3.0;
                let rows = &shifted[9 * i..9 * (i + 1)];
                let g = [0, 1, 2].map(|a| {
                    let there = rows[3 * a..3 * a + 3].iter().map(|&x| sigmoid(x)).sum::<f32>() / 3.0;
                    (there - here) / (STEP * here.max(1e-3))
                });
                lit_tilt(nv, v, r, TILT_SHARE * roughness[i], g)
            })
            .collect()
    }

    /// The part of each sample's channel-mean `(S1, S2)` that the specular lobe's tilt adds to
    /// NeRSP's lobe polarized about the normal (zero when the lobe does not tilt): what a measured
    /// AoP holds that no normal's plane explains, for the geometric cue to take away.
    pub fn off_axis(&self, params: &[f32], s: &ShadingInput) -> Vec<[f32; 2]> {
        let n = s.points.len() / 3;
        if !self.tilt {
            return vec![[0.0; 2]; n];
        }
        let mut cache = ShadingCache::default();
        self.shade(params, s, false, Some(&mut cache));
        cache.off_axis
    }

    /// Backward of [`Radiance::shade`]: parameter gradients into `grad`; returns the gradients
    /// with respect to the normals (n x 3) and the features (n x features).
    pub fn shade_backward(
        &self,
        params: &[f32],
        s: &ShadingInput,
        cache: &ShadingCache,
        d_stokes: &[f32],
        grad: &mut [f32],
    ) -> (Vec<f32>, Vec<f32>) {
        let n = s.points.len() / 3;
        let f = self.features;
        let row3 = |a: &[f32], i: usize| [a[3 * i], a[3 * i + 1], a[3 * i + 2]];
        let mut d_normal = vec![0f32; 3 * n];
        let mut d_features = vec![0f32; f * n];
        let mut d_diffuse_raw = vec![0f32; 3 * n];
        let mut d_specular_raw = vec![0f32; 3 * n];
        let mut d_cos = vec![0f32; n];
        let scale = self.specular_polarization(params);
        let mut d_scale = 0f32;
        for i in 0..n {
            let (nv, v) = (row3(s.normals, i), row3(s.view, i));
            let c = dot(nv, v);
            let ((rho_d, fresnel_s), (drho_d, dfresnel_s)) = degrees(c);
            let (rho_s, drho_s) = (scale * fresnel_s, scale * dfresnel_s);
            let (fx, fy) = (row3(s.frame_x, i), row3(s.frame_y, i));
            let ((c2, s2), (dc2, ds2)) = double_azimuth(nv, fx, fy);
            let tilt = cache.tilt_value.get(i).copied().unwrap_or([0.0; 3]);
            let ((c2h, s2h), (dc2h, ds2h)) = double_azimuth(tilted(nv, tilt), fx, fy);
            let (t, dt) = self.transmission(c);
            let g = &d_stokes[STOKES * i..STOKES * (i + 1)];
            let (mut g_rho_d, mut g_rho_s, mut g_t) = (0.0, 0.0, 0.0);
            let (mut g_c2, mut g_s2, mut g_c2h, mut g_s2h) = (0.0, 0.0, 0.0, 0.0);
            for ch in 0..3 {
                let (raw, sp) = (cache.diffuse_rgb[3 * i + ch], cache.specular_rgb[3 * i + ch]);
                let d = t * raw;
                let along = g[3 + ch] * c2 + g[6 + ch] * s2;
                let along_h = g[3 + ch] * c2h + g[6 + ch] * s2h;
                g_rho_d += d * along;
                g_rho_s -= sp * along_h;
                g_c2 += rho_d * d * g[3 + ch];
                g_s2 += rho_d * d * g[6 + ch];
                g_c2h -= rho_s * sp * g[3 + ch];
                g_s2h -= rho_s * sp * g[6 + ch];
                g_t += (g[ch] + rho_d * along) * raw;
                d_diffuse_raw[3 * i + ch] = (g[ch] + rho_d * along) * t * raw * (1.0 - raw);
                if !cache.diffuse_only {
                    d_specular_raw[3 * i + ch] = (g[ch] - rho_s * along_h) * sp * (1.0 - sp);
                }
            }
            d_cos[i] = g_rho_d * drho_d + g_rho_s * drho_s + g_t * dt;
            d_scale += g_rho_s * fresnel_s;
            // The tilted half vector m = n + tilt - (tilt . n) n.
            let d_m = [0, 1, 2].map(|k| g_c2h * dc2h[k] + g_s2h * ds2h[k]);
            let (across, m_along) = (1.0 - dot(tilt, nv), dot(d_m, nv));
            for k in 0..3 {
                d_normal[3 * i + k] += g_c2 * dc2[k] + g_s2 * ds2[k] + d_m[k] * across - tilt[k] * m_along;
            }
        }
        if let Some(p) = self.polarization {
            grad[p] += d_scale;
        }
        let d_in = self.diffuse.backward(params, &cache.diffuse, &d_diffuse_raw, grad);
        let width = 6 + f;
        for i in 0..n {
            let row = &d_in[width * i..width * (i + 1)];
            for k in 0..3 {
                d_normal[3 * i + k] += row[3 + k];
            }
            d_features[f * i..f * (i + 1)].iter_mut().zip(&row[6..]).for_each(|(a, b)| *a += b);
        }
        if !cache.diffuse_only {
            let d_in = self.specular.backward(params, &cache.specular, &d_specular_raw, grad);
            let width = IDE_WIDTH + 1 + f;
            let mut d_rough_raw = vec![0f32; n];
            for i in 0..n {
                let row = &d_in[width * i..width * (i + 1)];
                let (nv, v) = (row3(s.normals, i), row3(s.view, i));
                let c = dot(nv, v);
                let mut d_reflected = [0f32; 3];
                let mut d_rough = 0f32;
                for (k, (dw, dr)) in cache.ide_jacobian[i].iter().enumerate() {
                    let d_value = row[k];
                    for a in 0..3 {
                        d_reflected[a] += d_value * dw[a];
                    }
                    d_rough += d_value * dr;
                }
                let r = cache.roughness_value[i];
                d_rough_raw[i] = d_rough * r * (1.0 - r);
                // reflected = 2 c n - v, c = n . v (also a direct input).
                let dc = row[IDE_WIDTH] + 2.0 * dot(d_reflected, nv);
                for a in 0..3 {
                    d_normal[3 * i + a] += 2.0 * c * d_reflected[a];
                }
                d_cos[i] += dc;
                d_features[f * i..f * (i + 1)].iter_mut().zip(&row[IDE_WIDTH + 1..]).for_each(|(a, b)| *a += b);
            }
            let d_in = self.roughness.backward(params, &cache.roughness, &d_rough_raw, grad);
            let width = 3 + f;
            for i in 0..n {
                d_features[f * i..f * (i + 1)]
                    .iter_mut()
                    .zip(&d_in[width * i + 3..width * (i + 1)])
                    .for_each(|(a, b)| *a += b);
            }
        }
        for i in 0..n {
            let v = row3(s.view, i);
            for a in 0..3 {
                d_normal[3 * i + a] += d_cos[i] * v[a];
            }
        }
        (d_normal, d_features)
    }
}
