//! NeRSP's networks: the SDF field (`paper`: 8x256 MLP with positional encoding; `fast`: hash
//! grid and a small MLP) and the radiance networks (diffuse, roughness, specular with the
//! integrated directional encoding), combined into per-sample Stokes vectors by [`crate::pbrdf`].

use crate::engine::encoding::{ide, positional_encoding, IDE_WIDTH};
use crate::engine::{hashgrid, Activation, HashGrid, Init, Mlp, MlpCache, ParamLayout};
use crate::pbrdf::{degrees, dot, double_azimuth, transmission};
use crate::presets::Preset;
use rmvp_dataset::rng::Rng;
use serde::{Deserialize, Serialize};

/// Network shapes.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ModelConfig {
    /// Which preset these shapes come from.
    pub preset: Preset,
    /// Feature vector passed from the SDF field to the radiance networks.
    pub features: usize,
    /// SDF MLP width and hidden depth.
    pub sdf_hidden: usize,
    /// Hidden layers of the SDF MLP.
    pub sdf_depth: usize,
    /// Layer receiving the skip connection.
    pub sdf_skip: Option<usize>,
    /// Positional-encoding frequencies (paper preset).
    pub frequencies: usize,
    /// Hash grid `(levels, log2 table size, coarsest, finest resolution)` (fast preset).
    pub grid: Option<(usize, u32, u32, u32)>,
    /// Radiance networks' width and hidden depth.
    pub color_hidden: usize,
    /// Hidden layers of the radiance networks.
    pub color_depth: usize,
    /// Learn one scale of the specular lobe's degree of polarization for the whole object
    /// ([`Radiance::specular_polarization`]); off: NeRSP's dielectric Fresnel as it is.
    #[serde(default)]
    pub learned_polarization: bool,
    /// Scale the diffuse lobe by its Fresnel transmission out of the surface at the view angle,
    /// `T(n.v) / T(1)` (a dielectric's diffuse light dims towards grazing views, which a
    /// view-independent diffuse network cannot follow); off: NeRSP's normalised diffuse.
    #[serde(default)]
    pub diffuse_transmission: bool,
}

/// The SDF field: point -> (SDF, features).
#[derive(Clone, Debug)]
pub struct Field {
    grid: Option<HashGrid>,
    frequencies: usize,
    mlp: Mlp,
    features: usize,
}

/// The hash grid's share of a backward pass, kept apart so that a batch's gradient need not
/// span the grid's tables (most of the parameters): where the grid was looked up, and the
/// gradient of its encoding there.
#[derive(Default)]
pub struct GridGradient {
    points: Vec<f32>,
    d_encoding: Vec<f32>,
}

/// What [`Field::forward`] keeps for [`Field::backward`].
#[derive(Default)]
pub struct FieldCache {
    points: Vec<f32>,
    mlp: MlpCache,
}

impl Field {
    /// The SDF network's parameters reserved in `layout`; the hash grid's tables (if any) are
    /// reserved later, by [`Field::reserve_grid`], after every network's.
    fn new(layout: &mut ParamLayout, config: &ModelConfig) -> Self {
        let encoded = match config.grid {
            Some((levels, ..)) => levels * hashgrid::FEATURES,
            None => 6 * config.frequencies,
        };
        let mlp = Mlp::new(
            layout,
            3 + encoded,
            config.sdf_hidden,
            config.sdf_depth,
            1 + config.features,
            Activation::Softplus(100.0),
            config.sdf_skip,
        );
        Self { grid: None, frequencies: config.frequencies, mlp, features: config.features }
    }

    /// Reserve the hash grid's tables of `config` at the end of `layout`.
    fn reserve_grid(&mut self, layout: &mut ParamLayout, config: &ModelConfig) {
        self.grid = config.grid.map(|(levels, log2, base, finest)| HashGrid::new(layout, levels, log2, base, finest));
    }

    /// Values per point: the SDF then the features.
    pub fn outputs(&self) -> usize {
        1 + self.features
    }

    /// The hash grid (None for the MLP preset).
    pub fn grid(&self) -> Option<&HashGrid> {
        self.grid.as_ref()
    }

    /// The SDF network.
    pub fn mlp(&self) -> &Mlp {
        &self.mlp
    }

    /// Hash-grid levels (0 for the MLP preset).
    pub fn levels(&self) -> usize {
        self.grid.as_ref().map_or(0, |g| g.levels())
    }

    /// The hash grid's finest active resolution under `level_weight` (None without a grid).
    pub fn finest_active(&self, level_weight: &[f32]) -> Option<u32> {
        let g = self.grid.as_ref()?;
        g.resolutions().iter().zip(level_weight).rev().find(|(_, &w)| w > 0.0).map(|(&r, _)| r)
    }

