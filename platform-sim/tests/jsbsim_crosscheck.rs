//! The cross-check of issue 20: our airframe (`AircraftParams::aerosonde()`) flown by both
//! flight models — the built-in 6-DOF and JSBSim with `platform-sim/jsbsim/aircraft/
//! skyframe-uav` written from the same parameters — from the same trimmed state with the same
//! control inputs: trim, a step on each control, a coordinated turn. Where they differ and
//! why: docs/plants.md. Needs python3 with the jsbsim package (`.ci/run` installs it).

use skyframe_sim::plant::jsbsim::{JsbsimConfig, JsbsimModel, JsbsimStart, OUR_AIRFRAME};
use skyframe_sim::plant::trim::trim_level_flight;
use skyframe_sim::plant::{ActuatorCommands, FlightModel, PlantConfig, SixDofModel, Truth};

const SPEED_MPS: f64 = 23.0;
const ALTITUDE_M: f64 = 150.0;
const G: f64 = 9.80665;

/// Both models at the built-in model's trim for 23 m/s, level, heading north, calm air.
fn both() -> (Box<dyn FlightModel>, Box<dyn FlightModel>, ActuatorCommands) {
    let config = PlantConfig::default();
    let trim = trim_level_flight(&config.params, SPEED_MPS, ALTITUDE_M, 0.0)
        .unwrap_or_else(|e| panic!("{e:?}"));
    let ours = SixDofModel::new(config.clone(), trim.initial, 1);
    let jsbsim = JsbsimModel::start(
        JsbsimConfig {
            given_trim: Some((trim.commands, trim.alpha_rad)),
            ..JsbsimConfig::new(OUR_AIRFRAME)
        },
        &config,
        JsbsimStart::InFlight {
            altitude_m: ALTITUDE_M,
            airspeed_mps: SPEED_MPS,
            heading_rad: 0.0,
        },
        1,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    (Box::new(ours), Box::new(jsbsim), trim.commands)
}

/// Flies `model` for `seconds` in 1 ms steps with the commands `control` gives for the truth
/// (the same function for both models); the truth every 10 ms.
fn fly(
    model: &mut dyn FlightModel,
    seconds: f64,
    control: &mut dyn FnMut(&Truth) -> ActuatorCommands,
) -> Vec<Truth> {
    let mut out = Vec::new();
    for k in 0..(seconds * 1000.0).round() as usize {
        let t = model.truth();
        if k % 10 == 0 {
            out.push(t);
        }
        let c = control(&t);
        model.step(0.001, &c).unwrap_or_else(|e| panic!("{e}"));
    }
    out
}

fn at(h: &[Truth], t_s: f64) -> Truth {
    let i = ((t_s * 100.0).round() as usize).min(h.len() - 1);
    h[i]
}

/// A step of `delta` on top of the trim from 1 s on.
fn step(trim: ActuatorCommands, delta: ActuatorCommands) -> impl FnMut(&Truth) -> ActuatorCommands {
    move |t: &Truth| {
        if t.t_s < 1.0 {
            trim
        } else {
            ActuatorCommands {
                aileron: trim.aileron + delta.aileron,
                elevator: trim.elevator + delta.elevator,
                rudder: trim.rudder + delta.rudder,
                throttle: trim.throttle + delta.throttle,
                brake: 0.0,
            }
        }
    }
}

fn report(what: &str, ours: f64, theirs: f64) {
    println!(
        "{what:<48} built-in {ours:>9.4}   JSBSim {theirs:>9.4}   diff {:>8.4}",
        theirs - ours
    );
}

#[test]
fn trim_holds_on_both() {
    let (mut a, mut b, trim) = both();
    let ha = fly(a.as_mut(), 10.0, &mut |_| trim);
    let hb = fly(b.as_mut(), 10.0, &mut |_| trim);
    let (ea, eb) = (at(&ha, 10.0), at(&hb, 10.0));
    report(
        "trim: airspeed after 10 s (m/s)",
        ea.airspeed_mps,
        eb.airspeed_mps,
    );
    report(
        "trim: height change over 10 s (m)",
        ea.height_above_ground_m - ALTITUDE_M,
        eb.height_above_ground_m - ALTITUDE_M,
    );
    report(
        "trim: pitch after 10 s (deg)",
        ea.pitch_rad.to_degrees(),
        eb.pitch_rad.to_degrees(),
    );
    report(
        "trim: alpha after 10 s (deg)",
        ea.alpha_rad.to_degrees(),
        eb.alpha_rad.to_degrees(),
    );
    report(
        "trim: roll after 10 s (deg)",
        ea.roll_rad.to_degrees(),
        eb.roll_rad.to_degrees(),
    );
    // The built-in model's trim is a trim of JSBSim's copy of the airframe too: both hold
    // speed, height and attitude for 10 s with the controls fixed.
    for e in [ea, eb] {
        assert!((e.airspeed_mps - SPEED_MPS).abs() < 0.5, "{e:?}");
        assert!((e.height_above_ground_m - ALTITUDE_M).abs() < 3.0, "{e:?}");
        assert!(e.roll_rad.abs() < 3f64.to_radians(), "{e:?}");
    }
    assert!((ea.pitch_rad - eb.pitch_rad).abs() < 1f64.to_radians());
}

#[test]
fn a_step_on_each_control_moves_both_alike() {
    let cases = [
        (
            "elevator +0.1: pitch rate at 1.5 s (deg/s)",
            ActuatorCommands {
                elevator: 0.1,
                ..Default::default()
            },
            1usize,
        ),
        (
            "aileron +0.1: roll rate at 1.5 s (deg/s)",
            ActuatorCommands {
                aileron: 0.1,
                ..Default::default()
            },
            0,
        ),
        (
            "rudder +0.1: yaw rate at 1.5 s (deg/s)",
            ActuatorCommands {
                rudder: 0.1,
                ..Default::default()
            },
            2,
        ),
    ];
    for (what, delta, axis) in cases {
        let (mut a, mut b, trim) = both();
        let ha = fly(a.as_mut(), 1.5, &mut step(trim, delta));
        let hb = fly(b.as_mut(), 1.5, &mut step(trim, delta));
        let (ra, rb) = (
            at(&ha, 1.5).rates_body_radps[axis].to_degrees(),
            at(&hb, 1.5).rates_body_radps[axis].to_degrees(),
        );
        report(what, ra, rb);
        // Same sign, and within 25 % of each other half a second into the step.
        assert!(ra > 1.0 && rb > 1.0, "{what}: {ra} {rb}");
        assert!((ra - rb).abs() < 0.25 * ra.abs(), "{what}: {ra} {rb}");
    }
    // Throttle: the speed gained in 5 s.
    let delta = ActuatorCommands {
        throttle: 0.2,
        ..Default::default()
    };
    let (mut a, mut b, trim) = both();
    let ha = fly(a.as_mut(), 6.0, &mut step(trim, delta));
    let hb = fly(b.as_mut(), 6.0, &mut step(trim, delta));
    let (va, vb) = (
        at(&ha, 6.0).airspeed_mps - SPEED_MPS,
        at(&hb, 6.0).airspeed_mps - SPEED_MPS,
    );
    let (za, zb) = (
        at(&ha, 6.0).height_above_ground_m - ALTITUDE_M,
        at(&hb, 6.0).height_above_ground_m - ALTITUDE_M,
    );
    report("throttle +0.2: airspeed change at 5 s (m/s)", va, vb);
    report("throttle +0.2: height change at 5 s (m)", za, zb);
    // Energy: the extra thrust goes into speed and height alike on both.
    let (ea, eb) = (SPEED_MPS * va + G * za, SPEED_MPS * vb + G * zb);
    report("throttle +0.2: specific energy gained (J/kg)", ea, eb);
    assert!(
        ea > 0.0 && eb > 0.0 && (ea - eb).abs() < 0.3 * ea,
        "{ea} {eb}"
    );
}

#[test]
fn a_coordinated_turn_turns_at_the_rate_physics_says() {
    // The same simple pilot on both: bank to 30° with aileron, hold height with elevator,
    // no sideslip with rudder.
    let bank = 30f64.to_radians();
    let pilot = |trim: ActuatorCommands| {
        let mut roll_integral = 0.0;
        move |t: &Truth| {
            let roll_error = bank - t.roll_rad;
            roll_integral += roll_error * 0.001;
            let climb = -t.velocity_ned_mps[2];
            ActuatorCommands {
                aileron: trim.aileron + 2.0 * roll_error + 1.0 * roll_integral
                    - 0.3 * t.rates_body_radps[0],
                // Up elevator for the turn's load factor, and the height held.
                elevator: trim.elevator
                    + 0.08
                    + 0.02 * (ALTITUDE_M - t.height_above_ground_m).clamp(-10.0, 10.0)
                    - 0.05 * climb,
                // Positive rudder yaws right, into a sideslip from the right (β > 0).
                rudder: trim.rudder + 2.0 * t.beta_rad,
                throttle: trim.throttle + 0.1,
                brake: 0.0,
            }
        }
    };
    let (mut a, mut b, trim) = both();
    let ha = fly(a.as_mut(), 20.0, &mut pilot(trim));
    let hb = fly(b.as_mut(), 20.0, &mut pilot(trim));
    for (name, h) in [("built-in", &ha), ("JSBSim", &hb)] {
        // Over the last 10 s: the mean turn rate against g·tan(φ)/V for the mean bank and speed.
        let tail = &h[h.len() - 1000..];
        let n = tail.len() as f64;
        let roll = tail.iter().map(|t| t.roll_rad).sum::<f64>() / n;
        let speed = tail
            .iter()
            .map(|t| t.velocity_ned_mps[0].hypot(t.velocity_ned_mps[1]))
            .sum::<f64>()
            / n;
        let course = |t: &Truth| t.velocity_ned_mps[1].atan2(t.velocity_ned_mps[0]);
        let mut turned = 0.0;
        for w in tail.windows(2) {
            let mut d = course(&w[1]) - course(&w[0]);
            if d > std::f64::consts::PI {
                d -= std::f64::consts::TAU;
            }
            if d < -std::f64::consts::PI {
                d += std::f64::consts::TAU;
            }
            turned += d;
        }
        let rate = turned / ((n - 1.0) * 0.01);
        let physics = G * roll.tan() / speed;
        let beta = tail.iter().map(|t| t.beta_rad.abs()).fold(0.0, f64::max);
        println!(
            "{name:<9} turn: bank {:.1} deg, speed {:.2} m/s, rate {:.2} deg/s, g·tanφ/V {:.2} deg/s, max |β| {:.2} deg",
            roll.to_degrees(),
            speed,
            rate.to_degrees(),
            physics.to_degrees(),
            beta.to_degrees()
        );
        assert!(
            (roll - bank).abs() < 3f64.to_radians(),
            "{name}: bank {}",
            roll.to_degrees()
        );
        assert!(
            (rate - physics).abs() < 0.05 * physics,
            "{name}: {rate} vs {physics}"
        );
    }
    let (ea, eb) = (at(&ha, 20.0), at(&hb, 20.0));
    report(
        "turn: heading after 20 s (deg)",
        ea.yaw_rad.to_degrees(),
        eb.yaw_rad.to_degrees(),
    );
    // Both plants, same pilot: within 3° of each other after 240° of turn, and at one height.
    let apart = (ea.yaw_rad - eb.yaw_rad + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
        - std::f64::consts::PI;
    assert!(apart.abs() < 3f64.to_radians(), "{}", apart.to_degrees());
    assert!((ea.height_above_ground_m - eb.height_above_ground_m).abs() < 3.0);
}
