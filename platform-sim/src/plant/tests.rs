//! Behaviour of the whole plant: trim, control signs, ground handling, take-off, stall,
//! determinism, sensor timing through the plant, and robustness to any command.

use super::dynamics::{self, AirMass, ControlInputs, RigidBodyState};
use super::math::quat_from_euler;
use super::trim::{Trim, trim_level_flight};
use super::*;

const DT: f64 = 0.01;

fn trimmed(airspeed: f64) -> Trim {
    trim_level_flight(&AircraftParams::aerosonde(), airspeed, 100.0, 0.0).expect("trim")
}

fn calm_plant(initial: InitialState, seed: u64) -> Plant {
    Plant::new(
        AircraftParams::aerosonde(),
        initial,
        WindConfig::calm(),
        seed,
    )
}

fn fly(plant: &mut Plant, seconds: f64, cmd: &ActuatorCommands) {
    for _ in 0..(seconds / DT).round() as usize {
        plant.step(DT, cmd);
    }
}

#[test]
fn trimmed_level_flight_holds_altitude_and_speed_for_30_s() {
    for airspeed in [20.0, 25.0, 30.0] {
        let trim = trimmed(airspeed);
        println!(
            "trim at {airspeed} m/s: alpha {:.2}°, roll {:.2}°, throttle {:.3}, elevator {:+.3}, aileron {:+.4}, rudder {:+.4}",
            trim.alpha_rad.to_degrees(),
            trim.roll_rad.to_degrees(),
            trim.commands.throttle,
            trim.commands.elevator,
            trim.commands.aileron,
            trim.commands.rudder
        );
        let mut plant = calm_plant(trim.initial, 1);
        let start = plant.truth();
        assert!((start.airspeed_mps - airspeed).abs() < 1e-9);
        fly(&mut plant, 30.0, &trim.commands);
        let end = plant.truth();
        let climb = end.height_above_ground_m - start.height_above_ground_m;
        assert!(
            climb.abs() < 3.0,
            "{airspeed} m/s: altitude changed {climb} m"
        );
        assert!(
            (end.airspeed_mps - airspeed).abs() < 0.5,
            "{airspeed} m/s: now {}",
            end.airspeed_mps
        );
        assert!(
            end.roll_rad.abs() < 2f64.to_radians(),
            "roll {}",
            end.roll_rad
        );
        assert!(end.yaw_rad.abs() < 2f64.to_radians(), "yaw {}", end.yaw_rad);
        assert!(!end.on_ground);
    }
}

#[test]
fn trim_commands_are_plausible() {
    let t = trimmed(25.0);
    // Up elevator (positive by our convention) and part throttle.
    assert!(
        t.commands.throttle > 0.2 && t.commands.throttle < 0.9,
        "{t:?}"
    );
    assert!(t.alpha_rad > 0.0 && t.alpha_rad < 0.15, "{t:?}");
    // Faster flight needs less angle of attack and more throttle.
    let fast = trimmed(30.0);
    assert!(fast.alpha_rad < t.alpha_rad && fast.commands.throttle > t.commands.throttle);
    // Beyond the top speed there is no trim: not enough thrust.
    let top = trim_level_flight(&AircraftParams::aerosonde(), 40.0, 100.0, 0.0);
    assert!(
        matches!(top, Err(super::trim::TrimError::OutOfRange { .. })),
        "{top:?}"
    );
}

/// Body rates 0.5 s after adding `delta` to the trim commands, minus those of trim alone.
fn rate_response(delta: ActuatorCommands) -> [f64; 3] {
    let trim = trimmed(25.0);
    let mut base = calm_plant(trim.initial, 1);
    let mut moved = calm_plant(trim.initial, 1);
    let cmd = ActuatorCommands {
        aileron: trim.commands.aileron + delta.aileron,
        elevator: trim.commands.elevator + delta.elevator,
        rudder: trim.commands.rudder + delta.rudder,
        ..trim.commands
    };
    fly(&mut base, 0.5, &trim.commands);
    fly(&mut moved, 0.5, &cmd);
    let (a, b) = (
        base.truth().rates_body_radps,
        moved.truth().rates_body_radps,
    );
    [b[0] - a[0], b[1] - a[1], b[2] - a[2]]
}

