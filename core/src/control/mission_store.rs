//! The mission slot: the mission in force, a staging area an upload fills item by item, and a
//! generation counter the control task watches (as it reads the parameter table between
//! steps). Fixed capacity, no allocation: the telemetry task applies the link's mission
//! commands to it ([`crate::link::messages::Command::MissionItem`] and the rest), the control
//! task copies the mission when the generation moves on.

use super::mission::{MAX_WAYPOINTS, Mission, Waypoint};
use heapless::Vec;

/// Limits of a mission taken over the link, as the mission file loader checks them
/// (`shell/src/mission.rs`).
pub mod limits {
    pub const MIN_ALTITUDE_M: f32 = 20.0;
    pub const MAX_ALTITUDE_M: f32 = 1000.0;
    pub const MIN_AIRSPEED_MPS: f32 = 17.0;
    pub const MAX_AIRSPEED_MPS: f32 = 32.0;
    /// North/east of home, either way.
    pub const MAX_DISTANCE_M: f32 = 100_000.0;
    pub const MIN_SWITCH_RADIUS_M: f32 = 1.0;
    pub const MAX_SWITCH_RADIUS_M: f32 = 1000.0;
    /// The tightest circle the airplane flies at cruise within the bank limit.
    pub const MIN_LOITER_RADIUS_M: f32 = 110.0;
    pub const MAX_LOITER_RADIUS_M: f32 = 5000.0;
}

/// A waypoint the airplane can fly: finite, within the altitude and airspeed range.
pub fn waypoint_in_range(w: &Waypoint) -> bool {
    use limits::*;
    // NaN fails every comparison.
    (-MAX_DISTANCE_M..=MAX_DISTANCE_M).contains(&w.north_m)
        && (-MAX_DISTANCE_M..=MAX_DISTANCE_M).contains(&w.east_m)
        && (MIN_ALTITUDE_M..=MAX_ALTITUDE_M).contains(&w.altitude_m)
        && (MIN_AIRSPEED_MPS..=MAX_AIRSPEED_MPS).contains(&w.airspeed_mps)
}

/// Switch and loiter radii the airplane can fly.
pub fn radii_in_range(switch_radius_m: f32, loiter_radius_m: f32) -> bool {
    use limits::*;
    (MIN_SWITCH_RADIUS_M..=MAX_SWITCH_RADIUS_M).contains(&switch_radius_m)
        && (MIN_LOITER_RADIUS_M..=MAX_LOITER_RADIUS_M).contains(&loiter_radius_m)
}

/// Why a mission command was not applied.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StoreRefusal {
    /// An item out of order, or of another upload's count.
    OutOfSequence,
    /// A commit whose count is not the items staged.
    Incomplete,
    /// A set-current past the mission in force.
    NoSuchWaypoint,
}

#[derive(Clone, Debug, PartialEq)]
pub struct MissionStore {
    in_force: Mission,
    staging: Vec<Waypoint, MAX_WAYPOINTS>,
    /// The count the staged items announced (0: nothing staged).
    staging_count: usize,
    generation: u32,
    /// The waypoint to fly first after the latest change.
    start_index: usize,
}

impl Default for MissionStore {
    fn default() -> Self {
        Self::new(None)
    }
}

impl MissionStore {
    /// The store holding `mission` (`None`: no mission), generation 0.
    pub fn new(mission: Option<&Mission>) -> Self {
        Self {
            in_force: mission.cloned().unwrap_or_default(),
            staging: Vec::new(),
            staging_count: 0,
            generation: 0,
            start_index: 0,
        }
    }

    /// The mission in force (no waypoints: none).
    pub fn mission(&self) -> &Mission {
        &self.in_force
    }

    /// Moves on at every change of the mission in force or of its current waypoint.
    pub fn generation(&self) -> u32 {
        self.generation
    }

    /// The waypoint to fly first since the latest change.
    pub fn start_index(&self) -> usize {
        self.start_index
    }

    fn changed(&mut self, start_index: usize) {
        self.generation = self.generation.wrapping_add(1);
        self.start_index = start_index;
    }

    /// No mission in force (the radii stay); any staged upload is dropped.
    pub fn clear(&mut self) {
        self.in_force.waypoints.clear();
        self.staging.clear();
        self.staging_count = 0;
        self.changed(0);
    }

    /// Stages item `index` of an upload of `count` waypoints. Item 0 starts a new upload;
    /// the others must follow in order with the same count. The caller checked the ranges.
    pub fn stage(
        &mut self,
        index: usize,
        count: usize,
        waypoint: Waypoint,
    ) -> Result<(), StoreRefusal> {
        if count == 0 || count > MAX_WAYPOINTS || index >= count {
            return Err(StoreRefusal::OutOfSequence);
        }
        if index == 0 {
            self.staging.clear();
            self.staging_count = count;
        }
        if count != self.staging_count || index != self.staging.len() {
            return Err(StoreRefusal::OutOfSequence);
        }
        self.staging
            .push(waypoint)
            .map_err(|_| StoreRefusal::OutOfSequence)
    }

