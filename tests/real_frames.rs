//! Real raw frames of a Sony IMX250MZR from outside the project (`shared/real_raw`: fruit on a
//! table, polarizers on a window sill) through `rmvp demosaic`: the outputs against a
//! reference computed here from the mosaic's cells, and the AoP against the physics of
//! reflection, which fixes the polarizers' handedness.

use std::f64::consts::PI;

mod common;
use common::{fails, ok, rmvp, s};

const W: usize = 1224;
const H: usize = 1024;

/// The four images behind the polarizers (0, 45, 90, 135 degrees from image +x towards +y,
/// down), read off the 2x2 cells as the light shows them: 90 top left, 135 top right, 45
/// bottom left, 0 bottom right (the vendor names the diagonal sites 45 and 135 the other way
/// round, counting towards image up).
fn cells(mosaic: &image::ImageBuffer<image::Luma<u8>, Vec<u8>>) -> [Vec<f64>; 4] {
    let at = |x: usize, y: usize| f64::from(mosaic.get_pixel(x as u32, y as u32).0[0]);
    let image = |dx: usize, dy: usize| (0..W * H).map(|k| at(2 * (k % W) + dx, 2 * (k / W) + dy)).collect();
    [image(1, 1), image(0, 1), image(0, 0), image(1, 0)]
}

/// Stokes of the four polarizer images, least squares (`I(theta) = (S0 + S1 cos 2theta + S2 sin
/// 2theta) / 2`).
fn stokes(i: &[Vec<f64>; 4]) -> [Vec<f64>; 3] {
    let per_pixel = |f: &dyn Fn(usize) -> f64| (0..W * H).map(f).collect::<Vec<_>>();
    [
        per_pixel(&|k| 0.5 * (i[0][k] + i[1][k] + i[2][k] + i[3][k])),
        per_pixel(&|k| i[0][k] - i[2][k]),
        per_pixel(&|k| i[1][k] - i[3][k]),
    ]
}

/// Difference of two angles of polarization, in degrees, in [0, 90].
fn aop_difference_deg(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(PI);
    d.min(PI - d).to_degrees()
}

/// A round, glossy object's outline in the picture: centre and radius in Stokes pixels.
struct Rim {
    name: &'static str,
    centre: (f64, f64),
    radius: f64,
}

/// Near a round glossy object's outline (0.9 to 1 radius, DoP above 0.1), how the AoP lies
/// against the outline: the mean of `cos 4 (AoP - radial angle)` (1 where every pixel is
/// tangential or radial, 0 for no relation) and the median angle from the tangent, degrees.
fn rim_agreement(rim: &Rim, aop: &[f32], dop: &[f32]) -> (f64, f64) {
    let (mut cos_sum, mut off_tangent) = (0.0, Vec::new());
    for k in 0..W * H {
        let (x, y) = ((k % W) as f64 + 0.5 - rim.centre.0, (k / W) as f64 + 0.5 - rim.centre.1);
        let r = x.hypot(y) / rim.radius;
        if !(0.9..1.0).contains(&r) || dop[k] <= 0.1 {
            continue;
        }
        let radial = y.atan2(x);
        cos_sum += (4.0 * (f64::from(aop[k]) - radial)).cos();
        off_tangent.push(aop_difference_deg(f64::from(aop[k]), radial + PI / 2.0));
    }
    assert!(off_tangent.len() > 5000, "{}: {} rim pixels", rim.name, off_tangent.len());
    off_tangent.sort_by(f64::total_cmp);
    (cos_sum / off_tangent.len() as f64, off_tangent[off_tangent.len() / 2])
}