    fn encode(&self, params: &[f32], points: &[f32], level_weight: &[f32]) -> Vec<f32> {
        let n = points.len() / 3;
        let width = self.mlp.inputs();
        let mut out = vec![0f32; n * width];
        match &self.grid {
            Some(g) => {
                let mut enc = vec![0f32; n * g.outputs()];
                g.encode(params, points, level_weight, &mut enc);
                for ((o, p), e) in
                    out.chunks_exact_mut(width).zip(points.chunks_exact(3)).zip(enc.chunks_exact(g.outputs()))
                {
                    o[..3].copy_from_slice(p);
                    o[3..].copy_from_slice(e);
                }
            }
            None => positional_encoding(points, self.frequencies, &mut out),
        }
        out
    }

    /// `(n x outputs)` for `points` (n x 3), keeping what backward needs.
    pub fn forward(&self, params: &[f32], points: &[f32], level_weight: &[f32], cache: &mut FieldCache) -> Vec<f32> {
        let input = self.encode(params, points, level_weight);
        cache.points = points.to_vec();
        self.mlp.forward(params, &input, points.len() / 3, &mut cache.mlp)
    }

    /// Add the network's parameter gradients of `d_out` (n x outputs) into `grad` (which
    /// needs to cover the networks only, [`Model::network_params`]); the hash grid's are
    /// returned, to be added by [`Field::add_grid_gradients`].
    pub fn backward(&self, params: &[f32], cache: &FieldCache, d_out: &[f32], grad: &mut [f32]) -> GridGradient {
        let d_in = self.mlp.backward(params, &cache.mlp, d_out, grad);
        match &self.grid {
            Some(_) => {
                let width = self.mlp.inputs();
                let d_encoding = d_in.chunks_exact(width).flat_map(|row| row[3..].iter().copied()).collect();
                GridGradient { points: cache.points.clone(), d_encoding }
            }
            None => GridGradient::default(),
        }
    }

    /// Add the hash grid's parameter gradients of `parts` into `grad` (all parameters),
    /// level by level in parallel, each level's parts in order.
    pub fn add_grid_gradients(&self, parts: &[&GridGradient], level_weight: &[f32], grad: &mut [f32]) {
        if let Some(g) = &self.grid {
            let batches: Vec<(&[f32], &[f32])> =
                parts.iter().map(|p| (p.points.as_slice(), p.d_encoding.as_slice())).collect();
            g.backward_batches(&batches, level_weight, grad);
        }
    }

    /// `(n x outputs)` for `points` (n x 3), keeping nothing (inference).
    pub fn infer(&self, params: &[f32], points: &[f32], level_weight: &[f32]) -> Vec<f32> {
        let input = self.encode(params, points, level_weight);
        self.mlp.infer(params, &input, points.len() / 3)
    }

    /// The SDF alone (inference).
    pub fn sdf(&self, params: &[f32], points: &[f32], level_weight: &[f32]) -> Vec<f32> {
        self.infer(params, points, level_weight).chunks_exact(self.outputs()).map(|r| r[0]).collect()
    }

    fn init(&self, params: &mut [f32], rng: &mut Rng) {
        self.mlp.init(params, Init::Sphere(0.5), rng);
        if let Some(g) = &self.grid {
            g.init(params, rng);
        }
    }
}

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
}

/// The three radiance networks, and the specular lobe's polarization scale when it is learned.
#[derive(Clone, Debug)]
pub struct Radiance {
    diffuse: Mlp,
    roughness: Mlp,
    specular: Mlp,
    features: usize,
    polarization: Option<usize>,
    diffuse_transmission: bool,
}

fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