#[test]
fn positive_aileron_rolls_right() {
    let d = rate_response(ActuatorCommands {
        aileron: 0.3,
        ..Default::default()
    });
    assert!(d[0] > 0.1, "{d:?}");
    let d = rate_response(ActuatorCommands {
        aileron: -0.3,
        ..Default::default()
    });
    assert!(d[0] < -0.1, "{d:?}");
}

#[test]
fn positive_elevator_pitches_up() {
    let d = rate_response(ActuatorCommands {
        elevator: 0.3,
        ..Default::default()
    });
    assert!(d[1] > 0.05, "{d:?}");
    let d = rate_response(ActuatorCommands {
        elevator: -0.3,
        ..Default::default()
    });
    assert!(d[1] < -0.05, "{d:?}");
}

#[test]
fn positive_rudder_yaws_right() {
    let d = rate_response(ActuatorCommands {
        rudder: 0.3,
        ..Default::default()
    });
    assert!(d[2] > 0.02, "{d:?}");
    let d = rate_response(ActuatorCommands {
        rudder: -0.3,
        ..Default::default()
    });
    assert!(d[2] < -0.02, "{d:?}");
}

#[test]
fn parked_airplane_stays_put_and_reads_minus_g() {
    let params = AircraftParams::aerosonde();
    let mut plant = calm_plant(InitialState::on_runway(&params, 0.3), 1);
    fly(&mut plant, 10.0, &ActuatorCommands::default());
    let t = plant.truth();
    assert!(t.on_ground);
    assert!(
        t.position_ned_m[0].abs() < 1e-3 && t.position_ned_m[1].abs() < 1e-3,
        "{t:?}"
    );
    assert!((t.height_above_ground_m - params.ground.rest_height_m(params.mass_kg)).abs() < 1e-3);
    assert!(t.roll_rad.abs() < 1e-4 && t.pitch_rad.abs() < 1e-4 && (t.yaw_rad - 0.3).abs() < 1e-4);
    let f = t.specific_force_body_mps2;
    assert!(f[0].abs() < 1e-3 && f[1].abs() < 1e-3, "{f:?}");
    assert!((f[2] + GRAVITY_MPS2).abs() < 1e-3, "{f:?}");
    let imu = plant.sample_imu();
    assert!(
        (imu.specific_force_mps2[2] + GRAVITY_MPS2).abs() < 0.3,
        "{imu:?}"
    );
}

#[test]
fn dropped_airplane_settles_on_its_wheels_without_bouncing_away() {
    let params = AircraftParams::aerosonde();
    let mut initial = InitialState::on_runway(&params, 0.0);
    initial.position_ned_m[2] -= 1.0;
    initial.velocity_ned_mps = [0.0, 0.0, 3.0];
    let mut plant = calm_plant(initial, 1);
    let mut highest = f64::MIN;
    for _ in 0..500 {
        plant.step(DT, &ActuatorCommands::default());
        highest = highest.max(plant.truth().height_above_ground_m);
    }
    assert!(highest < 1.5, "bounced to {highest} m");
    fly(&mut plant, 5.0, &ActuatorCommands::default());
    let t = plant.truth();
    assert!(
        t.on_ground && t.velocity_ned_mps.iter().all(|v| v.abs() < 1e-2),
        "{t:?}"
    );
}

#[test]
fn brakes_stop_a_rolling_airplane() {
    let params = AircraftParams::aerosonde();
    let mut initial = InitialState::on_runway(&params, 0.0);
    initial.velocity_ned_mps = [10.0, 0.0, 0.0];
    let mut coasting = calm_plant(initial, 1);
    let mut braking = calm_plant(initial, 1);
    fly(&mut coasting, 3.0, &ActuatorCommands::default());
    fly(
        &mut braking,
        3.0,
        &ActuatorCommands {
            brake: 1.0,
            ..Default::default()
        },
    );
    let (c, b) = (coasting.truth(), braking.truth());
    assert!(c.velocity_ned_mps[0] > 5.0, "coasting {c:?}");
    assert!(b.velocity_ned_mps[0] < 2.0, "braking {b:?}");
    assert!(b.position_ned_m[0] < c.position_ned_m[0]);
}

