//! JSBSim through the driver, checked against physics and JSBSim's own figures. These need
//! python3 with the jsbsim package (`.ci/run` installs it): they fail, not skip, without it.

use super::*;
use crate::plant::GRAVITY_MPS2;
use crate::plant::math::{mat_vec, quat_to_rotation};

fn start(aircraft: &str, start: JsbsimStart) -> JsbsimModel {
    JsbsimModel::start(
        JsbsimConfig::new(aircraft),
        &PlantConfig::default(),
        start,
        1,
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

fn fly(model: &mut JsbsimModel, seconds: f64, commands: &ActuatorCommands) -> Vec<Truth> {
    let steps = (seconds * 1000.0).round() as usize;
    let mut out = Vec::with_capacity(steps);
    for _ in 0..steps {
        model
            .step(0.001, commands)
            .unwrap_or_else(|e| panic!("{e}"));
        out.push(model.truth());
    }
    out
}

#[test]
fn parked_c172x_reads_gravity_and_stands_still() {
    let mut m = start("c172x", JsbsimStart::OnRunway { heading_rad: 0.0 });
    let brakes = ActuatorCommands {
        brake: 1.0,
        ..Default::default()
    };
    let truths = fly(&mut m, 3.0, &brakes);
    let t = truths.last().copied().unwrap_or_else(Truth::at_rest);
    println!("{t:?}");
    // At rest on level ground the wheels push up with the weight: f = (0, 0, −g).
    let [fx, fy, fz] = t.specific_force_body_mps2;
    assert!(fx.abs() < 0.3 && fy.abs() < 0.1, "{fx} {fy}");
    assert!((fz + GRAVITY_MPS2).abs() < 0.1, "{fz}");
    assert!(t.on_ground);
    assert!(t.velocity_ned_mps.iter().all(|v| v.abs() < 0.05));
    assert!(t.rates_body_radps.iter().all(|r| r.abs() < 0.01));
    assert!(t.position_ned_m[0].abs() < 0.5 && t.position_ned_m[1].abs() < 0.5);
    // c172x's file asks for CSV output in the working directory; the driver turns it off.
    assert!(!std::path::Path::new("JSBout172B.csv").exists());
}

/// The airplane's accelerometer in level, unaccelerated flight reads −g along the body's
/// "up", tilted by the attitude: `f = Rᵀ (0, 0, −g)`.
fn gravity_in_body(t: &Truth) -> [f64; 3] {
    let r = quat_to_rotation(t.attitude);
    [
        -GRAVITY_MPS2 * r[2][0],
        -GRAVITY_MPS2 * r[2][1],
        -GRAVITY_MPS2 * r[2][2],
    ]
}

#[test]
fn unit_conversions_are_the_exact_definitions() {
    // 1 ft = 0.3048 m and 1 lbf = 0.45359237 kg × 9.80665 m/s² (both exact by definition).
    assert_eq!(FT_M, 0.3048);
    assert!((LBF_N - 0.453_592_37 * 9.806_65).abs() < 1e-12);
    // A slug is the mass 1 lbf accelerates at 1 ft/s²: lbf/slug·ft = (N/kg) for the
    // specific force, i.e. 1 lbf/slug = 0.3048 m/s².
    let slug_kg = LBF_N / FT_M;
    assert!((slug_kg - 14.593_902_94).abs() < 1e-6, "{slug_kg}");
}

#[test]
fn trimmed_c172x_flies_level_at_the_asked_speed_and_its_sensors_read_physics() {
    let mut m = start(
        "c172x",
        JsbsimStart::InFlight {
            altitude_m: 300.0,
            airspeed_mps: 40.0,
            heading_rad: 30f64.to_radians(),
        },
    );
    let (trim, pitch) = m.trim().expect("an in-flight start is trimmed");
    // JSBSim's trim for a 172 at 78 kt: some power, a little up or down elevator, pitch a
    // few degrees (its own published trim figures are in this range).
    assert!(trim.throttle > 0.3 && trim.throttle < 0.95, "{trim:?}");
    assert!(pitch.abs() < 6f64.to_radians(), "{pitch}");
    let truths = fly(&mut m, 5.0, &trim);
    let t = truths.last().copied().unwrap_or_else(Truth::at_rest);
    // Speed, heading and height held (trim holds for seconds, not forever: no controller).
    assert!((t.airspeed_mps - 40.0).abs() < 1.0, "{}", t.airspeed_mps);
    assert!(
        (t.yaw_rad - 30f64.to_radians()).abs() < 3f64.to_radians(),
        "{}",
        t.yaw_rad
    );
    assert!((t.height_above_ground_m - 300.0).abs() < 5.0);
    // Ground velocity agrees with airspeed and heading (calm air) and with the position's
    // change from JSBSim's latitude and longitude, converted through our WGS-84 code.
    let [vn, ve, _] = t.velocity_ned_mps;
    assert!((vn.hypot(ve) - t.airspeed_mps).abs() < 1.0);
    let course = ve.atan2(vn);
    assert!(
        (course - 30f64.to_radians()).abs() < 3f64.to_radians(),
        "{course}"
    );
    let a = truths[truths.len() - 1001];
    let moved = [
        t.position_ned_m[0] - a.position_ned_m[0],
        t.position_ned_m[1] - a.position_ned_m[1],
    ];
    assert!(
        (moved[0] - vn).abs() < 0.5 && (moved[1] - ve).abs() < 0.5,
        "{moved:?} {vn} {ve}"
    );
    // The accelerometer reads gravity through the attitude (1 g, ±0.1 m/s² of manoeuvre).
    let g = gravity_in_body(&t);
    for i in 0..3 {
        assert!(
            (t.specific_force_body_mps2[i] - g[i]).abs() < 0.3,
            "{t:?} {g:?}"
        );
    }
    // Body velocity is the NED velocity rotated into the body.
    let r = quat_to_rotation(t.attitude);
    let back = mat_vec(&r, t.velocity_body_mps);
    for i in 0..3 {
        assert!(
            (back[i] - t.velocity_ned_mps[i]).abs() < 0.05,
            "{back:?} {t:?}"
        );
    }
    assert!(!t.on_ground && t.thrust_n > 100.0 && t.motor_speed_radps > 150.0);
}

#[test]
fn each_control_moves_the_airplane_our_way_round() {
    // conventions.md: positive aileron rolls right, elevator pitches up, rudder yaws right.
    let flying = JsbsimStart::InFlight {
        altitude_m: 500.0,
        airspeed_mps: 40.0,
        heading_rad: 0.0,
    };
    for (axis, push) in [
        (
            0,
            ActuatorCommands {
                aileron: 0.3,
                ..Default::default()
            },
        ),
        (
            1,
            ActuatorCommands {
                elevator: 0.3,
                ..Default::default()
            },
        ),
        (
            2,
            ActuatorCommands {
                rudder: 0.3,
                ..Default::default()
            },
        ),
    ] {
        let mut m = start("c172x", flying);
        let (trim, _) = m.trim().expect("trimmed");
        let cmd = ActuatorCommands {
            aileron: trim.aileron + push.aileron,
            elevator: trim.elevator + push.elevator,
            rudder: trim.rudder + push.rudder,
            ..trim
        };
        let truths = fly(&mut m, 0.5, &cmd);
        let rate = truths.last().map_or(0.0, |t| t.rates_body_radps[axis]);
        assert!(rate > 0.02, "axis {axis}: {rate} rad/s");
    }
}

#[test]
fn the_same_commands_give_the_same_flight() {
    let flying = JsbsimStart::InFlight {
        altitude_m: 200.0,
        airspeed_mps: 35.0,
        heading_rad: 0.0,
    };
    let cfg = PlantConfig {
        wind: crate::scenario::Scenario::parse(
            "duration_s = 1\n[wind]\nspeed_mps = 3\nfrom_deg = 45\nturbulence = \"moderate\"\n",
        )
        .map(|s| s.wind_config())
        .unwrap_or_else(|e| panic!("{e}")),
        ..PlantConfig::default()
    };
    let run = || {
        let mut m = JsbsimModel::start(JsbsimConfig::new("c172x"), &cfg, flying, 9)
            .unwrap_or_else(|e| panic!("{e}"));
        let (trim, _) = m.trim().expect("trimmed");
        fly(&mut m, 2.0, &trim)
    };
    let (a, b) = (run(), run());
    assert_eq!(a, b, "lock-step JSBSim is deterministic for a seed");
    // The gusts reached JSBSim: its total wind is ours (steady + gust).
    let last = a.last().copied().unwrap_or_else(Truth::at_rest);
    assert!((last.wind_ned_mps[0] + 3.0 * 45f64.to_radians().cos()).abs() < 3.0);
    assert!(a.windows(2).any(|w| w[0].wind_ned_mps != w[1].wind_ned_mps));
}

// --- what goes wrong: one line each, never a panic or a hang ---------------------------------

/// A stand-in for python3: a shell script (it gets `-u -c DRIVER` and ignores them).
fn fake_python(name: &str, body: &str) -> String {
    let dir = std::env::temp_dir().join(format!("skyframe-jsbsim-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{e}"));
    let path = dir.join("python");
    std::fs::write(&path, format!("#!/bin/sh\n{body}\n")).unwrap_or_else(|e| panic!("{e}"));
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755))
            .unwrap_or_else(|e| panic!("{e}"));
    }
    path.to_string_lossy().into_owned()
}