impl Radiance {
    fn new(layout: &mut ParamLayout, config: &ModelConfig) -> Self {
        let (f, h, d) = (config.features, config.color_hidden, config.color_depth);
        Self {
            diffuse: Mlp::new(layout, 6 + f, h, d, 3, Activation::Relu, None),
            roughness: Mlp::new(layout, 3 + f, h, d.min(2), 1, Activation::Relu, None),
            specular: Mlp::new(layout, IDE_WIDTH + 1 + f, h, d, 3, Activation::Relu, None),
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

    fn init(&self, params: &mut [f32], rng: &mut Rng) {
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
        mut cache: Option<&mut ShadingCache>,
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
        let (mut roughness_value, mut ide_jacobian) = (Vec::new(), Vec::new());
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
            for i in 0..n {
                let (nv, v) = (row3(s.normals, i), row3(s.view, i));
                let c = dot(nv, v);
                let reflected = [0, 1, 2].map(|k| 2.0 * c * nv[k] - v[k]);
                let (values, jac) = ide(reflected, roughness_value[i]);
                input.extend_from_slice(&values);
                input.push(c);
                input.extend_from_slice(&s.features[f * i..f * (i + 1)]);
                ide_jacobian.push(jac);
            }
            specular_rgb = self
                .specular
                .evaluate(params, &input, n, cache.as_deref_mut().map(|c| &mut c.specular))
                .iter()
                .map(|&x| sigmoid(x))
                .collect();
        }
        let scale = self.specular_polarization(params);
        let mut stokes = vec![0f32; STOKES * n];
        for i in 0..n {
            let nv = row3(s.normals, i);
            let c = dot(nv, row3(s.view, i));
            let ((rho_d, rho_s), _) = degrees(c);
            let rho_s = scale * rho_s;
            let (t, _) = self.transmission(c);
            let ((c2, s2), _) = double_azimuth(nv, row3(s.frame_x, i), row3(s.frame_y, i));
            let out = &mut stokes[STOKES * i..STOKES * (i + 1)];
            for ch in 0..3 {
                let (d, sp) = (t * diffuse_rgb[3 * i + ch], specular_rgb[3 * i + ch]);
                let polarized = rho_d * d - rho_s * sp;
                out[ch] = d + sp;
                out[3 + ch] = polarized * c2;
                out[6 + ch] = polarized * s2;
            }
        }
        if let Some(cache) = cache {
            cache.diffuse_only = diffuse_only;
            cache.roughness_value = roughness_value;
            cache.ide_jacobian = ide_jacobian;
            cache.diffuse_rgb = diffuse_rgb;
            cache.specular_rgb = specular_rgb;
        }
        stokes
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
            let ((c2, s2), (dc2, ds2)) = double_azimuth(nv, row3(s.frame_x, i), row3(s.frame_y, i));
            let (t, dt) = self.transmission(c);
            let g = &d_stokes[STOKES * i..STOKES * (i + 1)];
            let (mut g_rho_d, mut g_rho_s, mut g_c2, mut g_s2, mut g_t) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for ch in 0..3 {
                let (raw, sp) = (cache.diffuse_rgb[3 * i + ch], cache.specular_rgb[3 * i + ch]);
                let d = t * raw;
                let along = g[3 + ch] * c2 + g[6 + ch] * s2;
                let polarized = rho_d * d - rho_s * sp;
                g_rho_d += d * along;
                g_rho_s -= sp * along;
                g_c2 += polarized * g[3 + ch];
                g_s2 += polarized * g[6 + ch];
                g_t += (g[ch] + rho_d * along) * raw;
                d_diffuse_raw[3 * i + ch] = (g[ch] + rho_d * along) * t * raw * (1.0 - raw);
                if !cache.diffuse_only {
                    d_specular_raw[3 * i + ch] = (g[ch] - rho_s * along) * sp * (1.0 - sp);
                }
            }
            d_cos[i] = g_rho_d * drho_d + g_rho_s * drho_s + g_t * dt;
            d_scale += g_rho_s * fresnel_s;
            for k in 0..3 {
                d_normal[3 * i + k] += g_c2 * dc2[k] + g_s2 * ds2[k];
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
                    for a in 0..3 {
                        d_reflected[a] += row[k] * dw[a];
                    }
                    d_rough += row[k] * dr;
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

/// The whole model: field, radiance and the NeuS variance, over one flat parameter vector.
#[derive(Clone, Debug)]
pub struct Model {
    /// Network shapes.
    pub config: ModelConfig,
    /// Layout of the parameter vector.
    pub layout: ParamLayout,
    /// The SDF field.
    pub field: Field,
    /// The radiance networks.
    pub radiance: Radiance,
    /// Offset of the variance parameter (`inv_s = exp(VARIANCE_SCALE * variance)`).
    pub variance: usize,
    network_params: usize,
}

/// NeuS's initial variance parameter.
pub const INITIAL_VARIANCE: f32 = 0.3;
/// NeuS's sharpness is `s = exp(VARIANCE_SCALE * variance)` (the official code: 10).
pub const VARIANCE_SCALE: f32 = 10.0;

impl Model {
    /// Build the shapes of `config`.
    pub fn new(config: ModelConfig) -> Self {
        // The networks first, the hash grid's tables last: a batch's network gradient is then a
        // short prefix of the parameter vector (see `Field::backward`).
        let mut layout = ParamLayout::default();
        let mut field = Field::new(&mut layout, &config);
        let mut radiance = Radiance::new(&mut layout, &config);
        let variance = layout.reserve(1, crate::engine::Group::Variance);
        if config.learned_polarization {
            radiance.polarization = Some(layout.reserve(1, crate::engine::Group::Network));
        }
        let network_params = layout.len();
        field.reserve_grid(&mut layout, &config);
        Self { config, layout, field, radiance, variance, network_params }
    }

    /// Parameters of the networks and the variance: the vector's first ones, before the hash
    /// grid's tables.
    pub fn network_params(&self) -> usize {
        self.network_params
    }

    /// Initial parameters (geometric initialisation to a sphere of radius 0.5).
    pub fn init(&self, seed: u64) -> Vec<f32> {
        let mut params = vec![0f32; self.layout.len()];
        let mut rng = Rng::for_pixel(seed, u32::MAX, 0);
        self.field.init(&mut params, &mut rng);
        self.radiance.init(&mut params, &mut rng);
        params[self.variance] = INITIAL_VARIANCE;
        if let Some(p) = self.radiance.polarization {
            params[p] = 1.0;
        }
        params
    }

    /// NeuS's inverse standard deviation `s = exp(VARIANCE_SCALE variance)`.
    pub fn inv_s(&self, params: &[f32]) -> f32 {
        // Capped at 1e6, but a NaN variance stays NaN (f32::min would hide it).
        let s = (VARIANCE_SCALE * params[self.variance]).exp();
        if s > 1e6 {
            1e6
        } else {
            s
        }
    }
}
