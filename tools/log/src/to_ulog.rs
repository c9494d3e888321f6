//! `to-ulog`: one flight (every stream of a flight directory, or one `.bin`) as one PX4 ULog
//! file, for PlotJuggler, pyulog/pandas and Flight Review (`docs/ulog.md`).
//!
//! ```text
//! *.bin ──Flight::load──▶ records (raw bytes) ─┬─ skyframe_<what> topics: the bytes as they are
//!                                             ├─ PX4 topics: PX4_TOPICS, converted per field
//!                                             ├─ parameters (control.2), logged messages, dropouts
//!                                             └─ sorted by time ──▶ flight.ulg
//! ```
//!
//! All streams share one clock: a ULog timestamp is the log TIME less the flight's first TIME,
//! in µs (`skyframe_time_origin_ns` in the info messages says what that first TIME was).

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

use skyframe_core::estimation::geo::{GeoPoint, LocalFrame};
use skyframe_core::estimation::nalgebra::Vector3;
use skyframe_core::logfmt::FieldType;

use crate::Outcome;
use crate::flightlog::{Flight, Layout, Rec, stream_files};

const ULOG_MAGIC: [u8; 7] = [b'U', b'L', b'o', b'g', 0x01, 0x12, 0x35];
const ULOG_VERSION: u8 = 1;

/// What to write besides the records.
#[derive(Clone, Debug)]
pub struct UlogOptions {
    /// The PX4-named topics (off: only the skyframe topics, i.e. exactly the log's records).
    pub px4_topics: bool,
    pub vehicle_id: Option<String>,
    pub ver_sw: Option<String>,
}

impl Default for UlogOptions {
    fn default() -> Self {
        Self {
            px4_topics: true,
            vehicle_id: None,
            ver_sw: None,
        }
    }
}

/// `skyframe-log to-ulog INPUT [-o OUT]`: the default output is `<dir>/flight.ulg` for a
/// flight directory, `<stem>.ulg` beside a single file.
pub fn run(input: &Path, output: Option<&Path>, options: &UlogOptions) -> Outcome {
    let output = match output {
        Some(o) => o.to_path_buf(),
        None if input.is_dir() => input.join("flight.ulg"),
        None => input.with_extension("ulg"),
    };
    Outcome::of_conversion(convert(input, &output, options))
}

/// Converts; returns the lines to report (reader problems, notes).
pub fn convert(input: &Path, output: &Path, options: &UlogOptions) -> Result<Vec<String>, String> {
    let files = stream_files(input)?;
    let flight = Flight::load(&files)?;
    let mut reported: Vec<String> = flight.damage.iter().map(|d| d.line.clone()).collect();
    if flight.records.is_empty() {
        return Err(format!(
            "{}: no data records to convert{}",
            input.display(),
            if reported.is_empty() {
                String::new()
            } else {
                format!(" ({} problems reported)", reported.len())
            }
        ));
    }
    // A ULog names its message layouts with a u16 (and so does ours, PX4 topics included).
    if flight.layouts.len() > 60_000 {
        return Err(format!(
            "{}: {} distinct format layouts: more than a ULog can name",
            input.display(),
            flight.layouts.len()
        ));
    }
    for stream in &flight.streams {
        if stream.byte_arrays > 0 {
            reported.push(format!(
                "skyframe-log: note: {}: {} byte arrays not converted (ULog has no \
                 variable-length messages)",
                stream.path.display(),
                stream.byte_arrays
            ));
        }
    }
    let flight_id = flight_id(input);
    let ulog = build(&flight, &flight_id, options);
    let out_err = |e: io::Error| format!("{}: {e}", output.display());
    let file = File::create(output).map_err(out_err)?;
    let mut out = BufWriter::with_capacity(256 * 1024, file);
    ulog.write(&mut out).map_err(out_err)?;
    out.flush().map_err(out_err)?;
    Ok(reported)
}

/// A flight's id: its directory's name (`flights/<UTC start>/`), or the file's stem.
pub fn flight_id(input: &Path) -> String {
    let path = if input.is_dir() {
        input.to_path_buf()
    } else {
        input.with_extension("")
    };
    let path = std::fs::canonicalize(&path).unwrap_or(path);
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "unknown".into())
}

// ---------------------------------------------------------------------------------------------
// The skyframe topics: every format of every stream, its columns as fields, bytes as logged.

/// The ULog names of skyframe's own formats (`docs/log-streams.md`); a stream or index not
/// listed is `skyframe_<stream>` (index 1) or `skyframe_<stream>_<index>`.
const SKYFRAME_TOPICS: &[(&str, u8, &str)] = &[
    ("executive", 1, "skyframe_executive"),
    ("executive", 2, "skyframe_timer_check"),
    ("imu", 1, "skyframe_imu"),
    ("imu", 2, "skyframe_imu_slow"),
    ("imu", 3, "skyframe_device_status"),
    ("gps", 1, "skyframe_gps"),
    ("gps", 2, "skyframe_device_status"),
    ("servo", 1, "skyframe_servo_board"),
    ("servo", 2, "skyframe_servo_command"),
    ("servo", 3, "skyframe_device_status"),
    ("health", 1, "skyframe_task_timing"),
    ("watchdog", 1, "skyframe_watchdog"),
    ("link", 1, "skyframe_link"),
    ("truth", 1, "skyframe_truth"),
    ("truth", 2, "skyframe_truth_origin"),
    ("estimator", 1, "skyframe_estimator"),
    ("estimator", 2, "skyframe_estimator_status"),
    ("estimator", 3, "skyframe_estimator_sd"),
    ("control", 1, "skyframe_control"),
    ("control", 2, "skyframe_control_gains"),
    ("horizon", 1, "skyframe_horizon"),
];

