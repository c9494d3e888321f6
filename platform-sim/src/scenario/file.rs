//! The scenario file as written (the TOML's tables, `deny_unknown_fields`) and its reading
//! into a validated [`Scenario`]: every value range-checked, every error one line with where.

use super::locate::{Locator, finite, in_range, key_before, line_column, one_of};
use super::*;
use crate::pilot::{Direction, Manoeuvre, wrap_pi};
use crate::plant::ActuatorCommands;
use serde::Deserialize;
use std::ops::Range;
use toml::Spanned;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    seed: Option<u64>,
    duration_s: Spanned<f64>,
    initial: Option<Spanned<RawInitial>>,
    wind: Option<Spanned<RawWind>>,
    gps: Option<Spanned<RawGps>>,
    runway: Option<Spanned<RawRunway>>,
    plant: Option<Spanned<RawPlant>>,
    /// The flight computer's parameters for this flight (`control.roll_kp = 1.2`): an
    /// airplane's own gains. Names and ranges are the vehicle's to check (the shell applies
    /// them through the parameter table, as the link's `set` does).
    #[serde(default)]
    parameters: std::collections::BTreeMap<String, f64>,
    #[serde(default)]
    timeline: Vec<Spanned<RawTimelineEntry>>,
    #[serde(default)]
    fault: Vec<Spanned<RawFault>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawInitial {
    kind: String,
    heading_deg: Option<f64>,
    altitude_m: Option<f64>,
    airspeed_mps: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawWind {
    north_mps: Option<f64>,
    east_mps: Option<f64>,
    down_mps: Option<f64>,
    speed_mps: Option<f64>,
    from_deg: Option<f64>,
    turbulence: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGps {
    preset: String,
}

/// `[plant]`: which flight model flies, and which aircraft.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPlant {
    kind: String,
    aircraft: Option<String>,
    cruise_airspeed_mps: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRunway {
    touchdown_north_m: Option<f64>,
    touchdown_east_m: Option<f64>,
    heading_deg: Option<f64>,
}

/// Every key any timeline entry may have; which apply depends on `pilot`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTimelineEntry {
    t_s: f64,
    pilot: Option<String>,
    switch: Option<String>,
    rotate_speed_mps: Option<f64>,
    climb_pitch_deg: Option<f64>,
    climb_to_m: Option<f64>,
    altitude_m: Option<f64>,
    airspeed_mps: Option<f64>,
    heading_deg: Option<f64>,
    max_bank_deg: Option<f64>,
    direction: Option<String>,
    glide_slope_deg: Option<f64>,
    final_m: Option<f64>,
    aileron: Option<f64>,
    elevator: Option<f64>,
    rudder: Option<f64>,
    throttle: Option<f64>,
    brake: Option<f64>,
    duration_s: Option<f64>,
}

impl RawTimelineEntry {
    /// The manoeuvre parameters that are set, by key.
    fn parameters(&self) -> Vec<(&'static str, bool)> {
        vec![
            ("rotate_speed_mps", self.rotate_speed_mps.is_some()),
            ("climb_pitch_deg", self.climb_pitch_deg.is_some()),
            ("climb_to_m", self.climb_to_m.is_some()),
            ("altitude_m", self.altitude_m.is_some()),
            ("airspeed_mps", self.airspeed_mps.is_some()),
            ("heading_deg", self.heading_deg.is_some()),
            ("max_bank_deg", self.max_bank_deg.is_some()),
            ("direction", self.direction.is_some()),
            ("glide_slope_deg", self.glide_slope_deg.is_some()),
            ("final_m", self.final_m.is_some()),
            ("aileron", self.aileron.is_some()),
            ("elevator", self.elevator.is_some()),
            ("rudder", self.rudder.is_some()),
            ("throttle", self.throttle.is_some()),
            ("brake", self.brake.is_some()),
            ("duration_s", self.duration_s.is_some()),
        ]
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFault {
    t_s: f64,
    duration_s: f64,
    kind: String,
    device: Option<String>,
    task: Option<String>,
    extra_us: Option<u64>,
}

const MANOEUVRES: [&str; 10] = [
    "takeoff", "climb", "level", "turn", "hold", "roll", "loop", "approach", "land", "sticks",
];

/// Keys each manoeuvre takes (besides `t_s` and `pilot`).
fn manoeuvre_keys(pilot: &str) -> &'static [&'static str] {
    match pilot {
        "takeoff" => &["rotate_speed_mps", "climb_pitch_deg", "climb_to_m"],
        "climb" | "level" => &["altitude_m", "airspeed_mps"],
        "turn" => &["heading_deg", "max_bank_deg", "direction"],
        "hold" => &["altitude_m", "heading_deg", "airspeed_mps"],
        "roll" => &["direction"],
        "loop" => &[],
        "approach" => &["glide_slope_deg", "final_m"],
        "land" => &["glide_slope_deg"],
        "sticks" => &[
            "aileron",
            "elevator",
            "rudder",
            "throttle",
            "brake",
            "duration_s",
        ],
        _ => &[],
    }
}

impl Scenario {
    /// Reads a scenario from TOML text.
    pub fn parse(src: &str) -> Result<Self, ScenarioError> {
        let raw: RawScenario = toml::from_str(src).map_err(|e| {
            let (line, column) = e.span().map_or((0, 0), |s| line_column(src, s.start));
            let mut message = e.message().trim().replace('\n', "; ");
            // A value of the wrong type: say whose value it is.
            if let Some(key) = e.span().and_then(|s| key_before(src, s.start)) {
                if !message.contains(key) {
                    message = format!("`{key}`: {message}");
                }
            }
            ScenarioError {
                line,
                column,
                message,
            }
        })?;
        let loc = Locator { src };

        let duration_span = raw.duration_s.span();
        let duration_s = *raw.duration_s.get_ref();
        if !(duration_s.is_finite() && duration_s > 0.0 && duration_s <= 24.0 * 3600.0) {
            return Err(loc.at(
                duration_span.start,
                format!("`duration_s` = {duration_s} must be > 0 and at most a day"),
            ));
        }

        let initial = match &raw.initial {
            None => InitialCondition::OnRunway { heading_rad: 0.0 },
            Some(s) => parse_initial(&loc, &s.span(), s.get_ref())?,
        };
        let (wind_ned_mps, turbulence) = match &raw.wind {
            None => ([0.0; 3], Turbulence::None),
            Some(s) => parse_wind(&loc, &s.span(), s.get_ref())?,
        };
        let gps = match &raw.gps {
            None => GpsPreset::Nominal,
            Some(s) => one_of(
                &loc,
                &s.span(),
                "[gps]",
                "preset",
                &s.get_ref().preset,
                &[
                    ("nominal", GpsPreset::Nominal),
                    ("seed_receiver", GpsPreset::SeedReceiver),
                    ("ideal", GpsPreset::Ideal),
                ],
            )?,
        };
        let runway = parse_runway(&loc, raw.runway.as_ref(), initial)?;

        let mut timeline = Vec::with_capacity(raw.timeline.len());
        for (i, entry) in raw.timeline.iter().enumerate() {
            let span = entry.span();
            let e = parse_timeline_entry(&loc, &span, i + 1, entry.get_ref(), runway)?;
            if e.t_s > duration_s {
                return Err(loc.key(
                    &span,
                    "t_s",
                    format!(
                        "timeline entry {}: `t_s` = {} is after the end (duration_s = {duration_s})",
                        i + 1,
                        e.t_s
                    ),
                ));
            }
            let previous = timeline.last().map_or(0.0, |p: &TimelineEntry| p.t_s);
            if e.t_s < previous {
                return Err(loc.key(
                    &span,
                    "t_s",
                    format!(
                        "timeline entry {}: `t_s` = {} is before the entry above it ({previous}); keep the timeline in time order",
                        i + 1,
                        e.t_s
                    ),
                ));
            }
            timeline.push(e);
        }

        let mut faults = Vec::with_capacity(raw.fault.len());
        for (i, f) in raw.fault.iter().enumerate() {
            let fault = parse_fault(&loc, &f.span(), i + 1, f.get_ref())?;
            if fault.t_s > duration_s {
                return Err(loc.key(
                    &f.span(),
                    "t_s",
                    format!(
                        "fault {}: `t_s` = {} is after the end (duration_s = {duration_s})",
                        i + 1,
                        fault.t_s
                    ),
                ));
            }
            faults.push(fault);
        }
        faults.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));

        let mut pilot_cruise_airspeed_mps = None;
        let plant = match &raw.plant {
            None => PlantKind::BuiltIn,
            Some(s) => {
                if let Some(v) = s.get_ref().cruise_airspeed_mps {
                    pilot_cruise_airspeed_mps = Some(in_range(
                        &loc,
                        &s.span(),
                        "plant",
                        "cruise_airspeed_mps",
                        v,
                        10.0,
                        100.0,
                    )?);
                }
                let p = s.get_ref();
                let aircraft = p.aircraft.as_deref();
                if aircraft.is_some_and(|a| {
                    a.is_empty()
                        || !a
                            .chars()
                            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
                }) {
                    return Err(loc.key(
                        &s.span(),
                        "aircraft",
                        "plant: `aircraft` must be a name of letters, digits, '-', '_' or '.'"
                            .into(),
                    ));
                }
                PlantKind::from_names(&p.kind, aircraft)
                    .map_err(|e| loc.key(&s.span(), "kind", format!("plant: {e}")))?
            }
        };

        Ok(Self {
            seed: raw.seed.unwrap_or(DEFAULT_SEED),
            duration_s,
            initial,
            wind_ned_mps,
            turbulence,
            gps,
            runway,
            plant,
            pilot_cruise_airspeed_mps,
            parameters: raw.parameters.into_iter().collect(),
            timeline,
            faults,
        })
    }
}

