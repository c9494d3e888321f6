//! PX4 ULog → [`FlightLog`], through the PX4 project's own parser crate (`px4-ulog`).
//!
//! The crate is fed one message at a time, cut at the ULog framing (a 16-byte header, then
//! `u16 size, u8 type, payload`), so an error names the byte offset of the message it is in.
//! Fields are read by name with bounds-checked slices: a field missing from this firmware's
//! topic, or of another type, is `None`, never a panic.
//!
//! Topics used (instance 0): `sensor_combined` (mean rates over `gyro_integral_dt`) or else
//! `sensor_gyro` + `sensor_accel` (samples), `vehicle_gps_position` or else `sensor_gps`,
//! `vehicle_attitude`, `vehicle_global_position` or else `vehicle_local_position` with its
//! reference point, `airspeed` / `airspeed_validated`, `vehicle_magnetometer` (counted).

use std::collections::HashMap;

use px4_ulog::stream_parser::LogParser;
use px4_ulog::stream_parser::model::{DataMessage, FlattenedFieldType};

use super::flightlog::{
    AttitudeRecord, FlightLog, GpsRecord, NavRecord, error_at, rates_to_increments,
};

const HEADER: [u8; 7] = *b"ULog\x01\x12\x35";

/// True if `bytes` starts like a ULog file.
pub fn looks_like_ulog(bytes: &[u8]) -> bool {
    bytes.starts_with(&HEADER)
}

/// A topic's fields: name → (type, offset into the data message).
type Fields = HashMap<String, (FlattenedFieldType, usize)>;

/// The fields of the topics replay reads, per (topic, message id), as the data messages
/// arrive.
#[derive(Default)]
struct Collected {
    formats: HashMap<u16, (String, u8, Fields)>,
    rows: HashMap<String, Vec<Row>>,
}

/// One data message's fields that replay reads, by name.
type Row = HashMap<&'static str, f64>;

/// A GPS fix's fields, under either of PX4's topic names (older and newer field names both).
const GPS_FIELDS: &[&str] = &[
    "timestamp",
    "lat",
    "lon",
    "alt",
    "latitude_deg",
    "longitude_deg",
    "altitude_msl_m",
    "vel_n_m_s",
    "vel_e_m_s",
    "vel_d_m_s",
    "vel_ned_valid",
    "fix_type",
    "eph",
    "epv",
    "hdop",
    "satellites_used",
];

const WANTED: &[(&str, &[&str])] = &[
    (
        "sensor_combined",
        &[
            "timestamp",
            "gyro_rad[0]",
            "gyro_rad[1]",
            "gyro_rad[2]",
            "gyro_integral_dt",
            "accelerometer_m_s2[0]",
            "accelerometer_m_s2[1]",
            "accelerometer_m_s2[2]",
            "accelerometer_integral_dt",
        ],
    ),
    (
        "sensor_gyro",
        &["timestamp", "timestamp_sample", "x", "y", "z"],
    ),
    (
        "sensor_accel",
        &["timestamp", "timestamp_sample", "x", "y", "z"],
    ),
    ("vehicle_gps_position", GPS_FIELDS),
    ("sensor_gps", GPS_FIELDS),
    (
        "vehicle_attitude",
        &["timestamp", "q[0]", "q[1]", "q[2]", "q[3]"],
    ),
    (
        "vehicle_global_position",
        &["timestamp", "lat", "lon", "alt"],
    ),
    (
        "vehicle_local_position",
        &[
            "timestamp",
            "x",
            "y",
            "z",
            "vx",
            "vy",
            "vz",
            "xy_valid",
            "z_valid",
            "v_xy_valid",
            "v_z_valid",
            "xy_global",
            "z_global",
            "ref_lat",
            "ref_lon",
            "ref_alt",
        ],
    ),
    ("airspeed", &["timestamp", "indicated_airspeed_m_s"]),
    (
        "airspeed_validated",
        &["timestamp", "equivalent_airspeed_m_s"],
    ),
    ("vehicle_magnetometer", &["timestamp"]),
];