/// A crude test pilot: full throttle, rotate past 16 m/s, then hold 12° of pitch, wings level.
fn takeoff_pilot(t: &Truth) -> ActuatorCommands {
    let rotate = t.airspeed_mps > 16.0 || !t.on_ground;
    let elevator = if rotate {
        3.0 * (12f64.to_radians() - t.pitch_rad) - 0.5 * t.rates_body_radps[1]
    } else {
        0.0
    };
    ActuatorCommands {
        aileron: -2.0 * t.roll_rad - 0.3 * t.rates_body_radps[0],
        elevator,
        rudder: -t.yaw_rad - 0.3 * t.rates_body_radps[2],
        throttle: 1.0,
        brake: 0.0,
    }
}

#[test]
fn full_throttle_takes_off_and_climbs() {
    let params = AircraftParams::aerosonde();
    let mut plant = calm_plant(InitialState::on_runway(&params, 0.0), 1);
    let mut liftoff: Option<(f64, f64, f64)> = None;
    for _ in 0..3000 {
        let t = plant.truth();
        assert!(!t.airframe_strike, "tail or wing strike: {t:?}");
        if liftoff.is_none() && !t.on_ground && t.height_above_ground_m > 1.0 {
            liftoff = Some((t.t_s, t.position_ned_m[0], t.airspeed_mps));
        }
        plant.step(DT, &takeoff_pilot(&t));
    }
    let (t_lo, roll_m, v_lo) = liftoff.expect("never left the ground");
    println!("lift-off after {t_lo:.1} s, {roll_m:.0} m of runway, at {v_lo:.1} m/s");
    let end = plant.truth();
    assert!(
        t_lo < 15.0 && roll_m < 200.0,
        "slow take-off: {t_lo} s, {roll_m} m"
    );
    assert!(end.height_above_ground_m > 50.0, "{end:?}");
    assert!(end.velocity_ned_mps[2] < -1.0, "not climbing: {end:?}");
    assert!(
        end.position_ned_m[1].abs() < 20.0,
        "left the runway line: {end:?}"
    );
}

/// A crude landing pilot: hold the sink rate with pitch and the airspeed with throttle down
/// to 4 m, then flare on pitch and power, then brake on the ground.
struct LandingPilot {
    trim: Trim,
    rest_height_m: f64,
}

impl LandingPilot {
    fn command(&self, t: &Truth) -> ActuatorCommands {
        let height = t.height_above_ground_m - self.rest_height_m;
        let climb = -t.velocity_ned_mps[2];
        let wings_level = -2.0 * t.roll_rad - 0.3 * t.rates_body_radps[0];
        let heading = -t.yaw_rad - 0.3 * t.rates_body_radps[2];
        if t.on_ground && height < 0.05 {
            return ActuatorCommands {
                aileron: wings_level,
                elevator: 0.0,
                rudder: heading,
                throttle: 0.0,
                brake: if t.airspeed_mps < 15.0 { 1.0 } else { 0.0 },
            };
        }
        let flare = height < 4.0;
        let target_climb = if flare { -0.2 - 0.2 * height } else { -1.5 };
        let pitch_target = self.trim.pitch_rad + 0.15 * (target_climb - climb);
        let elevator = self.trim.commands.elevator + 3.0 * (pitch_target - t.pitch_rad)
            - 0.5 * t.rates_body_radps[1];
        // The elevator alone cannot flare much (the Aerosonde's C_m_α is strong and its
        // elevator reaches only about 9° of α), so power stays on and holds the sink down.
        let throttle = if flare {
            (0.6 * self.trim.commands.throttle + 0.5 * (target_climb - climb)).clamp(0.0, 1.0)
        } else {
            self.trim.commands.throttle + 0.1 * (20.0 - t.airspeed_mps)
        };
        ActuatorCommands {
            aileron: self.trim.commands.aileron + wings_level,
            elevator,
            rudder: heading,
            throttle,
            brake: 0.0,
        }
    }
}