fn parse_initial(
    loc: &Locator,
    span: &Range<usize>,
    raw: &RawInitial,
) -> Result<InitialCondition, ScenarioError> {
    let what = "[initial]";
    #[derive(Clone, Copy)]
    enum Kind {
        Runway,
        Flight,
    }
    let kind = one_of(
        loc,
        span,
        what,
        "kind",
        &raw.kind,
        &[("runway", Kind::Runway), ("flight", Kind::Flight)],
    )?;
    let heading_rad = wrap_pi(
        finite(
            loc,
            span,
            what,
            "heading_deg",
            raw.heading_deg.unwrap_or(0.0),
        )?
        .to_radians(),
    );
    match kind {
        Kind::Runway => {
            for (key, set) in [
                ("altitude_m", raw.altitude_m.is_some()),
                ("airspeed_mps", raw.airspeed_mps.is_some()),
            ] {
                if set {
                    return Err(loc.key(
                        span,
                        key,
                        format!("{what}: `{key}` does not apply to kind = \"runway\""),
                    ));
                }
            }
            Ok(InitialCondition::OnRunway { heading_rad })
        }
        Kind::Flight => {
            let altitude_m = raw.altitude_m.ok_or_else(|| {
                loc.at(
                    span.start,
                    format!("{what}: kind = \"flight\" needs `altitude_m`"),
                )
            })?;
            let airspeed_mps = raw.airspeed_mps.ok_or_else(|| {
                loc.at(
                    span.start,
                    format!("{what}: kind = \"flight\" needs `airspeed_mps`"),
                )
            })?;
            Ok(InitialCondition::InFlight {
                altitude_m: in_range(loc, span, what, "altitude_m", altitude_m, 5.0, 3000.0)?,
                airspeed_mps: in_range(loc, span, what, "airspeed_mps", airspeed_mps, 15.0, 35.0)?,
                heading_rad,
            })
        }
    }
}