/// A ULog identifier from any text (column names keep their case; topic names are lower
/// case, as PX4's).
fn identifier(text: &str) -> String {
    crate::flightlog::identifier(text, "x")
}

fn skyframe_topic_name(layout: &Layout) -> String {
    let base = SKYFRAME_TOPICS
        .iter()
        .find(|(s, i, _)| *s == layout.stream && *i == layout.index)
        .map(|(_, _, n)| (*n).to_string())
        .unwrap_or_else(|| {
            let stream = identifier(&layout.stream).to_ascii_lowercase();
            match layout.index {
                1 => format!("skyframe_{stream}"),
                i => format!("skyframe_{stream}_{i}"),
            }
        });
    match layout.version {
        0 => base,
        v => format!("{base}_{v}"),
    }
}

pub fn ulog_type(ty: FieldType) -> &'static str {
    match ty {
        FieldType::I8 => "int8_t",
        FieldType::U8 => "uint8_t",
        FieldType::I16 => "int16_t",
        FieldType::U16 => "uint16_t",
        FieldType::I32 => "int32_t",
        FieldType::U32 => "uint32_t",
        FieldType::I64 => "int64_t",
        FieldType::U64 => "uint64_t",
        FieldType::F32 => "float",
        FieldType::F64 => "double",
    }
}

/// ULog field names: the columns made identifiers, unique, never `timestamp` (ULog's own).
fn field_names(columns: &[String]) -> Vec<String> {
    let mut names: Vec<String> = Vec::with_capacity(columns.len());
    for (i, column) in columns.iter().enumerate() {
        let mut name = identifier(column.trim());
        if name == "timestamp" || name.starts_with("_padding") {
            name = format!("{name}_log");
        }
        if names.contains(&name) {
            name = format!("{name}_{i}");
        }
        names.push(name);
    }
    names
}

// ---------------------------------------------------------------------------------------------
// The PX4 topics: one table, one row per PX4 field.

/// A record's values by column name.
pub struct Row<'a> {
    layout: &'a Layout,
    values: &'a [f64],
}

impl Row<'_> {
    /// The column's value; NaN when the layout has no such column.
    fn get(&self, column: &str) -> f64 {
        self.layout
            .column(column)
            .and_then(|c| self.values.get(c).copied())
            .unwrap_or(f64::NAN)
    }
}

/// What a flight knows beyond one record.
pub struct Context {
    /// The estimator's local frame: its origin is the first valid GPS fix (the estimator's
    /// home unless one was configured, which the logs do not say).
    frame: Option<LocalFrame>,
    /// The log TIME is UTC wall clock (a vehicle's, not a simulation's virtual clock).
    utc: bool,
    /// The record's TIME in ns.
    t_ns: i64,
}

type Value = fn(&Row, &Context, usize) -> f64;

/// One field of a PX4 message: its ULog type, name, array length (1: scalar) and how each
/// element is computed from the skyframe record.
pub struct Px4Field {
    pub ty: &'static str,
    pub name: &'static str,
    pub len: usize,
    value: Value,
}

/// When a record makes a message.
#[derive(Clone, Copy)]
enum Emit {
    Always,
    /// Only when this column is finite (a setpoint of a loop that ran).
    IfFinite(&'static str),
    /// When the message's values change, and at least every this many seconds (PX4 publishes
    /// vehicle_status at 1-2 Hz and on change).
    OnChange(f64),
}

/// A PX4 topic made from one skyframe format.
pub struct Px4Topic {
    pub topic: &'static str,
    pub multi_id: u8,
    pub stream: &'static str,
    pub index: u8,
    /// Columns the source format must have.
    needs: &'static [&'static str],
    emit: Emit,
    pub fields: Vec<Px4Field>,
}

fn f(ty: &'static str, name: &'static str, value: Value) -> Px4Field {
    Px4Field {
        ty,
        name,
        len: 1,
        value,
    }
}

fn a(ty: &'static str, name: &'static str, len: usize, value: Value) -> Px4Field {
    Px4Field {
        ty,
        name,
        len,
        value,
    }
}

fn b(x: bool) -> f64 {
    f64::from(u8::from(x))
}

/// GGA fix quality → PX4 fix_type (0-1 none, 3 3D, 4 DGPS, 5 RTK float, 6 RTK fixed,
/// 8 extrapolated). 255 (not reported) with a valid fix counts as 3D.
fn fix_type(r: &Row) -> f64 {
    if r.get("valid") != 1.0 {
        return 0.0;
    }
    match r.get("quality") as u8 {
        0 => 0.0,
        2 | 3 | 9 => 4.0,
        4 => 6.0,
        5 => 5.0,
        6 => 8.0,
        _ => 3.0,
    }
}

/// PX4 nav_state from skyframe's control mode (0 manual, 1 stabilise, 2 auto) and reason
/// (4: auto without a mission holds course and altitude, PX4's loiter).
fn nav_state(r: &Row) -> f64 {
    match (r.get("mode") as u8, r.get("reason") as u8) {
        (0, _) => 0.0,  // NAVIGATION_STATE_MANUAL
        (1, _) => 15.0, // NAVIGATION_STATE_STAB
        (_, 4) => 4.0,  // NAVIGATION_STATE_AUTO_LOITER
        _ => 3.0,       // NAVIGATION_STATE_AUTO_MISSION
    }
}

/// Hamilton quaternion (w, x, y, z), body FRD → NED, of 3-2-1 Euler angles.
fn quaternion(roll: f64, pitch: f64, yaw: f64) -> [f64; 4] {
    let (sr, cr) = (roll / 2.0).sin_cos();
    let (sp, cp) = (pitch / 2.0).sin_cos();
    let (sy, cy) = (yaw / 2.0).sin_cos();
    [
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ]
}