#[test]
fn approach_touches_down_gently_and_stops_on_its_wheels() {
    let params = AircraftParams::aerosonde();
    let trim = trim_level_flight(&params, 20.0, 30.0, 0.0).expect("trim");
    let pilot = LandingPilot {
        trim,
        rest_height_m: params.ground.rest_height_m(params.mass_kg),
    };
    let mut plant = calm_plant(trim.initial, 1);
    let mut touchdown: Option<Truth> = None;
    for _ in 0..9000 {
        let t = plant.truth();
        assert!(!t.airframe_strike, "strike: {t:?}");
        if touchdown.is_none() && t.on_ground {
            touchdown = Some(t);
        }
        let c = pilot.command(&t);
        plant.step(DT, &c);
    }
    let td = touchdown.expect("never touched down");
    println!(
        "touchdown at {:.1} s, {:.0} m, sink {:.2} m/s, {:.1} m/s airspeed, pitch {:.1}°",
        td.t_s,
        td.position_ned_m[0],
        td.velocity_ned_mps[2],
        td.airspeed_mps,
        td.pitch_rad.to_degrees()
    );
    assert!(td.velocity_ned_mps[2] < 1.0, "hard landing: {td:?}");
    let end = plant.truth();
    println!(
        "stopped {:.0} m after touchdown",
        end.position_ned_m[0] - td.position_ned_m[0]
    );
    assert!(
        end.on_ground && end.velocity_ned_mps.iter().all(|v| v.abs() < 0.05),
        "{end:?}"
    );
    assert!(
        end.roll_rad.abs() < 0.01 && end.pitch_rad.abs() < 0.01,
        "{end:?}"
    );
    assert!(
        end.position_ned_m[0] - td.position_ned_m[0] < 300.0,
        "{end:?}"
    );
}

#[test]
fn lift_falls_past_the_stall_angle() {
    let p = AircraftParams::aerosonde();
    let lift_at = |alpha: f64| {
        let s = RigidBodyState {
            position_ned_m: [0.0, 0.0, -100.0],
            velocity_body_mps: [20.0 * alpha.cos(), 0.0, 20.0 * alpha.sin()],
            attitude: quat_from_euler(0.0, 0.0, 0.0),
            rates_body_radps: [0.0; 3],
        };
        let f = dynamics::forces_and_moments(
            &p,
            &s,
            &ControlInputs::default(),
            &AirMass::default(),
            &[],
        );
        let [fx, _, fz] = f.contact_and_aero_force_body_n;
        // Lift is perpendicular to the relative wind; remove the (zero) thrust first.
        let fx = fx - f.propulsion.thrust_n;
        fx * alpha.sin() - fz * alpha.cos()
    };
    let pre = lift_at(0.40);
    let post = lift_at(0.60);
    assert!(lift_at(0.2) < pre, "lift grows with alpha before the stall");
    assert!(
        post < 0.6 * pre,
        "no stall: {pre} N at 0.40 rad, {post} N at 0.60 rad"
    );
}

fn gusty_config() -> PlantConfig {
    PlantConfig {
        wind: WindConfig {
            steady_ned_mps: [3.0, -2.0, 0.0],
            turbulence: Some(DrydenParams::moderate_low_altitude()),
        },
        gps: SimGpsConfig {
            outage_probability: 0.01,
            ..SimGpsConfig::seed_receiver()
        },
        ..PlantConfig::default()
    }
}

