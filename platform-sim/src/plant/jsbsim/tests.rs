//! JSBSim through the driver, checked against physics and JSBSim's own figures. These need
//! python3 with the jsbsim package (`.ci/run` installs it): they fail, not skip, without it.

use super::*;
use crate::plant::GRAVITY_MPS2;

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
        model.step(0.001, commands).unwrap_or_else(|e| panic!("{e}"));
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
}