    /// Puts the `count` staged waypoints in force with these radii, flown from the first.
    pub fn commit(
        &mut self,
        count: usize,
        switch_radius_m: f32,
        loiter_radius_m: f32,
        loiter_clockwise: bool,
    ) -> Result<(), StoreRefusal> {
        if count == 0 || count != self.staging_count || self.staging.len() != count {
            return Err(StoreRefusal::Incomplete);
        }
        self.in_force = Mission {
            waypoints: core::mem::take(&mut self.staging),
            switch_radius_m,
            loiter_radius_m,
            loiter_clockwise,
        };
        self.staging_count = 0;
        self.changed(0);
        Ok(())
    }

    /// Flies the mission in force from waypoint `index`.
    pub fn set_current(&mut self, index: usize) -> Result<(), StoreRefusal> {
        if index >= self.in_force.waypoints.len() {
            return Err(StoreRefusal::NoSuchWaypoint);
        }
        self.changed(index);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::mission::tests::wp;
    use super::*;

    #[test]
    fn an_upload_is_in_force_only_when_committed_whole() {
        let first = Mission::new(&[wp(500.0, 0.0)]).expect("fits");
        let mut s = MissionStore::new(Some(&first));
        assert_eq!((s.mission(), s.generation()), (&first, 0));
        s.stage(0, 2, wp(1.0, 2.0)).expect("first");
        // Not whole yet: the commit is refused and nothing changes.
        assert_eq!(
            s.commit(2, 30.0, 150.0, true),
            Err(StoreRefusal::Incomplete)
        );
        assert_eq!((s.mission(), s.generation()), (&first, 0));
        // Out of order, or another count: refused.
        assert_eq!(
            s.stage(2, 2, wp(0.0, 0.0)),
            Err(StoreRefusal::OutOfSequence)
        );
        assert_eq!(
            s.stage(1, 3, wp(0.0, 0.0)),
            Err(StoreRefusal::OutOfSequence)
        );
        s.stage(1, 2, wp(3.0, 4.0)).expect("second");
        assert_eq!(
            s.commit(3, 30.0, 150.0, true),
            Err(StoreRefusal::Incomplete)
        );
        s.commit(2, 40.0, 200.0, false).expect("whole");
        assert_eq!(s.generation(), 1);
        assert_eq!(s.start_index(), 0);
        let m = s.mission();
        assert_eq!(m.waypoints.as_slice(), &[wp(1.0, 2.0), wp(3.0, 4.0)]);
        assert_eq!(
            (m.switch_radius_m, m.loiter_radius_m, m.loiter_clockwise),
            (40.0, 200.0, false)
        );
        // The staging area is spent: a second commit has nothing to put in force.
        assert_eq!(
            s.commit(2, 40.0, 200.0, false),
            Err(StoreRefusal::Incomplete)
        );
        // A new upload restarts at item 0 whatever was staged before.
        s.stage(0, 3, wp(9.0, 9.0)).expect("restart");
        s.stage(0, 1, wp(7.0, 7.0)).expect("restart again");
        s.commit(1, 30.0, 150.0, true).expect("one waypoint");
        assert_eq!(s.mission().waypoints.as_slice(), &[wp(7.0, 7.0)]);
        assert_eq!(s.generation(), 2);
    }

    #[test]
    fn clear_and_set_current_move_the_generation_on() {
        let two = Mission::new(&[wp(500.0, 0.0), wp(0.0, 500.0)]).expect("fits");
        let mut s = MissionStore::new(Some(&two));
        assert_eq!(s.set_current(2), Err(StoreRefusal::NoSuchWaypoint));
        assert_eq!(s.generation(), 0);
        s.set_current(1).expect("second waypoint");
        assert_eq!((s.generation(), s.start_index()), (1, 1));
        s.stage(0, 2, wp(1.0, 1.0)).expect("staged");
        s.clear();
        assert!(s.mission().waypoints.is_empty());
        assert_eq!((s.generation(), s.start_index()), (2, 0));
        assert_eq!(
            s.commit(2, 30.0, 150.0, true),
            Err(StoreRefusal::Incomplete)
        );
        assert_eq!(s.set_current(0), Err(StoreRefusal::NoSuchWaypoint));
        assert!(MissionStore::new(None).mission().waypoints.is_empty());
    }

    #[test]
    fn ranges_are_the_mission_files() {
        assert!(waypoint_in_range(&wp(600.0, -500.0)));
        let at_altitude = |altitude_m| Waypoint {
            altitude_m,
            ..wp(0.0, 0.0)
        };
        let at_airspeed = |airspeed_mps| Waypoint {
            airspeed_mps,
            ..wp(0.0, 0.0)
        };
        for bad in [
            at_altitude(19.9),
            at_altitude(1000.5),
            at_airspeed(16.0),
            at_airspeed(33.0),
            at_airspeed(f32::NAN),
            wp(f32::INFINITY, 0.0),
            wp(0.0, f32::NAN),
            wp(0.0, 1e6),
        ] {
            assert!(!waypoint_in_range(&bad), "{bad:?}");
        }
        assert!(radii_in_range(30.0, 150.0));
        assert!(!radii_in_range(30.0, 100.0));
        assert!(!radii_in_range(f32::NAN, 150.0));
        assert!(!radii_in_range(0.0, 150.0));
    }
}