fn parse_wind(
    loc: &Locator,
    span: &Range<usize>,
    raw: &RawWind,
) -> Result<([f64; 3], Turbulence), ScenarioError> {
    let what = "[wind]";
    let ned_given = raw.north_mps.is_some() || raw.east_mps.is_some() || raw.down_mps.is_some();
    let polar_given = raw.speed_mps.is_some() || raw.from_deg.is_some();
    if ned_given && polar_given {
        let key = if raw.speed_mps.is_some() {
            "speed_mps"
        } else {
            "from_deg"
        };
        return Err(loc.key(
            span,
            key,
            format!(
                "{what}: give the wind either as north_mps/east_mps/down_mps or as speed_mps/from_deg, not both"
            ),
        ));
    }
    let steady = if polar_given {
        let speed = in_range(
            loc,
            span,
            what,
            "speed_mps",
            raw.speed_mps.unwrap_or(0.0),
            0.0,
            30.0,
        )?;
        let from = finite(loc, span, what, "from_deg", raw.from_deg.unwrap_or(0.0))?.to_radians();
        // Wind from the north blows towards the south.
        [-speed * from.cos(), -speed * from.sin(), 0.0]
    } else {
        [
            in_range(
                loc,
                span,
                what,
                "north_mps",
                raw.north_mps.unwrap_or(0.0),
                -30.0,
                30.0,
            )?,
            in_range(
                loc,
                span,
                what,
                "east_mps",
                raw.east_mps.unwrap_or(0.0),
                -30.0,
                30.0,
            )?,
            in_range(
                loc,
                span,
                what,
                "down_mps",
                raw.down_mps.unwrap_or(0.0),
                -10.0,
                10.0,
            )?,
        ]
    };
    let turbulence = match &raw.turbulence {
        None => Turbulence::None,
        Some(t) => one_of(
            loc,
            span,
            what,
            "turbulence",
            t,
            &[
                ("none", Turbulence::None),
                ("light", Turbulence::Light),
                ("moderate", Turbulence::Moderate),
            ],
        )?,
    };
    Ok((steady, turbulence))
}

