//! Scenario files (TOML): the initial state, the wind, the GPS receiver, a timeline of pilot
//! manoeuvres and switch changes, and injected faults. `scenarios/README.md` documents the
//! format; [`Scenario::parse`] reads it and [`run_pilot_only`] flies it with the scripted pilot
//! alone (no flight computer), in virtual time, for tests.
//!
//! Faults are data here: parsed, validated and offered through [`Scenario::active_faults`];
//! applying them is the business of whoever simulates the device or the executive.
//!
//! Errors are one line and say where: `line 12, column 1: timeline entry 3: unknown pilot
//! manoeuvre "barrel", expected one of ...`. Parsing never panics.

use crate::pilot::{Direction, Manoeuvre, Pilot, PilotConfig, Runway, SwitchPosition, wrap_pi};
use crate::plant::trim::trim_level_flight;
use crate::plant::{
    ActuatorCommands, AircraftParams, DrydenParams, InitialState, Plant, PlantConfig, PlantKind,
    SimGpsConfig, Truth, WindConfig,
};
use crate::servo_board::{OutputSource, ServoBoard, TransmitterInput};
use serde::Deserialize;
use std::fmt;
use std::ops::Range;
use toml::Spanned;

/// Seed used when the file gives none.
pub const DEFAULT_SEED: u64 = 1;

/// A scenario file that could not be read, and where.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScenarioError {
    /// 1-based; 0 when the place is unknown.
    pub line: usize,
    pub column: usize,
    pub message: String,
}

impl fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "{}", self.message)
        } else {
            write!(
                f,
                "line {}, column {}: {}",
                self.line, self.column, self.message
            )
        }
    }
}

impl std::error::Error for ScenarioError {}

// ------------------------------------------------------------------------------------------
// The file as written
// ------------------------------------------------------------------------------------------

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

// ------------------------------------------------------------------------------------------
// The scenario as used
// ------------------------------------------------------------------------------------------

/// Where the airplane starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InitialCondition {
    /// Parked at the origin, nose towards `heading_rad`.
    OnRunway { heading_rad: f64 },
    /// Trimmed level flight over the origin.
    InFlight {
        altitude_m: f64,
        airspeed_mps: f64,
        heading_rad: f64,
    },
}

impl InitialCondition {
    pub fn heading_rad(&self) -> f64 {
        match *self {
            InitialCondition::OnRunway { heading_rad }
            | InitialCondition::InFlight { heading_rad, .. } => heading_rad,
        }
    }
}

/// Turbulence level.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Turbulence {
    #[default]
    None,
    Light,
    Moderate,
}

/// The GPS receiver model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GpsPreset {
    /// A clean 10 Hz receiver.
    #[default]
    Nominal,
    /// The seed airframe's: 140 ms mean interval, 300 ms peaks.
    SeedReceiver,
    /// Exact fixes every 100 ms.
    Ideal,
}

impl GpsPreset {
    pub fn config(self) -> SimGpsConfig {
        match self {
            GpsPreset::Nominal => SimGpsConfig::nominal_10hz(),
            GpsPreset::SeedReceiver => SimGpsConfig::seed_receiver(),
            GpsPreset::Ideal => SimGpsConfig::ideal(),
        }
    }
}