#[test]
fn real_frames_demosaic_to_their_cells_and_glossy_rims_polarize_tangentially() {
    let frame = rmvp_testkit::real_raw("fruits_IMX250MZR.png");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path();
    ok(&["demosaic", s(&frame), "--pixel-format", "Polarized8", "-o", s(out)]);

    let mosaic = image::open(&frame).unwrap().into_luma8();
    assert_eq!(mosaic.dimensions(), (2 * W as u32, 2 * H as u32));
    let reference = cells(&mosaic);
    // The angle images are the cells themselves (mono: no demosaicing), 8 bits scaled to 16.
    for (deg, expected) in ["000", "045", "090", "135"].iter().zip(&reference) {
        let written = image::open(out.join(format!("fruits_IMX250MZR_{deg}.png"))).unwrap().into_luma16();
        let off = written.pixels().zip(expected).filter(|(p, &e)| f64::from(p.0[0]) != e * 257.0).count();
        assert_eq!(off, 0, "{deg} degrees: {off} pixels differ from the cells");
    }
    // Stokes in units of full scale (255), and the AoP.
    let truth = stokes(&reference);
    let written = rmvp_dataset::layout::rmvp::read_stokes(&out.join("fruits_IMX250MZR_stokes.exr")).unwrap();
    for (k, (image, expected)) in [&written.s0, &written.s1, &written.s2].iter().zip(&truth).enumerate() {
        let worst =
            image.data().iter().zip(expected).map(|(&v, e)| (f64::from(v) - e / 255.0).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-6, "S{k} off by {worst}");
    }
    let aop = rmvp_dataset::io::exr::read_exr(&out.join("fruits_IMX250MZR_aop.exr"), &["AoP"]).unwrap();
    let dop = rmvp_dataset::io::exr::read_exr(&out.join("fruits_IMX250MZR_dop.exr"), &["DoP"]).unwrap();
    let worst_aop = (0..W * H)
        .filter(|&k| truth[1][k].hypot(truth[2][k]) > 0.0)
        .map(|k| aop_difference_deg(f64::from(aop.data()[k]), 0.5 * truth[2][k].atan2(truth[1][k])))
        .fold(0.0, f64::max);
    assert!(worst_aop < 3e-5, "AoP off by {worst_aop} degrees");

    // The physics: specular reflection off the glossy apple and orange is polarized across the
    // plane of incidence, tangentially along their outlines. Mirrored (the diagonal sites
    // swapped), the AoP bears no relation to the outline.
    let mirrored: Vec<f32> = aop.data().iter().map(|&a| (std::f32::consts::PI - a) % std::f32::consts::PI).collect();
    for rim in [
        Rim { name: "apple", centre: (366.0, 316.0), radius: 277.0 },
        Rim { name: "orange", centre: (900.0, 266.0), radius: 202.0 },
    ] {
        let (coherence, median) = rim_agreement(&rim, aop.data(), dop.data());
        eprintln!("{}: cos 4(AoP - radial) {coherence:.3}, median {median:.1} degrees from the tangent", rim.name);
        assert!(coherence > 0.4 && median < 15.0, "{}: {coherence:.3}, {median:.1} degrees", rim.name);
        let (coherence, median) = rim_agreement(&rim, &mirrored, dop.data());
        eprintln!("{} mirrored: {coherence:.3}, {median:.1} degrees", rim.name);
        assert!(coherence < 0.2 && median > 25.0, "{} mirrored: {coherence:.3}, {median:.1} degrees", rim.name);
    }
}

#[test]
fn a_png_mosaic_needs_its_format_and_a_mono_one_is_not_taken_for_colour() {
    let fruits = rmvp_testkit::real_raw("fruits_IMX250MZR.png");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let err = fails(&["demosaic", s(&fruits), "-o", s(&out)]);
    assert!(err.contains("fruits_IMX250MZR.png") && err.contains("carries no pixel format"), "{err}");
    // Under a colour format (a Bayer name with its sensor declared polarized, too): its Bayer
    // colours have one mean, as only a mono sensor's do.
    for colour in [&["BayerRGPolarized8"][..], &["BayerRG8", "--polarized-sensor"]] {
        let err = fails(&[&["demosaic", s(&fruits), "-o", s(&out), "--pixel-format"][..], colour].concat());
        assert!(err.contains("fruits_IMX250MZR.png") && err.contains("Polarized8"), "{err}");
    }
    // The demosaicing method means nothing for a mono sensor: refused, not ignored.
    let err = fails(&["demosaic", s(&fruits), "--pixel-format", "Polarized8", "--method", "edge-aware", "-o", s(&out)]);
    assert!(err.contains("--method edge-aware") && err.contains("not demosaiced"), "{err}");
    assert!(!out.exists(), "nothing written by a refused command");
}

#[test]
fn saturated_pixels_are_counted_with_or_without_dropping_them_and_quiet_is_quiet() {
    // The window's sky saturates about 13 % of the polarizer scene's pixels.
    let frame = rmvp_testkit::real_raw("polarizer_IMX250MZR.png");
    let tmp = tempfile::tempdir().unwrap();
    let count = |extra: &[&str]| {
        let out = tmp.path().join(format!("out{}", extra.len()));
        let mut args = vec!["demosaic", s(&frame), "--pixel-format", "Polarized8", "-o", s(&out)];
        args.extend(extra);
        let stdout = ok(&args);
        let words: Vec<&str> = stdout.split_whitespace().collect();
        let at = words.iter().position(|w| *w == "pixels").unwrap_or_else(|| panic!("{stdout}"));
        words[at - 1].parse::<usize>().unwrap()
    };
    let kept = count(&[]);
    let dropped = count(&["--saturation-aware"]);
    assert_eq!(kept, dropped);
    assert!((0.05..0.25).contains(&(kept as f64 / (W * H) as f64)), "{kept} saturated pixels");

    let out = rmvp(&["--quiet", "demosaic", s(&frame), "--pixel-format", "Polarized8", "-o", s(&tmp.path().join("q"))]);
    assert!(out.status.success());
    assert!(out.stdout.is_empty() && out.stderr.is_empty(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(tmp.path().join("q/polarizer_IMX250MZR_stokes.exr").is_file());
}
