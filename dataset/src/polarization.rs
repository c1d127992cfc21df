//! Linear polarization in the image frame: the one definition of Stokes, AoP and DoP in rmvp.
//!
//! - Stokes `(S0, S1, S2)` are expressed in the image frame: x right, y down.
//! - A linear polarizer at angle `theta`, measured from image +x towards image +y, transmits
//!   `I(theta) = 0.5 * (S0 + S1 cos 2theta + S2 sin 2theta)`.
//! - The angle of polarization `AoP = 0.5 * atan2(S2, S1)`, wrapped to `[0, pi)`, is measured
//!   the same way, so it compares directly with the azimuth `atan2(n_y, n_x)` of a camera-frame
//!   normal. The degree of linear polarization is `DoP = sqrt(S1^2 + S2^2) / S0`.

use std::f32::consts::{FRAC_PI_2, PI};

/// Polarizer angles of a four-directional polarization sensor, in degrees.
pub const POLARIZER_ANGLES_DEG: [u32; 4] = [0, 45, 90, 135];

/// A 2x2 cell of a polarization sensor: the transmission axis of each site, in degrees in the
/// image frame (from +x towards +y, down), row by row: `[[top left, top right], [bottom left,
/// bottom right]]`.
pub type PolarizerCell = [[u32; 2]; 2];

/// The Sony IMX250MZR/MYR cell as the light shows it: `[90 135; 45 0]`.
///
/// Sony and FLIR name the sites `[90 45; 135 0]` with angles that turn counter-clockwise as a
/// person sees the picture (towards image *up*). Measured on real IMX250MZR frames
/// (`docs/conventions.md`): near the rims of glossy fruit, specular reflection is polarized
/// tangentially only when the site named 45 is read at 135 degrees in the +y-down frame (median
/// 4-7 degrees off the tangent), and the 0/90 naming holds (horizontal glare has `S1 > 0`).
pub const SENSOR_POLARIZER_CELL: PolarizerCell = [[90, 135], [45, 0]];

/// The vendor's names taken as +y-down angles, `[90 45; 135 0]`: what sessions written before
/// the layout was recorded were processed with. It mirrors every AoP (`S2` has the wrong sign).
pub const VENDOR_NAMES_AS_IMAGE_ANGLES: PolarizerCell = [[90, 45], [135, 0]];

/// Offset `(dx, dy)` inside `cell` of the polarizer at each of [`POLARIZER_ANGLES_DEG`].
///
/// # Panics
/// If an angle of [`POLARIZER_ANGLES_DEG`] is not in the cell exactly once (at compile time
/// for a constant cell).
pub const fn polarizer_offsets(cell: &PolarizerCell) -> [(usize, usize); 4] {
    let mut offsets = [(0, 0); 4];
    let mut k = 0;
    while k < 4 {
        let mut found = 0;
        let mut site = 0;
        while site < 4 {
            let (dx, dy) = (site % 2, site / 2);
            if cell[dy][dx] == POLARIZER_ANGLES_DEG[k] {
                offsets[k] = (dx, dy);
                found += 1;
            }
            site += 1;
        }
        assert!(found == 1, "a polarizer cell holds each of 0, 45, 90 and 135 degrees once");
        k += 1;
    }
    offsets
}

/// A cell written as the vendor does, `[a b; c d]`.
pub fn cell_name(cell: &PolarizerCell) -> String {
    format!("[{} {}; {} {}]", cell[0][0], cell[0][1], cell[1][0], cell[1][1])
}

/// The row of the measurement model: `I(theta) = row . (S0, S1, S2)`.
pub fn measurement_row(theta_rad: f64) -> [f64; 3] {
    [0.5, 0.5 * (2.0 * theta_rad).cos(), 0.5 * (2.0 * theta_rad).sin()]
}

/// Intensity behind a linear polarizer at `theta_rad`.
pub fn intensity(s0: f32, s1: f32, s2: f32, theta_rad: f32) -> f32 {
    0.5 * (s0 + s1 * (2.0 * theta_rad).cos() + s2 * (2.0 * theta_rad).sin())
}

/// Stokes `(S0, S1, S2)` from intensities behind polarizers at 0, 45, 90 and 135 degrees
/// (the least-squares solution of the four measurements).
pub fn stokes_from_four(i: [f32; 4]) -> [f32; 3] {
    [0.5 * (i[0] + i[1] + i[2] + i[3]), i[0] - i[2], i[1] - i[3]]
}