fn geodetic(r: &Row, c: &Context) -> Option<GeoPoint> {
    let frame = c.frame.as_ref()?;
    Some(frame.to_geodetic(&Vector3::new(r.get("pn_m"), r.get("pe_m"), r.get("pd_m"))))
}

fn home(c: &Context) -> Option<GeoPoint> {
    c.frame.as_ref().map(LocalFrame::home)
}

const NAN: f64 = f64::NAN;

/// Every PX4 topic skyframe's logs can fill, with PX4's field names, types and units
/// (PX4 v1.14 message definitions, `msg/*.msg`; `docs/ulog.md` explains each mapping).
/// Our frames already are PX4's (body FRD, NED, Hamilton w-first quaternions, rad, m/s,
/// m/s²); units change only where PX4 uses integers (1e-7 deg, mm) or AMSL altitudes.
pub fn px4_topics() -> Vec<Px4Topic> {
    vec![
        // sensor_combined ← imu.1 (rates and specific force, body FRD, like PX4's).
        Px4Topic {
            topic: "sensor_combined",
            multi_id: 0,
            stream: "imu",
            index: 1,
            needs: &[
                "p_rad_s", "q_rad_s", "r_rad_s", "fx_m_s2", "fy_m_s2", "fz_m_s2",
            ],
            emit: Emit::Always,
            fields: vec![
                a("float", "gyro_rad", 3, |r, _, i| {
                    r.get(["p_rad_s", "q_rad_s", "r_rad_s"][i])
                }),
                a("float", "accelerometer_m_s2", 3, |r, _, i| {
                    r.get(["fx_m_s2", "fy_m_s2", "fz_m_s2"][i])
                }),
                // Gyro and accelerometer are one sample of one device.
                f("int32_t", "accelerometer_timestamp_relative", |_, _, _| 0.0),
            ],
        },
        // vehicle_gps_position ← gps.1 (PX4 v1.14 sensor_gps: lat/lon 1e-7 deg, alt mm MSL).
        Px4Topic {
            topic: "vehicle_gps_position",
            multi_id: 0,
            stream: "gps",
            index: 1,
            needs: &[
                "valid", "lat_deg", "lon_deg", "alt_m", "vn_m_s", "ve_m_s", "vd_m_s",
            ],
            emit: Emit::Always,
            fields: vec![
                f("int32_t", "lat", |r, _, _| (r.get("lat_deg") * 1e7).round()),
                f("int32_t", "lon", |r, _, _| (r.get("lon_deg") * 1e7).round()),
                f("int32_t", "alt", |r, _, _| (r.get("alt_m") * 1e3).round()),
                f("uint8_t", "fix_type", |r, _, _| fix_type(r)),
                // 1-σ horizontal and vertical position errors (GST), metres.
                f("float", "eph", |r, _, _| {
                    r.get("sd_n_m").hypot(r.get("sd_e_m"))
                }),
                f("float", "epv", |r, _, _| r.get("sd_d_m")),
                f("float", "hdop", |r, _, _| r.get("hdop")),
                f("float", "vdop", |r, _, _| r.get("vdop")),
                f("float", "vel_m_s", |r, _, _| {
                    r.get("vn_m_s").hypot(r.get("ve_m_s"))
                }),
                f("float", "vel_n_m_s", |r, _, _| r.get("vn_m_s")),
                f("float", "vel_e_m_s", |r, _, _| r.get("ve_m_s")),
                f("float", "vel_d_m_s", |r, _, _| r.get("vd_m_s")),
                f("float", "cog_rad", |r, _, _| {
                    r.get("ve_m_s").atan2(r.get("vn_m_s"))
                }),
                f("bool", "vel_ned_valid", |r, _, _| b(r.get("valid") == 1.0)),
                // 255 means "not reported": PX4 has no such value, 0 is the honest count.
                f("uint8_t", "satellites_used", |r, _, _| {
                    match r.get("satellites") {
                        s if s >= 255.0 => 0.0,
                        s => s,
                    }
                }),
                // µs since 1970 when the log clock is UTC (a vehicle), 0 (unknown) in a
                // simulation, as PX4 does before the receiver knows the time.
                f("uint64_t", "time_utc_usec", |_, c, _| {
                    if c.utc { (c.t_ns / 1000) as f64 } else { 0.0 }
                }),
            ],
        },
        // vehicle_attitude ← estimator.1 (quaternion body FRD → NED, scalar first: PX4's).
        Px4Topic {
            topic: "vehicle_attitude",
            multi_id: 0,
            stream: "estimator",
            index: 1,
            needs: &["qw", "qx", "qy", "qz"],
            emit: Emit::Always,
            fields: vec![a("float", "q", 4, |r, _, i| {
                r.get(["qw", "qx", "qy", "qz"][i])
            })],
        },
        // vehicle_local_position ← estimator.1 (NED from home; PX4's origin is EKF2's).
        Px4Topic {
            topic: "vehicle_local_position",
            multi_id: 0,
            stream: "estimator",
            index: 1,
            needs: &[
                "pn_m", "pe_m", "pd_m", "vn_m_s", "ve_m_s", "vd_m_s", "yaw_rad", "healthy",
            ],
            emit: Emit::Always,
            fields: vec![
                f("bool", "xy_valid", |r, _, _| b(r.get("healthy") == 1.0)),
                f("bool", "z_valid", |r, _, _| b(r.get("healthy") == 1.0)),
                f("bool", "v_xy_valid", |r, _, _| b(r.get("healthy") == 1.0)),
                f("bool", "v_z_valid", |r, _, _| b(r.get("healthy") == 1.0)),
                f("float", "x", |r, _, _| r.get("pn_m")),
                f("float", "y", |r, _, _| r.get("pe_m")),
                f("float", "z", |r, _, _| r.get("pd_m")),
                f("float", "vx", |r, _, _| r.get("vn_m_s")),
                f("float", "vy", |r, _, _| r.get("ve_m_s")),
                f("float", "vz", |r, _, _| r.get("vd_m_s")),
                f("float", "heading", |r, _, _| r.get("yaw_rad")),
                f("bool", "xy_global", |_, c, _| b(c.frame.is_some())),
                f("bool", "z_global", |_, c, _| b(c.frame.is_some())),
                f("double", "ref_lat", |_, c, _| {
                    home(c).map_or(NAN, |h| h.latitude_deg)
                }),
                f("double", "ref_lon", |_, c, _| {
                    home(c).map_or(NAN, |h| h.longitude_deg)
                }),
                f("float", "ref_alt", |_, c, _| {
                    home(c).map_or(NAN, |h| h.altitude_m)
                }),
            ],
        },
        // vehicle_global_position ← estimator.1 placed at home (WGS-84 deg, m AMSL).
        Px4Topic {
            topic: "vehicle_global_position",
            multi_id: 0,
            stream: "estimator",
            index: 1,
            needs: &["pn_m", "pe_m", "pd_m"],
            emit: Emit::Always,
            fields: vec![
                f("double", "lat", |r, c, _| {
                    geodetic(r, c).map_or(NAN, |g| g.latitude_deg)
                }),
                f("double", "lon", |r, c, _| {
                    geodetic(r, c).map_or(NAN, |g| g.longitude_deg)
                }),
                f("float", "alt", |r, c, _| {
                    geodetic(r, c).map_or(NAN, |g| g.altitude_m)
                }),
            ],
        },
        // actuator_outputs ← servo.2: what the computer commanded, normalised ([-1, 1],
        // throttle [0, 1]) as PX4's actuator_outputs_sim: aileron, elevator, throttle, rudder.
        Px4Topic {
            topic: "actuator_outputs",
            multi_id: 0,
            stream: "servo",
            index: 2,
            needs: &["aileron_cmd", "elevator_cmd", "throttle_cmd", "rudder_cmd"],
            emit: Emit::Always,
            fields: vec![
                f("uint32_t", "noutputs", |_, _, _| 4.0),
                a("float", "output", 16, |r, _, i| match i {
                    0..4 => r.get(["aileron_cmd", "elevator_cmd", "throttle_cmd", "rudder_cmd"][i]),
                    _ => 0.0,
                }),
            ],
        },
        // input_rc ← servo.1: the pilot's receiver channels as the board measured them (µs).
        Px4Topic {
            topic: "input_rc",
            multi_id: 0,
            stream: "servo",
            index: 1,
            needs: &["ch1_us", "ch8_us"],
            emit: Emit::Always,
            fields: vec![
                f("uint8_t", "channel_count", |_, _, _| 8.0),
                a("uint16_t", "values", 18, |r, _, i| match i {
                    0..8 => r.get(
                        [
                            "ch1_us", "ch2_us", "ch3_us", "ch4_us", "ch5_us", "ch6_us", "ch7_us",
                            "ch8_us",
                        ][i],
                    ),
                    _ => 0.0,
                }),
            ],
        },
        // battery_status ← servo.1: instance 0 the avionics battery, 1 the servo battery.
        Px4Topic {
            topic: "battery_status",
            multi_id: 0,
            stream: "servo",
            index: 1,
            needs: &["batt_avionics_v"],
            emit: Emit::Always,
            fields: vec![
                f("bool", "connected", |r, _, _| {
                    b(r.get("batt_avionics_v") > 0.0)
                }),
                f("float", "voltage_v", |r, _, _| r.get("batt_avionics_v")),
                // PX4: -1 when unknown; the board measures no current or charge.
                f("float", "current_a", |_, _, _| -1.0),
                f("float", "remaining", |_, _, _| -1.0),
                f("uint8_t", "id", |_, _, _| 1.0),
            ],
        },
        Px4Topic {
            topic: "battery_status",
            multi_id: 1,
            stream: "servo",
            index: 1,
            needs: &["batt_servo_v"],
            emit: Emit::Always,
            fields: vec![
                f(
                    "bool",
                    "connected",
                    |r, _, _| b(r.get("batt_servo_v") > 0.0),
                ),
                f("float", "voltage_v", |r, _, _| r.get("batt_servo_v")),
                f("float", "current_a", |_, _, _| -1.0),
                f("float", "remaining", |_, _, _| -1.0),
                f("uint8_t", "id", |_, _, _| 2.0),
            ],
        },
        // vehicle_status ← control.1: the mode flown as PX4's nav_state.
        Px4Topic {
            topic: "vehicle_status",
            multi_id: 0,
            stream: "control",
            index: 1,
            needs: &["mode", "reason"],
            emit: Emit::OnChange(1.0),
            fields: vec![f("uint8_t", "nav_state", |r, _, _| nav_state(r))],
        },
        // vehicle_attitude_setpoint ← control.1 when the attitude loops ran (stabilise, auto).
        // Our lateral loop commands a course, not a yaw: yaw_body is that course (rad).
        Px4Topic {
            topic: "vehicle_attitude_setpoint",
            multi_id: 0,
            stream: "control",
            index: 1,
            needs: &["roll_c_rad", "pitch_c_rad", "course_c_rad", "throttle"],
            emit: Emit::IfFinite("roll_c_rad"),
            fields: vec![
                f("float", "roll_body", |r, _, _| r.get("roll_c_rad")),
                f("float", "pitch_body", |r, _, _| r.get("pitch_c_rad")),
                f("float", "yaw_body", |r, _, _| r.get("course_c_rad")),
                a("float", "q_d", 4, |r, _, i| {
                    let yaw = r.get("course_c_rad");
                    let yaw = if yaw.is_finite() { yaw } else { 0.0 };
                    quaternion(r.get("roll_c_rad"), r.get("pitch_c_rad"), yaw)[i]
                }),
                // Fixed wing: thrust_body[0] is the throttle demand.
                a("float", "thrust_body", 3, |r, _, i| match i {
                    0 => r.get("throttle"),
                    _ => 0.0,
                }),
            ],
        },
        // tecs_status ← control.1 in auto: the altitude (AMSL) and airspeed targets.
        Px4Topic {
            topic: "tecs_status",
            multi_id: 0,
            stream: "control",
            index: 1,
            needs: &["alt_c_m", "speed_c_m_s"],
            emit: Emit::IfFinite("alt_c_m"),
            fields: vec![
                f("float", "altitude_sp", |r, c, _| {
                    home(c).map_or(NAN, |h| h.altitude_m + r.get("alt_c_m"))
                }),
                f("float", "true_airspeed_sp", |r, _, _| r.get("speed_c_m_s")),
                f("float", "true_airspeed_filtered", |r, _, _| {
                    r.get("speed_m_s")
                }),
            ],
        },
        // Simulator ground truth ← truth.1 (NED from the start point, 3-2-1 attitude).
        Px4Topic {
            topic: "vehicle_attitude_groundtruth",
            multi_id: 0,
            stream: "truth",
            index: 1,
            needs: &["roll_rad", "pitch_rad", "yaw_rad"],
            emit: Emit::Always,
            fields: vec![a("float", "q", 4, |r, _, i| {
                quaternion(r.get("roll_rad"), r.get("pitch_rad"), r.get("yaw_rad"))[i]
            })],
        },
        Px4Topic {
            topic: "vehicle_local_position_groundtruth",
            multi_id: 0,
            stream: "truth",
            index: 1,
            needs: &[
                "north_m", "east_m", "down_m", "vn_m_s", "ve_m_s", "vd_m_s", "yaw_rad",
            ],
            emit: Emit::Always,
            fields: vec![
                f("float", "x", |r, _, _| r.get("north_m")),
                f("float", "y", |r, _, _| r.get("east_m")),
                f("float", "z", |r, _, _| r.get("down_m")),
                f("float", "vx", |r, _, _| r.get("vn_m_s")),
                f("float", "vy", |r, _, _| r.get("ve_m_s")),
                f("float", "vz", |r, _, _| r.get("vd_m_s")),
                f("float", "heading", |r, _, _| r.get("yaw_rad")),
            ],
        },
    ]
}