fn parse_runway(
    loc: &Locator,
    raw: Option<&Spanned<RawRunway>>,
    initial: InitialCondition,
) -> Result<Runway, ScenarioError> {
    let heading = initial.heading_rad();
    // By default the airplane lands where it took off from, 100 m down the runway.
    let mut runway = Runway {
        touchdown_ne_m: [100.0 * heading.cos(), 100.0 * heading.sin()],
        heading_rad: heading,
    };
    if let Some(s) = raw {
        let (span, r) = (s.span(), s.get_ref());
        let what = "[runway]";
        if let Some(h) = r.heading_deg {
            runway.heading_rad = wrap_pi(finite(loc, &span, what, "heading_deg", h)?.to_radians());
        }
        if let Some(n) = r.touchdown_north_m {
            runway.touchdown_ne_m[0] =
                in_range(loc, &span, what, "touchdown_north_m", n, -5000.0, 5000.0)?;
        }
        if let Some(e) = r.touchdown_east_m {
            runway.touchdown_ne_m[1] =
                in_range(loc, &span, what, "touchdown_east_m", e, -5000.0, 5000.0)?;
        }
    }
    Ok(runway)
}

fn parse_direction(
    loc: &Locator,
    span: &Range<usize>,
    what: &str,
    value: Option<&String>,
) -> Result<Option<Direction>, ScenarioError> {
    value
        .map(|d| {
            one_of(
                loc,
                span,
                what,
                "direction",
                d,
                &[("left", Direction::Left), ("right", Direction::Right)],
            )
        })
        .transpose()
}

fn parse_timeline_entry(
    loc: &Locator,
    span: &Range<usize>,
    index: usize,
    raw: &RawTimelineEntry,
    runway: Runway,
) -> Result<TimelineEntry, ScenarioError> {
    let what = format!("timeline entry {index}");
    let what = what.as_str();
    let t_s = in_range(loc, span, what, "t_s", raw.t_s, 0.0, f64::MAX)?;
    let line = loc.line_of(span);
    let action = match (&raw.pilot, &raw.switch) {
        (Some(_), Some(_)) => {
            return Err(loc.key(
                span,
                "switch",
                format!("{what}: has both `pilot` and `switch`; give one per entry"),
            ));
        }
        (None, None) => {
            return Err(loc.at(
                span.start,
                format!("{what}: needs `pilot = \"...\"` or `switch = \"auto\"|\"manual\"`"),
            ));
        }
        (None, Some(switch)) => {
            if let Some((key, _)) = raw.parameters().into_iter().find(|(_, set)| *set) {
                return Err(loc.key(
                    span,
                    key,
                    format!("{what}: `{key}` does not apply to a switch entry"),
                ));
            }
            TimelineAction::Switch(one_of(
                loc,
                span,
                what,
                "switch",
                switch,
                &[
                    ("auto", SwitchPosition::Auto),
                    ("manual", SwitchPosition::Manual),
                ],
            )?)
        }
        (Some(pilot), None) => {
            let known: Vec<(&str, ())> = MANOEUVRES.iter().map(|m| (*m, ())).collect();
            one_of(loc, span, what, "pilot", pilot, &known)?;
            let allowed = manoeuvre_keys(pilot);
            if let Some((key, _)) = raw
                .parameters()
                .into_iter()
                .find(|(key, set)| *set && !allowed.contains(key))
            {
                let takes = if allowed.is_empty() {
                    "no parameters".to_string()
                } else {
                    allowed.join(", ")
                };
                return Err(loc.key(
                    span,
                    key,
                    format!(
                        "{what}: `{key}` does not apply to pilot = \"{pilot}\" (it takes {takes})"
                    ),
                ));
            }
            TimelineAction::Pilot(parse_manoeuvre(loc, span, what, pilot, raw, runway)?)
        }
    };
    Ok(TimelineEntry { t_s, action, line })
}

