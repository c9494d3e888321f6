//! skyframe's missions as MAVLink mission items, and back.
//!
//! A skyframe mission is waypoints in metres north/east of home with an altitude above home
//! and an airspeed each, flown in order, then a loiter around the last
//! (`core/src/control/mission.rs`). As MAVLink items (`MISSION_ITEM_INT`, sequence from 0,
//! no home item: the autopilot is `MAV_AUTOPILOT_GENERIC`):
//!
//! - `MAV_CMD_DO_CHANGE_SPEED` (param1 0 = airspeed, param2 m/s) before the first waypoint
//!   and before each waypoint whose airspeed differs from the one before;
//! - `MAV_CMD_NAV_WAYPOINT` (param2 = the acceptance radius, the mission's switch radius) in
//!   `MAV_FRAME_GLOBAL_RELATIVE_ALT` (x, y in degE7 as MISSION_ITEM_INT has them; z metres
//!   above home; the older `_INT` frame numbers are accepted on upload as the same);
//! - a final `MAV_CMD_NAV_LOITER_UNLIM` at the last waypoint, param3 = the loiter radius
//!   (positive clockwise, as MAVLink says).

// The `_INT` frames are deprecated synonyms, still sent by ground stations: accepted.
#![allow(deprecated)]

use super::mav::{MISSION_ITEM_INT_DATA, MavCmd, MavFrame, MavMissionResult, MavMissionType};
use skyframe_core::control::mission::{MAX_WAYPOINTS, Mission, Waypoint};
use skyframe_core::estimation::geo::{GeoPoint, LocalFrame};
use skyframe_core::estimation::nalgebra::Vector3;

/// The airplane's level-flight airspeed range and the altitudes a waypoint may have: the
/// same limits as mission files (`shell/src/mission.rs`).
const AIRSPEED_M_S: std::ops::RangeInclusive<f32> = 17.0..=32.0;
const ALTITUDE_M: std::ops::RangeInclusive<f32> = 20.0..=1000.0;
/// The tightest circle the airplane can fly (`shell/src/mission.rs`).
const MIN_LOITER_RADIUS_M: f32 = 110.0;

/// A mission as items, and for each waypoint the sequence number of its NAV_WAYPOINT item
/// (for MISSION_CURRENT and MISSION_ITEM_REACHED); the loiter item is last.
#[derive(Debug, Clone)]
pub struct Items {
    pub items: Vec<MISSION_ITEM_INT_DATA>,
    pub waypoint_seq: Vec<u16>,
}

impl Items {
    pub fn loiter_seq(&self) -> u16 {
        u16::try_from(self.items.len().saturating_sub(1)).unwrap_or(u16::MAX)
    }
}

fn item(seq: usize, command: MavCmd, frame: MavFrame) -> MISSION_ITEM_INT_DATA {
    MISSION_ITEM_INT_DATA {
        seq: u16::try_from(seq).unwrap_or(u16::MAX),
        command,
        frame,
        autocontinue: 1,
        mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
        ..MISSION_ITEM_INT_DATA::default()
    }
}

fn deg_e7(deg: f64) -> i32 {
    // Latitudes and longitudes are within ±180°, so ±1.8e9 fits an i32.
    (deg * 1e7).round() as i32
}

/// The items of `mission`, positions from `home`.
pub fn items_from_mission(mission: &Mission, home: &LocalFrame) -> Items {
    let mut items = Vec::new();
    let mut waypoint_seq = Vec::new();
    let mut speed: Option<f32> = None;
    for w in &mission.waypoints {
        if speed != Some(w.airspeed_mps) {
            let mut s = item(
                items.len(),
                MavCmd::MAV_CMD_DO_CHANGE_SPEED,
                MavFrame::MAV_FRAME_MISSION,
            );
            s.param1 = 0.0;
            s.param2 = w.airspeed_mps;
            s.param3 = -1.0;
            items.push(s);
            speed = Some(w.airspeed_mps);
        }
        let p = home.to_geodetic(&Vector3::new(
            f64::from(w.north_m),
            f64::from(w.east_m),
            0.0,
        ));
        let mut n = item(
            items.len(),
            MavCmd::MAV_CMD_NAV_WAYPOINT,
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
        );
        n.param2 = mission.switch_radius_m;
        n.x = deg_e7(p.latitude_deg);
        n.y = deg_e7(p.longitude_deg);
        n.z = w.altitude_m;
        waypoint_seq.push(n.seq);
        items.push(n);
    }
    if let Some(last) = items
        .iter()
        .rev()
        .find(|i| i.command == MavCmd::MAV_CMD_NAV_WAYPOINT)
        .cloned()
    {
        let mut l = item(
            items.len(),
            MavCmd::MAV_CMD_NAV_LOITER_UNLIM,
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
        );
        l.param3 = if mission.loiter_clockwise {
            mission.loiter_radius_m
        } else {
            -mission.loiter_radius_m
        };
        l.x = last.x;
        l.y = last.y;
        l.z = last.z;
        items.push(l);
    }
    Items {
        items,
        waypoint_seq,
    }
}