impl Px4Field {
    fn format(&self) -> String {
        match self.len {
            1 => format!("{} {}", self.ty, self.name),
            n => format!("{}[{n}] {}", self.ty, self.name),
        }
    }
}

/// Appends `value` as a ULog field of type `ty`: floats as they are (NaN stays NaN),
/// integers rounded toward zero and saturated (NaN → 0), booleans 1 for any non-zero.
fn put(out: &mut Vec<u8>, ty: &str, value: f64) {
    match ty {
        "float" => out.extend_from_slice(&(value as f32).to_le_bytes()),
        "double" => out.extend_from_slice(&value.to_le_bytes()),
        "bool" => out.push(u8::from(value != 0.0 && !value.is_nan())),
        "int8_t" => out.extend_from_slice(&(value as i8).to_le_bytes()),
        "uint8_t" => out.push(value as u8),
        "int16_t" => out.extend_from_slice(&(value as i16).to_le_bytes()),
        "uint16_t" => out.extend_from_slice(&(value as u16).to_le_bytes()),
        "int32_t" => out.extend_from_slice(&(value as i32).to_le_bytes()),
        "uint32_t" => out.extend_from_slice(&(value as u32).to_le_bytes()),
        "int64_t" => out.extend_from_slice(&(value as i64).to_le_bytes()),
        _ => out.extend_from_slice(&(value as u64).to_le_bytes()),
    }
}

