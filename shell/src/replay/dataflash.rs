//! ArduPilot DataFlash (`.bin`) → [`FlightLog`]. No maintained Rust reader exists, and the
//! format is small: every message is `0xA3 0x95 type` and a payload whose layout an earlier
//! `FMT` message (type 128) declared as a name, a string of type letters and column names.
//! This reader takes those declarations from the file itself, so it reads any firmware's
//! logs as long as the columns replay needs keep their names.
//!
//! Robustness: any bytes. A file that does not start with a message is refused (error at
//! byte 0); inside the file, bytes that are not a message of a declared type are skipped to
//! the next `0xA3 0x95` and reported once (offset and count) as a warning; a truncated last
//! message is a warning. Every read is bounds-checked.
//!
//! Messages used (first instance only): `IMU` (rates, held over the interval since the
//! previous sample), or `IMT` when logged (delta angles and velocities with their own
//! intervals); `GPS` (+ `GPA` accuracies when logged); `ATT` (onboard attitude); `POS`
//! (onboard position); `XKF1`/`NKF1`/`EKF1` (onboard velocity); `ARSP` (airspeed); `MAG` (counted).

use std::collections::HashMap;

use super::flightlog::{
    AttitudeRecord, FlightLog, GpsRecord, ImuRecord, NavRecord, error_at, quaternion_from_euler,
    rates_to_increments,
};

const HEAD: [u8; 2] = [0xA3, 0x95];
const FMT_TYPE: u8 = 128;
/// FMT's own length (header included): type, length, name[4], format[16], columns[64].
const FMT_LEN: usize = 89;

/// True if `bytes` starts like a DataFlash log (a message header, normally the FMT of FMT).
pub fn looks_like_dataflash(bytes: &[u8]) -> bool {
    bytes.starts_with(&HEAD)
}

#[derive(Clone, Debug)]
struct Format {
    name: String,
    length: usize,
    types: Vec<u8>,
    columns: Vec<String>,
}

/// Size in bytes of one type letter (`None`: a letter this reader does not know, which makes
/// the whole format unreadable).
fn type_size(t: u8) -> Option<usize> {
    Some(match t {
        b'b' | b'B' | b'M' => 1,
        b'h' | b'H' | b'c' | b'C' => 2,
        b'i' | b'I' | b'f' | b'e' | b'E' | b'L' | b'n' => 4,
        b'd' | b'q' | b'Q' => 8,
        b'N' => 16,
        b'Z' | b'a' => 64,
        _ => return None,
    })
}

/// The value of one field in natural units (the `c`/`C`/`e`/`E` letters are hundredths,
/// `L` 1e-7 degrees); strings and arrays are `None`.
fn value(t: u8, b: &[u8]) -> Option<f64> {
    let a = |n: usize| b.get(..n);
    Some(match t {
        b'b' => f64::from(i8::from_le_bytes(a(1)?.try_into().ok()?)),
        b'B' | b'M' => f64::from(*a(1)?.first()?),
        b'h' => f64::from(i16::from_le_bytes(a(2)?.try_into().ok()?)),
        b'H' => f64::from(u16::from_le_bytes(a(2)?.try_into().ok()?)),
        b'c' => f64::from(i16::from_le_bytes(a(2)?.try_into().ok()?)) * 0.01,
        b'C' => f64::from(u16::from_le_bytes(a(2)?.try_into().ok()?)) * 0.01,
        b'i' => f64::from(i32::from_le_bytes(a(4)?.try_into().ok()?)),
        b'I' => f64::from(u32::from_le_bytes(a(4)?.try_into().ok()?)),
        b'e' => f64::from(i32::from_le_bytes(a(4)?.try_into().ok()?)) * 0.01,
        b'E' => f64::from(u32::from_le_bytes(a(4)?.try_into().ok()?)) * 0.01,
        b'L' => f64::from(i32::from_le_bytes(a(4)?.try_into().ok()?)) * 1e-7,
        b'f' => f64::from(f32::from_le_bytes(a(4)?.try_into().ok()?)),
        b'd' => f64::from_le_bytes(a(8)?.try_into().ok()?),
        b'q' => i64::from_le_bytes(a(8)?.try_into().ok()?) as f64,
        b'Q' => u64::from_le_bytes(a(8)?.try_into().ok()?) as f64,
        _ => return None,
    })
}

