//! A small deterministic random number generator (SplitMix64) for synthetic scenes.
//!
//! Recordings must be reproducible from a seed on every machine, so the generator is
//! written out here (no platform-dependent state, no external crate).

/// SplitMix64 (Steele, Lea and Flood 2014): 64-bit state, one add and a mix per draw.
#[derive(Debug, Clone)]
pub struct SplitMix64 {
    state: u64,
}

const GOLDEN_GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

impl SplitMix64 {
    pub fn new(seed: u64) -> Self {
        SplitMix64 {
            state: seed ^ 0x5DEE_CE66_D1CE_4E5B,
        }
    }

    /// A generator derived from this seed and a stream label (independent streams for
    /// cameras, subject, noise, ...).
    pub fn stream(seed: u64, label: u64) -> Self {
        let mut g = SplitMix64::new(seed);
        g.state ^= mix(label.wrapping_mul(GOLDEN_GAMMA).wrapping_add(0xA5A5));
        g
    }

    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(GOLDEN_GAMMA);
        mix(self.state)
    }

    /// Uniform in [0, 1).
    #[inline]
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in [lo, hi).
    #[inline]
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Standard normal (Box-Muller).
    pub fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// True with probability `p`.
    pub fn chance(&mut self, p: f64) -> bool {
        self.uniform() < p
    }
}

#[inline]
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A hash of integer lattice coordinates to [0, 1) (value noise).
#[inline]
pub fn hash3(x: i64, y: i64, z: i64, seed: u64) -> f32 {
    let h = mix((x as u64).wrapping_mul(0x9E37_79B1)
        ^ (y as u64).wrapping_mul(0x85EB_CA77_C2B2_AE63)
        ^ (z as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ seed.wrapping_mul(GOLDEN_GAMMA));
    (h >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
}

#[inline]
fn smooth(t: f32) -> f32 {
    t * t * (3.0 - 2.0 * t)
}

/// Smooth value noise in 2-D, range [0, 1), lattice period 1.
pub fn value_noise2(x: f64, y: f64, seed: u64) -> f32 {
    let (xf, yf) = (x.floor(), y.floor());
    let (xi, yi) = (xf as i64, yf as i64);
    let (tx, ty) = (smooth((x - xf) as f32), smooth((y - yf) as f32));
    let a = hash3(xi, yi, 0, seed);
    let b = hash3(xi + 1, yi, 0, seed);
    let c = hash3(xi, yi + 1, 0, seed);
    let d = hash3(xi + 1, yi + 1, 0, seed);
    let top = a + (b - a) * tx;
    let bot = c + (d - c) * tx;
    top + (bot - top) * ty
}

/// Smooth value noise in 3-D, range [0, 1), lattice period 1.
pub fn value_noise3(x: f64, y: f64, z: f64, seed: u64) -> f32 {
    let (xf, yf, zf) = (x.floor(), y.floor(), z.floor());
    let (xi, yi, zi) = (xf as i64, yf as i64, zf as i64);
    let (tx, ty, tz) = (
        smooth((x - xf) as f32),
        smooth((y - yf) as f32),
        smooth((z - zf) as f32),
    );
    let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
    let mut plane = [0.0f32; 2];
    for (k, p) in plane.iter_mut().enumerate() {
        let zk = zi + k as i64;
        let a = hash3(xi, yi, zk, seed);
        let b = hash3(xi + 1, yi, zk, seed);
        let c = hash3(xi, yi + 1, zk, seed);
        let d = hash3(xi + 1, yi + 1, zk, seed);
        *p = lerp(lerp(a, b, tx), lerp(c, d, tx), ty);
    }
    lerp(plane[0], plane[1], tz)
}

/// Fractal sum of `octaves` 2-D value noises (each half the amplitude, twice the
/// frequency), normalised to [0, 1).
pub fn fbm2(x: f64, y: f64, octaves: u32, seed: u64) -> f32 {
    let (mut sum, mut amp, mut norm, mut f) = (0.0f32, 1.0f32, 0.0f32, 1.0f64);
    for o in 0..octaves {
        sum += amp * value_noise2(x * f, y * f, seed.wrapping_add(o as u64));
        norm += amp;
        amp *= 0.5;
        f *= 2.0;
    }
    sum / norm
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_deterministic_and_distinct() {
        let a: Vec<u64> = (0..4)
            .map({
                let mut g = SplitMix64::stream(7, 1);
                move |_| g.next_u64()
            })
            .collect();
        let b: Vec<u64> = (0..4)
            .map({
                let mut g = SplitMix64::stream(7, 1);
                move |_| g.next_u64()
            })
            .collect();
        let c: Vec<u64> = (0..4)
            .map({
                let mut g = SplitMix64::stream(7, 2);
                move |_| g.next_u64()
            })
            .collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn normal_has_unit_variance() {
        let mut g = SplitMix64::new(3);
        let n = 20_000;
        let xs: Vec<f64> = (0..n).map(|_| g.normal()).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(
            mean.abs() < 0.03 && (var - 1.0).abs() < 0.05,
            "{mean} {var}"
        );
    }

    #[test]
    fn value_noise_is_continuous_and_bounded() {
        for i in 0..200 {
            let x = i as f64 * 0.037;
            let a = value_noise2(x, 0.3, 1);
            let b = value_noise2(x + 1e-4, 0.3, 1);
            assert!((0.0..1.0).contains(&a));
            assert!((a - b).abs() < 1e-2);
        }
    }
}