// ---------------------------------------------------------------------------------------------
// The ULog file.

/// Syslog levels as ULog's logged messages carry them (ASCII digits, as PX4 writes them).
#[derive(Clone, Copy, PartialEq)]
enum Level {
    Warning,
    Info,
}

impl Level {
    fn byte(self) -> u8 {
        match self {
            Level::Warning => b'4',
            Level::Info => b'6',
        }
    }
}

struct Topic {
    name: String,
    fields: Vec<String>,
}

struct Subscription {
    multi_id: u8,
    topic: usize,
}

/// A ULog file before writing: definitions, then data messages sorted by time.
#[derive(Default)]
struct Ulog {
    info: Vec<(String, Vec<u8>)>,
    parameters: Vec<(String, f32)>,
    topics: Vec<Topic>,
    subscriptions: Vec<Subscription>,
    /// Data-section messages, encoded whole, with (timestamp µs, sequence) to sort on.
    messages: Vec<u8>,
    order: Vec<(u64, u64, usize, usize)>,
}

impl Ulog {
    fn topic(&mut self, name: &str, fields: Vec<String>) -> usize {
        if let Some(t) = self.topics.iter().position(|t| t.name == name) {
            return t;
        }
        self.topics.push(Topic {
            name: name.to_string(),
            fields,
        });
        self.topics.len() - 1
    }

    fn subscribe(&mut self, topic: usize, multi_id: u8) -> u16 {
        self.subscriptions.push(Subscription { multi_id, topic });
        u16::try_from(self.subscriptions.len() - 1).unwrap_or(u16::MAX)
    }