/// Flies a scripted run and records everything observable.
fn recorded_run(
    seed: u64,
) -> (
    Vec<Truth>,
    Vec<SimImuReading>,
    Vec<SimGpsSolution>,
    Vec<BatterySample>,
) {
    let trim = trimmed(25.0);
    let mut plant = Plant::with_config(gusty_config(), trim.initial, seed);
    let (mut truth, mut imu, mut gps, mut bat) = (vec![], vec![], vec![], vec![]);
    for k in 0..1000 {
        let t = k as f64 * DT;
        let cmd = ActuatorCommands {
            aileron: trim.commands.aileron + 0.2 * (0.7 * t).sin(),
            elevator: trim.commands.elevator + 0.1 * (0.3 * t).cos(),
            ..trim.commands
        };
        plant.step(DT, &cmd);
        truth.push(plant.truth());
        imu.push(plant.sample_imu());
        while let Some(s) = plant.sample_gps() {
            gps.push(s);
        }
        bat.push(plant.sample_battery());
    }
    (truth, imu, gps, bat)
}

#[test]
fn same_seed_gives_a_bit_identical_run() {
    let a = recorded_run(99);
    let b = recorded_run(99);
    // PartialEq on f64 is exact equality: bit-identical (no NaN appears, checked elsewhere).
    assert!(a == b, "runs with the same seed differ");
    let c = recorded_run(100);
    assert!(
        a.0 != c.0 && a.1 != c.1 && a.2 != c.2,
        "the seed changes nothing"
    );
    // Turbulence was really on.
    assert!(a.0.iter().any(|t| t.gust_body_mps != [0.0; 3]));
}

#[test]
fn gps_through_the_plant_keeps_its_mean_interval() {
    let cfg = PlantConfig {
        gps: SimGpsConfig::seed_receiver(),
        max_step_s: 0.01,
        ..PlantConfig::default()
    };
    let params = AircraftParams::aerosonde();
    let mut plant = Plant::with_config(cfg, InitialState::on_runway(&params, 0.0), 5);
    let mut valid_at = vec![];
    let home = GeodeticPosition::default();
    for _ in 0..12_000 {
        plant.step(DT, &ActuatorCommands::default());
        while let Some(s) = plant.sample_gps() {
            assert!(s.available_at_s <= plant.time_s() + 1e-12);
            valid_at.push(s.valid_at_s);
            // A parked airplane's fixes are within metres of home (GPS drift is ~1.5 m 1σ).
            let e = home.ned_to(&s.position);
            assert!(e[0].hypot(e[1]) < 15.0, "{s:?}");
        }
    }
    let mean = (valid_at[valid_at.len() - 1] - valid_at[0]) / (valid_at.len() - 1) as f64;
    assert!((mean - 0.14).abs() < 0.007, "mean GPS interval {mean}");
}

#[test]
fn truth_reports_the_wind() {
    let trim = trimmed(25.0);
    let wind = WindConfig {
        steady_ned_mps: [0.0, 5.0, 0.0],
        turbulence: None,
    };
    let mut plant = Plant::new(AircraftParams::aerosonde(), trim.initial, wind, 1);
    plant.step(DT, &trim.commands);
    let t = plant.truth();
    assert_eq!(t.wind_ned_mps, [0.0, 5.0, 0.0]);
    // A crosswind from the west (blowing east) on a northbound airplane: sideslip is negative
    // (the air comes from the left).
    assert!(t.beta_rad < -0.1, "{t:?}");
}

#[test]
fn battery_sags_with_throttle() {
    let params = AircraftParams::aerosonde();
    let mut plant = calm_plant(InitialState::on_runway(&params, 0.0), 1);
    fly(
        &mut plant,
        0.5,
        &ActuatorCommands {
            brake: 1.0,
            ..Default::default()
        },
    );
    let idle = plant.battery_truth().1.voltage_v;
    fly(
        &mut plant,
        0.5,
        &ActuatorCommands {
            throttle: 1.0,
            brake: 1.0,
            ..Default::default()
        },
    );
    let (avionics, full) = plant.battery_truth();
    assert!(idle - full.voltage_v > 1.0, "{idle} → {}", full.voltage_v);
    assert!(full.current_a > 20.0, "{full:?}");
    assert!(
        avionics.voltage_v > 11.0 && avionics.voltage_v < 12.6,
        "{avionics:?}"
    );
}

