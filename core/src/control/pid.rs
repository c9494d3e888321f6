//! A PID loop for the autopilot: derivative on the measurement (no kick when the setpoint
//! steps), anti-windup by conditional integration (the integrator stops while the output is
//! clamped in the direction the error pushes, and is itself bounded so that `ki·I` alone
//! stays inside the output range), output limits and an output rate limit.

/// Gains and limits. `rate_limit_per_s` ≤ 0 means none.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PidGains {
    pub kp: f32,
    pub ki: f32,
    pub kd: f32,
    pub out_min: f32,
    pub out_max: f32,
    pub rate_limit_per_s: f32,
}

impl PidGains {
    pub const fn new(kp: f32, ki: f32, kd: f32, out_min: f32, out_max: f32) -> Self {
        Self {
            kp,
            ki,
            kd,
            out_min,
            out_max,
            rate_limit_per_s: 0.0,
        }
    }

    pub const fn with_rate_limit(mut self, per_s: f32) -> Self {
        self.rate_limit_per_s = per_s;
        self
    }
}

/// The terms of the last update, for logs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PidTerms {
    pub p: f32,
    pub i: f32,
    pub d: f32,
    pub output: f32,
    pub saturated: bool,
}

#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Pid {
    pub gains: PidGains,
    integrator: f32,
    last_measurement: Option<f32>,
    last_output: Option<f32>,
    terms: PidTerms,
}

impl Pid {
    pub const fn new(gains: PidGains) -> Self {
        Self {
            gains,
            integrator: 0.0,
            last_measurement: None,
            last_output: None,
            terms: PidTerms {
                p: 0.0,
                i: 0.0,
                d: 0.0,
                output: 0.0,
                saturated: false,
            },
        }
    }

    /// Forgets the integrator, the derivative's memory and the rate limiter's.
    pub fn reset(&mut self) {
        self.integrator = 0.0;
        self.last_measurement = None;
        self.last_output = None;
    }

    /// Bumpless transfer: the integrator is set so that, with zero error, the output is
    /// `output` (e.g. the trim or the pilot's stick when the computer takes over).
    pub fn preset(&mut self, output: f32) {
        self.reset();
        if self.gains.ki.abs() > f32::EPSILON {
            self.integrator = self.clamp(output) / self.gains.ki;
        }
        self.last_output = Some(self.clamp(output));
    }

    pub fn integrator(&self) -> f32 {
        self.integrator
    }

    pub fn terms(&self) -> PidTerms {
        self.terms
    }

    fn clamp(&self, x: f32) -> f32 {
        let (lo, hi) = (
            self.gains.out_min.min(self.gains.out_max),
            self.gains.out_max,
        );
        x.clamp(lo, hi.max(lo))
    }

    /// One step with the setpoint and the measurement; the derivative is the measurement's,
    /// differenced.
    pub fn update(&mut self, setpoint: f32, measurement: f32, dt_s: f32) -> f32 {
        let rate = match self.last_measurement {
            Some(last) if dt_s > 0.0 => (measurement - last) / dt_s,
            _ => 0.0,
        };
        self.last_measurement = Some(measurement);
        self.update_with_rate(setpoint - measurement, rate, dt_s)
    }

