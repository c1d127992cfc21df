//! Environment maps for datasets: an equirectangular panorama (a THETA Z1's, say) read from
//! EXR, Radiance HDR, PNG or JPEG and turned into the dataset's world frame.
//!
//! The convention of `gt/env.exr` (and `env.exr` of our layout), written down once: texel
//! `(i, j)` of a `W x H` map (`W = 2H`) holds the linear RGB radiance arriving from the world
//! direction `d = (sin t sin p, cos t, -sin t cos p)` with `p = 2 pi (i + 0.5) / W`,
//! `t = pi (j + 0.5) / H`: Mitsuba 3's `envmap` mapping applied to world directions
//! ([`rmvp_render::envmap`]). A panorama is taken in its own frame (+Y up, its centre column
//! looking along -Z); [`to_world`] resamples it through the rotation from the world to that
//! frame.

use crate::{Error, Result};
use nalgebra::{Matrix3, Rotation3, Vector3};
use rmvp_dataset::io::picture::{is_picture, read_picture};
use rmvp_dataset::Image;
use rmvp_render::EnvMap;
use std::path::Path;

/// A panorama read from `path` as linear RGB ([`read_picture`]'s rule: EXR, HDR, 16-bit PNG and
/// TIFF as stored, 8-bit PNG, JPEG and TIFF decoded from sRGB). It must be equirectangular (width
/// twice the height, within a pixel).
pub fn read_panorama(path: &Path) -> Result<Image<f32>> {
    let bad = |why: String| Error::Panorama { path: path.to_path_buf(), why };
    if !is_picture(path) {
        return Err(bad("unknown panorama format (EXR, HDR, PNG, JPEG or TIFF)".into()));
    }
    let image = read_picture(path)?.pixels.into_linear();
    let (w, h) = (image.width(), image.height());
    if image.channels() < 3 {
        return Err(bad(format!("{} channel(s); an RGB panorama is needed", image.channels())));
    }
    if w.abs_diff(2 * h) > 1 {
        return Err(bad(format!("{w}x{h} is not equirectangular (the width must be twice the height)")));
    }
    // Light is finite and not negative: said here, by name, not later by the build.
    if let Some(i) = image.data().iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
        let (c, pixel) = (image.channels(), i / image.channels());
        return Err(bad(format!(
            "pixel ({}, {}) holds {} in channel {}: light must be finite and not negative",
            pixel % w,
            pixel / w,
            image.data()[i],
            i % c
        )));
    }
    Ok(image)
}

/// The rotation from a world frame to a panorama's frame: `base` (world to a +Y-up frame whose
/// -Z is the panorama's centre column before turning), then a turn of `yaw_deg` about +Y.
pub fn world_to_panorama(base: &Matrix3<f64>, yaw_deg: f64) -> Matrix3<f64> {
    Rotation3::from_axis_angle(&Vector3::y_axis(), yaw_deg.to_radians()).into_inner() * base
}

/// `panorama` resampled into the world frame (the module's convention) at its own size:
/// texel directions are world directions, looked up in the panorama at `world_to_panorama * d`.
pub fn to_world(panorama: &Image<f32>, world_to_panorama: &Matrix3<f64>) -> Result<Image<f32>> {
    let env = EnvMap::new(panorama)?.with_rotation(world_to_panorama);
    Ok(env.world_image(panorama.width(), panorama.height()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{PI, TAU};

    /// The direction of texel centre `(i, j)` of a `w x h` map, by the convention above.
    fn direction(i: usize, j: usize, w: usize, h: usize) -> Vector3<f64> {
        let (p, t) = (TAU * (i as f64 + 0.5) / w as f64, PI * (j as f64 + 0.5) / h as f64);
        Vector3::new(t.sin() * p.sin(), t.cos(), -t.sin() * p.cos())
    }

    #[test]
    fn a_sun_in_the_panorama_shines_from_its_world_direction() {
        // A dark panorama with one bright texel, turned from the board's frame and 30 degrees.
        let (w, h) = (256, 128);
        let mut pano = Image::new(w, h, 3);
        pano.data_mut().iter_mut().for_each(|v| *v = 0.01);
        let sun = (40, 30);
        pano.pixel_mut(sun.0, sun.1).copy_from_slice(&[100.0; 3]);
        let rotation = world_to_panorama(&rmvp_calib::board::board_to_y_up(), 30.0);
        let world = to_world(&pano, &rotation).unwrap();
        let brightest = (0..w * h).max_by(|&a, &b| world.data()[3 * a].total_cmp(&world.data()[3 * b])).unwrap();
        let seen = direction(brightest % w, brightest / w, w, h);
        let want = rotation.transpose() * direction(sun.0, sun.1, w, h);
        let angle = seen.angle(&want).to_degrees();
        assert!(angle < 2.0, "the sun is {angle:.2} deg from where it should be");
        // The world's up (board +z) is the panorama's up.
        let up = rotation * Vector3::z();
        assert!((up - Vector3::y()).norm() < 1e-12, "{up}");
    }

    #[test]
    fn a_panorama_with_nan_or_negative_light_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        for (value, said) in [(f32::NAN, "NaN"), (-1.0, "-1")] {
            let path = dir.path().join("sky.exr");
            let mut image = Image::new(64, 32, 3);
            image.pixel_mut(5, 7)[1] = value;
            rmvp_dataset::io::exr::write_exr(&path, &image, &["R", "G", "B"]).unwrap();
            let err = read_panorama(&path).unwrap_err().to_string();
            assert!(err.contains("sky.exr") && err.contains("pixel (5, 7)") && err.contains(said), "{err}");
        }
    }

    #[test]
    fn a_panorama_of_the_wrong_aspect_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("square.png");
        rmvp_dataset::io::png::write_png_u8(&path, &Image::new(64, 64, 3)).unwrap();
        let err = read_panorama(&path).unwrap_err();
        assert!(matches!(err, Error::Panorama { .. }), "{err}");
        assert!(err.to_string().contains("square.png") && err.to_string().contains("64x64"), "{err}");
    }
}