/// Why an upload was refused, and at which item.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refusal {
    pub result: MavMissionResult,
    pub seq: u16,
}

fn refuse(result: MavMissionResult, seq: u16) -> Refusal {
    Refusal { result, seq }
}

/// The north/east/altitude-above-home of a positional item.
fn position(i: &MISSION_ITEM_INT_DATA, home: &LocalFrame) -> Result<(f32, f32, f32), Refusal> {
    let above_home = match i.frame {
        MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT => {
            i.z
        }
        MavFrame::MAV_FRAME_GLOBAL_INT | MavFrame::MAV_FRAME_GLOBAL => {
            i.z - home.home().altitude_m as f32
        }
        _ => {
            return Err(refuse(
                MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME,
                i.seq,
            ));
        }
    };
    let lat = f64::from(i.x) * 1e-7;
    let lon = f64::from(i.y) * 1e-7;
    if !(-90.0..=90.0).contains(&lat) {
        return Err(refuse(
            MavMissionResult::MAV_MISSION_INVALID_PARAM5_X,
            i.seq,
        ));
    }
    if !(-180.0..=180.0).contains(&lon) {
        return Err(refuse(
            MavMissionResult::MAV_MISSION_INVALID_PARAM6_Y,
            i.seq,
        ));
    }
    if !above_home.is_finite() || !ALTITUDE_M.contains(&above_home) {
        return Err(refuse(MavMissionResult::MAV_MISSION_INVALID_PARAM7, i.seq));
    }
    let ned = home.to_ned(&GeoPoint {
        latitude_deg: lat,
        longitude_deg: lon,
        altitude_m: home.home().altitude_m,
    });
    Ok((ned.x as f32, ned.y as f32, above_home))
}

