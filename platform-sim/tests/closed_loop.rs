//! The estimator and the autopilot flying the simulated Aerosonde directly: no executive, no
//! byte protocols. The filter runs at 100 Hz on `plant.sample_imu()` with the GPS solutions
//! from `plant.sample_gps()` (80 ms latency, 10 Hz, drift and noise), the autopilot at 50 Hz.
//! From a trimmed start at 25 m/s, 100 m, in light Dryden turbulence: 60 s holding altitude,
//! heading and airspeed, then four waypoints and the loiter.
//!
//! Long (a few simulated minutes at 1 ms RK4): ignored in debug builds. Run with
//! `cargo test -p skyframe-sim --release --test closed_loop -- --nocapture`.

use skyframe_core::angles::wrap_pi_f32 as wrap_pi;
use skyframe_core::control::autopilot::{Autopilot, AutopilotGains};
use skyframe_core::control::mission::{Mission, MissionProgress, Waypoint};
use skyframe_core::devices::gps::GpsFix;
use skyframe_core::estimation::ekf::NominalState;
use skyframe_core::estimation::geo::GeoPoint;
use skyframe_core::estimation::nalgebra;
use skyframe_core::estimation::{Estimator, EstimatorConfig};
use skyframe_sim::plant::trim::trim_level_flight;
use skyframe_sim::plant::{
    ActuatorCommands, AircraftParams, DrydenParams, GpsFixType, Plant, PlantConfig, SimGpsConfig,
    SimGpsSolution, WindConfig,
};
use std::time::Instant;

const DT: f64 = 0.01;

fn fix_of(s: &SimGpsSolution) -> GpsFix {
    let v = s.velocity_ned_mps;
    let speed = (v[0] * v[0] + v[1] * v[1]).sqrt();
    GpsFix {
        received_ns: (s.available_at_s * 1e9).round() as u64,
        valid: s.fix == GpsFixType::Fix3d,
        satellites: Some(s.satellites),
        latitude_deg: Some(s.position.lat_deg),
        longitude_deg: Some(s.position.lon_deg),
        altitude_msl_m: Some(s.position.alt_msl_m),
        ground_speed_mps: Some(speed as f32),
        course_rad: Some(v[1].atan2(v[0]) as f32),
        velocity_ned_mps: [Some(v[0] as f32), Some(v[1] as f32), Some(v[2] as f32)],
        hdop: Some(s.hdop as f32),
        vdop: Some(s.vdop as f32),
        position_sd_m: [
            Some(s.horizontal_std_m as f32),
            Some(s.horizontal_std_m as f32),
            Some(s.vertical_std_m as f32),
        ],
        ..Default::default()
    }
}

fn wrap_deg(a: f64) -> f64 {
    let mut a = a % 360.0;
    if a > 180.0 {
        a -= 360.0;
    } else if a <= -180.0 {
        a += 360.0;
    }
    a
}

#[derive(Default)]
struct Rms {
    sum: f64,
    n: f64,
    max: f64,
}

impl Rms {
    fn add(&mut self, x: f64) {
        self.sum += x * x;
        self.n += 1.0;
        self.max = self.max.max(x.abs());
    }
    fn rms(&self) -> f64 {
        (self.sum / self.n.max(1.0)).sqrt()
    }
}

#[test]
#[cfg_attr(debug_assertions, ignore)]
fn estimator_and_autopilot_fly_the_aerosonde() {
    fly(SimGpsConfig::nominal_10hz(), "nominal 10 Hz receiver");
}

/// The seed's receiver (thesis §6.1.2): 140 ms mean interval with 300 ms peaks.
#[test]
#[cfg_attr(debug_assertions, ignore)]
fn estimator_and_autopilot_fly_the_aerosonde_with_the_seed_receiver() {
    fly(SimGpsConfig::seed_receiver(), "seed receiver");
}

