//! NeRSP's networks: the SDF field ([`field`]: `paper`, an 8x256 MLP with positional encoding;
//! `fast`, a hash grid and a small MLP) and the radiance networks ([`radiance`]: diffuse,
//! roughness, specular with the integrated directional encoding), combined into per-sample Stokes
//! vectors by [`crate::pbrdf`], the specular lobe's polarization optionally turned towards its
//! light ([`tilt`]); [`Model`] assembles them over one flat parameter vector.

pub mod field;
pub mod radiance;
pub mod tilt;

pub use field::{Field, FieldCache, GridGradient};
pub use radiance::{Radiance, ShadingCache, ShadingInput, STOKES};

use crate::engine::ParamLayout;
use rmvp_dataset::rng::Rng;
use serde::{Deserialize, Serialize};

/// Network shapes.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ModelConfig {
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
    use super::tilt::{lit_tilt, tilted};
    use super::*;
    use crate::engine::vector::{cross, dot};
    use crate::presets::{self, Preset};

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