fn field(data: &[u8], ty: &FlattenedFieldType, offset: usize) -> Option<f64> {
    use FlattenedFieldType as T;
    let bytes = |n: usize| data.get(offset..offset.checked_add(n)?);
    let v = match ty {
        T::Int8 => f64::from(i8::from_le_bytes(bytes(1)?.try_into().ok()?)),
        T::UInt8 | T::Bool | T::Char => f64::from(*bytes(1)?.first()?),
        T::Int16 => f64::from(i16::from_le_bytes(bytes(2)?.try_into().ok()?)),
        T::UInt16 => f64::from(u16::from_le_bytes(bytes(2)?.try_into().ok()?)),
        T::Int32 => f64::from(i32::from_le_bytes(bytes(4)?.try_into().ok()?)),
        T::UInt32 => f64::from(u32::from_le_bytes(bytes(4)?.try_into().ok()?)),
        T::Int64 => i64::from_le_bytes(bytes(8)?.try_into().ok()?) as f64,
        T::UInt64 => u64::from_le_bytes(bytes(8)?.try_into().ok()?) as f64,
        T::Float => f64::from(f32::from_le_bytes(bytes(4)?.try_into().ok()?)),
        T::Double => f64::from_le_bytes(bytes(8)?.try_into().ok()?),
    };
    Some(v)
}

impl Collected {
    fn take(&mut self, msg: &DataMessage<'_>) {
        let id = msg.msg_id;
        // A message id's format is fixed for the file: its fields are looked up once.
        let (name, multi, fields) = self.formats.entry(id).or_insert_with(|| {
            let format = msg.flattened_format;
            let fields = format
                .field_iter()
                .map(|f| {
                    (
                        f.flattened_field_name.clone(),
                        (f.field_type.clone(), usize::from(f.offset)),
                    )
                })
                .collect();
            (
                format.message_name().to_string(),
                msg.multi_id.value(),
                fields,
            )
        });
        if *multi != 0 {
            return;
        }
        let Some((topic, wanted)) = WANTED.iter().find(|(t, _)| t == name) else {
            return;
        };
        let row: Row = wanted
            .iter()
            .filter_map(|&w| {
                let (ty, offset) = fields.get(w)?;
                Some((w, field(msg.data, ty, *offset)?))
            })
            .collect();
        self.rows.entry((*topic).to_string()).or_default().push(row);
    }
}

/// Reads a ULog file's bytes; `path` only names it in messages.
pub fn read(path: &str, bytes: &[u8]) -> Result<FlightLog, String> {
    if bytes.len() < 16 || !looks_like_ulog(bytes) {
        return Err(error_at(path, 0, "not a ULog file (no ULog header)"));
    }
    let mut collected = Collected::default();
    let mut warnings = Vec::new();
    {
        let mut callback = |msg: &DataMessage<'_>| collected.take(msg);
        let mut parser = LogParser::default();
        parser.set_data_message_callback(&mut callback);
        let header = bytes.get(..16).unwrap_or_default();
        parser
            .consume_bytes(header)
            .map_err(|e| error_at(path, 0, e))?;
        let mut at = 16usize;
        let mut guard = Guard::default();
        while at < bytes.len() {
            let Some(&[lo, hi, _]) = bytes.get(at..at + 3) else {
                warnings.push(error_at(
                    path,
                    at,
                    "truncated message header at the end: ignored",
                ));
                break;
            };
            let end = at + 3 + usize::from(u16::from_le_bytes([lo, hi]));
            let Some(message) = bytes.get(at..end) else {
                warnings.push(error_at(path, at, "truncated last message: ignored"));
                break;
            };
            if let Err(e) = guard
                .check(message)
                .and_then(|()| parser.consume_bytes(message).map_err(|e| e.to_string()))
            {
                // A broken record inside the data section after good data: keep what was
                // read (as PX4's tools do) but say where it stopped; before the data,
                // nothing is usable.
                if parser.in_data() && !collected.rows.is_empty() {
                    warnings.push(error_at(path, at, format!("{e}; the rest ignored")));
                    break;
                }
                return Err(error_at(path, at, e));
            }
            at = end;
        }
    }
    Ok(assemble(&collected.rows, warnings))
}

/// What `px4-ulog` 0.6.1 does not check before it indexes, checked here first, so a damaged
/// file is an error, not a panic (found by the `flight_log` fuzz target):
/// - an info (`I`), parameter (`P`) or add-logged (`A`) message shorter than its own key
///   length or fixed fields;
/// - message formats (`F`) that nest other formats in arrays so deep that flattening them
///   would take billions of steps (a format of zero fields repeated 65535 × 65535 times).
#[derive(Default)]
struct Guard {
    /// Each format's fields: (type name, repeat count).
    formats: HashMap<String, Vec<(String, u64)>>,
    /// The formats were sized (at the first message after the definitions).
    sized: bool,
}

