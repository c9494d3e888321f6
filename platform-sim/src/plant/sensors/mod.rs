//! Sensor models: IMU, GPS receiver and the two battery packs, one model a file. Each owns a
//! seeded noise stream, so a run is reproducible for a seed however often each sensor is read,
//! and each reads only the plant's [`Truth`](super::Truth), so it works on any flight model.

mod battery;
mod gps;
mod imu;

pub use battery::*;
pub use gps::*;
pub use imu::*;

#[cfg(test)]
mod tests {
    use super::super::rng::{NoiseRng, stream};
    use super::*;

    #[test]
    fn ideal_imu_reads_the_truth() {
        let mut imu = SimImu::new(SimImuConfig::ideal(), NoiseRng::new(3, stream::IMU));
        let s = imu.sample(0.01, [0.1, -0.2, 0.3], [0.0, 0.0, -9.80665]);
        assert_eq!(s.gyro_radps, [0.1, -0.2, 0.3]);
        assert_eq!(s.specific_force_mps2, [0.0, 0.0, -9.80665]);
    }

    #[test]
    fn imu_noise_and_bias_have_the_configured_size() {
        let cfg = SimImuConfig {
            gyro_bias_walk_radps_per_sqrt_s: 0.0,
            accel_bias_walk_mps2_per_sqrt_s: 0.0,
            ..SimImuConfig::mems_100hz()
        };
        let mut imu = SimImu::new(cfg, NoiseRng::new(5, stream::IMU));
        let (gb, _) = imu.biases();
        let n = 20_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for k in 0..n {
            let x = imu.sample(k as f64 * 0.01, [0.0; 3], [0.0; 3]).gyro_radps[0] - gb[0];
            s += x;
            s2 += x * x;
        }
        let std = (s2 / n as f64 - (s / n as f64).powi(2)).sqrt();
        assert!(
            (std - cfg.gyro_noise_std_radps).abs() < 0.1 * cfg.gyro_noise_std_radps,
            "{std}"
        );
        assert!((s / n as f64).abs() < 1e-4);
        // The bias walks when the walk is on.
        let mut walking = SimImu::new(SimImuConfig::mems_100hz(), NoiseRng::new(5, stream::IMU));
        let before = walking.biases().0;
        walking.sample(0.0, [0.0; 3], [0.0; 3]);
        walking.sample(100.0, [0.0; 3], [0.0; 3]);
        assert_ne!(before, walking.biases().0);
    }

    /// A reading is the mean of the truth over its period: a rate ramp from 0 to 1 rad/s over
    /// ten 1 ms steps reads its mean 0.55 (the end points of the steps), not the last 1.0.
    /// With the motor running, the y gyro's spread is the bench noise and the Zurich
    /// vibration together, √(0.002² + 0.023²) = 0.0231 rad/s; without, the bench noise alone.
    #[test]
    fn imu_reads_the_mean_over_its_period_and_shakes_with_the_motor() {
        let mut ideal = SimImu::new(SimImuConfig::ideal(), NoiseRng::new(3, stream::IMU));
        for k in 1..=10 {
            ideal.integrate(0.001, [0.1 * f64::from(k), 0.0, 0.0], [0.0, 0.0, -9.8]);
        }
        let s = ideal.sample(0.01, [1.0, 0.0, 0.0], [0.0, 0.0, -9.8]);
        assert!((s.gyro_radps[0] - 0.55).abs() < 1e-12, "{s:?}");
        assert!((s.specific_force_mps2[2] + 9.8).abs() < 1e-12);
        // Nothing integrated since: the instantaneous truth.
        let s = ideal.sample(0.02, [0.3, 0.0, 0.0], [0.0; 3]);
        assert_eq!(s.gyro_radps[0], 0.3);

        let cfg = SimImuConfig {
            gyro_bias_walk_radps_per_sqrt_s: 0.0,
            ..SimImuConfig::airframe_100hz()
        };
        let spread = |running: bool| {
            let mut imu = SimImu::new(cfg, NoiseRng::new(9, stream::IMU));
            imu.set_motor_running(running);
            let n = 20_000;
            let (mut s, mut s2) = (0.0, 0.0);
            for k in 0..n {
                let y = imu.sample(k as f64 * 0.01, [0.0; 3], [0.0; 3]).gyro_radps[1];
                s += y;
                s2 += y * y;
            }
            (s2 / n as f64 - (s / n as f64).powi(2)).sqrt()
        };
        let (shaking, still) = (spread(true), spread(false));
        assert!((shaking - 0.0231).abs() < 0.05 * 0.0231, "{shaking}");
        assert!((still - 0.002).abs() < 0.1 * 0.002, "{still}");
    }

    #[test]
    fn geodetic_offsets_round_trip_and_have_the_right_size() {
        let home = GeodeticPosition::default();
        let p = home.offset_by_ned([1000.0, -500.0, -120.0]);
        // A degree of latitude is about 111.2 km at 47°.
        assert!(((p.lat_deg - home.lat_deg) * 111_200.0 - 1000.0).abs() < 5.0);
        assert!(p.lon_deg < home.lon_deg);
        assert!((p.alt_msl_m - (home.alt_msl_m + 120.0)).abs() < 1e-9);
        let back = home.ned_to(&p);
        for (a, b) in back.iter().zip([1000.0, -500.0, -120.0]) {
            assert!((a - b).abs() < 1e-6, "{back:?}");
        }
    }

