//! Fixed encodings: NeRF positional encoding of points and Ref-NeRF's integrated directional
//! encoding (IDE) of reflected directions.

/// `[x, sin(2^k x), cos(2^k x)]` for `k < frequencies`, per coordinate (NeuS's embedder): 3 +
/// 6 * frequencies values per point. Points are constants of training, so no backward is needed.
pub fn positional_encoding(points: &[f32], frequencies: usize, out: &mut [f32]) {
    let width = 3 + 6 * frequencies;
    for (p, o) in points.chunks_exact(3).zip(out.chunks_exact_mut(width)) {
        o[..3].copy_from_slice(p);
        for k in 0..frequencies {
            let f = (1u32 << k) as f32;
            for a in 0..3 {
                let (s, c) = (p[a] * f).sin_cos();
                o[3 + 6 * k + a] = s;
                o[6 + 6 * k + a] = c;
            }
        }
    }
}

/// Spherical-harmonic degrees used by the IDE (Ref-NeRF with NeRSP's three levels).
pub const IDE_DEGREES: [u32; 3] = [1, 2, 4];
/// Values of the IDE: real harmonics of each degree `l` (2l + 1 each).
pub const IDE_WIDTH: usize = 3 + 5 + 9;

/// Forward-mode dual number with three partials, to differentiate the harmonics exactly.
#[derive(Clone, Copy, Debug)]
struct Dual {
    v: f32,
    d: [f32; 3],
}

impl Dual {
    fn var(v: f32, axis: usize) -> Self {
        let mut d = [0.0; 3];
        d[axis] = 1.0;
        Self { v, d }
    }
    fn c(self, k: f32) -> Self {
        Self { v: self.v * k, d: self.d.map(|x| x * k) }
    }
    fn add_const(self, k: f32) -> Self {
        Self { v: self.v + k, d: self.d }
    }
}

impl std::ops::Add for Dual {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self { v: self.v + o.v, d: [self.d[0] + o.d[0], self.d[1] + o.d[1], self.d[2] + o.d[2]] }
    }
}

impl std::ops::Sub for Dual {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        self + o.c(-1.0)
    }
}

// The product rule: d(uv) = u dv + v du.
#[allow(clippy::suspicious_arithmetic_impl)]
impl std::ops::Mul for Dual {
    type Output = Self;
    fn mul(self, o: Self) -> Self {
        let d = [0, 1, 2].map(|a| self.d[a] * o.v + self.v * o.d[a]);
        Self { v: self.v * o.v, d }
    }
}

/// Real orthonormal spherical harmonics of degrees 1, 2 and 4 of a unit direction.
fn harmonics(x: Dual, y: Dual, z: Dual) -> [Dual; IDE_WIDTH] {
    let (xx, yy, zz) = (x * x, y * y, z * z);
    let xy = x * y;
    [
        // l = 1
        y.c(0.488_602_5),
        z.c(0.488_602_5),
        x.c(0.488_602_5),
        // l = 2
        xy.c(1.092_548_4),
        (y * z).c(1.092_548_4),
        zz.c(3.0).add_const(-1.0).c(0.315_391_57),
        (x * z).c(1.092_548_4),
        (xx - yy).c(0.546_274_2),
        // l = 4
        (xy * (xx - yy)).c(2.503_342_9),
        (y * z * (xx.c(3.0) - yy)).c(1.770_130_8),
        (xy * zz.c(7.0).add_const(-1.0)).c(0.946_174_7),
        (y * z * zz.c(7.0).add_const(-3.0)).c(0.669_046_5),
        ((zz * zz).c(35.0) - zz.c(30.0)).add_const(3.0).c(0.105_785_55),
        (x * z * zz.c(7.0).add_const(-3.0)).c(0.669_046_5),
        ((xx - yy) * zz.c(7.0).add_const(-1.0)).c(0.473_087_35),
        (x * z * (xx - yy.c(3.0))).c(1.770_130_8),
        (xx * (xx - yy.c(3.0)) - yy * (xx.c(3.0) - yy)).c(0.625_835_7),
    ]
}

fn degree_of(k: usize) -> f32 {
    match k {
        0..3 => 1.0,
        3..8 => 2.0,
        _ => 4.0,
    }
}

/// Integrated directional encoding of unit direction `w` with roughness `r`:
/// `exp(-l(l+1) r / 2) Y_lm(w)`. Returns the values and, per value, `(d/dw, d/dr)`.
pub fn ide(w: [f32; 3], r: f32) -> ([f32; IDE_WIDTH], [([f32; 3], f32); IDE_WIDTH]) {
    let y = harmonics(Dual::var(w[0], 0), Dual::var(w[1], 1), Dual::var(w[2], 2));
    let mut value = [0f32; IDE_WIDTH];
    let mut jac = [([0f32; 3], 0f32); IDE_WIDTH];
    for k in 0..IDE_WIDTH {
        let l = degree_of(k);
        let a = (-0.5 * l * (l + 1.0) * r).exp();
        value[k] = a * y[k].v;
        jac[k] = (y[k].d.map(|d| a * d), -0.5 * l * (l + 1.0) * value[k]);
    }
    (value, jac)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn harmonics_are_orthonormal_on_the_sphere() {
        // Fibonacci sphere quadrature of <Y_i, Y_j> over 4 pi.
        let n = 20_000;
        let mut gram = [[0f64; IDE_WIDTH]; IDE_WIDTH];
        for i in 0..n {
            let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
            let phi = i as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
            let s = (1.0 - z * z).sqrt();
            let (v, _) = ide([(s * phi.cos()) as f32, (s * phi.sin()) as f32, z as f32], 0.0);
            for a in 0..IDE_WIDTH {
                for b in 0..IDE_WIDTH {
                    gram[a][b] += v[a] as f64 * v[b] as f64 * 4.0 * std::f64::consts::PI / n as f64;
                }
            }
        }
        for (a, row) in gram.iter().enumerate() {
            for (b, &g) in row.iter().enumerate() {
                let want = if a == b { 1.0 } else { 0.0 };
                assert!((g - want).abs() < 2e-3, "<Y{a}, Y{b}> = {g}");
            }
        }
    }

    #[test]
    fn positional_encoding_matches_its_definition() {
        let mut out = vec![0.0; 3 + 6 * 2];
        positional_encoding(&[0.5, -0.25, 1.0], 2, &mut out);
        assert_eq!(&out[..3], &[0.5, -0.25, 1.0]);
        assert!((out[3 + 6 + 1] - (-0.5f32).sin()).abs() < 1e-7); // sin(2 * y)
        assert!((out[6 + 6 + 2] - 2f32.cos()).abs() < 1e-7); // cos(2 * z)
    }
}