    fn info_text(&mut self, key: &str, value: &str) {
        self.info.push((
            format!("char[{}] {key}", value.len()),
            value.as_bytes().to_vec(),
        ));
    }

    /// Adds a data-section message `kind` whose body is `parts` joined, at `timestamp_us`.
    fn push(&mut self, timestamp_us: u64, kind: u8, parts: &[&[u8]]) {
        let start = self.messages.len();
        let len: usize = parts.iter().map(|p| p.len()).sum();
        // Bodies are at most a format's fields (< 2 KiB) or a short text.
        let size = u16::try_from(len).unwrap_or(u16::MAX);
        self.messages.extend_from_slice(&size.to_le_bytes());
        self.messages.push(kind);
        let mut left = usize::from(size);
        for part in parts {
            let take = part.len().min(left);
            self.messages
                .extend_from_slice(part.get(..take).unwrap_or(&[]));
            left -= take;
        }
        let sequence = self.order.len() as u64;
        self.order
            .push((timestamp_us, sequence, start, self.messages.len()));
    }

    fn data(&mut self, msg_id: u16, timestamp_us: u64, payload: &[u8]) {
        self.push(
            timestamp_us,
            b'D',
            &[&msg_id.to_le_bytes(), &timestamp_us.to_le_bytes(), payload],
        );
    }

    fn log(&mut self, timestamp_us: u64, level: Level, text: &str) {
        self.push(
            timestamp_us,
            b'L',
            &[
                &[level.byte()],
                &timestamp_us.to_le_bytes(),
                text.as_bytes(),
            ],
        );
    }

    fn dropout(&mut self, timestamp_us: u64, duration_ms: u64) {
        let ms = u16::try_from(duration_ms).unwrap_or(u16::MAX);
        self.push(timestamp_us, b'O', &[&ms.to_le_bytes()]);
    }

    fn parameter_change(&mut self, timestamp_us: u64, name: &str, value: f32) {
        let body = key_value(&format!("float {name}"), &value.to_le_bytes());
        self.push(timestamp_us, b'P', &[&body]);
    }

    fn write(mut self, out: &mut impl Write) -> io::Result<()> {
        let mut header = Vec::with_capacity(16);
        header.extend_from_slice(&ULOG_MAGIC);
        header.push(ULOG_VERSION);
        header.extend_from_slice(&0u64.to_le_bytes());
        out.write_all(&header)?;
        // Flag bits: no compatible or incompatible flags, no appended data.
        message(out, b'B', &[0u8; 40])?;
        for (key, value) in &self.info {
            message(out, b'I', &key_value(key, value))?;
        }
        for (name, value) in &self.parameters {
            message(
                out,
                b'P',
                &key_value(&format!("float {name}"), &value.to_le_bytes()),
            )?;
        }
        for topic in &self.topics {
            let text = format!("{}:{};", topic.name, topic.fields.join(";"));
            message(out, b'F', text.as_bytes())?;
        }
        for (id, s) in self.subscriptions.iter().enumerate() {
            let mut body = vec![s.multi_id];
            body.extend_from_slice(&u16::try_from(id).unwrap_or(u16::MAX).to_le_bytes());
            if let Some(topic) = self.topics.get(s.topic) {
                body.extend_from_slice(topic.name.as_bytes());
            }
            message(out, b'A', &body)?;
        }
        // One clock for every stream: messages in time order (file order within a time).
        self.order.sort_unstable_by_key(|&(t, seq, _, _)| (t, seq));
        for &(_, _, start, end) in &self.order {
            out.write_all(self.messages.get(start..end).unwrap_or(&[]))?;
        }
        Ok(())
    }
}

fn key_value(key: &str, value: &[u8]) -> Vec<u8> {
    let mut body = vec![u8::try_from(key.len()).unwrap_or(u8::MAX)];
    body.extend_from_slice(key.as_bytes().get(..usize::from(body[0])).unwrap_or(&[]));
    body.extend_from_slice(value);
    body
}

fn message(out: &mut impl Write, kind: u8, body: &[u8]) -> io::Result<()> {
    let size = u16::try_from(body.len()).map_err(|_| io::Error::other("ULog message too long"))?;
    out.write_all(&size.to_le_bytes())?;
    out.write_all(&[kind])?;
    out.write_all(body)
}

/// Formats whose records are parameters: (stream, index, name prefix). control.2 holds the
/// `control.*` parameters at start and after every change (`docs/log-streams.md`).
const PARAMETER_FORMATS: &[(&str, u8, &str)] = &[("control", 2, "control.")];