fn fly(gps: SimGpsConfig, label: &str) {
    println!("--- {label}");
    let params = AircraftParams::aerosonde();
    let trim = trim_level_flight(&params, 25.0, 100.0, 0.0).expect("trim");
    let config = PlantConfig {
        params,
        wind: WindConfig {
            steady_ned_mps: [0.0; 3],
            turbulence: Some(DrydenParams::light_low_altitude()),
        },
        gps,
        ..PlantConfig::default()
    };
    let home = config.gps.home;
    let latency_ns = (config.gps.latency_s * 1e9).round() as u64;
    let mut plant = Plant::with_config(config, trim.initial, 7);

    let mut est = Estimator::new(EstimatorConfig {
        home: Some(GeoPoint {
            latitude_deg: home.lat_deg,
            longitude_deg: home.lon_deg,
            altitude_m: home.alt_msl_m,
        }),
        gps_latency_ns: latency_ns,
        ..EstimatorConfig::default()
    });
    // As if aligned on the ground before: attitude 1° and 5° off, biases unknown.
    let t0 = plant.truth();
    let mut x = NominalState::at_rest(nalgebra::UnitQuaternion::from_euler_angles(
        t0.roll_rad + 1f64.to_radians(),
        t0.pitch_rad,
        t0.yaw_rad + 5f64.to_radians(),
    ));
    x.position_ned_m = nalgebra::Vector3::from(t0.position_ned_m);
    x.velocity_ned_mps = nalgebra::Vector3::from(t0.velocity_ned_mps);
    est.start_from(0, x, 10f64.to_radians());

    let mut gains = AutopilotGains::aerosonde();
    gains.trim_elevator = trim.commands.elevator as f32;
    gains.trim_throttle = trim.commands.throttle as f32;
    let mut ap = Autopilot::new(gains);
    let wp = |n: f32, e: f32, alt: f32| Waypoint {
        north_m: n,
        east_m: e,
        altitude_m: alt,
        airspeed_mps: 25.0,
    };
    let mission = Mission::new(&[
        wp(1500.0, 300.0, 100.0),
        wp(1500.0, 900.0, 120.0),
        wp(900.0, 900.0, 120.0),
        wp(900.0, 300.0, 100.0),
    ])
    .expect("fits");
    let mut progress = MissionProgress::default();

    let mut commands = trim.commands;
    let (mut roll, mut pitch, mut yaw) = (Rms::default(), Rms::default(), Rms::default());
    let (mut alt_hold, mut course_hold, mut speed_hold) =
        (Rms::default(), Rms::default(), Rms::default());
    let mut alt_est_err = Rms::default();
    let mut filter_ns: Vec<u64> = Vec::new();
    let mut reached: Vec<(u8, f64)> = Vec::new();
    let mut last_wp = 0u8;
    let mut loiter_at = None;
    let mut loiter_radius = Rms::default();
    let total_s = 420.0;
    let steps = (total_s / DT).round() as u64;
    for k in 1..=steps {
        plant.step(DT, &commands);
        let t = k as f64 * DT;
        let t_ns = (t * 1e9).round() as u64;
        let imu = plant.sample_imu();
        let w = imu.gyro_radps.map(|x| x as f32);
        let f = imu.specific_force_mps2.map(|x| x as f32);
        let start = Instant::now();
        est.imu(t_ns, DT, w, f);
        while let Some(s) = plant.sample_gps() {
            est.gps(&fix_of(&s));
        }
        filter_ns.push(start.elapsed().as_nanos() as u64);
        let e = est.estimate();
        let truth = plant.truth();
        if t > 10.0 {
            roll.add(wrap_deg((e.roll_rad as f64 - truth.roll_rad).to_degrees()));
            pitch.add(wrap_deg(
                (e.pitch_rad as f64 - truth.pitch_rad).to_degrees(),
            ));
            yaw.add(wrap_deg((e.yaw_rad as f64 - truth.yaw_rad).to_degrees()));
            alt_est_err.add(e.altitude_m() as f64 + truth.position_ned_m[2]);
        }
        if k % 2 != 0 {
            continue;
        }
        assert!(e.health.healthy || t < 1.0, "t {t}: {:?}", e.health.reason);
        let (c, targets) = if t < 60.0 {
            ap.auto(&e, 0.0, 100.0, 25.0, 0.02)
        } else {
            let [n, east, _] = e.position_ned_m;
            let g = progress.guide(&mission, n, east).expect("mission");
            if g.waypoint != last_wp {
                reached.push((last_wp, t));
                last_wp = g.waypoint;
            }
            if g.loitering && loiter_at.is_none() {
                reached.push((last_wp, t));
                loiter_at = Some(t);
            }
            if loiter_at.is_some_and(|t0| t > t0 + 40.0) {
                let c = mission.waypoints.last().expect("waypoints");
                let dn = truth.position_ned_m[0] - c.north_m as f64;
                let de = truth.position_ned_m[1] - c.east_m as f64;
                loiter_radius.add((dn * dn + de * de).sqrt() - mission.loiter_radius_m as f64);
            }
            ap.auto(
                &e,
                wrap_pi(g.course_rad),
                g.altitude_m,
                g.airspeed_mps,
                0.02,
            )
        };
        if (20.0..60.0).contains(&t) {
            let v = truth.velocity_ned_mps;
            let course = v[1].atan2(v[0]);
            alt_hold.add(-truth.position_ned_m[2] - targets.altitude_m as f64);
            course_hold.add(wrap_deg((course - targets.course_rad as f64).to_degrees()));
            speed_hold.add(truth.airspeed_mps - targets.airspeed_mps as f64);
        }
        commands = ActuatorCommands {
            aileron: c.aileron as f64,
            elevator: c.elevator as f64,
            throttle: c.throttle as f64,
            rudder: c.rudder as f64,
            ..Default::default()
        };
        assert!(!truth.airframe_strike && !truth.on_ground, "crashed at {t}");
    }
    filter_ns.sort_unstable();
    let mean_us = filter_ns.iter().sum::<u64>() as f64 / filter_ns.len() as f64 / 1e3;
    let p99_us = filter_ns[filter_ns.len() * 99 / 100] as f64 / 1e3;
    let max_us = *filter_ns.last().expect("steps") as f64 / 1e3;
    let h = est.estimate().health;
    println!(
        "attitude error RMS (max), t > 10 s: roll {:.2}° ({:.2}°), pitch {:.2}° ({:.2}°), yaw {:.2}° ({:.2}°)",
        roll.rms(),
        roll.max,
        pitch.rms(),
        pitch.max,
        yaw.rms(),
        yaw.max
    );
    println!(
        "altitude estimate error RMS {:.2} m (max {:.2} m: GPS drift)",
        alt_est_err.rms(),
        alt_est_err.max
    );
    println!(
        "hold 20–60 s (truth vs target): altitude RMS {:.2} m (max {:.2}), course RMS {:.2}° (max {:.2}°), airspeed RMS {:.2} m/s (max {:.2})",
        alt_hold.rms(),
        alt_hold.max,
        course_hold.rms(),
        course_hold.max,
        speed_hold.rms(),
        speed_hold.max
    );
    println!(
        "waypoints reached (index, t s): {reached:?}; loiter radius error RMS {:.1} m",
        loiter_radius.rms()
    );
    println!(
        "filter step (IMU propagate + any GPS update), release: mean {mean_us:.1} µs, p99 {p99_us:.1} µs, max {max_us:.1} µs"
    );
    println!("estimator counters: {:?}", h.counters);
    assert!(roll.rms() < 1.0 && pitch.rms() < 1.0, "attitude");
    assert!(yaw.rms() < 3.0, "yaw");
    assert!(alt_hold.rms() < 5.0, "altitude hold");
    assert!(course_hold.rms() < 5.0, "course hold");
    assert_eq!(reached.len(), 4, "{reached:?}");
    assert!(loiter_at.is_some());
    assert!(loiter_radius.rms() < 20.0, "loiter");
    assert_eq!(h.counters.resets, 0);
}