fn all_finite(t: &Truth) -> bool {
    let scalars = [
        t.roll_rad,
        t.pitch_rad,
        t.yaw_rad,
        t.airspeed_mps,
        t.alpha_rad,
        t.beta_rad,
        t.thrust_n,
        t.motor_speed_radps,
        t.height_above_ground_m,
    ];
    t.position_ned_m
        .iter()
        .chain(&t.velocity_ned_mps)
        .chain(&t.velocity_body_mps)
        .chain(&t.attitude)
        .chain(&t.rates_body_radps)
        .chain(&t.specific_force_body_mps2)
        .chain(&t.wind_ned_mps)
        .chain(&scalars)
        .all(|x| x.is_finite())
}

mod robustness {
    use super::*;
    use proptest::prelude::*;

    fn command() -> impl Strategy<Value = ActuatorCommands> {
        (
            -1.0..=1.0f64,
            -1.0..=1.0f64,
            -1.0..=1.0f64,
            0.0..=1.0f64,
            0.0..=1.0f64,
        )
            .prop_map(
                |(aileron, elevator, rudder, throttle, brake)| ActuatorCommands {
                    aileron,
                    elevator,
                    rudder,
                    throttle,
                    brake,
                },
            )
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

        /// Any in-range commands, changed every half second, in gusty air, from the air or
        /// from the runway, never produce a NaN or an infinity within 4 s.
        #[test]
        fn no_nan_for_any_commands(
            commands in proptest::collection::vec(command(), 8),
            from_air in any::<bool>(),
            low in any::<bool>(),
            seed in any::<u64>(),
            coarse in any::<bool>(),
        ) {
            let params = AircraftParams::aerosonde();
            let initial = if from_air {
                let mut t = trim_level_flight(&params, 25.0, 100.0, 0.0).expect("trim").initial;
                // Sometimes close to the ground, so that crashes are exercised too.
                if low { t.position_ned_m[2] = -3.0; }
                t
            } else {
                InitialState::on_runway(&params, 1.0)
            };
            // Both the default 1 ms step and the coarsest step the plant allows.
            let max_step_s = if coarse { MAX_STEP_S } else { 0.001 };
            let cfg = PlantConfig { max_step_s, ..gusty_config() };
            let mut plant = Plant::with_config(cfg, initial, seed);
            for cmd in &commands {
                for _ in 0..50 {
                    plant.step(DT, cmd);
                    let t = plant.truth();
                    prop_assert!(all_finite(&t), "{:?}", t);
                    // Never sinks through the ground.
                    prop_assert!(t.height_above_ground_m > -0.5, "{:?}", t);
                }
                let imu = plant.sample_imu();
                prop_assert!(imu.gyro_radps.iter().chain(&imu.specific_force_mps2).all(|x| x.is_finite()));
            }
        }
    }
}

/// Not a correctness test: how fast the plant runs. `cargo test --release -p skyframe-sim
/// plant_speed -- --ignored --nocapture`.
#[test]
#[ignore]
fn plant_speed() {
    let trim = trimmed(25.0);
    let cfg = PlantConfig {
        wind: WindConfig {
            steady_ned_mps: [3.0, 0.0, 0.0],
            turbulence: Some(DrydenParams::light_low_altitude()),
        },
        ..PlantConfig::default()
    };
    let mut plant = Plant::with_config(cfg, trim.initial, 1);
    let plant_seconds = 600.0;
    let start = std::time::Instant::now();
    for _ in 0..(plant_seconds / DT) as usize {
        plant.step(DT, &trim.commands);
        let _ = plant.sample_imu();
        while plant.sample_gps().is_some() {}
    }
    let wall = start.elapsed().as_secs_f64();
    println!(
        "{plant_seconds} plant s at 1 kHz RK4 (+100 Hz IMU, GPS) in {wall:.3} wall s: {:.0} plant s per wall s",
        plant_seconds / wall
    );
}

