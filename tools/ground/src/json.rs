//! Messages as `monitor` prints them: one JSON object, or one line of text, per datagram.
//! Field names follow the protocol's (`docs/link-protocol.md`), units in the names.

use crate::model::GroundModel;
use crate::net::{Incoming, Received};
use crate::values::{ack_result_name, value_text};
use serde_json::{Map, Value as Json, json};
use skyframe_core::control::mode::FlightMode;
use skyframe_core::link::frame::{FrameError, Header};
use skyframe_core::link::messages::{LogHealth, Telemetry, Value};

pub fn value_json(value: &Value) -> Json {
    match *value {
        Value::Bool(b) => Json::Bool(b),
        Value::I32(v) => json!(v),
        Value::U32(v) => json!(v),
        // NaN (a value the device did not give) has no JSON number: null.
        Value::F32(v) => {
            serde_json::Number::from_f64(f64::from(v)).map_or(Json::Null, Json::Number)
        }
        Value::F64(v) => serde_json::Number::from_f64(v).map_or(Json::Null, Json::Number),
    }
}

pub fn mode_name(mode: Option<FlightMode>) -> &'static str {
    match mode {
        Some(FlightMode::Manual) => "manual",
        Some(FlightMode::Stabilise) => "stabilise",
        Some(FlightMode::Auto) => "auto",
        None => "none",
    }
}

pub fn frame_error_name(error: FrameError) -> &'static str {
    match error {
        FrameError::BadCrc => "bad_crc",
        FrameError::Malformed => "malformed",
        FrameError::Unsigned => "unsigned",
        FrameError::BadSignature => "bad_signature",
    }
}

pub fn telemetry_type_name(telemetry: &Telemetry) -> &'static str {
    match telemetry {
        Telemetry::TaskData(_) => "task_data",
        Telemetry::TaskFormat(_) => "task_format",
        Telemetry::TaskStatus(_) => "task_status",
        Telemetry::ExecutiveStatus(_) => "executive_status",
        Telemetry::ParamValue(_) => "param_value",
        Telemetry::CommandAck(_) => "command_ack",
    }
}

fn task_name(model: &GroundModel, vehicle_id: u16, task_index: u8) -> Option<String> {
    model
        .vehicle(vehicle_id)
        .and_then(|v| v.tasks.get(&task_index))
        .and_then(|t| t.name())
        .map(str::to_string)
}

fn column_names(model: &GroundModel, vehicle_id: u16, task: u8, format: u8) -> Vec<String> {
    model
        .vehicle(vehicle_id)
        .and_then(|v| v.tasks.get(&task))
        .and_then(|t| t.formats.get(&format))
        .map(|f| f.columns.clone())
        .unwrap_or_default()
}

/// The message's own fields.
pub fn telemetry_fields(
    telemetry: &Telemetry,
    vehicle_id: u16,
    model: &GroundModel,
) -> Map<String, Json> {
    let mut m = Map::new();
    let mut put = |k: &str, v: Json| {
        m.insert(k.to_string(), v);
    };
    match telemetry {
        Telemetry::TaskData(d) => {
            put("task_index", json!(d.task_index));
            if let Some(name) = task_name(model, vehicle_id, d.task_index) {
                put("task", json!(name));
            }
            put("format_index", json!(d.format_index));
            // The record's log TIME: as seconds, and exactly as the CSV's time column.
            put(
                "time",
                json!(f64::from(d.time.sec) + f64::from(d.time.nsec) * 1e-9),
            );
            put("log_time", json!(d.time.to_string()));
            let columns = column_names(model, vehicle_id, d.task_index, d.format_index);
            let known = columns.len() == d.values.len();
            put("columns_known", json!(known));
            let name = |i: usize| match columns.get(i) {
                Some(c) if known => c.clone(),
                _ => format!("c{i}"),
            };
            let values: Map<String, Json> = d
                .values
                .iter()
                .enumerate()
                .map(|(i, v)| (name(i), value_json(v)))
                .collect();
            put("values", Json::Object(values));
            let units: Map<String, Json> = columns
                .iter()
                .filter(|_| known)
                .filter_map(|c| crate::model::column_unit(c).map(|u| (c.clone(), json!(u))))
                .collect();
            if !units.is_empty() {
                put("units", Json::Object(units));
            }
        }
        Telemetry::TaskFormat(f) => {
            put("task_index", json!(f.task_index));
            put("format_index", json!(f.format_index));
            put(
                "columns",
                json!(
                    String::from_utf8_lossy(&f.columns)
                        .split(',')
                        .collect::<Vec<_>>()
                ),
            );
        }
        Telemetry::TaskStatus(s) => {
            put("task_index", json!(s.task_index));
            put("task", json!(s.name.as_str()));
            put("initialised", json!(s.initialised));
            put("running", json!(s.running));
            put("in_frame", json!(s.in_frame));
            put("alive", json!(s.alive));
            put("releases", json!(s.releases));
            put("overruns_budget", json!(s.overruns_budget));
            put("overruns_frame", json!(s.overruns_frame));
            put("overruns_missed", json!(s.overruns_missed));
            put("skipped", json!(s.skipped));
            put("resets", json!(s.resets));
            put("faults", json!(s.faults));
            put("init_failures", json!(s.init_failures));
            put("watchdog_misses", json!(s.watchdog_misses));
            put("log_records_dropped", json!(s.log_records_dropped));
            put("telemetry_interval_ms", json!(s.telemetry_interval_ms));
            put("exec_mean_ns", json!(s.exec_mean_ns));
            put("exec_max_ns", json!(s.exec_max_ns));
            put("budget_ns", json!(s.budget_ns));
            put("period_ns", json!(s.period_ns));
        }
        Telemetry::ExecutiveStatus(e) => {
            put("elapsed_ns", json!(e.elapsed_ns));
            put("duration_ns", json!(e.duration_ns));
            put("mode", json!(mode_name(e.mode)));
            put("task_count", json!(e.task_count));
            put("health_period_ms", json!(e.health_period_ms));
            let f = &e.frames;
            put(
                "frames",
                json!({
                    "frames": f.frames, "missed": f.missed, "late": f.late, "overrun": f.overrun,
                    "max_start_latency_ns": f.max_start_latency_ns,
                    "max_frame_work_ns": f.max_frame_work_ns,
                    "timing_records_dropped": f.timing_records_dropped,
                }),
            );
            let l = &e.link;
            put(
                "link",
                json!({
                    "received": l.received, "accepted": l.accepted, "bad_crc": l.bad_crc,
                    "malformed": l.malformed, "wrong_vehicle": l.wrong_vehicle,
                    "unsigned": l.unsigned, "bad_signature": l.bad_signature,
                    "wrong_run": l.wrong_run, "replayed": l.replayed,
                    "too_many_senders": l.too_many_senders, "out_of_range": l.out_of_range,
                    "unknown_param": l.unknown_param, "wrong_type": l.wrong_type,
                    "telemetry_sent": l.telemetry_sent,
                    "telemetry_send_failed": l.telemetry_send_failed,
                    "rate_limited": l.rate_limited,
                }),
            );
            let log = &e.log;
            put(
                "log",
                json!({
                    "free_mib": (log.free_mib != LogHealth::UNKNOWN).then_some(log.free_mib),
                    "records_lost": log.records_lost,
                    "streams_suspended": log.streams_suspended,
                }),
            );
        }
        Telemetry::ParamValue(p) => {
            put("index", json!(p.index));
            put("count", json!(p.count));
            put("name", json!(p.name.as_str()));
            put("value", value_json(&p.value));
            put("min", value_json(&p.min));
            put("max", value_json(&p.max));
        }
        Telemetry::CommandAck(a) => {
            put("command_sender_id", json!(a.command_sender_id));
            put("command_sequence", json!(a.command_sequence));
            put("command_type", json!(a.command_type));
            put("result", json!(ack_result_name(a.result)));
            put(
                "value_in_force",
                a.value_in_force.as_ref().map_or(Json::Null, value_json),
            );
        }
    }
    m
}