/// What happens at a timeline entry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TimelineAction {
    Pilot(Manoeuvre),
    Switch(SwitchPosition),
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimelineEntry {
    pub t_s: f64,
    pub action: TimelineAction,
    /// Line in the scenario file, for messages.
    pub line: usize,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultKind {
    /// The device sends nothing.
    SensorSilence,
    /// The device sends random bytes.
    GarbageBurst,
    /// The GPS receiver loses its fix (it reports no fix, or nothing).
    GpsLoss,
    /// A task is made to run `extra_us` longer than it would.
    TaskOverrun,
    /// The servo board's serial port disappears (unplugged).
    ServoPortVanish,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Device {
    Imu,
    Gps,
    Servo,
}

/// An injected fault, active over `[t_s, t_s + duration_s)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Fault {
    pub t_s: f64,
    pub duration_s: f64,
    pub kind: FaultKind,
    /// The device it hits: always set for sensor silence and garbage bursts, `Gps` for GPS
    /// loss and `Servo` for a vanished servo port; `None` for a task overrun.
    pub device: Option<Device>,
    /// The task made to overrun (task overrun only).
    pub task: Option<String>,
    /// How much longer the task runs (task overrun only), µs.
    pub extra_us: Option<u64>,
    pub line: usize,
}

impl Fault {
    pub fn is_active(&self, t_s: f64) -> bool {
        t_s >= self.t_s && t_s < self.t_s + self.duration_s
    }

    pub fn end_s(&self) -> f64 {
        self.t_s + self.duration_s
    }
}

/// A parsed, validated scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    pub seed: u64,
    pub duration_s: f64,
    pub initial: InitialCondition,
    pub wind_ned_mps: [f64; 3],
    pub turbulence: Turbulence,
    pub gps: GpsPreset,
    /// Where approaches and landings go.
    pub runway: Runway,
    /// The flight model and aircraft (`[plant]`; default the built-in Aerosonde).
    pub plant: PlantKind,
    /// The scripted pilot's cruise speed on the scenario's aircraft (`[plant]`), when it is not
    /// the Aerosonde's: the pilot flies from the trim the plant finds there.
    pub pilot_cruise_airspeed_mps: Option<f64>,
    /// In time order.
    pub timeline: Vec<TimelineEntry>,
    /// In start-time order.
    pub faults: Vec<Fault>,
}

/// Line and column (1-based) of a byte offset.
fn line_column(src: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(src.len());
    let before = src.get(..offset).unwrap_or(src);
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// The text a table's keys are in: for an inline table its span; for a `[header]` table (whose
/// span is the header alone) from the header to the next header or the end.
fn table_region(src: &str, span: &Range<usize>) -> Range<usize> {
    let header = src.get(span.clone()).unwrap_or("");
    if !header.trim_start().starts_with('[') {
        return span.clone();
    }
    let body_start = span.end.min(src.len());
    let rest = src.get(body_start..).unwrap_or("");
    let mut offset = body_start;
    for line in rest.split_inclusive('\n') {
        if offset > body_start && line.trim_start().starts_with('[') {
            return span.start..offset;
        }
        offset += line.len();
    }
    span.start..src.len()
}

/// Where `key = ...` is written in the table at `span`, or the start of `span` if it is not
/// found.
fn key_offset(src: &str, span: &Range<usize>, key: &str) -> usize {
    let region = table_region(src, span);
    let Some(text) = src.get(region.clone()) else {
        return span.start;
    };
    let bytes = text.as_bytes();
    let mut from = 0;
    while let Some(found) = text.get(from..).and_then(|t| t.find(key)) {
        let at = from + found;
        let before_ok =
            at == 0 || !matches!(bytes[at - 1], b'a'..=b'z' | b'A'..=b'Z' | b'0'..=b'9' | b'_');
        let rest = text.get(at + key.len()..).unwrap_or("");
        let after_ok = rest.trim_start_matches([' ', '\t']).starts_with('=');
        if before_ok && after_ok {
            return region.start + at;
        }
        from = at + key.len();
    }
    span.start
}

/// The key whose value starts at `offset` (`key = value` on one line), if any.
fn key_before(src: &str, offset: usize) -> Option<&str> {
    let before = src.get(..offset)?;
    let line = before.rsplit('\n').next()?;
    let assignment = line.rfind('=')?;
    let name = line.get(..assignment)?.trim_end();
    let start = name
        .rfind(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .map_or(0, |i| i + 1);
    let key = name.get(start..)?;
    (!key.is_empty()).then_some(key)
}

struct Locator<'a> {
    src: &'a str,
}

impl Locator<'_> {
    fn at(&self, offset: usize, message: String) -> ScenarioError {
        let (line, column) = line_column(self.src, offset);
        ScenarioError {
            line,
            column,
            message,
        }
    }

    fn key(&self, span: &Range<usize>, key: &str, message: String) -> ScenarioError {
        self.at(key_offset(self.src, span, key), message)
    }

    fn line_of(&self, span: &Range<usize>) -> usize {
        line_column(self.src, span.start).0
    }
}

fn finite(
    loc: &Locator,
    span: &Range<usize>,
    what: &str,
    key: &str,
    value: f64,
) -> Result<f64, ScenarioError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(loc.key(
            span,
            key,
            format!("{what}: `{key}` must be a finite number"),
        ))
    }
}