/// Flattening work a log may ask for: far beyond any real log's few thousand fields.
const MAX_FLATTENED_FIELDS: u64 = 1_000_000;

const PRIMITIVES: &[&str] = &[
    "int8_t", "uint8_t", "int16_t", "uint16_t", "int32_t", "uint32_t", "int64_t", "uint64_t",
    "float", "double", "bool", "char",
];

impl Guard {
    fn check(&mut self, message: &[u8]) -> Result<(), String> {
        let kind = message.get(2).copied().unwrap_or_default();
        let payload = message.get(3..).unwrap_or_default();
        let first = payload.first().copied().map(usize::from);
        let short = match kind {
            b'I' => first.is_none_or(|k| payload.len() < 1 + k),
            b'P' => first.is_none_or(|k| payload.len() < 1 + k),
            b'A' => payload.len() < 3,
            _ => false,
        };
        if short {
            return Err(format!(
                "'{}' message of {} bytes is shorter than its fields",
                char::from(kind),
                payload.len()
            ));
        }
        if kind == b'F' {
            self.add_format(payload);
        } else if !self.sized && matches!(kind, b'A' | b'D' | b'L' | b'C' | b'O' | b'R' | b'S') {
            self.sized = true;
            let mut memo = HashMap::new();
            let mut total = 0u64;
            for name in self.formats.keys() {
                total = total.saturating_add(self.cost(name, &mut memo, 0));
            }
            if total > MAX_FLATTENED_FIELDS {
                return Err(format!(
                    "the message formats expand to more than {MAX_FLATTENED_FIELDS} fields"
                ));
            }
        }
        Ok(())
    }

    fn add_format(&mut self, payload: &[u8]) {
        let Ok(text) = std::str::from_utf8(payload) else {
            return;
        };
        let Some((name, fields)) = text.split_once(':') else {
            return;
        };
        let fields = fields
            .split(';')
            .filter_map(|f| {
                let (ty, _) = f.split_once(' ')?;
                Some(match ty.split_once('[') {
                    Some((base, n)) => (
                        base.to_string(),
                        n.trim_end_matches(']').parse::<u64>().unwrap_or(u64::MAX),
                    ),
                    None => (ty.to_string(), 1),
                })
            })
            .collect();
        self.formats.insert(name.to_string(), fields);
    }

    /// Steps to flatten `name` (each field visit counts one, arrays times their length);
    /// saturating, and a reference cycle or depth past 64 counts as too much.
    fn cost(&self, name: &str, memo: &mut HashMap<String, u64>, depth: u32) -> u64 {
        if let Some(&c) = memo.get(name) {
            return c;
        }
        if depth > 64 {
            return u64::MAX;
        }
        let Some(fields) = self.formats.get(name) else {
            return 1;
        };
        let mut total = 1u64;
        for (ty, n) in fields {
            let each = if PRIMITIVES.contains(&ty.as_str()) {
                1
            } else {
                self.cost(ty, memo, depth + 1)
            };
            total = total.saturating_add(n.saturating_mul(each.max(1)));
        }
        memo.insert(name.to_string(), total);
        total
    }
}

fn rows<'a>(all: &'a HashMap<String, Vec<Row>>, topic: &str) -> &'a [Row] {
    all.get(topic).map(Vec::as_slice).unwrap_or_default()
}

fn get(row: &Row, name: &str) -> Option<f64> {
    row.get(name).copied().filter(|v| v.is_finite())
}

fn time_us(row: &Row) -> Option<u64> {
    get(row, "timestamp")
        .filter(|t| (0.0..1.8e19).contains(t))
        .map(|t| t as u64)
}