/// The mission uploaded items describe; `cruise_m_s` is the airspeed of waypoints before any
/// DO_CHANGE_SPEED. Refused: commands other than NAV_WAYPOINT, NAV_LOITER_UNLIM (last only)
/// and DO_CHANGE_SPEED (`MAV_MISSION_UNSUPPORTED`), frames other than the global ones
/// (`MAV_MISSION_UNSUPPORTED_FRAME`), values outside the airplane's limits
/// (`MAV_MISSION_INVALID_PARAMn`), more than 32 waypoints (`MAV_MISSION_NO_SPACE`), none
/// (`MAV_MISSION_INVALID`).
pub fn mission_from_items(
    items: &[MISSION_ITEM_INT_DATA],
    home: &LocalFrame,
    cruise_m_s: f32,
) -> Result<Mission, Refusal> {
    let mut waypoints: Vec<Waypoint> = Vec::new();
    let mut mission = Mission::default();
    let mut speed = cruise_m_s.clamp(*AIRSPEED_M_S.start(), *AIRSPEED_M_S.end());
    let mut switch_radius: Option<f32> = None;
    for (k, i) in items.iter().enumerate() {
        let last = k + 1 == items.len();
        match i.command {
            MavCmd::MAV_CMD_DO_CHANGE_SPEED => {
                // param2 -1: no change (MAVLink's convention).
                if i.param2 == -1.0 {
                    continue;
                }
                if !(i.param1 == 0.0 || i.param1 == 1.0) {
                    return Err(refuse(MavMissionResult::MAV_MISSION_INVALID_PARAM1, i.seq));
                }
                if !AIRSPEED_M_S.contains(&i.param2) {
                    return Err(refuse(MavMissionResult::MAV_MISSION_INVALID_PARAM2, i.seq));
                }
                speed = i.param2;
            }
            MavCmd::MAV_CMD_NAV_WAYPOINT => {
                let (north_m, east_m, altitude_m) = position(i, home)?;
                if i.param2 > 0.0 {
                    if !(5.0..=500.0).contains(&i.param2) {
                        return Err(refuse(MavMissionResult::MAV_MISSION_INVALID_PARAM2, i.seq));
                    }
                    switch_radius.get_or_insert(i.param2);
                }
                push(&mut waypoints, (north_m, east_m, altitude_m), speed, i.seq)?;
            }
            MavCmd::MAV_CMD_NAV_LOITER_UNLIM if last => {
                let radius = i.param3.abs();
                if !radius.is_finite() || !(MIN_LOITER_RADIUS_M..=5000.0).contains(&radius) {
                    return Err(refuse(MavMissionResult::MAV_MISSION_INVALID_PARAM3, i.seq));
                }
                mission.loiter_radius_m = radius;
                mission.loiter_clockwise = i.param3 >= 0.0;
                // A loiter away from the last waypoint is one more waypoint to fly to first:
                // skyframe always loiters around its last waypoint.
                let (north_m, east_m, altitude_m) = position(i, home)?;
                let same = waypoints.last().is_some_and(|w| {
                    (w.north_m - north_m).hypot(w.east_m - east_m) < 1.0
                        && (w.altitude_m - altitude_m).abs() < 0.5
                });
                if !same {
                    push(&mut waypoints, (north_m, east_m, altitude_m), speed, i.seq)?;
                }
            }
            _ => return Err(refuse(MavMissionResult::MAV_MISSION_UNSUPPORTED, i.seq)),
        }
    }
    if waypoints.is_empty() {
        return Err(refuse(MavMissionResult::MAV_MISSION_INVALID, 0));
    }
    mission.waypoints = heapless::Vec::from_slice(&waypoints)
        .map_err(|_| refuse(MavMissionResult::MAV_MISSION_NO_SPACE, 0))?;
    if let Some(r) = switch_radius {
        mission.switch_radius_m = r;
    }
    Ok(mission)
}

/// One more waypoint of an upload, refused as MAV_MISSION_NO_SPACE past skyframe's capacity.
fn push(
    waypoints: &mut Vec<Waypoint>,
    (north_m, east_m, altitude_m): (f32, f32, f32),
    airspeed_mps: f32,
    seq: u16,
) -> Result<(), Refusal> {
    if waypoints.len() == MAX_WAYPOINTS {
        return Err(refuse(MavMissionResult::MAV_MISSION_NO_SPACE, seq));
    }
    waypoints.push(Waypoint {
        north_m,
        east_m,
        altitude_m,
        airspeed_mps,
    });
    Ok(())
}

/// Two missions fly the same (positions within 0.5 m: degE7 steps are 1.1 cm).
pub fn same_mission(a: &Mission, b: &Mission) -> bool {
    a.waypoints.len() == b.waypoints.len()
        && a.waypoints.iter().zip(&b.waypoints).all(|(x, y)| {
            (x.north_m - y.north_m).abs() < 0.5
                && (x.east_m - y.east_m).abs() < 0.5
                && (x.altitude_m - y.altitude_m).abs() < 0.01
                && (x.airspeed_mps - y.airspeed_mps).abs() < 0.01
        })
        && (a.switch_radius_m - b.switch_radius_m).abs() < 0.01
        && (a.loiter_radius_m - b.loiter_radius_m).abs() < 0.01
        && a.loiter_clockwise == b.loiter_clockwise
}

#[cfg(test)]
mod tests {
    use super::*;

    fn home() -> LocalFrame {
        LocalFrame::new(GeoPoint {
            latitude_deg: 47.397742,
            longitude_deg: 8.545594,
            altitude_m: 488.0,
        })
        .expect("home")
    }

    fn circuit() -> Mission {
        crate::mission::parse(include_str!("../../../scenarios/circuit-mission.toml"))
            .expect("the shipped mission")
    }