#[allow(clippy::too_many_arguments)]
fn in_range(
    loc: &Locator,
    span: &Range<usize>,
    what: &str,
    key: &str,
    value: f64,
    low: f64,
    high: f64,
) -> Result<f64, ScenarioError> {
    if value.is_finite() && (low..=high).contains(&value) {
        Ok(value)
    } else {
        Err(loc.key(
            span,
            key,
            format!("{what}: `{key}` = {value} is outside {low}..={high}"),
        ))
    }
}

fn one_of<T: Copy>(
    loc: &Locator,
    span: &Range<usize>,
    what: &str,
    key: &str,
    value: &str,
    choices: &[(&str, T)],
) -> Result<T, ScenarioError> {
    choices
        .iter()
        .find(|(name, _)| *name == value)
        .map(|(_, v)| *v)
        .ok_or_else(|| {
            let names: Vec<String> = choices.iter().map(|(n, _)| format!("\"{n}\"")).collect();
            loc.key(
                span,
                key,
                format!(
                    "{what}: unknown {key} \"{value}\", expected one of {}",
                    names.join(", ")
                ),
            )
        })
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
            timeline,
            faults,
        })
    }

    /// Reads a scenario file; errors start with the path.
    pub fn load(path: &std::path::Path) -> Result<Self, ScenarioError> {
        let src =
            skyframe_input_files::read_text(path, "scenario", skyframe_input_files::CONFIG_LIMIT)
                .map_err(|message| ScenarioError {
                line: 0,
                column: 0,
                message,
            })?;
        Self::parse(&src).map_err(|e| ScenarioError {
            message: format!("{}: {}", path.display(), e.message),
            ..e
        })
    }

    /// The faults active at `t_s`.
    pub fn active_faults(&self, t_s: f64) -> impl Iterator<Item = &Fault> {
        self.faults.iter().filter(move |f| f.is_active(t_s))
    }

    /// The wind model this scenario asks for.
    pub fn wind_config(&self) -> WindConfig {
        WindConfig {
            steady_ned_mps: self.wind_ned_mps,
            turbulence: match self.turbulence {
                Turbulence::None => None,
                Turbulence::Light => Some(DrydenParams::light_low_altitude()),
                Turbulence::Moderate => Some(DrydenParams::moderate_low_altitude()),
            },
        }
    }

    /// The plant configuration: default airframe and sensors with this wind and GPS.
    pub fn plant_config(&self) -> PlantConfig {
        PlantConfig {
            wind: self.wind_config(),
            gps: self.gps.config(),
            ..PlantConfig::default()
        }
    }

    /// The plant's initial state; in flight it is trimmed level flight (falling back to an
    /// untrimmed state at that speed if the airframe cannot trim there).
    pub fn initial_state(&self, params: &AircraftParams) -> InitialState {
        match self.initial {
            InitialCondition::OnRunway { heading_rad } => {
                InitialState::on_runway(params, heading_rad)
            }
            InitialCondition::InFlight {
                altitude_m,
                airspeed_mps,
                heading_rad,
            } => trim_level_flight(params, airspeed_mps, altitude_m, heading_rad)
                .map(|t| t.initial)
                .unwrap_or_else(|_| InitialState::in_flight(altitude_m, airspeed_mps, heading_rad)),
        }
    }

    /// Checks every task-overrun fault names one of `task_names` (the schedule's tasks).
    pub fn check_tasks(&self, task_names: &[&str]) -> Result<(), ScenarioError> {
        for f in &self.faults {
            if let Some(task) = &f.task {
                if !task_names.contains(&task.as_str()) {
                    return Err(ScenarioError {
                        line: f.line,
                        column: 1,
                        message: format!(
                            "task_overrun: no task \"{task}\" in the schedule (it has {})",
                            task_names.join(", ")
                        ),
                    });
                }
            }
        }
        Ok(())
    }

    /// A timeline player for this scenario.
    pub fn player(&self) -> TimelinePlayer {
        TimelinePlayer {
            timeline: self.timeline.clone(),
            next: 0,
        }
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

// ------------------------------------------------------------------------------------------
// Playing the timeline
// ------------------------------------------------------------------------------------------

/// Hands the timeline's entries to a [`Pilot`] as their times come.
#[derive(Debug, Clone)]
pub struct TimelinePlayer {
    timeline: Vec<TimelineEntry>,
    next: usize,
}

impl TimelinePlayer {
    /// Applies every entry due by `t_s` (in order); returns how many.
    pub fn advance(&mut self, t_s: f64, pilot: &mut Pilot) -> usize {
        let mut applied = 0;
        while let Some(e) = self.timeline.get(self.next) {
            if e.t_s > t_s {
                break;
            }
            match e.action {
                TimelineAction::Pilot(m) => pilot.fly(m),
                TimelineAction::Switch(s) => pilot.set_switch(s),
            }
            self.next += 1;
            applied += 1;
        }
        applied
    }

    pub fn is_finished(&self) -> bool {
        self.next >= self.timeline.len()
    }
}

/// The person with the transmitter in a scenario: the scripted pilot, fed by the timeline.
/// Call [`ScenarioPilot::update`] at the control rate with the plant's truth; it returns what
/// the radio receiver hands the servo board.
#[derive(Debug, Clone)]
pub struct ScenarioPilot {
    pilot: Pilot,
    player: TimelinePlayer,
}

impl ScenarioPilot {
    pub fn new(scenario: &Scenario, params: &AircraftParams) -> Self {
        let mut pilot = Pilot::new(params, PilotConfig::default());
        // Starting in the air, the pilot already has the sticks and holds what it finds.
        if matches!(scenario.initial, InitialCondition::InFlight { .. }) {
            pilot.fly(Manoeuvre::Hold {
                altitude_m: None,
                heading_rad: None,
                airspeed_mps: None,
            });
        }
        Self {
            pilot,
            player: scenario.player(),
        }
    }

    /// Applies the timeline entries due by `truth.t_s`, then looks and moves the sticks.
    pub fn update(&mut self, truth: &Truth) -> TransmitterInput {
        self.player.advance(truth.t_s, &mut self.pilot);
        let sticks = self.pilot.update(truth);
        TransmitterInput {
            sticks,
            switch: self.pilot.switch(),
        }
    }

    pub fn pilot(&self) -> &Pilot {
        &self.pilot
    }

    /// See [`Pilot::retrim`].
    pub fn retrim(
        &mut self,
        trim: ActuatorCommands,
        trim_pitch_rad: f64,
        cruise_airspeed_mps: f64,
    ) {
        self.pilot.retrim(trim, trim_pitch_rad, cruise_airspeed_mps);
    }
}

// ------------------------------------------------------------------------------------------
// Pilot-only runs
// ------------------------------------------------------------------------------------------

/// How a pilot-only run steps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunOptions {
    /// How often the pilot looks and the board updates the servos (s).
    pub control_period_s: f64,
    /// The plant's longest integration step (s); coarser is faster and a little less exact.
    pub plant_max_step_s: f64,
    /// How often the summary records a sample (s).
    pub sample_period_s: f64,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            control_period_s: 0.02,
            plant_max_step_s: 0.001,
            sample_period_s: 0.1,
        }
    }
}