fn assemble(all: &HashMap<String, Vec<Row>>, warnings: Vec<String>) -> FlightLog {
    let mut log = FlightLog {
        format: "PX4 ULog",
        warnings,
        ..FlightLog::default()
    };
    read_imu(all, &mut log);
    read_gps(all, &mut log);
    for row in rows(all, "vehicle_attitude") {
        let q = ["q[0]", "q[1]", "q[2]", "q[3]"].map(|n| get(row, n).unwrap_or(f64::NAN));
        if let Some(t_us) = time_us(row) {
            log.onboard_attitude.push(AttitudeRecord {
                t_us,
                quaternion: q,
            });
        }
    }
    if !log.onboard_attitude.is_empty() {
        log.attitude_source = "vehicle_attitude.q".into();
    }
    read_nav(all, &mut log);
    for (topic, name) in [
        ("airspeed_validated", "equivalent_airspeed_m_s"),
        ("airspeed", "indicated_airspeed_m_s"),
    ] {
        if log.airspeed.is_empty() {
            log.airspeed = rows(all, topic)
                .iter()
                .filter_map(|r| Some((time_us(r)?, get(r, name)?)))
                .collect();
        }
    }
    log.magnetometer_samples = rows(all, "vehicle_magnetometer").len();
    log.normalise();
    log
}

/// A logging dropout longer than this leaves a gap in the IMU instead of one long sample.
const MAX_IMU_GAP_S: f64 = 0.05;

fn read_imu(all: &HashMap<String, Vec<Row>>, log: &mut FlightLog) {
    let combined = rows(all, "sensor_combined");
    if !combined.is_empty() {
        let samples: Vec<_> = combined
            .iter()
            .filter_map(|r| {
                let g = ["gyro_rad[0]", "gyro_rad[1]", "gyro_rad[2]"].map(|n| get(r, n));
                let a = [
                    "accelerometer_m_s2[0]",
                    "accelerometer_m_s2[1]",
                    "accelerometer_m_s2[2]",
                ]
                .map(|n| get(r, n));
                // Current firmware logs the interval as integer microseconds, firmware of
                // 2016-17 as float seconds: no real IMU interval is a microsecond long, so a
                // value below 1 is seconds.
                let interval =
                    get(r, "gyro_integral_dt").map(|v| if v < 1.0 { v } else { v * 1e-6 });
                Some((
                    time_us(r)?,
                    interval,
                    [g[0]?, g[1]?, g[2]?],
                    [a[0]?, a[1]?, a[2]?],
                ))
            })
            .collect();
        log.imu = rates_to_increments(&samples, MAX_IMU_GAP_S);
        log.imu_source = "sensor_combined: gyro_rad and accelerometer_m_s2 are means over \
                          gyro_integral_dt, taken as angle and velocity increments"
            .into();
        return;
    }
    // Separate gyro and accelerometer topics: pair each gyro sample with the accelerometer
    // sample nearest in time (they are published together by the same driver, at the same
    // rate, on the IMUs PX4 logs them for).
    let series = |topic: &str| -> Vec<(u64, [f64; 3])> {
        let mut v: Vec<_> = rows(all, topic)
            .iter()
            .filter_map(|r| {
                let t = get(r, "timestamp_sample")
                    .filter(|t| *t > 0.0)
                    .map(|t| t as u64)
                    .or_else(|| time_us(r))?;
                Some((t, [get(r, "x")?, get(r, "y")?, get(r, "z")?]))
            })
            .collect();
        v.sort_by_key(|s| s.0);
        v
    };
    let gyro = series("sensor_gyro");
    let accel = series("sensor_accel");
    if gyro.is_empty() || accel.is_empty() {
        return;
    }
    let mut j = 0usize;
    let samples: Vec<_> = gyro
        .iter()
        .map(|&(t, w)| {
            while accel.get(j + 1).is_some_and(|a| {
                a.0.abs_diff(t) <= accel.get(j).map_or(u64::MAX, |b| b.0.abs_diff(t))
            }) {
                j += 1;
            }
            let f = accel.get(j).map_or([f64::NAN; 3], |a| a.1);
            (t, None, w, f)
        })
        .collect();
    log.imu = rates_to_increments(&samples, MAX_IMU_GAP_S);
    log.imu_source = "sensor_gyro + sensor_accel: samples held over the interval since the \
                      previous one"
        .into();
}

