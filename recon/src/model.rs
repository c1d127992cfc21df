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
    /// Let the specular lobe's polarization turn off the normal: the half vector whose plane of
    /// incidence sets the specular AoP leans towards the light that the specular network says
    /// lies beside the mirror direction ([`Radiance::off_axis`]); off: NeRSP's lobe, polarized
    /// about the normal.
    #[serde(default)]
    pub specular_tilt: bool,
    /// Radius of the sphere the SDF starts from (NeuS's geometric initialisation), in the
    /// scene's unit sphere: the surface grows out of it to meet the masks, so a concavity
    /// that the masks do not show stays open only if the start lies inside it.
    #[serde(default = "neus_initial_radius")]
    pub initial_radius: f32,
}

/// NeuS's initial sphere, radius 0.5 of the unit sphere (and checkpoints from before the radius
/// was recorded).
pub fn neus_initial_radius() -> f32 {
    0.5
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

    fn init(&self, params: &mut [f32], radius: f32, rng: &mut Rng) {
        self.mlp.init(params, Init::Sphere(radius), rng);
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
    polarization: Option<usize>,
    diffuse_transmission: bool,
}

/// The largest shift of the mean lit reflected direction off the mirror direction (radians,
/// about): a lobe's light cannot lean farther than its own width.
const MAX_SHIFT: f32 = 0.5;

/// The share of the lit lobe's shift ([`lit_tilt`]) that the model applies. The shift is one
/// bounce of an unshadowed lobe; on Mitsuba's renders that one-bounce prediction, made from the
/// true shape and light, explains the measured off-axis polarization best at 0.34-0.79 of its
/// scale (`docs/benchmarks.md`), the rest being shadowed, interreflected or unpolarized light.
const TILT_SHARE: f32 = 0.5;

/// The tilt (across the unit normal `n`, [`tilted`]) of the half vector that reflects the unit
/// view direction `v` into the mean lit direction of a lobe about the mirror direction `r`
/// with variance `rough` under light whose log has gradient `grad_log` at `r`: that mean is
/// `r + rough * grad_log` across `r` (at most [`MAX_SHIFT`] away).
fn lit_tilt(n: [f32; 3], v: [f32; 3], r: [f32; 3], rough: f32, grad_log: [f32; 3]) -> [f32; 3] {
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

fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// The specular lobe's tilted half vector (unnormalised): the unit normal `n` plus the part of
/// `tilt` across it.
fn tilted(n: [f32; 3], tilt: [f32; 3]) -> [f32; 3] {
    let along = dot(tilt, n);
    [0, 1, 2].map(|k| n[k] + tilt[k] - along * n[k])
}

impl Radiance {
    fn new(layout: &mut ParamLayout, config: &ModelConfig) -> Self {
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
        cache: Option<&mut ShadingCache>,
    ) -> Vec<f32> {
        self.shade_tilted(params, s, diffuse_only, cache, None)
    }

    /// [`Radiance::shade`] with the lobe's tilts given (`tilts`, one per sample) instead of
    /// read from the light, as the backward pass sees them.
    fn shade_tilted(
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

    /// Initial parameters (geometric initialisation to a sphere of
    /// [`ModelConfig::initial_radius`]).
    pub fn init(&self, seed: u64) -> Vec<f32> {
        let mut params = vec![0f32; self.layout.len()];
        let mut rng = Rng::for_pixel(seed, u32::MAX, 0);
        self.field.init(&mut params, self.config.initial_radius, &mut rng);
        self.radiance.init(&mut params, &mut rng);
        params[self.variance] = INITIAL_VARIANCE;
        if let Some(p) = self.radiance.polarization {
            params[p] = 1.0;
        }
        params
    }

    /// Where the start `params` (from [`Model::init`]) has no surface, the initial radius
    /// above which it would: the SDF at the centre is that radius less
    /// [`ModelConfig::initial_radius`] (the radius is the last layer's bias, and nothing else
    /// depends on it). The paper network's softplus layers lift the centre by about 0.32, so a
    /// start of 0.2 leaves its SDF positive everywhere and nothing to grow from.
    pub fn start_without_surface(&self, params: &[f32]) -> Option<f32> {
        let level_weight = vec![1.0; self.field.levels()];
        let centre = self.field.sdf(params, &[0.0; 3], &level_weight)[0];
        (centre >= 0.0).then_some(self.config.initial_radius + centre)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pbrdf::cross;
    use crate::presets;

    /// `n` random unit vectors.
    fn unit_vectors(n: usize, rng: &mut Rng) -> Vec<f32> {
        (0..n)
            .flat_map(|_| {
                let v = [rng.normal(), rng.normal(), rng.normal()];
                let l = dot(v, v).sqrt();
                v.map(|x| x / l)
            })
            .collect()
    }

    /// `n` random shading samples: points, unit normals, features, views 17 to 69 degrees off
    /// their normals in random azimuths, and each ray's Stokes frame.
    struct Samples {
        points: Vec<f32>,
        normals: Vec<f32>,
        features: Vec<f32>,
        view: Vec<f32>,
        frame_x: Vec<f32>,
        frame_y: Vec<f32>,
    }

    impl Samples {
        fn new(n: usize, features: usize, rng: &mut Rng) -> Self {
            let points: Vec<f32> = (0..3 * n).map(|_| rng.next_f32() - 0.5).collect();
            let normals = unit_vectors(n, rng);
            let features: Vec<f32> = (0..n * features).map(|_| rng.normal()).collect();
            let (mut view, mut frame_x, mut frame_y) = (Vec::new(), Vec::new(), Vec::new());
            for nv in normals.chunks_exact(3) {
                let nv = [nv[0], nv[1], nv[2]];
                let u = [rng.normal(), rng.normal(), rng.normal()];
                let along = dot(u, nv);
                let t = [0, 1, 2].map(|k| u[k] - along * nv[k]);
                let t = t.map(|x| x / dot(t, t).sqrt());
                let angle = 0.3 + 0.9 * rng.next_f32();
                let v = [0, 1, 2].map(|k| angle.cos() * nv[k] + angle.sin() * t[k]);
                let a = if v[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
                let along = dot(a, v);
                let x = [0, 1, 2].map(|k| a[k] - along * v[k]);
                let x = x.map(|c| c / dot(x, x).sqrt());
                view.extend_from_slice(&v);
                frame_x.extend_from_slice(&x);
                frame_y.extend_from_slice(&cross(v, x));
            }
            Self { points, normals, features, view, frame_x, frame_y }
        }

        /// The samples with the given normals.
        fn input<'a>(&'a self, normals: &'a [f32]) -> ShadingInput<'a> {
            ShadingInput {
                points: &self.points,
                normals,
                features: &self.features,
                view: &self.view,
                frame_x: &self.frame_x,
                frame_y: &self.frame_y,
            }
        }
    }

    #[test]
    fn the_field_starts_as_a_blob_of_the_initial_radius_around_the_centre() {
        // The geometric initialisation approximates a sphere: along rays from the centre the
        // zero crossing (found by bisection) lies between 0.4 and 1.5 radii in every direction
        // (the fast preset's two-layer network gives 0.46-1.38), and a smaller radius shrinks it.
        let mut rng = Rng::for_pixel(3, 0, 0);
        let directions = unit_vectors(20, &mut rng);
        let mean_crossing = |preset: Preset, radius: f32| {
            let model = Model::new(ModelConfig { initial_radius: radius, ..presets::model(preset) });
            let params = model.init(7);
            let lw = vec![1.0; model.config.grid.map_or(0, |g| g.0)];
            let sdf = |p: [f32; 3]| model.field.sdf(&params, &p, &lw)[0];
            assert!(sdf([0.0; 3]) < 0.0, "{preset:?}, radius {radius}: the centre is outside");
            let mut sum = 0.0;
            for d in directions.chunks_exact(3) {
                let at = |t: f32| [d[0] * t, d[1] * t, d[2] * t];
                let (mut inside, mut outside) = (0.0f32, 1.0f32);
                assert!(sdf(at(outside)) > 0.0, "{preset:?}, radius {radius}: the unit sphere is inside");
                for _ in 0..30 {
                    let mid = 0.5 * (inside + outside);
                    if sdf(at(mid)) < 0.0 {
                        inside = mid;
                    } else {
                        outside = mid;
                    }
                }
                let share = inside / radius;
                assert!((0.4..1.5).contains(&share), "{preset:?}, radius {radius}: surface at {inside:.3}");
                sum += inside;
            }
            sum / 20.0
        };
        assert!(mean_crossing(Preset::Paper, 0.5) > 0.3);
        let (small, neus) = (mean_crossing(Preset::Fast, 0.2), mean_crossing(Preset::Fast, 0.5));
        assert!(small < 0.5 * neus, "radius 0.2: mean surface at {small:.3}, radius 0.5: {neus:.3}");
    }

    #[test]
    fn a_start_without_a_surface_is_found_with_the_radius_it_needs() {
        let start = |preset: Preset, radius: f32| {
            let model = Model::new(ModelConfig { initial_radius: radius, ..presets::model(preset) });
            model.start_without_surface(&model.init(0))
        };
        assert_eq!(start(Preset::Fast, 0.2), None);
        assert_eq!(start(Preset::Paper, 0.5), None);
        let least = start(Preset::Paper, 0.2).expect("the paper network at 0.2 starts without a surface");
        assert!((0.25..0.45).contains(&least), "{least}");
        // The same threshold from any radius below it; just above it the start has a surface.
        assert!((start(Preset::Paper, 0.1).unwrap() - least).abs() < 1e-4);
        assert_eq!(start(Preset::Paper, least + 0.01), None);
        assert!(start(Preset::Paper, least - 0.01).is_some());
    }

    #[test]
    fn the_lit_tilt_reflects_the_view_into_the_light_weighted_mean_of_the_lobe() {
        // A von Mises-Fisher lobe of concentration 1 / rough about the mirror direction under
        // light exp(a . w), integrated over the sphere (Fibonacci points): its light-weighted mean
        // direction is where the tilted half vector must reflect the view.
        let n = [0.0, 0.0, 1.0];
        for (v, rough, a) in [
            ([0.6f32, 0.0, 0.8], 0.05f32, [0.0f32, 2.0, 0.0]),
            ([0.0, -0.8, 0.6], 0.1, [1.5, 0.0, 0.0]),
            ([0.3, 0.4, 0.866], 0.02, [-3.0, 1.0, 0.5]),
        ] {
            let l = dot(v, v).sqrt();
            let v = v.map(|x| x / l);
            let c = dot(n, v);
            let r = [0, 1, 2].map(|k| 2.0 * c * n[k] - v[k]);
            // The light's gradient across r (its part along r changes no direction's weight
            // relative to its neighbours' to first order, and the formula drops it).
            let along = dot(a, r);
            let a = [0, 1, 2].map(|k| a[k] - along * r[k]);
            let count = 400_000;
            let mut mean = [0f64; 3];
            for i in 0..count {
                let z = 1.0 - (2.0 * i as f64 + 1.0) / count as f64;
                let phi = i as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
                let s = (1.0 - z * z).sqrt();
                let w = [s * phi.cos(), s * phi.sin(), z];
                let e = |d: [f32; 3]| (0..3).map(|k| d[k] as f64 * w[k]).sum::<f64>();
                let weight = ((e(r) - 1.0) / rough as f64 + e(a)).exp();
                (0..3).for_each(|k| mean[k] += weight * w[k]);
            }
            let len = mean.iter().map(|x| x * x).sum::<f64>().sqrt();
            let mean = mean.map(|x| (x / len) as f32);
            let tilt = lit_tilt(n, v, r, rough, a);
            assert!(dot(tilt, n).abs() < 1e-6, "the tilt lies across the normal");
            let h = tilted(n, tilt);
            let h_len = dot(h, h).sqrt();
            let h = h.map(|x| x / h_len);
            let hv = dot(h, v);
            let reflected = [0, 1, 2].map(|k| 2.0 * hv * h[k] - v[k]);
            let angle = dot(reflected, mean).clamp(-1.0, 1.0).acos().to_degrees();
            let shift = dot(r, mean).clamp(-1.0, 1.0).acos().to_degrees();
            assert!(shift > 3.0, "the light moves the lobe's mean by {shift} degrees");
            assert!(angle < 0.02 * shift, "reflected {reflected:?}, lobe mean {mean:?} ({angle} degrees apart)");
        }
    }

    #[test]
    fn the_off_axis_part_is_what_the_tilt_adds_to_the_shaded_polarization() {
        let mut config = presets::model(Preset::Fast);
        config.grid = Some((4, 12, 8, 32));
        config.specular_tilt = true;
        let model = Model::new(config);
        // Networks livelier than at their start, so that the specular light varies by direction.
        let mut params = model.init(3);
        params[..model.variance].iter_mut().for_each(|p| *p *= 3.0);
        let radiance = &model.radiance;
        let n = 64;
        let samples = Samples::new(n, model.config.features, &mut Rng::for_pixel(5, 0, 0));
        let input = samples.input(&samples.normals);
        // The same parameters shaded by NeRSP's lobe, polarized about the normal.
        let untilted = Model::new(ModelConfig { specular_tilt: false, ..model.config.clone() });
        assert_eq!(untilted.layout.len(), model.layout.len(), "the tilt has no parameters of its own");
        let untilted = untilted.radiance.shade(&params, &input, false, None);
        let tilted = radiance.shade(&params, &input, false, None);
        let off_axis = radiance.off_axis(&params, &input);
        let mut largest = 0f32;
        for i in 0..n {
            let mean = |s: &[f32], k: usize| s[STOKES * i + 3 * k..STOKES * i + 3 * k + 3].iter().sum::<f32>() / 3.0;
            assert!((mean(&tilted, 0) - mean(&untilted, 0)).abs() < 1e-6, "the tilt changes no intensity");
            for (k, d) in [1, 2].into_iter().zip(off_axis[i]) {
                let added = mean(&tilted, k) - mean(&untilted, k);
                assert!((added - d).abs() < 1e-5, "sample {i} S{k}: {added} vs {d}");
                largest = largest.max(d.abs());
            }
        }
        assert!(largest > 1e-2, "the tilt should turn some samples' polarization: {largest}");
    }

    #[test]
    fn the_normals_gradient_holds_with_the_tilt_held() {
        let mut config = presets::model(Preset::Fast);
        config.grid = Some((4, 12, 8, 32));
        config.specular_tilt = true;
        config.diffuse_transmission = true;
        let model = Model::new(config);
        let params = model.init(7);
        let radiance = &model.radiance;
        let n = 32;
        let mut rng = Rng::for_pixel(9, 0, 0);
        let samples = Samples::new(n, model.config.features, &mut rng);
        let normals = samples.normals.clone();
        let weights: Vec<f32> = (0..STOKES * n).map(|_| rng.normal()).collect();
        let shaded = |normals: &[f32], tilts: &[[f32; 3]]| {
            let stokes = radiance.shade_tilted(&params, &samples.input(normals), false, None, Some(tilts));
            stokes.iter().zip(&weights).map(|(a, b)| (a * b) as f64).sum::<f64>()
        };
        let s = samples.input(&normals);
        // Tilts of about 15 degrees, held as the backward pass holds them.
        let tilts: Vec<[f32; 3]> = (0..n).map(|_| [0, 1, 2].map(|_| 0.15 * rng.normal())).collect();
        let mut cache = ShadingCache::default();
        radiance.shade_tilted(&params, &s, false, Some(&mut cache), Some(&tilts));
        let mut grad = vec![0f32; params.len()];
        let (d_normal, _) = radiance.shade_backward(&params, &s, &cache, &weights, &mut grad);
        let h = 1e-3;
        let mut worst = 0f64;
        for j in 0..3 * n {
            let (mut up, mut down) = (normals.clone(), normals.clone());
            up[j] += h;
            down[j] -= h;
            let numeric = (shaded(&up, &tilts) - shaded(&down, &tilts)) / (2.0 * h as f64);
            let scale = numeric.abs().max(d_normal[j].abs() as f64).max(1e-2);
            worst = worst.max((numeric - d_normal[j] as f64).abs() / scale);
        }
        assert!(worst < 2e-2, "largest relative error of d/dn: {worst}");
    }
}