/// One recorded moment of a run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectorySample {
    pub t_s: f64,
    pub position_ned_m: [f64; 3],
    pub height_m: f64,
    pub airspeed_mps: f64,
    pub roll_rad: f64,
    pub pitch_rad: f64,
    pub yaw_rad: f64,
    pub on_ground: bool,
    pub switch: SwitchPosition,
    pub source: OutputSource,
    pub pilot_phase: &'static str,
}

/// What a pilot-only run did.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightSummary {
    pub samples: Vec<TrajectorySample>,
    /// First time the wheels left the ground (wheels off and above 1 m), and where.
    pub liftoff: Option<(f64, [f64; 3])>,
    /// First time the wheels touched again after lift-off, and where.
    pub touchdown: Option<(f64, [f64; 3])>,
    pub final_truth: Truth,
    pub max_height_m: f64,
    /// Furthest horizontal distance from the origin (m).
    pub max_distance_m: f64,
    /// An airframe strike (tail, wing tip, crash) at any moment.
    pub airframe_strike: bool,
    /// The first one's time and the truth then.
    pub first_strike: Option<Truth>,
    /// The pilot's landing ended with the airplane stopped.
    pub parked: bool,
    /// Time the board spent on each source (s): pilot, computer, failsafe.
    pub time_on_pilot_s: f64,
    pub time_on_computer_s: f64,
    pub time_on_failsafe_s: f64,
}

