//! Seeded random streams. Each noise source gets its own ChaCha stream derived from the one
//! plant seed, so that e.g. sampling the IMU more often never changes the gusts: a run is a
//! function of the seed and the commands alone.

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{RngCore, SeedableRng};

/// Stream numbers: one per noise source, fixed so that results stay comparable over versions.
pub mod stream {
    pub const WIND: u64 = 1;
    pub const IMU: u64 = 2;
    pub const GPS: u64 = 3;
    pub const BATTERY: u64 = 4;
}

#[derive(Debug, Clone)]
pub struct NoiseRng {
    rng: ChaCha8Rng,
    /// Box–Muller makes normals in pairs; the second is kept for the next call.
    spare_normal: Option<f64>,
}

impl NoiseRng {
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(stream);
        Self {
            rng,
            spare_normal: None,
        }
    }

    /// Uniform in (0, 1]: never 0, so it is safe under `ln`.
    pub fn uniform(&mut self) -> f64 {
        ((self.rng.next_u64() >> 11) + 1) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in [lo, hi).
    pub fn uniform_in(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (1.0 - self.uniform())
    }

    /// True with probability `p`.
    pub fn chance(&mut self, p: f64) -> bool {
        self.uniform() <= p
    }

    /// Standard normal, by the Box–Muller transform.
    pub fn normal(&mut self) -> f64 {
        if let Some(z) = self.spare_normal.take() {
            return z;
        }
        let r = (-2.0 * self.uniform().ln()).sqrt();
        let (s, c) = (2.0 * std::f64::consts::PI * self.uniform()).sin_cos();
        self.spare_normal = Some(r * s);
        r * c
    }

    /// Three independent standard normals.
    pub fn normal3(&mut self) -> [f64; 3] {
        [self.normal(), self.normal(), self.normal()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_has_unit_variance_and_streams_differ() {
        let mut a = NoiseRng::new(7, stream::WIND);
        let n = 200_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let z = a.normal();
            s += z;
            s2 += z * z;
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        assert!(mean.abs() < 0.01, "{mean}");
        assert!((var - 1.0).abs() < 0.02, "{var}");
        let mut b = NoiseRng::new(7, stream::IMU);
        let mut c = NoiseRng::new(7, stream::WIND);
        let x = c.uniform();
        assert_ne!(x, b.uniform());
        assert_eq!(x, NoiseRng::new(7, stream::WIND).uniform());
    }
}
