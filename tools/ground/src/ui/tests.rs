//! The widgets' text rules.

use super::widgets::{log_time_text, ratio, shown, shown_text, strip_unit};

#[test]
fn log_times_read_as_flight_seconds_or_utc_time_of_day() {
    assert_eq!(log_time_text(29), "2.9 s");
    // 2026-11-25T01:14:39.3Z
    assert_eq!(log_time_text(17_955_692_793), "01:14:39.3 UTC");
}

#[test]
fn names_lose_their_unit_suffix_only() {
    assert_eq!(strip_unit("p_rad_s"), "p");
    assert_eq!(strip_unit("fz_m_s2"), "fz");
    assert_eq!(strip_unit("alt_c_m"), "alt_c");
    assert_eq!(strip_unit("satellites"), "satellites");
    assert_eq!(strip_unit("_m"), "_m");
}

#[test]
fn values_are_shown_in_the_units_people_read() {
    let roll = shown("roll_rad", std::f64::consts::FRAC_PI_4);
    assert_eq!(shown_text(&roll), "45");
    let rate = shown("p_rad_s", 0.1);
    assert_eq!(shown_text(&rate), "5.730");
    // Latitude keeps seven decimals of a degree (1 cm); counters stay whole.
    assert_eq!(shown_text(&shown("lat_deg", 47.397_742_1)), "47.3977421");
    assert_eq!(shown_text(&shown("satellites", 9.0)), "9");
    assert_eq!(shown_text(&shown("alt_m", 488.25)), "488.2");
}

#[test]
fn gauges_clamp_and_survive_nonsense() {
    assert_eq!(ratio(3.75, 3.3, 4.2), (3.75 - 3.3) / (4.2 - 3.3));
    assert_eq!(ratio(5.0, 3.3, 4.2), 1.0);
    assert_eq!(ratio(1.0, 3.3, 4.2), 0.0);
    assert_eq!(ratio(f64::NAN, 3.3, 4.2), 0.0);
    assert_eq!(ratio(1.0, 2.0, 2.0), 0.0);
}