/// Near-minimax coefficients of `atan(a)/a` in `a^2` on `[0, 1]` (max error 1.5e-7 rad in f32).
const ATAN_COEFFS: [f32; 8] = [
    0.999_999_34,
    -0.333_298_6,
    0.199_465_66,
    -0.139_086_3,
    0.096_421_99,
    -0.055_912_334,
    0.021_862_956,
    -0.004_054_565,
];

/// `atan2(y, x)` in `(-pi, pi]`, branch-free so that loops over images vectorise; accurate to
/// 3e-7 rad, about one `f32` ulp at pi. `atan2(0, 0) = 0`.
#[inline]
pub fn atan2(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let (lo, hi) = (ax.min(ay), ax.max(ay));
    let a = if hi > 0.0 { lo / hi } else { 0.0 };
    let s = a * a;
    let mut p = ATAN_COEFFS[7];
    for c in ATAN_COEFFS[..7].iter().rev() {
        p = p * s + c;
    }
    let mut r = p * a;
    r = if ay > ax { FRAC_PI_2 - r } else { r };
    r = if x < 0.0 { PI - r } else { r };
    if y < 0.0 {
        -r
    } else {
        r
    }
}

/// Angle of polarization in `[0, pi)`, from image +x towards image +y.
#[inline]
pub fn aop(s1: f32, s2: f32) -> f32 {
    let a = 0.5 * atan2(s2, s1);
    let a = if a < 0.0 { a + PI } else { a };
    if a >= PI {
        a - PI
    } else {
        a
    }
}

/// Degree of linear polarization; 0 where `S0 <= 0`. Not clamped: noise can push it above 1.
#[inline]
pub fn dop(s0: f32, s1: f32, s2: f32) -> f32 {
    if s0 > 0.0 {
        (s1 * s1 + s2 * s2).sqrt() / s0
    } else {
        0.0
    }
}

/// An AoP is compared with another (captured against rendered, a model against its input) only
/// where the reference light is at least this polarized: below it the AoP is mostly noise.
pub const AOP_MIN_DOP: f32 = 0.05;

/// The smallest angle between two AoPs, in degrees (an AoP is periodic in 180 degrees).
pub fn aop_difference_deg(a: f32, b: f32) -> f32 {
    let d = (a - b).rem_euclid(PI);
    d.min(PI - d).to_degrees()
}

/// AoP and DoP of one image row from its S0, S1, S2 rows of `channels` interleaved channels,
/// each pixel's channel-mean Stokes vector (the NeRSP definition for RGB). Contiguous,
/// branch-free loops: both vectorise.
pub fn aop_dop_row(stokes_rows: [&[f32]; 3], channels: usize, aop: &mut [f32], dop: &mut [f32]) {
    let scale = 1.0 / channels as f32;
    let mean = |row: &[f32]| -> Vec<f32> {
        match channels {
            1 => row.to_vec(),
            3 => row.chunks_exact(3).map(|p| (p[0] + p[1] + p[2]) * scale).collect(),
            _ => row.chunks_exact(channels).map(|p| p.iter().sum::<f32>() * scale).collect(),
        }
    };
    let [m0, m1, m2] = stokes_rows.map(mean);
    for ((a, &x), &y) in aop.iter_mut().zip(&m1).zip(&m2) {
        *a = self::aop(x, y);
    }
    for (((d, &i), &x), &y) in dop.iter_mut().zip(&m0).zip(&m1).zip(&m2) {
        *d = self::dop(i, x, y);
    }
}

/// Full scale of the 16-bit AoP encoding of the NeRSP layout: `count = round(AoP / pi * 65535)`.
pub const AOP_U16_FULL_SCALE: f64 = 65535.0;

/// Encode an AoP in `[0, pi)` as a 16-bit count (NeRSP `input_azimuth_maps`).
pub fn aop_to_u16(aop: f32) -> u16 {
    (aop as f64 / std::f64::consts::PI * AOP_U16_FULL_SCALE).round().clamp(0.0, AOP_U16_FULL_SCALE) as u16
}