/// The start-up path on the simulated runway: 10 s at rest (alignment: gyro bias, roll,
/// pitch), then a full-throttle take-off run; the heading comes from the first GPS course
/// above 5 m/s. Checked against the plant's truth and its IMU's true biases.
#[test]
#[cfg_attr(debug_assertions, ignore)]
fn alignment_on_the_runway_and_heading_from_the_take_off_run() {
    let params = AircraftParams::aerosonde();
    let runway_heading = 1.2;
    let initial = skyframe_sim::plant::InitialState::on_runway(&params, runway_heading);
    let config = PlantConfig {
        params,
        ..PlantConfig::default()
    };
    let latency_ns = (config.gps.latency_s * 1e9).round() as u64;
    let mut plant = Plant::with_config(config, initial, 11);
    let mut est = Estimator::new(EstimatorConfig {
        gps_latency_ns: latency_ns,
        ..EstimatorConfig::default()
    });
    let mut aligned_at = None;
    let mut running_at = None;
    let mut worst_tilt_after = 0f64;
    for k in 1..=2000u64 {
        let t = k as f64 * DT;
        let throttle = if t > 10.5 { 1.0 } else { 0.0 };
        plant.step(
            DT,
            &ActuatorCommands {
                throttle,
                ..Default::default()
            },
        );
        let imu = plant.sample_imu();
        est.imu(
            (t * 1e9).round() as u64,
            DT,
            imu.gyro_radps.map(|x| x as f32),
            imu.specific_force_mps2.map(|x| x as f32),
        );
        while let Some(s) = plant.sample_gps() {
            est.gps(&fix_of(&s));
        }
        let e = est.estimate();
        let truth = plant.truth();
        if aligned_at.is_none() && e.health.phase != skyframe_core::estimation::Phase::Aligning {
            aligned_at = Some(t);
            let (bg, _) = plant.imu_biases();
            let err: f64 = (0..3)
                .map(|i| (e.gyro_bias_radps[i] as f64 - bg[i]).powi(2))
                .sum::<f64>()
                .sqrt();
            println!("aligned at {t:.2} s: gyro bias error {err:.5} rad/s");
            assert!(err < 5e-4, "gyro bias error {err}");
        }
        if running_at.is_none() && e.health.phase == skyframe_core::estimation::Phase::Running {
            running_at = Some(t);
            let yaw_err = wrap_deg((e.yaw_rad as f64 - truth.yaw_rad).to_degrees());
            println!(
                "heading from GPS course at {t:.2} s, {:.1} m/s: yaw error {yaw_err:.2}°, healthy {}",
                truth.velocity_ned_mps[0].hypot(truth.velocity_ned_mps[1]),
                e.health.healthy
            );
            assert!(yaw_err.abs() < 3.0);
        }
        if running_at.is_some() && truth.on_ground {
            let r = wrap_deg((e.roll_rad as f64 - truth.roll_rad).to_degrees());
            let p = wrap_deg((e.pitch_rad as f64 - truth.pitch_rad).to_degrees());
            worst_tilt_after = worst_tilt_after.max(r.abs()).max(p.abs());
        }
    }
    println!("worst roll/pitch error on the take-off run: {worst_tilt_after:.2}°");
    assert!(aligned_at.is_some_and(|t| (9.9..10.2).contains(&t)));
    assert!(running_at.is_some());
    assert!(worst_tilt_after < 1.0);
    let h = est.estimate().health;
    assert!(h.healthy, "{:?}", h.reason);
    assert_eq!(h.counters.resets, 0);
}