fn text(b: &[u8]) -> String {
    let end = b.iter().position(|&c| c == 0).unwrap_or(b.len());
    String::from_utf8_lossy(b.get(..end).unwrap_or_default()).into_owned()
}

/// The messages replay reads, and the columns it takes from each.
const WANTED: &[&str] = &[
    "IMU", "IMT", "GPS", "GPA", "ATT", "POS", "XKF1", "NKF1", "EKF1", "ARSP", "MAG",
];

type Row = HashMap<String, f64>;

/// Reads a DataFlash log's bytes; `path` only names it in messages.
pub fn read(path: &str, bytes: &[u8]) -> Result<FlightLog, String> {
    if !looks_like_dataflash(bytes) {
        return Err(error_at(
            path,
            0,
            "not an ArduPilot DataFlash log (no 0xA3 0x95 message header)",
        ));
    }
    let mut formats: HashMap<u8, Format> = HashMap::new();
    let mut rows: HashMap<String, Vec<Row>> = HashMap::new();
    let mut warnings = Vec::new();
    let mut skipped: Option<(usize, usize)> = None;
    let mut at = 0usize;
    while at < bytes.len() {
        let header = bytes.get(at..at + 3);
        let known = match header {
            Some(&[0xA3, 0x95, t]) if t == FMT_TYPE => Some(FMT_LEN),
            Some(&[0xA3, 0x95, t]) => formats.get(&t).map(|f| f.length),
            Some(_) => None,
            None => {
                warnings.push(error_at(
                    path,
                    at,
                    "truncated message header at the end: ignored",
                ));
                break;
            }
        };
        let Some(length) = known else {
            // Not a message we can delimit: skip to the next header.
            let next = bytes
                .get(at + 1..)
                .and_then(|rest| rest.windows(2).position(|w| w == HEAD))
                .map_or(bytes.len(), |p| at + 1 + p);
            let (first, count) = skipped.get_or_insert((at, 0));
            let _ = first;
            *count += next - at;
            at = next;
            continue;
        };
        let Some(message) = bytes.get(at..at + length) else {
            warnings.push(error_at(path, at, "truncated last message: ignored"));
            break;
        };
        let t = message.get(2).copied().unwrap_or_default();
        let payload = message.get(3..).unwrap_or_default();
        if t == FMT_TYPE {
            if let Some(f) = parse_fmt(payload) {
                let ty = payload.first().copied().unwrap_or_default();
                // A message type's layout is fixed for the file; a second, different FMT for
                // it (corruption) is ignored rather than allowed to re-cut the rest.
                formats.entry(ty).or_insert(f);
            }
        } else if let Some(f) = formats.get(&t) {
            if WANTED.contains(&f.name.as_str()) {
                let mut row = Row::new();
                let mut offset = 0usize;
                for (&ty, column) in f.types.iter().zip(&f.columns) {
                    let size = type_size(ty).unwrap_or(usize::MAX);
                    let Some(field) = payload.get(offset..offset.saturating_add(size)) else {
                        break;
                    };
                    if let Some(v) = value(ty, field) {
                        row.insert(column.clone(), v);
                    }
                    offset += size;
                }
                rows.entry(f.name.clone()).or_default().push(row);
            }
        }
        at += length;
    }
    if let Some((first, count)) = skipped {
        warnings.push(error_at(
            path,
            first,
            format!("{count} bytes in all were not messages of a declared type: skipped"),
        ));
    }
    if formats.is_empty() {
        return Err(error_at(
            path,
            0,
            "no FMT message: not a readable DataFlash log",
        ));
    }
    Ok(assemble(&rows, warnings))
}

