//! Deterministic random numbers: one independent PCG32 stream per (seed, view, pixel), so that
//! images are identical whatever the number of threads.

/// PCG32 (O'Neill 2014): 64-bit state, 32-bit output.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
    inc: u64,
}

fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Rng {
    /// The stream for `seed`, `view` and `pixel`.
    pub fn for_pixel(seed: u64, view: u32, pixel: u64) -> Self {
        let key = splitmix(seed ^ splitmix((view as u64) << 40 ^ pixel));
        let mut rng = Self { state: 0, inc: (splitmix(key) << 1) | 1 };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(key);
        rng.next_u32();
        rng
    }

    /// The next 32 random bits.
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        xorshifted.rotate_right((old >> 59) as u32)
    }

    /// Uniform in `[0, 1)`.
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    /// A standard normal sample (Box-Muller).
    pub fn normal(&mut self) -> f32 {
        let u = 1.0 - self.next_f32();
        let v = self.next_f32();
        (-2.0 * u.ln()).sqrt() * (std::f32::consts::TAU * v).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_uniform_and_distinct() {
        let mut a = Rng::for_pixel(1, 0, 0);
        let n = 100_000;
        let mean = (0..n).map(|_| a.next_f32() as f64).sum::<f64>() / n as f64;
        assert!((mean - 0.5).abs() < 0.005, "{mean}");
        let first: Vec<u32> = (0..4).map(|p| Rng::for_pixel(1, 0, p).next_u32()).collect();
        assert!(first.windows(2).all(|w| w[0] != w[1]));
        assert_eq!(Rng::for_pixel(9, 3, 7).next_u32(), Rng::for_pixel(9, 3, 7).next_u32());
    }
}
