//! Rendered light through the sensor model to raw frames, and back through the capture chain:
//! the Stokes images return within the noise the model injected.

use rmvp_capture::sensor::SensorModel;
use rmvp_capture::FrameProcessor;
use rmvp_dataset::Stokes;
use rmvp_render::pbrdf::{Interface, Lobes};
use rmvp_render::rig::{look_at, rig_intrinsics};
use rmvp_render::{default_mesh, render_view, EnvMap, Object, Settings};

const W: u32 = 320;
const H: u32 = 256;

fn rendered() -> (Stokes, Vec<bool>) {
    // Smooth light (diffuse spot, uniform sky), so that the rendered Stokes are smooth at the
    // pixel scale and demosaicing interpolation is not mistaken for noise.
    let object = Object::new(&default_mesh(), Interface::Dielectric(1.5), Lobes::Diffuse).unwrap();
    let k = rig_intrinsics(W, H);
    let camera =
        look_at(k, nalgebra::Vector3::new(1.5, 0.8, 3.0), nalgebra::Vector3::zeros(), nalgebra::Vector3::y(), W, H);
    let view = render_view(&object, &EnvMap::uniform([0.9, 1.0, 1.1]), &camera, Settings { spp: 64, seed: 3 }, 0);
    // Compare away from silhouettes and texture edges, where demosaicing interpolates across
    // different surfaces: pixels whose 5x5 neighbourhood is all object.
    let (w, h) = (W as usize, H as usize);
    let inside = |x: usize, y: usize| view.mask.data()[y * w + x] > 0;
    let interior = (0..w * h)
        .map(|k| {
            let (x, y) = (k % w, k / w);
            x >= 2 && y >= 2 && x + 2 < w && y + 2 < h && (0..25).all(|d| inside(x + d % 5 - 2, y + d / 5 - 2))
        })
        .collect();
    let blur = |image: &rmvp_dataset::Image<f32>| (0..3).fold(image.clone(), |img, _| box3(&img));
    let smooth = Stokes { s0: blur(&view.stokes.s0), s1: blur(&view.stokes.s1), s2: blur(&view.stokes.s2) };
    (smooth, interior)
}

/// A 3x3 box filter (edges clamped): what remains of Monte Carlo noise after three passes is
/// far below the sensor noise, so the filtered image is a smooth ground truth.
fn box3(image: &rmvp_dataset::Image<f32>) -> rmvp_dataset::Image<f32> {
    let (w, h, c) = (image.width(), image.height(), image.channels());
    let mut out = image.clone();
    for y in 0..h {
        for x in 0..w {
            for ch in 0..c {
                let mut sum = 0.0;
                for d in 0..9 {
                    let (xx, yy) = ((x + d % 3).clamp(1, w) - 1, (y + d / 3).clamp(1, h) - 1);
                    sum += image.pixel(xx, yy)[ch];
                }
                out.pixel_mut(x, y)[ch] = sum / 9.0;
            }
        }
    }
    out
}

/// Per-pixel absolute S0 errors (in units of rendered radiance) over interior pixels.
fn s0_errors(model: &SensorModel, stokes: &Stokes, interior: &[bool]) -> Vec<f32> {
    let raw = model.expose(stokes, 11, 0);
    assert_eq!(raw.pixels.size(), (2 * W as usize, 2 * H as usize));
    let dark = model.clone().noise_free().dark_frame(W as usize, H as usize, 0);
    let processed = FrameProcessor { dark: Some(dark), ..Default::default() }.process(&raw).unwrap();
    let gain = model.stokes_gain();
    let got = processed.estimate.stokes.s0.data();
    let mut errors: Vec<f32> =
        (0..got.len()).filter(|k| interior[k / 3]).map(|k| (got[k] / gain - stokes.s0.data()[k]).abs()).collect();
    errors.sort_by(f32::total_cmp);
    errors
}

#[test]
fn raw_frames_give_back_the_rendered_stokes_within_the_injected_noise() {
    let (stokes, interior) = rendered();
    assert!(interior.iter().filter(|&&i| i).count() > 5000);
    let median = |e: &[f32]| e[e.len() / 2];
    // Noise-free: quantization and demosaicing interpolation only.
    let model = SensorModel::default();
    let clean = s0_errors(&model.clone().noise_free(), &stokes, &interior);
    // Noisy: shot and read noise. S0 averages four samples: its standard deviation in
    // radiance units is sqrt(mean electrons / 4) / (exposure x full well) at the median level.
    let noisy = s0_errors(&model, &stokes, &interior);
    let typical = {
        let mut s: Vec<f32> =
            stokes.s0.data().iter().enumerate().filter(|(k, _)| interior[k / 3]).map(|(_, v)| *v).collect();
        s.sort_by(f32::total_cmp);
        s[s.len() / 2]
    };
    let electrons = typical * model.exposure * model.full_well;
    let sigma = (electrons / 4.0 + model.read_noise.powi(2)).sqrt() / (model.exposure * model.full_well);
    assert!(median(&clean) < 0.2 * sigma, "noise-free median error {} vs noise {sigma}", median(&clean));
    // |N(0, sigma)| has median 0.67 sigma (measured: 0.70 sigma; brighter pixels are noisier
    // than the median level sigma is computed at, interpolated ones less noisy).
    assert!(median(&noisy) < sigma && median(&noisy) > 0.3 * sigma, "median error {} vs sigma {sigma}", median(&noisy));
    assert!(
        noisy[noisy.len() * 99 / 100] < 4.0 * sigma + clean[clean.len() * 99 / 100],
        "p99 {}",
        noisy[noisy.len() * 99 / 100]
    );
}

#[test]
fn extinction_ratio_and_saturation_are_modelled() {
    let (stokes, interior) = rendered();
    let mut model = SensorModel { extinction_ratio: Some(19.0), ..SensorModel::default() }.noise_free();
    let raw = model.expose(&stokes, 1, 0);
    let dark = model.dark_frame(W as usize, H as usize, 0);
    let processed = FrameProcessor { dark: Some(dark), ..Default::default() }.process(&raw).unwrap();
    // A polarizer with extinction ratio 19 sees 90 % of the linear polarization.
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for k in 0..stokes.s1.data().len() {
        if interior[k / 3] {
            num += (processed.estimate.stokes.s1.data()[k] / model.stokes_gain() * stokes.s1.data()[k]) as f64;
            den += (stokes.s1.data()[k] * stokes.s1.data()[k]) as f64;
        }
    }
    assert!((num / den - 0.9).abs() < 0.02, "S1 ratio {}", num / den);
    // Overexposed: counts stop at full scale.
    model.exposure = 50.0;
    assert!(model.expose(&stokes, 1, 0).pixels.data().contains(&4095));
}