fn parse_fmt(p: &[u8]) -> Option<Format> {
    let length = usize::from(*p.get(1)?);
    let name = text(p.get(2..6)?);
    let types: Vec<u8> = p
        .get(6..22)?
        .iter()
        .copied()
        .take_while(|&c| c != 0)
        .collect();
    let columns: Vec<String> = text(p.get(22..86)?)
        .split(',')
        .map(str::to_string)
        .collect();
    let payload: usize = types.iter().map(|&t| type_size(t)).sum::<Option<usize>>()?;
    // The declared length must hold the header and the fields exactly, or the stream
    // could not be cut by it.
    (length == payload + 3 && length >= 3 && !name.is_empty()).then_some(Format {
        name,
        length,
        types,
        columns,
    })
}

fn list<'a>(rows: &'a HashMap<String, Vec<Row>>, name: &str) -> &'a [Row] {
    rows.get(name).map(Vec::as_slice).unwrap_or_default()
}

fn get(row: &Row, name: &str) -> Option<f64> {
    row.get(name).copied().filter(|v| v.is_finite())
}

/// Microseconds since boot: `TimeUS`, or `TimeMS` in old logs.
fn time_us(row: &Row) -> Option<u64> {
    get(row, "TimeUS")
        .or_else(|| get(row, "TimeMS").map(|ms| ms * 1000.0))
        .filter(|t| (0.0..1.8e19).contains(t))
        .map(|t| t as u64)
}

/// The first instance of a multi-instance message (`I` or `C` column; absent in old logs,
/// which had IMU2, GPS2 as separate names).
fn first_instance(row: &&Row) -> bool {
    get(row, "I")
        .or_else(|| get(row, "C"))
        .is_none_or(|i| i == 0.0)
}