/// Removes `fake_python`'s directory.
fn remove_fake(python: &str) {
    if let Some(dir) = std::path::Path::new(python).parent() {
        let _ = std::fs::remove_dir_all(dir);
    }
}

fn start_with(python: String, aircraft: &str) -> Result<JsbsimModel, PlantError> {
    let config = JsbsimConfig {
        python,
        frame_timeout: Duration::from_secs(1),
        ..JsbsimConfig::new(aircraft)
    };
    JsbsimModel::start(
        config,
        &PlantConfig::default(),
        JsbsimStart::OnRunway { heading_rad: 0.0 },
        1,
    )
}

fn one_line(e: &PlantError) -> String {
    let text = e.to_string();
    assert!(!text.contains('\n'), "{text:?}");
    text
}

#[test]
fn a_missing_aircraft_is_named() {
    let e = start_with("python3".into(), "no-such-plane").expect_err("no such aircraft");
    let text = one_line(&e);
    assert!(text.contains("no aircraft \"no-such-plane\""), "{text}");
}

#[test]
fn a_missing_python_is_named() {
    let e = start_with("/nonexistent/python3".into(), "c172x").expect_err("no python");
    assert!(
        one_line(&e).contains("cannot run /nonexistent/python3"),
        "{e}"
    );
}