fn read_gps(all: &HashMap<String, Vec<Row>>, log: &mut FlightLog) {
    for topic in ["vehicle_gps_position", "sensor_gps"] {
        let rows = rows(all, topic);
        if rows.is_empty() {
            continue;
        }
        log.gps = rows
            .iter()
            .filter_map(|r| {
                // PX4 ≥ 1.14 logs degrees as doubles; earlier firmware 1e-7 degrees and mm.
                let lat = get(r, "latitude_deg").or(get(r, "lat").map(|v| v * 1e-7))?;
                let lon = get(r, "longitude_deg").or(get(r, "lon").map(|v| v * 1e-7))?;
                let alt = get(r, "altitude_msl_m").or(get(r, "alt").map(|v| v * 1e-3))?;
                let vel_ok = get(r, "vel_ned_valid").is_none_or(|v| v != 0.0);
                let v = |n| get(r, n).filter(|_| vel_ok);
                Some(GpsRecord {
                    t_us: time_us(r)?,
                    fix_3d: get(r, "fix_type").is_some_and(|f| f >= 3.0),
                    latitude_deg: lat,
                    longitude_deg: lon,
                    altitude_m: alt,
                    velocity_ned_m_s: [v("vel_n_m_s"), v("vel_e_m_s"), v("vel_d_m_s")],
                    horizontal_accuracy_m: get(r, "eph").filter(|e| *e > 0.0),
                    vertical_accuracy_m: get(r, "epv").filter(|e| *e > 0.0),
                    hdop: get(r, "hdop").filter(|e| *e > 0.0),
                    satellites: get(r, "satellites_used").map(|s| s.clamp(0.0, 255.0) as u8),
                })
            })
            .collect();
        log.gps_source = format!("{topic} (timestamp: when the autopilot received the fix)");
        return;
    }
}

fn read_nav(all: &HashMap<String, Vec<Row>>, log: &mut FlightLog) {
    let local = rows(all, "vehicle_local_position");
    let global = rows(all, "vehicle_global_position");
    let velocities: Vec<(u64, [f64; 3])> = local
        .iter()
        .filter_map(|r| {
            let ok = get(r, "v_xy_valid").is_none_or(|v| v != 0.0);
            let v = [get(r, "vx")?, get(r, "vy")?, get(r, "vz")?];
            ok.then_some((time_us(r)?, v))
        })
        .collect();
    if !global.is_empty() {
        log.onboard_nav = global
            .iter()
            .filter_map(|r| {
                Some(NavRecord {
                    t_us: time_us(r)?,
                    geodetic: Some([get(r, "lat")?, get(r, "lon")?, get(r, "alt")?]),
                    velocity_ned_m_s: None,
                })
            })
            .collect();
        log.onboard_nav
            .extend(velocities.iter().map(|&(t_us, v)| NavRecord {
                t_us,
                geodetic: None,
                velocity_ned_m_s: Some(v),
            }));
        log.nav_source = "vehicle_global_position (position), vehicle_local_position \
                          (velocity)"
            .into();
        return;
    }
    log.onboard_nav = local
        .iter()
        .filter_map(|r| {
            let t_us = time_us(r)?;
            let global_ok = get(r, "xy_global").is_some_and(|v| v != 0.0)
                && get(r, "z_global").is_some_and(|v| v != 0.0)
                && get(r, "xy_valid").is_none_or(|v| v != 0.0);
            let geodetic = (|| {
                let origin = skyframe_core::estimation::geo::LocalFrame::new(
                    skyframe_core::estimation::geo::GeoPoint {
                        latitude_deg: get(r, "ref_lat")?,
                        longitude_deg: get(r, "ref_lon")?,
                        altitude_m: get(r, "ref_alt")?,
                    },
                )?;
                let ned = skyframe_core::estimation::nalgebra::Vector3::new(
                    get(r, "x")?,
                    get(r, "y")?,
                    get(r, "z")?,
                );
                let p = origin.to_geodetic(&ned);
                Some([p.latitude_deg, p.longitude_deg, p.altitude_m])
            })()
            .filter(|_| global_ok);
            let ok = get(r, "v_xy_valid").is_none_or(|v| v != 0.0);
            let v = (|| Some([get(r, "vx")?, get(r, "vy")?, get(r, "vz")?]))().filter(|_| ok);
            Some(NavRecord {
                t_us,
                geodetic,
                velocity_ned_m_s: v,
            })
        })
        .collect();
    if !log.onboard_nav.is_empty() {
        log.nav_source = "vehicle_local_position with its reference point (ref_lat, ref_lon, \
                          ref_alt)"
            .into();
    }
}