    fn fix_times(cfg: SimGpsConfig, seconds: f64) -> Vec<f64> {
        let mut gps = SimGpsReceiver::new(cfg, NoiseRng::new(11, stream::GPS));
        let dt = 0.001;
        let mut times = Vec::new();
        for k in 0..(seconds / dt) as usize {
            let t = k as f64 * dt;
            gps.update(t, [0.0; 3], [0.0; 3]);
            while let Some(s) = gps.take(t) {
                assert!(s.available_at_s - s.valid_at_s - cfg.latency_s < 1e-9);
                assert!(s.available_at_s <= t);
                times.push(s.valid_at_s);
            }
        }
        times
    }

    #[test]
    fn gps_interval_statistics_match_the_configuration() {
        for cfg in [SimGpsConfig::nominal_10hz(), SimGpsConfig::seed_receiver()] {
            let times = fix_times(cfg, 600.0);
            let intervals: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
            let mean = intervals.iter().sum::<f64>() / intervals.len() as f64;
            let max = intervals.iter().cloned().fold(0.0, f64::max);
            assert!(
                (mean - cfg.mean_interval_s).abs() < 0.03 * cfg.mean_interval_s,
                "mean {mean} vs {}",
                cfg.mean_interval_s
            );
            if cfg.peak_probability > 0.0 {
                assert!((max - cfg.peak_interval_s).abs() < 1e-9, "max {max}");
            } else {
                assert!(
                    max <= cfg.mean_interval_s + cfg.interval_jitter_s + 1e-9,
                    "max {max}"
                );
            }
        }
    }

    #[test]
    fn gps_has_outages_and_dop_changes_but_never_nan() {
        let cfg = SimGpsConfig {
            outage_probability: 0.01,
            constellation_change_probability: 0.05,
            ..SimGpsConfig::nominal_10hz()
        };
        let mut gps = SimGpsReceiver::new(cfg, NoiseRng::new(2, stream::GPS));
        let (mut no_fix, mut fixes) = (0, 0);
        let mut hdops = Vec::new();
        for k in 0..60_000 {
            let t = k as f64 * 0.01;
            gps.update(t, [10.0, 20.0, -30.0], [25.0, 0.0, 0.0]);
            while let Some(s) = gps.take(t) {
                assert!(s.position.lat_deg.is_finite() && s.hdop.is_finite());
                match s.fix {
                    GpsFixType::NoFix => no_fix += 1,
                    GpsFixType::Fix3d => {
                        fixes += 1;
                        hdops.push(s.hdop);
                    }
                }
            }
        }
        // Outages start on 1 % of fixes and last 1.75 s on average: about a sixth of the time.
        assert!(
            no_fix > 300 && no_fix < 2_000 && fixes > 4_000,
            "{no_fix} {fixes}"
        );
        let lo = hdops.iter().cloned().fold(f64::MAX, f64::min);
        let hi = hdops.iter().cloned().fold(0.0, f64::max);
        assert!(hi > lo * 1.2, "DOP never changed: {lo}..{hi}");
    }

    #[test]
    fn gps_error_is_of_the_configured_size() {
        let cfg = SimGpsConfig::nominal_10hz();
        let mut gps = SimGpsReceiver::new(cfg, NoiseRng::new(4, stream::GPS));
        let home = cfg.home;
        let mut sum2 = 0.0;
        let mut n = 0;
        for k in 0..360_000 {
            let t = k as f64 * 0.01;
            gps.update(t, [0.0; 3], [0.0; 3]);
            while let Some(s) = gps.take(t) {
                if s.fix == GpsFixType::Fix3d {
                    let e = home.ned_to(&s.position);
                    sum2 += e[0] * e[0];
                    n += 1;
                }
            }
        }
        let rms = (sum2 / n as f64).sqrt();
        let want = (cfg.horizontal_drift_std_m.powi(2) + cfg.horizontal_noise_std_m.powi(2)).sqrt();
        // Drift with a 60 s correlation time over an hour: a loose check.
        assert!(
            rms > 0.5 * want && rms < 2.0 * want,
            "rms {rms} want {want}"
        );
    }

    #[test]
    fn battery_sags_under_load_and_recovers() {
        let mut b = SimBatteries::new(
            BatteryConfig::aerosonde(),
            NoiseRng::new(1, stream::BATTERY),
        );
        let rest = b.propulsion().voltage_v;
        assert!((rest - 12.0 * 4.2).abs() < 1e-9);
        b.step(0.01, 1.0, 40.0, 0.0);
        let loaded = b.propulsion().voltage_v;
        assert!(rest - loaded > 1.0, "instant sag {rest} → {loaded}");
        for _ in 0..3000 {
            b.step(0.01, 1.0, 40.0, 0.0);
        }
        let later = b.propulsion().voltage_v;
        assert!(later < loaded, "discharge and polarisation");
        for _ in 0..100 {
            b.step(0.01, 0.0, 0.0, 0.0);
        }
        assert!(
            b.propulsion().voltage_v > later + 1.0,
            "recovers without load"
        );
        assert!(b.propulsion().charge < 1.0 && b.avionics().charge < 1.0);
        let s = b.sample(31.0);
        assert!((s.propulsion_voltage_v - b.propulsion().voltage_v).abs() < 0.2);
    }
}