fn parse_manoeuvre(
    loc: &Locator,
    span: &Range<usize>,
    what: &str,
    pilot: &str,
    raw: &RawTimelineEntry,
    runway: Runway,
) -> Result<Manoeuvre, ScenarioError> {
    let required = |key: &str, value: Option<f64>| {
        value.ok_or_else(|| {
            loc.at(
                span.start,
                format!("{what}: pilot = \"{pilot}\" needs `{key}`"),
            )
        })
    };
    let deg = |key: &str, v: f64, low: f64, high: f64| {
        in_range(loc, span, what, key, v, low, high).map(f64::to_radians)
    };
    let altitude = |v: f64| in_range(loc, span, what, "altitude_m", v, 10.0, 3000.0);
    let airspeed = |v: Option<f64>| {
        v.map(|v| in_range(loc, span, what, "airspeed_mps", v, 17.0, 32.5))
            .transpose()
    };
    let heading =
        |v: f64| finite(loc, span, what, "heading_deg", v).map(|h| wrap_pi(h.to_radians()));
    let glide = |v: Option<f64>| deg("glide_slope_deg", v.unwrap_or(4.0), 2.0, 8.0);
    Ok(match pilot {
        "takeoff" => Manoeuvre::Takeoff {
            rotate_speed_mps: in_range(
                loc,
                span,
                what,
                "rotate_speed_mps",
                raw.rotate_speed_mps.unwrap_or(18.0),
                14.0,
                // Up to a light airplane's on JSBSim (a 172 rotates at about 28 m/s).
                40.0,
            )?,
            climb_pitch_rad: deg(
                "climb_pitch_deg",
                raw.climb_pitch_deg.unwrap_or(10.0),
                3.0,
                15.0,
            )?,
            climb_to_m: in_range(
                loc,
                span,
                what,
                "climb_to_m",
                raw.climb_to_m.unwrap_or(50.0),
                20.0,
                500.0,
            )?,
        },
        "climb" | "level" => Manoeuvre::Climb {
            altitude_m: altitude(required("altitude_m", raw.altitude_m)?)?,
            airspeed_mps: airspeed(raw.airspeed_mps)?,
        },
        "turn" => Manoeuvre::Turn {
            heading_rad: heading(required("heading_deg", raw.heading_deg)?)?,
            max_bank_rad: deg("max_bank_deg", raw.max_bank_deg.unwrap_or(30.0), 5.0, 60.0)?,
            direction: parse_direction(loc, span, what, raw.direction.as_ref())?,
        },
        "hold" => Manoeuvre::Hold {
            altitude_m: raw.altitude_m.map(altitude).transpose()?,
            heading_rad: raw.heading_deg.map(heading).transpose()?,
            airspeed_mps: airspeed(raw.airspeed_mps)?,
        },
        "roll" => Manoeuvre::Roll {
            direction: parse_direction(loc, span, what, raw.direction.as_ref())?
                .unwrap_or(Direction::Right),
        },
        "loop" => Manoeuvre::Loop,
        "approach" => Manoeuvre::Approach {
            runway,
            glide_slope_rad: glide(raw.glide_slope_deg)?,
            final_length_m: in_range(
                loc,
                span,
                what,
                "final_m",
                raw.final_m.unwrap_or(700.0),
                200.0,
                3000.0,
            )?,
        },
        "land" => Manoeuvre::Land {
            runway,
            glide_slope_rad: glide(raw.glide_slope_deg)?,
        },
        "sticks" => {
            let surface = |key: &str, v: Option<f64>| {
                in_range(loc, span, what, key, v.unwrap_or(0.0), -1.0, 1.0)
            };
            let unit = |key: &str, v: Option<f64>| {
                in_range(loc, span, what, key, v.unwrap_or(0.0), 0.0, 1.0)
            };
            Manoeuvre::Sticks {
                sticks: ActuatorCommands {
                    aileron: surface("aileron", raw.aileron)?,
                    elevator: surface("elevator", raw.elevator)?,
                    rudder: surface("rudder", raw.rudder)?,
                    throttle: unit("throttle", raw.throttle)?,
                    brake: unit("brake", raw.brake)?,
                },
                duration_s: in_range(
                    loc,
                    span,
                    what,
                    "duration_s",
                    required("duration_s", raw.duration_s)?,
                    0.0,
                    3600.0,
                )?,
            }
        }
        // `one_of` above has already refused anything else.
        other => {
            return Err(loc.key(
                span,
                "pilot",
                format!("{what}: unknown pilot manoeuvre \"{other}\""),
            ));
        }
    })
}

