//! Mission files: the waypoints the autopilot flies in AUTO, then a loiter circle around the
//! last one.
//!
//! ```toml
//! switch_radius_m = 40      # a waypoint is reached within this distance
//! loiter_radius_m = 150
//! loiter_clockwise = true
//! waypoints = [
//!   { north_m = 600, east_m = 0,   altitude_m = 100, airspeed_m_s = 23 },
//!   { north_m = 600, east_m = 500, altitude_m = 120, airspeed_m_s = 23 },
//! ]
//! ```
//!
//! Positions are metres north and east of home (the first valid GPS fix), altitudes above
//! home.

use serde::Deserialize;
use skyframe_core::control::mission::{MAX_WAYPOINTS, Mission, Waypoint};
use skyframe_core::schedule::file::toml_error_line;
use skyframe_input_files::{CONFIG_LIMIT, read_text};
use std::path::Path;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MissionFile {
    #[serde(default)]
    switch_radius_m: Option<f32>,
    #[serde(default)]
    loiter_radius_m: Option<f32>,
    #[serde(default)]
    loiter_clockwise: Option<bool>,
    waypoints: Vec<WaypointEntry>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct WaypointEntry {
    north_m: f32,
    east_m: f32,
    altitude_m: f32,
    airspeed_m_s: f32,
}

/// Reads a mission file; `Err` is one line naming the file and what is wrong.
pub fn load(path: &Path) -> Result<Mission, String> {
    let text = read_text(path, "mission", CONFIG_LIMIT)?;
    parse(&text).map_err(|e| format!("{}: {e}", path.display()))
}

pub fn parse(text: &str) -> Result<Mission, String> {
    let file: MissionFile = toml::from_str(text).map_err(|e| toml_error_line(&e, text))?;
    if file.waypoints.is_empty() || file.waypoints.len() > MAX_WAYPOINTS {
        return Err(format!(
            "waypoints: 1 to {MAX_WAYPOINTS} are needed, not {}",
            file.waypoints.len()
        ));
    }
    for (i, w) in file.waypoints.iter().enumerate() {
        let finite = [w.north_m, w.east_m, w.altitude_m, w.airspeed_m_s]
            .iter()
            .all(|v| v.is_finite());
        if !finite
            || !(17.0..=32.0).contains(&w.airspeed_m_s)
            || !(20.0..=1000.0).contains(&w.altitude_m)
        {
            return Err(format!(
                "waypoint {}: altitude 20-1000 m and airspeed 17-32 m/s (the airplane's level-flight range) are needed",
                i + 1
            ));
        }
    }
    let waypoints: Vec<Waypoint> = file
        .waypoints
        .iter()
        .map(|w| Waypoint {
            north_m: w.north_m,
            east_m: w.east_m,
            altitude_m: w.altitude_m,
            airspeed_mps: w.airspeed_m_s,
        })
        .collect();
    let mut mission = Mission::new(&waypoints).ok_or("too many waypoints")?;
    if let Some(r) = file.switch_radius_m {
        mission.switch_radius_m = r;
    }
    if let Some(r) = file.loiter_radius_m {
        if r < 110.0 {
            return Err(format!(
                "loiter_radius_m = {r}: the airplane cannot circle tighter than 110 m"
            ));
        }
        mission.loiter_radius_m = r;
    }
    if let Some(c) = file.loiter_clockwise {
        mission.loiter_clockwise = c;
    }
    Ok(mission)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mission_parses_and_bad_ones_say_why() {
        let m = parse(
            "loiter_radius_m = 160\nwaypoints = [\n { north_m = 600, east_m = 0, altitude_m = 100, airspeed_m_s = 23 },\n { north_m = 600, east_m = 500, altitude_m = 120, airspeed_m_s = 24 },\n]\n",
        )
        .expect("parses");
        assert_eq!(m.waypoints.len(), 2);
        assert_eq!(m.waypoints[1].east_m, 500.0);
        assert_eq!(m.loiter_radius_m, 160.0);
        assert!(
            parse("waypoints = []\n")
                .expect_err("empty")
                .contains("1 to 32")
        );
        let e = parse(
            "waypoints = [ { north_m = 1, east_m = 2, altitude_m = 100, airspeed_m_s = 50 } ]\n",
        )
        .expect_err("fast");
        assert!(e.contains("waypoint 1"), "{e}");
        let e = parse("waypoint = []\n").expect_err("typo");
        assert!(e.starts_with("line 1, column 1"), "{e}");
    }
}