fn build(flight: &Flight, flight_id: &str, options: &UlogOptions) -> Ulog {
    let start_ns = flight.start_ns().unwrap_or(0);
    let us = |t_ns: i64| u64::try_from((t_ns - start_ns) / 1000).unwrap_or(0);
    let mut ulog = Ulog::default();

    // Info: who flew what, and which clock.
    ulog.info_text("sys_name", "skyframe");
    ulog.info_text("ver_sw", options.ver_sw.as_deref().unwrap_or("unknown"));
    ulog.info_text(
        "sys_uuid",
        options.vehicle_id.as_deref().unwrap_or("unknown"),
    );
    ulog.info_text("skyframe_flight", flight_id);
    // Our log TIME is UTC (a vehicle's wall clock) or a simulation's clock: no local offset.
    ulog.info
        .push(("int32_t time_ref_utc".into(), 0i32.to_le_bytes().to_vec()));
    ulog.info.push((
        "int64_t skyframe_time_origin_ns".into(),
        start_ns.to_le_bytes().to_vec(),
    ));

    // The skyframe topics: every layout, its bytes as they are.
    let mut subscription_of_layout: Vec<Option<u16>> = vec![None; flight.layouts.len()];
    let mut multi_ids: BTreeMap<String, u8> = BTreeMap::new();
    for (l, layout) in flight.layouts.iter().enumerate() {
        let mut name = skyframe_topic_name(layout);
        let mut fields = vec!["uint64_t timestamp".to_string()];
        fields.extend(
            layout
                .types()
                .zip(field_names(&layout.columns))
                .map(|(ty, n)| format!("{} {n}", ulog_type(ty))),
        );
        // A name shared by several streams (device status) is one topic with a multi_id
        // per stream, which needs one format; a differing layout gets its own name.
        if let Some(t) = ulog.topics.iter().find(|t| t.name == name) {
            if t.fields != fields {
                name = format!("{name}_{}", identifier(&layout.stream).to_ascii_lowercase());
            }
        }
        let topic = ulog.topic(&name, fields);
        let multi = multi_ids.entry(name.clone()).or_insert(0);
        let multi_id = *multi;
        *multi = multi.saturating_add(1);
        if multi_id > 0 || SKYFRAME_TOPICS.iter().filter(|s| s.2 == name).count() > 1 {
            ulog.info_text(&format!("{name}_{multi_id}"), &layout.stream);
        }
        subscription_of_layout[l] = Some(ulog.subscribe(topic, multi_id));
    }
    for rec in &flight.records {
        if let Some(Some(id)) = subscription_of_layout.get(rec.layout) {
            ulog.data(*id, us(rec.t_ns), flight.bytes(rec));
        }
    }

    let frame = home_frame(flight);
    let utc = start_ns >= 1_000_000_000 * 1_000_000_000;
    if options.px4_topics {
        px4_messages(flight, &mut ulog, frame, utc, &us);
    }
    parameters(flight, &mut ulog, &us);
    events(flight, &mut ulog, &us);
    ulog
}

/// The first valid GPS fix: the estimator's home (unless one was configured).
fn home_frame(flight: &Flight) -> Option<LocalFrame> {
    let layout = flight.layout_of("gps", 1)?;
    let l = flight.layouts.get(layout)?;
    let mut values = Vec::new();
    for rec in flight.records_of(layout) {
        flight.values(rec, &mut values);
        let row = Row {
            layout: l,
            values: &values,
        };
        if row.get("valid") == 1.0 {
            let frame = LocalFrame::new(GeoPoint {
                latitude_deg: row.get("lat_deg"),
                longitude_deg: row.get("lon_deg"),
                altitude_m: row.get("alt_m"),
            });
            if frame.is_some() {
                return frame;
            }
        }
    }
    None
}

fn px4_messages(
    flight: &Flight,
    ulog: &mut Ulog,
    frame: Option<LocalFrame>,
    utc: bool,
    us: &impl Fn(i64) -> u64,
) {
    let mut values = Vec::new();
    let mut payload = Vec::new();
    for topic in px4_topics() {
        let Some(source) = flight.layout_of(topic.stream, topic.index) else {
            continue;
        };
        let Some(layout) = flight.layouts.get(source) else {
            continue;
        };
        if topic.needs.iter().any(|c| layout.column(c).is_none()) {
            continue;
        }
        let fields = std::iter::once("uint64_t timestamp".to_string())
            .chain(topic.fields.iter().map(Px4Field::format))
            .collect();
        let t = ulog.topic(topic.topic, fields);
        let id = ulog.subscribe(t, topic.multi_id);
        let mut last: Option<(Vec<u8>, i64)> = None;
        // Every layout of the source index (a redefinition keeps the columns' meaning).
        let sources: Vec<usize> = (0..flight.layouts.len())
            .filter(|&l| {
                flight
                    .layouts
                    .get(l)
                    .is_some_and(|x| x.stream == topic.stream && x.index == topic.index)
            })
            .collect();
        for rec in flight
            .records
            .iter()
            .filter(|r| sources.contains(&r.layout))
        {
            let Some(layout) = flight.layouts.get(rec.layout) else {
                continue;
            };
            flight.values(rec, &mut values);
            let row = Row {
                layout,
                values: &values,
            };
            let context = Context {
                frame,
                utc,
                t_ns: rec.t_ns,
            };
            if let Emit::IfFinite(column) = topic.emit {
                if !row.get(column).is_finite() {
                    continue;
                }
            }
            payload.clear();
            for field in &topic.fields {
                for i in 0..field.len {
                    put(&mut payload, field.ty, (field.value)(&row, &context, i));
                }
            }
            if let Emit::OnChange(every_s) = topic.emit {
                if let Some((previous, t)) = &last {
                    let due = (rec.t_ns - t) as f64 >= every_s * 1e9;
                    if *previous == payload && !due {
                        continue;
                    }
                }
                last = Some((payload.clone(), rec.t_ns));
            }
            ulog.data(id, us(rec.t_ns), &payload);
        }
    }
}

/// The parameters in force at start (the first record of each parameter format) and every
/// change after, as ULog parameter messages, each with an info-level logged message.
fn parameters(flight: &Flight, ulog: &mut Ulog, us: &impl Fn(i64) -> u64) {
    let mut values = Vec::new();
    for &(stream, index, prefix) in PARAMETER_FORMATS {
        let mut current: BTreeMap<String, f32> = BTreeMap::new();
        let mut first = true;
        let records: Vec<&Rec> = flight
            .records
            .iter()
            .filter(|r| {
                flight
                    .layouts
                    .get(r.layout)
                    .is_some_and(|l| l.stream == stream && l.index == index)
            })
            .collect();
        for rec in records {
            let Some(layout) = flight.layouts.get(rec.layout) else {
                continue;
            };
            flight.values(rec, &mut values);
            for (column, &value) in layout.columns.iter().zip(&values) {
                let name = format!("{prefix}{column}");
                let value = value as f32;
                if first {
                    ulog.parameters.push((name.clone(), value));
                } else if current
                    .get(&name)
                    .is_none_or(|v| v.to_bits() != value.to_bits())
                {
                    ulog.parameter_change(us(rec.t_ns), &name, value);
                    let old = current.get(&name).map_or("unset".into(), |v| v.to_string());
                    ulog.log(
                        us(rec.t_ns),
                        Level::Info,
                        &format!("parameter {name} changed: {old} -> {value}"),
                    );
                }
                current.insert(name, value);
            }
            first = false;
        }
    }
}