#[test]
fn parked_airplane_holds_still_in_gusty_wind() {
    let params = AircraftParams::aerosonde();
    let cases = [
        ([5.0, 0.0, 0.0], 0.0),
        ([-8.0, 0.0, 0.0], 1.0),
        ([0.0, 5.0, 0.0], 1.0),
        ([3.0, -4.0, 0.0], 1.0),
    ];
    for (wind, brake) in cases {
        let cfg = WindConfig {
            steady_ned_mps: wind,
            turbulence: Some(DrydenParams::light_low_altitude()),
        };
        let mut plant = Plant::new(
            params.clone(),
            InitialState::on_runway(&params, 0.0),
            cfg,
            1,
        );
        fly(
            &mut plant,
            60.0,
            &ActuatorCommands {
                brake,
                ..Default::default()
            },
        );
        let t = plant.truth();
        // Static friction holds it (mm of tyre flex), rather than a slow creep.
        let moved = t.position_ned_m[0].hypot(t.position_ned_m[1]);
        assert!(
            moved < 0.02,
            "wind {wind:?}, brake {brake}: moved {moved} m"
        );
        assert!(
            t.yaw_rad.abs() < 0.5f64.to_radians(),
            "wind {wind:?}: yaw {}",
            t.yaw_rad
        );
        assert!(t.on_ground && !t.airframe_strike);
    }
}

#[test]
fn surfaces_lag_their_commands_and_bad_commands_are_neutral() {
    let trim = trimmed(25.0);
    let mut plant = calm_plant(trim.initial, 1);
    // The first command is taken at once, so a run starts trimmed.
    plant.step(0.001, &trim.commands);
    assert_eq!(plant.actuators(), trim.commands);
    let cmd = ActuatorCommands {
        aileron: 1.0,
        ..trim.commands
    };
    let tau = plant.config().surface_time_constant_s;
    plant.step(tau, &cmd);
    let a = plant.actuators().aileron;
    let expected = trim.commands.aileron + (1.0 - trim.commands.aileron) * (1.0 - (-1.0f64).exp());
    assert!((a - expected).abs() < 1e-3, "{a} vs {expected}");
    assert_eq!(plant.truth().actuators.aileron, a);
    let bad = ActuatorCommands {
        aileron: f64::NAN,
        elevator: f64::INFINITY,
        rudder: 7.0,
        throttle: -3.0,
        brake: f64::NEG_INFINITY,
    };
    assert_eq!(
        bad.sanitized(),
        ActuatorCommands {
            aileron: 0.0,
            elevator: 0.0,
            rudder: 1.0,
            throttle: 0.0,
            brake: 0.0
        }
    );
    fly(&mut plant, 1.0, &bad);
    assert!(all_finite(&plant.truth()));
}

#[test]
fn ideal_gps_reports_where_the_airplane_was_when_the_fix_was_valid() {
    let trim = trimmed(25.0);
    let cfg = PlantConfig {
        gps: SimGpsConfig::ideal(),
        max_step_s: 0.01,
        ..PlantConfig::default()
    };
    let mut plant = Plant::with_config(cfg, trim.initial, 3);
    let mut history: Vec<Truth> = vec![plant.truth()];
    let mut checked = 0;
    for _ in 0..300 {
        plant.step(0.01, &trim.commands);
        history.push(plant.truth());
        while let Some(fix) = plant.sample_gps() {
            assert_eq!(fix.fix, GpsFixType::Fix3d);
            // Latency: delivered 80 ms after it was valid.
            assert!((fix.available_at_s - fix.valid_at_s - 0.08).abs() < 1e-9);
            // The truth at the nearest 10 ms step before the fix, moved on to its time.
            let before = history
                .iter()
                .rev()
                .find(|t| t.t_s <= fix.valid_at_s + 1e-12)
                .expect("history");
            let dt = fix.valid_at_s - before.t_s;
            let ned = plant.config().gps.home.ned_to(&fix.position);
            for (i, got) in ned.iter().enumerate() {
                let want = before.position_ned_m[i] + before.velocity_ned_mps[i] * dt;
                assert!((got - want).abs() < 0.05, "axis {i}: {got} vs {want}");
            }
            checked += 1;
        }
    }
    assert!(checked > 20);
}