#[test]
fn a_child_that_dies_says_so() {
    let python = fake_python(
        "dies",
        "read hello\necho '{\"ok\": true}'\necho 'boom' >&2\nexit 7",
    );
    let e = start_with(python.clone(), "c172x").expect_err("dead child");
    remove_fake(&python);
    let text = one_line(&e);
    assert!(text.contains("ended") || text.contains("gone"), "{text}");
    assert!(text.contains("boom"), "its last words: {text}");
}

#[test]
fn garbage_on_the_pipe_is_refused() {
    // A greeting, then 29 × 8 bytes that are no JSBSim frame ("xxxxxxxx" as f64).
    let python = fake_python(
        "garbage",
        "read hello\necho '{\"ok\": true}'\nhead -c 72 >/dev/null\n\
         i=0; while [ $i -lt 232 ]; do printf x; i=$((i+1)); done\nsleep 5",
    );
    let e = start_with(python.clone(), "c172x").expect_err("garbage");
    remove_fake(&python);
    assert!(one_line(&e).contains("garbage"), "{e}");
    let python = fake_python("garbage-greeting", "read hello\necho 'Segmentation fault'");
    let e = start_with(python.clone(), "c172x").expect_err("garbage greeting");
    remove_fake(&python);
    assert!(one_line(&e).contains("garbage"), "{e}");
}

#[test]
fn a_hung_child_times_out() {
    let python = fake_python("hangs", "read hello\necho '{\"ok\": true}'\nsleep 30");
    let t0 = std::time::Instant::now();
    let e = start_with(python.clone(), "c172x").expect_err("hung");
    remove_fake(&python);
    assert!(one_line(&e).contains("no answer"), "{e}");
    assert!(t0.elapsed() < Duration::from_secs(5), "{:?}", t0.elapsed());
}