    /// One step with the error (setpoint − measurement, already wrapped for angles) and the
    /// measurement's rate of change (e.g. a gyro rate): `u = kp·e + ki·∫e − kd·ṁ`.
    /// Non-finite inputs hold the last output.
    pub fn update_with_rate(&mut self, error: f32, measurement_rate: f32, dt_s: f32) -> f32 {
        let g = self.gains;
        if !(error.is_finite() && measurement_rate.is_finite() && dt_s.is_finite()) || dt_s <= 0.0 {
            return self.last_output.unwrap_or(0.0);
        }
        let p = g.kp * error;
        let d = -g.kd * measurement_rate;
        // Conditional integration: integrate unless the unclamped output is beyond a limit
        // and the error pushes further that way.
        let candidate = self.integrator + error * dt_s;
        let unclamped = p + g.ki * candidate + d;
        let pushes_up = error * g.ki > 0.0;
        let pushes_down = error * g.ki < 0.0;
        let blocked =
            (unclamped > g.out_max && pushes_up) || (unclamped < g.out_min && pushes_down);
        if !blocked {
            self.integrator = candidate;
        }
        if g.ki.abs() > f32::EPSILON {
            let a = g.out_min / g.ki;
            let b = g.out_max / g.ki;
            self.integrator = self.integrator.clamp(a.min(b), a.max(b));
        }
        let i = g.ki * self.integrator;
        let raw = p + i + d;
        let mut out = self.clamp(raw);
        if g.rate_limit_per_s > 0.0 {
            if let Some(last) = self.last_output {
                let step = g.rate_limit_per_s * dt_s;
                out = out.clamp(last - step, last + step);
            }
        }
        self.last_output = Some(out);
        self.terms = PidTerms {
            p,
            i,
            d,
            output: out,
            saturated: out != raw,
        };
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn proportional_integral_and_derivative_on_measurement() {
        let mut pid = Pid::new(PidGains::new(2.0, 1.0, 0.5, -100.0, 100.0));
        // First step: no derivative memory.
        let u = pid.update(1.0, 0.0, 0.1);
        assert!((u - (2.0 + 0.1)).abs() < 1e-6, "{u}");
        // The setpoint steps: no derivative kick.
        let u = pid.update(5.0, 0.0, 0.1);
        assert!((u - (10.0 + 0.6)).abs() < 1e-5, "{u}");
        // The measurement moves: derivative opposes it.
        let u = pid.update(5.0, 1.0, 0.1);
        let expected = 2.0 * 4.0 + (0.1 + 0.5 + 0.4) - 0.5 * 10.0;
        assert!((u - expected).abs() < 1e-5, "{u} vs {expected}");
    }

    #[test]
    fn output_is_clamped_and_the_integrator_does_not_wind_up() {
        let mut pid = Pid::new(PidGains::new(1.0, 1.0, 0.0, -1.0, 1.0));
        for _ in 0..1000 {
            assert!(pid.update_with_rate(10.0, 0.0, 0.1) <= 1.0);
        }
        // The integrator stayed bounded: ki·I ≤ out_max.
        assert!(pid.integrator() <= 1.0 + 1e-6, "{}", pid.integrator());
        assert!(pid.terms().saturated);
        // When the error reverses, the output leaves saturation at once (no wind-up).
        let u = pid.update_with_rate(-0.5, 0.0, 0.1);
        assert!(u < 1.0, "{u}");
        let mut steps = 0;
        while pid.update_with_rate(-0.5, 0.0, 0.1) > 0.0 {
            steps += 1;
            assert!(steps < 30, "wound up");
        }
    }

    #[test]
    fn rate_limit_bounds_each_step() {
        let mut pid = Pid::new(PidGains::new(1.0, 0.0, 0.0, -1.0, 1.0).with_rate_limit(2.0));
        pid.preset(0.0);
        let mut last = 0.0;
        for _ in 0..20 {
            let u = pid.update_with_rate(1.0, 0.0, 0.05);
            assert!(u - last <= 0.1 + 1e-6);
            last = u;
        }
        assert!((last - 1.0).abs() < 1e-6);
    }

    #[test]
    fn preset_gives_bumpless_transfer_and_reset_clears() {
        let mut pid = Pid::new(PidGains::new(1.0, 0.5, 0.0, -1.0, 1.0));
        pid.preset(0.3);
        assert!((pid.update_with_rate(0.0, 0.0, 0.02) - 0.3).abs() < 1e-6);
        pid.reset();
        assert_eq!(pid.update_with_rate(0.0, 0.0, 0.02), 0.0);
    }

    #[test]
    fn non_finite_inputs_hold_the_output() {
        let mut pid = Pid::new(PidGains::new(1.0, 0.0, 0.0, -1.0, 1.0));
        let u = pid.update_with_rate(0.4, 0.0, 0.02);
        assert_eq!(pid.update_with_rate(f32::NAN, 0.0, 0.02), u);
        assert_eq!(pid.update_with_rate(0.1, f32::INFINITY, 0.02), u);
        assert_eq!(pid.update_with_rate(0.1, 0.0, 0.0), u);
    }
}
