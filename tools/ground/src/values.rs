//! Link values as people read and type them: values, types, acknowledgements, rates.

use skyframe_core::link::messages::{AckResult, Value, ValueType, limits};

pub fn ack_result_name(result: AckResult) -> &'static str {
    match result {
        AckResult::Accepted => "accepted",
        AckResult::OutOfRange => "out of range",
        AckResult::UnknownParam => "unknown parameter",
        AckResult::WrongType => "wrong type",
        AckResult::Refused => "refused",
    }
}

pub fn value_text(value: &Value) -> String {
    match *value {
        Value::Bool(b) => b.to_string(),
        Value::I32(v) => v.to_string(),
        Value::U32(v) => v.to_string(),
        Value::F32(v) => v.to_string(),
        Value::F64(v) => v.to_string(),
    }
}

pub fn type_name(value_type: ValueType) -> &'static str {
    match value_type {
        ValueType::Bool => "bool",
        ValueType::I32 => "i32",
        ValueType::U32 => "u32",
        ValueType::F32 => "f32",
        ValueType::F64 => "f64",
    }
}

/// Reads `text` as a value of `value_type`.
pub fn parse_value(text: &str, value_type: ValueType) -> Option<Value> {
    let text = text.trim();
    Some(match value_type {
        ValueType::Bool => Value::Bool(match text {
            "true" | "1" | "on" | "yes" => true,
            "false" | "0" | "off" | "no" => false,
            _ => return None,
        }),
        ValueType::I32 => Value::I32(text.parse().ok()?),
        ValueType::U32 => Value::U32(text.parse().ok()?),
        ValueType::F32 => Value::F32(text.parse::<f32>().ok().filter(|v| v.is_finite())?),
        ValueType::F64 => Value::F64(text.parse::<f64>().ok().filter(|v| v.is_finite())?),
    })
}

/// A telemetry rate in Hz as the interval the protocol carries (0 Hz: stop sending).
pub fn interval_ms_for_hz(hz: f64) -> Option<u32> {
    if hz == 0.0 {
        return Some(0);
    }
    if !hz.is_finite() || hz < 0.0 {
        return None;
    }
    let ms = (1000.0 / hz).round();
    let range =
        f64::from(limits::MIN_TELEMETRY_INTERVAL_MS)..=f64::from(limits::MAX_TELEMETRY_INTERVAL_MS);
    range.contains(&ms).then_some(ms as u32)
}