/// The flight's events as logged messages: reader problems (warnings, with a dropout where
/// records were lost), logging pauses, mode changes, estimator phase/health changes, devices
/// going stale, the start-up timer check's verdict.
fn events(flight: &Flight, ulog: &mut Ulog, us: &impl Fn(i64) -> u64) {
    for damage in &flight.damage {
        let at = damage.after_ns.or(damage.before_ns).unwrap_or(0);
        ulog.log(us(at), Level::Warning, &damage.line);
        if damage.lost_data {
            if let (Some(after), Some(before)) = (damage.after_ns, damage.before_ns) {
                ulog.dropout(
                    us(after),
                    u64::try_from((before - after) / 1_000_000).unwrap_or(0),
                );
            }
        }
    }
    for stream in &flight.streams {
        // End Data then Begin Data: the task stopped logging (a reset), its records are
        // missing for that long.
        for &end in &stream.ends_ns {
            if let Some(&begin) = stream.begins_ns.iter().find(|&&b| b > end) {
                let ms = u64::try_from((begin - end) / 1_000_000).unwrap_or(0);
                ulog.log(
                    us(end),
                    Level::Warning,
                    &format!("{}: logging stopped for {ms} ms", stream.name),
                );
                ulog.dropout(us(end), ms);
            }
        }
    }
    let mut values = Vec::new();
    // (stream, index, the columns watched, what a change says and how loud). A state at the
    // start is logged too, except a device that is fine (no news).
    type Describe = fn(&Row) -> (Level, String);
    let watched: &[(&str, u8, &[&str], Describe)] = &[
        ("control", 1, &["mode", "reason"], |r| {
            let mode = match r.get("mode") as u8 {
                0 => "MANUAL",
                1 => "STABILISE",
                2 => "AUTO",
                _ => "unknown",
            };
            let reason = match r.get("reason") as u8 {
                0 => "requested",
                1 => "pilot switch on manual",
                2 => "no report from the servo board",
                3 => "estimator unhealthy",
                4 => "auto without a mission: holding course and altitude",
                _ => "unknown reason",
            };
            // Forced out of the requested mode: worth a warning.
            let forced = matches!(r.get("reason") as u8, 2 | 3);
            let level = if forced { Level::Warning } else { Level::Info };
            (level, format!("mode {mode} ({reason})"))
        }),
        ("estimator", 2, &["phase", "healthy", "reason"], |r| {
            let phase = match r.get("phase") as u8 {
                0 => "aligning",
                1 => "awaiting heading",
                2 => "running",
                _ => "unknown phase",
            };
            let reason = match r.get("reason") as u8 {
                0 => "ok",
                1 => "aligning",
                2 => "awaiting heading",
                3 => "no IMU",
                4 => "attitude uncertain",
                5 => "position uncertain",
                6 => "no GPS",
                7 => "reconverging after a reset",
                _ => "unknown reason",
            };
            if r.get("healthy") == 1.0 {
                (
                    Level::Info,
                    format!("estimator {phase}, healthy ({reason})"),
                )
            } else {
                (
                    Level::Warning,
                    format!("estimator {phase}, unhealthy ({reason})"),
                )
            }
        }),
        ("imu", 3, &["stale"], |r| stale("imu", r)),
        ("gps", 2, &["stale"], |r| stale("gps", r)),
        ("servo", 3, &["stale"], |r| stale("servo", r)),
        ("executive", 2, &["over_margin"], |r| {
            let late = r.get("over_margin") > 0.0;
            let text = format!(
                "timer check: wake-up latency p99 {} us, max {} us, margin {} us{}",
                r.get("wakeup_latency_p99_us"),
                r.get("wakeup_latency_max_us"),
                r.get("margin_us"),
                if late {
                    ": wake-ups later than the margin"
                } else {
                    ""
                }
            );
            (if late { Level::Warning } else { Level::Info }, text)
        }),
    ];
    for &(stream, index, columns, describe) in watched {
        let mut last: Option<Vec<u64>> = None;
        for rec in &flight.records {
            let Some(layout) = flight.layouts.get(rec.layout) else {
                continue;
            };
            if layout.stream != stream || layout.index != index {
                continue;
            }
            if columns.iter().any(|c| layout.column(c).is_none()) {
                continue;
            }
            flight.values(rec, &mut values);
            let row = Row {
                layout,
                values: &values,
            };
            let now: Vec<u64> = columns.iter().map(|c| row.get(c).to_bits()).collect();
            if last.as_ref() == Some(&now) {
                continue;
            }
            let (level, text) = describe(&row);
            let device_fine_at_start =
                last.is_none() && columns == ["stale"] && level == Level::Info;
            if !device_fine_at_start {
                ulog.log(us(rec.t_ns), level, &text);
            }
            last = Some(now);
        }
    }
}

fn stale(device: &str, r: &Row) -> (Level, String) {
    if r.get("stale") > 0.0 {
        (Level::Warning, format!("{device}: device stale"))
    } else {
        (Level::Info, format!("{device}: device reporting again"))
    }
}
