//! Scenario parsing, and the shipped scenarios flown by the scripted pilot alone.

use super::*;

const TAKEOFF_CIRCUIT: &str = include_str!("../../../scenarios/takeoff-circuit.toml");
const FAULTS: &str = include_str!("../../../scenarios/faults.toml");

fn parse(src: &str) -> Scenario {
    match Scenario::parse(src) {
        Ok(s) => s,
        Err(e) => panic!("{e}"),
    }
}

fn print_trace(summary: &FlightSummary) {
    for s in summary.samples.iter().step_by(10) {
        println!(
            "{:6.1} {:9} {:?} n {:7.1} e {:7.1} h {:6.1} V {:5.1} roll {:6.1} pitch {:6.1} yaw {:6.1} gnd {}",
            s.t_s,
            s.pilot_phase,
            s.switch,
            s.position_ned_m[0],
            s.position_ned_m[1],
            s.height_m,
            s.airspeed_mps,
            s.roll_rad.to_degrees(),
            s.pitch_rad.to_degrees(),
            s.yaw_rad.to_degrees(),
            s.on_ground
        );
    }
    println!(
        "liftoff {:?} touchdown {:?} max h {:.1} max dist {:.0} strike {} parked {} final {:?}",
        summary.liftoff,
        summary.touchdown,
        summary.max_height_m,
        summary.max_distance_m,
        summary.airframe_strike,
        summary.parked,
        summary.final_truth.position_ned_m
    );
}

#[test]
#[ignore]
fn explore_default() {
    let options = RunOptions {
        plant_max_step_s: std::env::var("STEP")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(0.001),
        ..RunOptions::default()
    };
    let start = std::time::Instant::now();
    let src = if std::env::var("FAULTS").is_ok() {
        FAULTS
    } else {
        TAKEOFF_CIRCUIT
    };
    let summary = run_pilot_only(&parse(src), options);
    println!("wall {:.2} s", start.elapsed().as_secs_f64());
    print_trace(&summary);
}