fn envelope_fields(m: &mut Map<String, Json>, header: &Header) {
    let e = header.envelope;
    m.insert("vehicle".into(), json!(e.vehicle_id));
    m.insert("sender_id".into(), json!(e.sender_id));
    m.insert("run_id".into(), json!(e.run_id));
    m.insert("sequence".into(), json!(e.sequence));
    m.insert("seq".into(), json!(e.sequence));
    m.insert("t_ns".into(), json!(e.t_ns));
    m.insert("signed".into(), json!(header.signed));
}

/// One JSON object for one received datagram.
pub fn received_json(received: &Received, model: &GroundModel) -> Json {
    let mut m = Map::new();
    m.insert("from".into(), json!(received.from.to_string()));
    match &received.incoming {
        Incoming::Telemetry { header, telemetry } => {
            envelope_fields(&mut m, header);
            m.insert("type".into(), json!(telemetry_type_name(telemetry)));
            m.extend(telemetry_fields(
                telemetry,
                header.envelope.vehicle_id,
                model,
            ));
        }
        Incoming::Command { header } => {
            envelope_fields(&mut m, header);
            m.insert("type".into(), json!("command"));
            m.insert("message_type".into(), json!(header.message_type));
        }
        Incoming::Refused(error) => {
            m.insert("type".into(), json!("refused"));
            m.insert("error".into(), json!(frame_error_name(*error)));
        }
    }
    Json::Object(m)
}

/// One line of text for one received datagram.
pub fn received_text(received: &Received, model: &GroundModel) -> String {
    match &received.incoming {
        Incoming::Telemetry { header, telemetry } => {
            let e = header.envelope;
            let fields = telemetry_fields(telemetry, e.vehicle_id, model);
            let body = match telemetry {
                Telemetry::TaskData(d) => {
                    let columns = column_names(model, e.vehicle_id, d.task_index, d.format_index);
                    let task = task_name(model, e.vehicle_id, d.task_index)
                        .unwrap_or_else(|| format!("task{}", d.task_index));
                    let values: Vec<String> = d
                        .values
                        .iter()
                        .enumerate()
                        .map(|(i, v)| match columns.get(i) {
                            Some(c) => format!("{c}={}", value_text(v)),
                            None => value_text(v),
                        })
                        .collect();
                    format!("{task}#{} {}", d.format_index, values.join(" "))
                }
                _ => fields
                    .iter()
                    .map(|(k, v)| format!("{k}={v}"))
                    .collect::<Vec<_>>()
                    .join(" "),
            };
            format!(
                "vehicle {} seq {} t {:.3}s {} {}",
                e.vehicle_id,
                e.sequence,
                e.t_ns as f64 * 1e-9,
                telemetry_type_name(telemetry),
                body
            )
        }
        Incoming::Command { header } => format!(
            "command 0x{:02x} from sender {} to vehicle {} (another ground station)",
            header.message_type, header.envelope.sender_id, header.envelope.vehicle_id
        ),
        Incoming::Refused(error) => {
            format!(
                "refused from {}: {}",
                received.from,
                frame_error_name(*error)
            )
        }
    }
}