/// Decode a 16-bit AoP count to radians; [`aop_to_u16`] gives the count back exactly.
pub fn aop_from_u16(count: u16) -> f32 {
    (count as f64 / AOP_U16_FULL_SCALE * std::f64::consts::PI) as f32
}

/// DoP of light leaving a dielectric of refractive index `eta` by diffuse (subsurface)
/// reflection at zenith angle `theta` (Atkinson and Hancock 2006); its AoP is the azimuth of
/// the surface normal.
pub fn diffuse_dop(theta: f32, eta: f32) -> f32 {
    let (s, c) = theta.sin_cos();
    let s2 = s * s;
    let a = (eta - 1.0 / eta).powi(2) * s2;
    let b = 2.0 + 2.0 * eta * eta - (eta + 1.0 / eta).powi(2) * s2 + 4.0 * c * (eta * eta - s2).sqrt();
    a / b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aop_differences_wrap_at_180_degrees() {
        assert!((aop_difference_deg(0.01, PI - 0.01) - 0.02f32.to_degrees()).abs() < 1e-3);
        assert!((aop_difference_deg(0.5, 0.2) - 0.3f32.to_degrees()).abs() < 1e-3);
    }

    #[test]
    fn atan2_matches_std_everywhere() {
        let mut worst = 0.0f64;
        for i in 0..20000 {
            let t = i as f64 / 20000.0 * std::f64::consts::TAU - std::f64::consts::PI;
            for r in [1e-3, 1.0, 7.5e3] {
                let (y, x) = ((r * t.sin()) as f32, (r * t.cos()) as f32);
                let err = (atan2(y, x) as f64 - (y as f64).atan2(x as f64)).abs();
                worst = worst.max(err.min(std::f64::consts::TAU - err));
            }
        }
        assert!(worst < 3e-7, "worst atan2 error {worst:e}");
        assert_eq!(atan2(0.0, 0.0), 0.0);
        assert!((atan2(0.0, -1.0) - PI).abs() < 1e-7);
    }

    #[test]
    fn aop_follows_polarizer_convention() {
        // Light fully polarized along theta: S = (1, cos 2theta, sin 2theta).
        for deg in [0.0f32, 10.0, 45.0, 90.0, 135.0, 179.0] {
            let th = deg.to_radians();
            let (s1, s2) = ((2.0 * th).cos(), (2.0 * th).sin());
            assert!((aop(s1, s2) - th).abs() < 1e-6, "{deg}");
            // The polarizer aligned with the AoP transmits everything, the crossed one nothing.
            assert!((intensity(1.0, s1, s2, th) - 1.0).abs() < 1e-6);
            assert!(intensity(1.0, s1, s2, th + FRAC_PI_2).abs() < 1e-6);
            assert!((dop(1.0, s1, s2) - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn four_angle_stokes_inverts_the_measurement_model() {
        let s = [0.8f32, -0.21, 0.37];
        let i = POLARIZER_ANGLES_DEG.map(|d| intensity(s[0], s[1], s[2], (d as f32).to_radians()));
        let back = stokes_from_four(i);
        for k in 0..3 {
            assert!((back[k] - s[k]).abs() < 1e-6);
        }
    }

    #[test]
    fn diffuse_dop_matches_fresnel_transmission() {
        // DoP of diffuse reflection = (T_p - T_s) / (T_p + T_s) for light refracted out of the
        // material, with Fresnel transmittances at the internal angle.
        let eta = 1.5f32;
        for deg in [0.0f32, 20.0, 45.0, 70.0, 89.0] {
            let theta_out = deg.to_radians();
            let theta_in = (theta_out.sin() / eta).asin();
            let (ci, co) = (theta_in.cos(), theta_out.cos());
            let rs = ((eta * ci - co) / (eta * ci + co)).powi(2);
            let rp = ((eta * co - ci) / (eta * co + ci)).powi(2);
            let expected = ((1.0 - rp) - (1.0 - rs)) / ((1.0 - rp) + (1.0 - rs));
            assert!(
                (diffuse_dop(theta_out, eta) - expected).abs() < 1e-5,
                "{deg}: {} vs {expected}",
                diffuse_dop(theta_out, eta)
            );
        }
    }

    #[test]
    fn aop_u16_round_trips_every_count() {
        for c in 0..=u16::MAX {
            assert_eq!(aop_to_u16(aop_from_u16(c)), c);
        }
    }
}
