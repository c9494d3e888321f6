//! The avionics and propulsion battery packs: LiPo open-circuit voltage, polarisation, sag.

use super::super::rng::NoiseRng;

/// One lithium-polymer pack: open-circuit voltage from the state of charge, an ohmic drop and
/// a first-order polarisation (RC) drop, so the voltage sags at once under load, sags a bit
/// more over seconds, and recovers when the load goes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PackConfig {
    pub cells: u32,
    pub capacity_ah: f64,
    pub internal_resistance_ohm: f64,
    pub polarisation_resistance_ohm: f64,
    pub polarisation_time_constant_s: f64,
    /// State of charge at start, 0..1.
    pub initial_charge: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BatteryConfig {
    /// Flight computer, radios, sensors.
    pub avionics: PackConfig,
    /// Avionics draw (A); it varies a little around this.
    pub avionics_load_a: f64,
    /// Motor (through the ESC) and servos.
    pub propulsion: PackConfig,
    /// Servo draw (A): idle plus a part proportional to how hard the surfaces are held over.
    pub servo_idle_a: f64,
    pub servo_load_a_per_unit_command: f64,
    /// Measurement noise (1σ).
    pub voltage_noise_std_v: f64,
    pub current_noise_std_a: f64,
}

impl BatteryConfig {
    pub fn aerosonde() -> Self {
        Self {
            avionics: PackConfig {
                cells: 3,
                capacity_ah: 2.2,
                internal_resistance_ohm: 0.03,
                polarisation_resistance_ohm: 0.02,
                polarisation_time_constant_s: 20.0,
                initial_charge: 1.0,
            },
            avionics_load_a: 1.2,
            propulsion: PackConfig {
                cells: 12,
                capacity_ah: 10.0,
                internal_resistance_ohm: 0.04,
                polarisation_resistance_ohm: 0.025,
                polarisation_time_constant_s: 30.0,
                initial_charge: 1.0,
            },
            servo_idle_a: 0.3,
            servo_load_a_per_unit_command: 0.8,
            voltage_noise_std_v: 0.02,
            current_noise_std_a: 0.1,
        }
    }
}

impl Default for BatteryConfig {
    fn default() -> Self {
        Self::aerosonde()
    }
}

/// Open-circuit voltage of one LiPo cell against state of charge (piecewise linear).
pub fn lipo_cell_ocv_v(charge: f64) -> f64 {
    const TABLE: [(f64, f64); 8] = [
        (0.0, 3.0),
        (0.05, 3.3),
        (0.1, 3.5),
        (0.2, 3.65),
        (0.5, 3.8),
        (0.8, 3.95),
        (0.9, 4.05),
        (1.0, 4.2),
    ];
    let x = charge.clamp(0.0, 1.0);
    for w in TABLE.windows(2) {
        let ((x0, y0), (x1, y1)) = (w[0], w[1]);
        if x <= x1 {
            return y0 + (y1 - y0) * (x - x0) / (x1 - x0);
        }
    }
    TABLE[TABLE.len() - 1].1
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PackState {
    pub charge: f64,
    pub polarisation_v: f64,
    pub current_a: f64,
    pub voltage_v: f64,
}

fn pack_step(cfg: &PackConfig, s: &mut PackState, current_a: f64, dt_s: f64) {
    s.current_a = current_a;
    s.charge = (s.charge - current_a * dt_s / (3600.0 * cfg.capacity_ah)).clamp(0.0, 1.0);
    let tau = cfg.polarisation_time_constant_s.max(1e-6);
    let phi = (-dt_s / tau).exp();
    s.polarisation_v =
        phi * s.polarisation_v + (1.0 - phi) * current_a * cfg.polarisation_resistance_ohm;
    s.voltage_v = (cfg.cells as f64 * lipo_cell_ocv_v(s.charge)
        - current_a * cfg.internal_resistance_ohm
        - s.polarisation_v)
        .max(0.0);
}

fn pack_at_rest(cfg: &PackConfig) -> PackState {
    let charge = cfg.initial_charge.clamp(0.0, 1.0);
    PackState {
        charge,
        polarisation_v: 0.0,
        current_a: 0.0,
        voltage_v: cfg.cells as f64 * lipo_cell_ocv_v(charge),
    }
}

/// A reading of both packs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BatterySample {
    pub t_s: f64,
    pub avionics_voltage_v: f64,
    pub avionics_current_a: f64,
    pub propulsion_voltage_v: f64,
    pub propulsion_current_a: f64,
}

#[derive(Debug, Clone)]
pub struct SimBatteries {
    config: BatteryConfig,
    rng: NoiseRng,
    avionics: PackState,
    propulsion: PackState,
}

impl SimBatteries {
    pub fn new(config: BatteryConfig, rng: NoiseRng) -> Self {
        Self {
            avionics: pack_at_rest(&config.avionics),
            propulsion: pack_at_rest(&config.propulsion),
            config,
            rng,
        }
    }

    /// Advances both packs by `dt_s`. `motor_current_a` is the motor winding current; the ESC
    /// draws `throttle ×` that from the pack (power in ≈ power out). `surface_effort` is the
    /// sum of |aileron|, |elevator|, |rudder| commands. A motor driven by the windmilling
    /// propeller does not charge the pack (the ESC does not regenerate).
    pub fn step(&mut self, dt_s: f64, throttle: f64, motor_current_a: f64, surface_effort: f64) {
        let c = &self.config;
        let esc_a = throttle * motor_current_a.max(0.0);
        let servo_a = c.servo_idle_a + c.servo_load_a_per_unit_command * surface_effort;
        pack_step(&c.propulsion, &mut self.propulsion, esc_a + servo_a, dt_s);
        pack_step(&c.avionics, &mut self.avionics, c.avionics_load_a, dt_s);
    }

    pub fn avionics(&self) -> &PackState {
        &self.avionics
    }

    pub fn propulsion(&self) -> &PackState {
        &self.propulsion
    }

    /// A noisy reading of both packs' voltage and current.
    pub fn sample(&mut self, t_s: f64) -> BatterySample {
        let vn = self.config.voltage_noise_std_v;
        let cn = self.config.current_noise_std_a;
        BatterySample {
            t_s,
            avionics_voltage_v: self.avionics.voltage_v + vn * self.rng.normal(),
            avionics_current_a: self.avionics.current_a + cn * self.rng.normal(),
            propulsion_voltage_v: self.propulsion.voltage_v + vn * self.rng.normal(),
            propulsion_current_a: self.propulsion.current_a + cn * self.rng.normal(),
        }
    }
}