impl FlightSummary {
    /// Time in the air (s).
    pub fn flight_time_s(&self) -> Option<f64> {
        match (self.liftoff, self.touchdown) {
            (Some((a, _)), Some((b, _))) => Some(b - a),
            _ => None,
        }
    }
}

/// A command from a stand-in flight computer: what it wants the servos to do and whether it
/// says it is ready to fly.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StandInCommand {
    pub commands: ActuatorCommands,
    pub autopilot_ready: bool,
}

/// Flies `scenario` with the scripted pilot alone: no flight computer, so whatever the switch
/// says the servo board gives the pilot the servos. Deterministic for the scenario's seed.
pub fn run_pilot_only(scenario: &Scenario, options: RunOptions) -> FlightSummary {
    run_with_computer(scenario, options, |_| None)
}

/// Flies `scenario` with the scripted pilot and a stand-in flight computer: `computer` is
/// asked once per control period, seeing the truth; `None` means it sent nothing then (a
/// computer that stops answering makes the board fail safe to the pilot after 100 ms).
pub fn run_with_computer(
    scenario: &Scenario,
    options: RunOptions,
    mut computer: impl FnMut(&Truth) -> Option<StandInCommand>,
) -> FlightSummary {
    let params = AircraftParams::aerosonde();
    let config = PlantConfig {
        max_step_s: options.plant_max_step_s,
        ..scenario.plant_config()
    };
    let mut plant = Plant::with_config(config, scenario.initial_state(&params), scenario.seed);
    let mut pilot = ScenarioPilot::new(scenario, &params);
    let mut board = ServoBoard::new();
    let dt = options.control_period_s.max(1e-3);
    let steps = (scenario.duration_s / dt).round() as u64;
    let sample_every = ((options.sample_period_s / dt).round() as u64).max(1);

    let start = plant.truth();
    let mut summary = FlightSummary {
        samples: Vec::new(),
        liftoff: None,
        touchdown: None,
        final_truth: start,
        max_height_m: start.height_above_ground_m,
        max_distance_m: 0.0,
        airframe_strike: false,
        first_strike: None,
        parked: false,
        time_on_pilot_s: 0.0,
        time_on_computer_s: 0.0,
        time_on_failsafe_s: 0.0,
    };
    let mut was_airborne = !start.on_ground;
    for k in 0..steps {
        let truth = plant.truth();
        let input = pilot.update(&truth);
        if let Some(c) = computer(&truth) {
            board.receive_computer_command(plant.time_ns(), c.commands, c.autopilot_ready);
        }
        let (out, source) = board.mix(plant.time_ns(), &input);
        match source {
            OutputSource::Pilot => summary.time_on_pilot_s += dt,
            OutputSource::Computer => summary.time_on_computer_s += dt,
            OutputSource::Failsafe => summary.time_on_failsafe_s += dt,
        }
        if k % sample_every == 0 {
            summary.samples.push(TrajectorySample {
                t_s: truth.t_s,
                position_ned_m: truth.position_ned_m,
                height_m: truth.height_above_ground_m,
                airspeed_mps: truth.airspeed_mps,
                roll_rad: truth.roll_rad,
                pitch_rad: truth.pitch_rad,
                yaw_rad: truth.yaw_rad,
                on_ground: truth.on_ground,
                switch: input.switch,
                source,
                pilot_phase: pilot.pilot().phase_name(),
            });
        }
        plant.step(dt, &out);
        let t = plant.truth();
        if t.airframe_strike && !summary.airframe_strike {
            summary.airframe_strike = true;
            summary.first_strike = Some(t);
        }
        summary.max_height_m = summary.max_height_m.max(t.height_above_ground_m);
        summary.max_distance_m = summary
            .max_distance_m
            .max(t.position_ned_m[0].hypot(t.position_ned_m[1]));
        if !t.on_ground && t.height_above_ground_m > 1.0 && !was_airborne {
            was_airborne = true;
            if summary.liftoff.is_none() {
                summary.liftoff = Some((t.t_s, t.position_ned_m));
            }
        }
        if t.on_ground && was_airborne && summary.touchdown.is_none() {
            summary.touchdown = Some((t.t_s, t.position_ned_m));
        }
    }
    summary.final_truth = plant.truth();
    summary.parked = pilot.pilot().is_parked();
    summary
}

#[cfg(test)]
mod tests;
