//! The sender ids of skyframe's own command senders, one table so that no two share an id
//! (the vehicle keeps one replay window per sender id: two senders on one id would replay
//! each other's sequence numbers away).

/// `skyframe-ground`'s default.
pub const GROUND_STATION: u8 = 1;
/// `skyframe-horizon --send`'s default: the horizon detector on the ground.
pub const HORIZON_DETECTOR: u8 = 2;
/// The vehicle's own MAVLink endpoint, which turns MAVLink commands into link commands.
pub const MAVLINK_ENDPOINT: u8 = 250;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_two_senders_share_an_id_and_none_is_the_vehicles() {
        let ids = [GROUND_STATION, HORIZON_DETECTOR, MAVLINK_ENDPOINT];
        for (i, a) in ids.iter().enumerate() {
            assert_ne!(*a, 0, "0 is the vehicle's own sender id");
            assert!(ids.iter().skip(i + 1).all(|b| b != a));
        }
    }
}
