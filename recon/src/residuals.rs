//! How far the trained model's Stokes are from its input, view by view: pictures of the
//! residuals of S0, S1 and S2 and of the AoP (`residuals.png`) and their figures
//! (`residuals.json`). Where the model cannot fit what was captured (a highlight it misses,
//! polarization it predicts too weak, an AoP it turns), these show it, with or without a
//! ground truth.
//!
//! Residuals are the model's minus the input's, each pixel's channel mean, over the pixels
//! that both the view's mask and the model's surface cover.

use rmvp_dataset::polarization::{aop, aop_difference_deg, dop, AOP_MIN_DOP};
use rmvp_dataset::visualize::{gray_ramp, quantile, signed_picture};
use rmvp_dataset::{Image, Stokes};
use serde::{Deserialize, Serialize};

/// The AoP residual's picture is white at this many degrees and beyond.
pub const AOP_RESIDUAL_MAP_MAX_DEG: f32 = 45.0;
/// The AoP residual's picture paints a compared pixel whose input DoP is at most
/// [`AOP_MIN_DOP`] (its AoP not compared) in this colour.
pub const UNPOLARIZED_COLOUR: [u8; 3] = [0, 0, 96];

/// One view's residuals.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ViewResiduals {
    /// The view's name.
    pub view: String,
    /// Pixels compared.
    pub pixels: usize,
    /// The input's mean S0 over them.
    pub mean_s0: f32,
    /// Mean absolute residual of S0, S1 and S2 over them, each relative to `mean_s0`.
    pub relative_mae: [f32; 3],
    /// Mean residual of S0 relative to `mean_s0` (above 0: the model is too bright).
    pub relative_bias_s0: f32,
    /// Median AoP residual, degrees, over the compared pixels whose input DoP exceeds
    /// [`AOP_MIN_DOP`] (none where no pixel does).
    pub aop_median_deg: Option<f32>,
    /// Those pixels.
    pub aop_pixels: usize,
}

