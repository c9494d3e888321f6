//! Wind: a steady NED wind plus Dryden turbulence in body axes (Beard & McLain §4.4).
//!
//! The Dryden transfer functions (eq. 4.15 of the 2nd edition) shape unit white noise:
//! - `H_u(s) = σ_u·√(2Va/(πL_u)) · 1/(s + Va/L_u)`
//! - `H_v(s) = σ_v·√(3Va/(πL_v)) · (s + Va/(√3·L_v)) / (s + Va/L_v)²`, and `H_w` likewise.
//!
//! With the book's normalisation (∫₀^∞ |H(jω)|² dω = σ²) the driving noise has intensity π,
//! so each gust component has standard deviation σ. The filters are stepped outside the RK4
//! stages (noise has no derivative) and held over each integration step.

use super::math::Vec3;
use super::rng::NoiseRng;

/// Dryden turbulence intensities (m/s) and length scales (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DrydenParams {
    pub sigma_u_mps: f64,
    pub sigma_v_mps: f64,
    pub sigma_w_mps: f64,
    pub length_u_m: f64,
    pub length_v_m: f64,
    pub length_w_m: f64,
}

impl DrydenParams {
    /// Low altitude (50 m), light turbulence (Beard & McLain table 4.1).
    pub fn light_low_altitude() -> Self {
        Self {
            sigma_u_mps: 1.06,
            sigma_v_mps: 1.06,
            sigma_w_mps: 0.7,
            length_u_m: 200.0,
            length_v_m: 200.0,
            length_w_m: 50.0,
        }
    }

    /// Low altitude (50 m), moderate turbulence (Beard & McLain table 4.1).
    pub fn moderate_low_altitude() -> Self {
        Self {
            sigma_u_mps: 2.12,
            sigma_v_mps: 2.12,
            sigma_w_mps: 1.4,
            ..Self::light_low_altitude()
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct WindConfig {
    /// Steady wind, the velocity of the air mass in NED (m/s): (5, 0, 0) blows towards north.
    pub steady_ned_mps: Vec3,
    /// None for still air.
    pub turbulence: Option<DrydenParams>,
}

impl WindConfig {
    pub fn calm() -> Self {
        Self::default()
    }
}

/// Below this airspeed the turbulence is shaped as if flying at it: the Dryden model is
/// written for an airplane moving through frozen turbulence, and at zero airspeed its
/// bandwidth and gain both vanish, which would make a parked airplane feel no gusts at all.
pub const DRYDEN_MIN_AIRSPEED_MPS: f64 = 5.0;
pub const DRYDEN_MAX_AIRSPEED_MPS: f64 = 100.0;

/// The Dryden filter states.
#[derive(Debug, Clone)]
pub struct WindModel {
    config: WindConfig,
    rng: NoiseRng,
    u: f64,
    /// Two-state realisations of the second-order filters: (x, ẋ).
    v: [f64; 2],
    w: [f64; 2],
    gust_body_mps: Vec3,
}

impl WindModel {
    pub fn new(config: WindConfig, rng: NoiseRng) -> Self {
        Self {
            config,
            rng,
            u: 0.0,
            v: [0.0; 2],
            w: [0.0; 2],
            gust_body_mps: [0.0; 3],
        }
    }

    pub fn config(&self) -> &WindConfig {
        &self.config
    }

    pub fn steady_ned_mps(&self) -> Vec3 {
        self.config.steady_ned_mps
    }

    /// The current gust, body axes (m/s).
    pub fn gust_body_mps(&self) -> Vec3 {
        self.gust_body_mps
    }

    /// Advances the turbulence by `dt_s` at airspeed `airspeed_mps`.
    pub fn step(&mut self, dt_s: f64, airspeed_mps: f64) {
        let Some(d) = self.config.turbulence else {
            return;
        };
        // Capped too: the semi-implicit filter step needs Va/L·dt well below 1, and no
        // Aerosonde flies at 100 m/s except in a dive that has already gone wrong.
        let va = airspeed_mps.clamp(DRYDEN_MIN_AIRSPEED_MPS, DRYDEN_MAX_AIRSPEED_MPS);

        // u: first order, stepped exactly as a Gauss–Markov process of variance σ_u².
        let phi = (-va / d.length_u_m * dt_s).exp();
        self.u = phi * self.u + d.sigma_u_mps * (1.0 - phi * phi).sqrt() * self.rng.normal();

        let gv = second_order(
            &mut self.v,
            &mut self.rng,
            dt_s,
            va,
            d.sigma_v_mps,
            d.length_v_m,
        );
        let gw = second_order(
            &mut self.w,
            &mut self.rng,
            dt_s,
            va,
            d.sigma_w_mps,
            d.length_w_m,
        );
        self.gust_body_mps = [self.u, gv, gw];
    }
}

/// One step of `K·(s + β)/(s + a)²` driven by white noise of intensity π, realised as
/// `ẍ = −a²x − 2aẋ + n`, `y = K(βx + ẋ)`; semi-implicit Euler (stable for a·dt < 1, and the
/// plant steps at ≤ 10 ms where a = Va/L is of order 1/s).
fn second_order(
    x: &mut [f64; 2],
    rng: &mut NoiseRng,
    dt: f64,
    va: f64,
    sigma: f64,
    length: f64,
) -> f64 {
    let a = va / length;
    let beta = va / (3f64.sqrt() * length);
    let k = sigma * (3.0 * va / (std::f64::consts::PI * length)).sqrt();
    let noise = (std::f64::consts::PI * dt).sqrt() * rng.normal();
    x[1] += dt * (-a * a * x[0] - 2.0 * a * x[1]) + noise;
    x[0] += dt * x[1];
    k * (beta * x[0] + x[1])
}

#[cfg(test)]
mod tests {
    use super::super::rng::{NoiseRng, stream};
    use super::*;

    #[test]
    fn calm_air_has_no_gusts() {
        let mut w = WindModel::new(WindConfig::calm(), NoiseRng::new(1, stream::WIND));
        for _ in 0..100 {
            w.step(0.01, 25.0);
        }
        assert_eq!(w.gust_body_mps(), [0.0; 3]);
    }

    #[test]
    fn dryden_gusts_have_the_configured_rms() {
        let d = DrydenParams::moderate_low_altitude();
        let cfg = WindConfig {
            steady_ned_mps: [0.0; 3],
            turbulence: Some(d),
        };
        let mut w = WindModel::new(cfg, NoiseRng::new(42, stream::WIND));
        let dt = 0.04;
        // 20 000 s at 25 m/s: 2 500 correlation lengths of the u gust (L/Va = 8 s each),
        // so the RMS estimate is good to a few percent.
        let n = 500_000;
        let mut sum2 = [0.0; 3];
        for _ in 0..n {
            w.step(dt, 25.0);
            let g = w.gust_body_mps();
            for i in 0..3 {
                sum2[i] += g[i] * g[i];
            }
        }
        let rms: Vec<f64> = sum2.iter().map(|s| (s / n as f64).sqrt()).collect();
        let want = [d.sigma_u_mps, d.sigma_v_mps, d.sigma_w_mps];
        for i in 0..3 {
            let rel = (rms[i] - want[i]).abs() / want[i];
            assert!(rel < 0.08, "axis {i}: rms {} vs σ {}", rms[i], want[i]);
        }
    }
}