fn assemble(rows: &HashMap<String, Vec<Row>>, warnings: Vec<String>) -> FlightLog {
    let mut log = FlightLog {
        format: "ArduPilot DataFlash",
        warnings,
        ..FlightLog::default()
    };
    let imt: Vec<ImuRecord> = list(rows, "IMT")
        .iter()
        .filter(first_instance)
        .filter_map(|r| {
            let dt = get(r, "DelaT")?;
            Some(ImuRecord {
                t_us: time_us(r)?,
                dt_s: dt,
                delta_angle_rad: [get(r, "DelAX")?, get(r, "DelAY")?, get(r, "DelAZ")?],
                // Angle and velocity intervals differ slightly; the velocity increment is
                // scaled to the angle's interval so one record has one interval.
                delta_velocity_m_s: {
                    let dv = get(r, "DelvT").filter(|v| *v > 0.0)?;
                    [get(r, "DelVX")?, get(r, "DelVY")?, get(r, "DelVZ")?].map(|v| v * dt / dv)
                },
            })
        })
        .collect();
    if !imt.is_empty() {
        log.imu = imt;
        log.imu_source = "IMT: delta angles and velocities over DelaT".into();
    } else {
        let samples: Vec<_> = list(rows, "IMU")
            .iter()
            .filter(first_instance)
            .filter_map(|r| {
                Some((
                    time_us(r)?,
                    None,
                    [get(r, "GyrX")?, get(r, "GyrY")?, get(r, "GyrZ")?],
                    [get(r, "AccX")?, get(r, "AccY")?, get(r, "AccZ")?],
                ))
            })
            .collect();
        log.imu = rates_to_increments(&samples, 0.1);
        log.imu_source = "IMU: rates held over the interval since the previous sample".into();
    }
    // GPA carries the receiver's accuracies for the GPS record of the same time.
    let accuracy: HashMap<u64, (Option<f64>, Option<f64>)> = list(rows, "GPA")
        .iter()
        .filter(first_instance)
        .filter_map(|r| Some((time_us(r)?, (get(r, "HAcc"), get(r, "VAcc")))))
        .collect();
    log.gps = list(rows, "GPS")
        .iter()
        .filter(first_instance)
        .filter_map(|r| {
            // Logs of 2014-15 have GPS time of week in TimeMS and the boot time in T.
            let t_us = match get(r, "T") {
                Some(ms) if (0.0..1.8e16).contains(&ms) => (ms * 1000.0) as u64,
                _ => get(r, "TimeUS")
                    .filter(|t| (0.0..1.8e19).contains(t))
                    .map(|t| t as u64)?,
            };
            let speed = get(r, "Spd");
            let course = get(r, "GCrs").map(f64::to_radians);
            let (vn, ve) = match (speed, course) {
                (Some(s), Some(c)) => (Some(s * c.cos()), Some(s * c.sin())),
                _ => (None, None),
            };
            let (h, v) = accuracy.get(&t_us).copied().unwrap_or((None, None));
            Some(GpsRecord {
                t_us,
                fix_3d: get(r, "Status").is_some_and(|s| s >= 3.0),
                latitude_deg: get(r, "Lat")?,
                longitude_deg: get(r, "Lng")?,
                altitude_m: get(r, "Alt")?,
                velocity_ned_m_s: [vn, ve, get(r, "VZ")],
                horizontal_accuracy_m: h.filter(|x| *x > 0.0),
                vertical_accuracy_m: v.filter(|x| *x > 0.0),
                hdop: get(r, "HDop").filter(|x| *x > 0.0),
                satellites: get(r, "NSats").map(|s| s.clamp(0.0, 255.0) as u8),
            })
        })
        .collect();
    log.gps_source = "GPS (TimeUS: when the autopilot logged the fix; velocity from Spd, GCrs, \
                      VZ)"
    .into();
    log.onboard_attitude = list(rows, "ATT")
        .iter()
        .filter_map(|r| {
            let (roll, pitch, yaw) = (get(r, "Roll")?, get(r, "Pitch")?, get(r, "Yaw")?);
            Some(AttitudeRecord {
                t_us: time_us(r)?,
                quaternion: quaternion_from_euler(
                    roll.to_radians(),
                    pitch.to_radians(),
                    yaw.to_radians(),
                ),
            })
        })
        .collect();
    log.attitude_source = "ATT (Roll, Pitch, Yaw: the AHRS the autopilot flew with)".into();
    log.onboard_nav = list(rows, "POS")
        .iter()
        .filter_map(|r| {
            Some(NavRecord {
                t_us: time_us(r)?,
                geodetic: Some([get(r, "Lat")?, get(r, "Lng")?, get(r, "Alt")?]),
                velocity_ned_m_s: None,
            })
        })
        .collect();
    // The EKF's first core, by the name of its firmware's time: XKF1 (EKF3), NKF1 (EKF2),
    // EKF1 (the EKF of 2014-15).
    let ekf = ["XKF1", "NKF1", "EKF1"]
        .into_iter()
        .find(|n| !list(rows, n).is_empty())
        .unwrap_or("XKF1");
    log.onboard_nav.extend(
        list(rows, ekf)
            .iter()
            .filter(first_instance)
            .filter_map(|r| {
                Some(NavRecord {
                    t_us: time_us(r)?,
                    geodetic: None,
                    velocity_ned_m_s: Some([get(r, "VN")?, get(r, "VE")?, get(r, "VD")?]),
                })
            }),
    );
    log.nav_source = format!("POS (position), {ekf} core 0 (velocity)");
    log.airspeed = list(rows, "ARSP")
        .iter()
        .filter(first_instance)
        .filter_map(|r| Some((time_us(r)?, get(r, "Airspeed")?)))
        .collect();
    log.magnetometer_samples = list(rows, "MAG").iter().filter(first_instance).count();
    log.normalise();
    log
}