/// The residuals of `model` against `input` (Stokes of the same size) over the pixels where
/// `mask` is set, and their pictures: S0, S1 and S2 ([`signed_picture`], full red or blue at
/// half the input's 99th-percentile magnitude of that component) and the AoP (grey from 0 to
/// [`AOP_RESIDUAL_MAP_MAX_DEG`], [`UNPOLARIZED_COLOUR`] where the input's DoP is too low to
/// compare).
pub fn view_residuals(view: &str, input: &Stokes, model: &Stokes, mask: &Image<u8>) -> (ViewResiduals, [Image<u8>; 4]) {
    let (w, h) = (mask.width(), mask.height());
    let compared: Vec<usize> =
        mask.data().chunks_exact(mask.channels()).enumerate().filter(|(_, m)| m[0] != 0).map(|(k, _)| k).collect();
    let means = |s: &Stokes| [&s.s0, &s.s1, &s.s2].map(|image| image.channel_mean().into_vec());
    let ([i0, i1, i2], [m0, m1, m2]) = (means(input), means(model));
    let pixels = compared.len();
    let mean_over =
        |value: &dyn Fn(usize) -> f32| compared.iter().map(|&k| value(k)).sum::<f32>() / pixels.max(1) as f32;
    let mean_s0 = mean_over(&|k| i0[k]);
    let norm = if mean_s0 > 0.0 { 1.0 / mean_s0 } else { 0.0 };

    let mut tiles: Vec<Image<u8>> = Vec::with_capacity(4);
    let mut relative_mae = [0f32; 3];
    for (k, (input_k, model_k)) in [(&i0, &m0), (&i1, &m1), (&i2, &m2)].into_iter().enumerate() {
        let residual: Vec<f32> = model_k.iter().zip(input_k).map(|(m, i)| m - i).collect();
        relative_mae[k] = norm * mean_over(&|p| residual[p].abs());
        let magnitudes: Vec<f32> = compared.iter().map(|&p| input_k[p].abs()).collect();
        let scale = quantile(&magnitudes, 0.99) / 2.0;
        let image = Image::from_vec(w, h, 1, residual).expect("the mask's size");
        tiles.push(signed_picture(&image, scale, Some(mask)));
    }
    let relative_bias_s0 = norm * mean_over(&|k| m0[k] - i0[k]);

    let mut aop_errors = Vec::new();
    let mut aop_map = Image::new(w, h, 1);
    let mut unpolarized = Vec::new();
    for &k in &compared {
        if dop(i0[k], i1[k], i2[k]) > AOP_MIN_DOP {
            let e = aop_difference_deg(aop(m1[k], m2[k]), aop(i1[k], i2[k]));
            aop_map.data_mut()[k] = e;
            aop_errors.push(e);
        } else {
            unpolarized.push(k);
        }
    }
    let mut aop_tile = gray_ramp(&aop_map, 0.0, AOP_RESIDUAL_MAP_MAX_DEG);
    for k in unpolarized {
        aop_tile.data_mut()[3 * k..3 * k + 3].copy_from_slice(&UNPOLARIZED_COLOUR);
    }
    tiles.push(aop_tile);
    let aop_pixels = aop_errors.len();
    let residuals = ViewResiduals {
        view: view.to_string(),
        pixels,
        mean_s0,
        relative_mae,
        relative_bias_s0,
        aop_median_deg: (aop_pixels > 0).then(|| quantile(&aop_errors, 0.5)),
        aop_pixels,
    };
    (residuals, tiles.try_into().expect("four tiles"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Stokes of `w x 1` pixels, three equal channels, from per-pixel `(S0, S1, S2)`.
    fn stokes(pixels: &[[f32; 3]]) -> Stokes {
        let image =
            |k: usize| Image::from_vec(pixels.len(), 1, 3, pixels.iter().flat_map(|p| [p[k]; 3]).collect()).unwrap();
        Stokes { s0: image(0), s1: image(1), s2: image(2) }
    }

    #[test]
    fn a_model_that_reproduces_its_input_has_no_residual() {
        let input = stokes(&[[1.0, 0.2, 0.0], [0.5, 0.0, -0.1], [0.8, 0.01, 0.0]]);
        let mask = Image::from_vec(3, 1, 1, vec![255, 255, 255]).unwrap();
        let (r, tiles) = view_residuals("000", &input, &input, &mask);
        assert_eq!((r.pixels, r.relative_mae, r.relative_bias_s0), (3, [0.0; 3], 0.0));
        assert_eq!((r.aop_median_deg, r.aop_pixels), (Some(0.0), 2));
        for tile in &tiles[..3] {
            assert!(tile.data().iter().all(|&v| v == 0));
        }
        // The third pixel's DoP (0.0125) is too low for its AoP to be compared.
        assert_eq!(&tiles[3].data()[6..9], &UNPOLARIZED_COLOUR);
    }

    #[test]
    fn residuals_are_the_known_differences_over_the_mask_only() {
        // Input: AoP 0 on both pixels inside the mask. Model: S0 10 % too bright on the first,
        // S2 added on both, turning the AoP by 22.5 degrees; the third pixel is off the mask.
        let input = stokes(&[[1.0, 0.2, 0.0], [1.0, 0.2, 0.0], [5.0, 0.0, 0.0]]);
        let model = stokes(&[[1.1, 0.2, 0.2], [1.0, 0.2, 0.2], [0.0, 3.0, 3.0]]);
        let mask = Image::from_vec(3, 1, 1, vec![255, 255, 0]).unwrap();
        let (r, tiles) = view_residuals("001", &input, &model, &mask);
        assert_eq!((r.view.as_str(), r.pixels, r.mean_s0), ("001", 2, 1.0));
        let expected = [0.05, 0.0, 0.2];
        for k in 0..3 {
            assert!((r.relative_mae[k] - expected[k]).abs() < 1e-6, "{:?}", r.relative_mae);
        }
        assert!((r.relative_bias_s0 - 0.05).abs() < 1e-6);
        assert!((r.aop_median_deg.unwrap() - 22.5).abs() < 1e-3);
        assert_eq!(r.aop_pixels, 2);
        // S2's residual (+0.2) is far above half the input's S2 magnitude (0): full red; the
        // pixel off the mask is black in every picture.
        assert_eq!(&tiles[2].data()[..3], &[255, 0, 0]);
        assert!(tiles.iter().all(|t| t.data()[6..9] == [0, 0, 0]));
        // 22.5 of 45 degrees: mid grey.
        assert_eq!(tiles[3].data()[0], 128);
    }
}