    #[test]
    fn a_mission_becomes_speed_waypoint_and_loiter_items_in_mavlink_units() {
        let m = circuit();
        let items = items_from_mission(&m, &home());
        // One speed (all waypoints fly 23 m/s), four waypoints, the loiter.
        assert_eq!(items.items.len(), 6);
        assert_eq!(items.waypoint_seq, vec![1, 2, 3, 4]);
        let speed = &items.items[0];
        assert_eq!(speed.command, MavCmd::MAV_CMD_DO_CHANGE_SPEED);
        assert_eq!(speed.param2, 23.0);
        // 700 m north of home: 700 / 6 367 km… ≈ 0.0062946° of latitude, in degE7.
        let w0 = &items.items[1];
        assert_eq!(w0.frame, MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT);
        assert_eq!(w0.y, 85_455_940);
        assert!(
            (f64::from(w0.x - 473_977_420) - 62_946.0).abs() < 30.0,
            "{}",
            w0.x
        );
        assert_eq!(w0.z, 100.0);
        assert_eq!(w0.param2, 40.0);
        let loiter = items.items.last().expect("loiter");
        assert_eq!(loiter.command, MavCmd::MAV_CMD_NAV_LOITER_UNLIM);
        assert_eq!(loiter.param3, 150.0);
        assert_eq!((loiter.x, loiter.y), (items.items[4].x, items.items[4].y));
        for (k, i) in items.items.iter().enumerate() {
            assert_eq!(usize::from(i.seq), k);
        }
    }

    #[test]
    fn items_translate_back_to_the_same_mission() {
        let m = circuit();
        let items = items_from_mission(&m, &home());
        let back = mission_from_items(&items.items, &home(), 25.0).expect("accepted");
        assert!(same_mission(&m, &back), "{m:?}\n{back:?}");
        assert!((back.waypoints[2].north_m - -400.0).abs() < 0.1);
        assert!((back.waypoints[2].east_m - 600.0).abs() < 0.1);
    }

    #[test]
    fn unsupported_commands_frames_and_values_are_refused_with_the_item() {
        let home = home();
        let good = items_from_mission(&circuit(), &home).items;
        let mut takeoff = good.clone();
        takeoff[2].command = MavCmd::MAV_CMD_NAV_TAKEOFF;
        assert_eq!(
            mission_from_items(&takeoff, &home, 25.0),
            Err(refuse(MavMissionResult::MAV_MISSION_UNSUPPORTED, 2))
        );
        let mut local = good.clone();
        local[1].frame = MavFrame::MAV_FRAME_LOCAL_NED;
        assert_eq!(
            mission_from_items(&local, &home, 25.0),
            Err(refuse(MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME, 1))
        );
        let mut low = good.clone();
        low[3].z = 5.0;
        assert_eq!(
            mission_from_items(&low, &home, 25.0),
            Err(refuse(MavMissionResult::MAV_MISSION_INVALID_PARAM7, 3))
        );
        let mut fast = good.clone();
        fast[0].param2 = 60.0;
        assert_eq!(
            mission_from_items(&fast, &home, 25.0),
            Err(refuse(MavMissionResult::MAV_MISSION_INVALID_PARAM2, 0))
        );
        let mut tight = good;
        let last = tight.len() - 1;
        tight[last].param3 = 50.0;
        assert_eq!(
            mission_from_items(&tight, &home, 25.0),
            Err(refuse(MavMissionResult::MAV_MISSION_INVALID_PARAM3, 5))
        );
        assert_eq!(
            mission_from_items(&[], &home, 25.0),
            Err(refuse(MavMissionResult::MAV_MISSION_INVALID, 0))
        );
    }

    #[test]
    fn amsl_altitudes_are_taken_above_home_and_speed_defaults_to_cruise() {
        let home = home();
        let mut w = item(
            0,
            MavCmd::MAV_CMD_NAV_WAYPOINT,
            MavFrame::MAV_FRAME_GLOBAL_INT,
        );
        w.x = 473_977_420;
        w.y = 85_455_940;
        w.z = 588.0;
        let m = mission_from_items(&[w], &home, 24.0).expect("accepted");
        assert_eq!(m.waypoints.len(), 1);
        assert!((m.waypoints[0].altitude_m - 100.0).abs() < 1e-3);
        assert!(m.waypoints[0].north_m.abs() < 0.01);
        assert_eq!(m.waypoints[0].airspeed_mps, 24.0);
    }
}