fn parse_fault(
    loc: &Locator,
    span: &Range<usize>,
    index: usize,
    raw: &RawFault,
) -> Result<Fault, ScenarioError> {
    let what = format!("fault {index}");
    let what = what.as_str();
    let t_s = in_range(loc, span, what, "t_s", raw.t_s, 0.0, f64::MAX)?;
    let duration_s = in_range(loc, span, what, "duration_s", raw.duration_s, 0.0, 3600.0)?;
    if duration_s == 0.0 {
        return Err(loc.key(
            span,
            "duration_s",
            format!("{what}: `duration_s` must be > 0"),
        ));
    }
    let kind = one_of(
        loc,
        span,
        what,
        "kind",
        &raw.kind,
        &[
            ("sensor_silence", FaultKind::SensorSilence),
            ("garbage_burst", FaultKind::GarbageBurst),
            ("gps_loss", FaultKind::GpsLoss),
            ("task_overrun", FaultKind::TaskOverrun),
            ("servo_port_vanish", FaultKind::ServoPortVanish),
        ],
    )?;
    let device = raw
        .device
        .as_ref()
        .map(|d| {
            one_of(
                loc,
                span,
                what,
                "device",
                d,
                &[
                    ("imu", Device::Imu),
                    ("gps", Device::Gps),
                    ("servo", Device::Servo),
                ],
            )
        })
        .transpose()?;
    let not_for = |key: &str, set: bool| {
        if set {
            Err(loc.key(
                span,
                key,
                format!("{what}: `{key}` does not apply to kind = \"{}\"", raw.kind),
            ))
        } else {
            Ok(())
        }
    };
    let device = match kind {
        FaultKind::SensorSilence | FaultKind::GarbageBurst => {
            not_for("task", raw.task.is_some())?;
            not_for("extra_us", raw.extra_us.is_some())?;
            Some(device.ok_or_else(|| {
                loc.at(
                    span.start,
                    format!(
                        "{what}: kind = \"{}\" needs `device` (\"imu\", \"gps\" or \"servo\")",
                        raw.kind
                    ),
                )
            })?)
        }
        FaultKind::GpsLoss | FaultKind::ServoPortVanish => {
            not_for("task", raw.task.is_some())?;
            not_for("extra_us", raw.extra_us.is_some())?;
            let only = if kind == FaultKind::GpsLoss {
                Device::Gps
            } else {
                Device::Servo
            };
            match device {
                Some(d) if d != only => {
                    return Err(loc.key(
                        span,
                        "device",
                        format!(
                            "{what}: kind = \"{}\" only hits device = \"{}\"",
                            raw.kind,
                            if only == Device::Gps { "gps" } else { "servo" }
                        ),
                    ));
                }
                _ => Some(only),
            }
        }
        FaultKind::TaskOverrun => {
            not_for("device", raw.device.is_some())?;
            let task = raw.task.as_deref().unwrap_or("");
            if task.trim().is_empty() {
                return Err(loc.at(
                    span.start,
                    format!("{what}: kind = \"task_overrun\" needs `task` (a task name from schedule.toml)"),
                ));
            }
            match raw.extra_us {
                None => {
                    return Err(loc.at(
                        span.start,
                        format!("{what}: kind = \"task_overrun\" needs `extra_us`"),
                    ));
                }
                Some(0) => {
                    return Err(loc.key(
                        span,
                        "extra_us",
                        format!("{what}: `extra_us` must be > 0"),
                    ));
                }
                Some(_) => {}
            }
            None
        }
    };
    Ok(Fault {
        t_s,
        duration_s,
        kind,
        device,
        task: raw.task.clone(),
        extra_us: raw.extra_us,
        line: loc.line_of(span),
    })
}
