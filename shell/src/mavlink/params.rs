//! skyframe's parameters as MAVLink parameters: names to ≤16-character ids, typed values to
//! PARAM_VALUE's `float` with C-cast encoding (`MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST`,
//! as ArduPilot does: the float holds the number, not the integer's bytes).
//!
//! The table itself stays the vehicle's (`core/src/link/params.rs`): this side keeps a copy of
//! what the vehicle last reported, and every set goes to the vehicle as a skyframe
//! `SetParam`, through the same range checks as the ground station's.

use mavlink::dialects::common::MavParamType;
use skyframe_core::link::messages::{ParamValue, Value, ValueType};

/// Longest MAVLink parameter id.
pub const ID_LEN: usize = 16;

/// Group prefixes (the part of a skyframe name before its first `.`), shortened.
const PREFIXES: [(&str, &str); 7] = [
    ("control", "CTL"),
    ("estimator", "EKF"),
    ("imu", "IMU"),
    ("gps", "GPS"),
    ("servo", "SRV"),
    ("telemetry", "TEL"),
    ("health", "HLT"),
];

/// Words shortened, in this order, while an id is longer than [`ID_LEN`].
const WORDS: [(&str, &str); 8] = [
    ("SPEED", "SPD"),
    ("STAB", "STB"),
    ("PITCH", "PTCH"),
    ("ELEVATOR", "ELEV"),
    ("THROTTLE", "THR"),
    ("AILERON", "AIL"),
    ("RUDDER", "RUD"),
    ("ALTITUDE", "ALT"),
];

/// The MAVLink id of a skyframe parameter name: the group prefix shortened
/// (`control.` → `CTL_`), upper case, `.` and `-` as `_`, then words shortened
/// (`SPEED` → `SPD`, …) until it fits in 16 characters; a name still too long keeps its
/// first 13 characters and gets `_` and two letters of a hash of the whole name, so two
/// long names never share an id by truncation alone. (`docs/mavlink.md` lists the shipped
/// mapping.)
pub fn mavlink_id(name: &str) -> String {
    let (group, rest) = match name.split_once('.') {
        Some((g, r)) => (Some(g), r),
        None => (None, name),
    };
    let mut id = String::new();
    if let Some(group) = group {
        match PREFIXES.iter().find(|(g, _)| *g == group) {
            Some((_, short)) => id.push_str(short),
            None => id.extend(group.chars().take(3).map(|c| c.to_ascii_uppercase())),
        }
        id.push('_');
    }
    id.extend(rest.chars().map(|c| match c {
        '.' | '-' => '_',
        c => c.to_ascii_uppercase(),
    }));
    for (long, short) in WORDS {
        if id.len() <= ID_LEN {
            break;
        }
        id = id
            .split('_')
            .map(|w| if w == long { short } else { w })
            .collect::<Vec<_>>()
            .join("_");
    }
    if id.len() > ID_LEN {
        let hash = skyframe_core::link::frame::crc32(name.as_bytes());
        let letters: String = [hash % 26, (hash / 26) % 26]
            .iter()
            .filter_map(|n| char::from_u32(u32::from(b'A') + n))
            .collect();
        id.truncate(ID_LEN - 3);
        id.push('_');
        id.push_str(&letters);
    }
    id
}

/// MAVLink's type for a skyframe value type.
pub fn param_type(t: ValueType) -> MavParamType {
    match t {
        ValueType::Bool => MavParamType::MAV_PARAM_TYPE_UINT8,
        ValueType::I32 => MavParamType::MAV_PARAM_TYPE_INT32,
        ValueType::U32 => MavParamType::MAV_PARAM_TYPE_UINT32,
        ValueType::F32 => MavParamType::MAV_PARAM_TYPE_REAL32,
        ValueType::F64 => MavParamType::MAV_PARAM_TYPE_REAL64,
    }
}

/// PARAM_VALUE's float for a value (C cast: integers above 2^24 lose their low bits, as
/// with every C-cast autopilot; none of skyframe's parameters is that large).
pub fn encode_value(v: Value) -> f32 {
    match v {
        Value::Bool(b) => f32::from(u8::from(b)),
        Value::I32(i) => i as f32,
        Value::U32(u) => u as f32,
        Value::F32(f) => f,
        Value::F64(f) => f as f32,
    }
}

/// The value a PARAM_SET's float asks for, in the parameter's own type; `None` when the
/// float is not a value of that type (a fraction for an integer, 2 for a bool, NaN): such a
/// set is refused and answered with the value in force.
pub fn decode_value(f: f32, t: ValueType) -> Option<Value> {
    if !f.is_finite() {
        return None;
    }
    let whole = f.fract() == 0.0;
    match t {
        ValueType::Bool if f == 0.0 || f == 1.0 => Some(Value::Bool(f == 1.0)),
        ValueType::I32 if whole && (-2_147_483_648.0..2_147_483_648.0).contains(&f) => {
            Some(Value::I32(f as i32))
        }
        ValueType::U32 if whole && (0.0..4_294_967_296.0).contains(&f) => {
            Some(Value::U32(f as u32))
        }
        ValueType::F32 => Some(Value::F32(f)),
        ValueType::F64 => Some(Value::F64(f64::from(f))),
        _ => None,
    }
}

/// One parameter as the vehicle last reported it.
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    pub id: String,
    pub name: String,
    pub value: Value,
}

/// The vehicle's parameter table as last reported (ParamValue messages), by index.
#[derive(Debug, Default)]
pub struct ParamCache {
    entries: Vec<Option<Entry>>,
}

impl ParamCache {
    /// Takes one of the vehicle's ParamValue messages; a table whose size changed starts over.
    pub fn update(&mut self, p: &ParamValue) {
        let count = usize::from(p.count);
        if self.entries.len() != count {
            self.entries = vec![None; count];
        }
        if let Some(slot) = self.entries.get_mut(usize::from(p.index)) {
            let name = p.name.as_str().to_string();
            *slot = Some(Entry {
                id: mavlink_id(&name),
                name,
                value: p.value,
            });
        }
    }

    /// Sets the value in force of parameter `index` (from a command's acknowledgement).
    pub fn set_value(&mut self, index: usize, value: Value) {
        if let Some(Some(e)) = self.entries.get_mut(index) {
            e.value = value;
        }
    }

    pub fn count(&self) -> usize {
        self.entries.len()
    }

    /// Every parameter reported.
    pub fn complete(&self) -> bool {
        !self.entries.is_empty() && self.entries.iter().all(Option::is_some)
    }

    pub fn get(&self, index: usize) -> Option<&Entry> {
        self.entries.get(index).and_then(Option::as_ref)
    }

    /// Index of the parameter with MAVLink id `id`.
    pub fn find(&self, id: &str) -> Option<usize> {
        self.entries
            .iter()
            .position(|e| e.as_ref().is_some_and(|e| e.id == id))
    }
}

/// PARAM_SET's and PARAM_REQUEST_READ's id: up to 16 bytes, NUL-padded (no NUL when all 16
/// are used). Bytes that are not ASCII make an id no parameter has.
pub fn id_from_bytes(bytes: &[u8]) -> String {
    bytes
        .iter()
        .take_while(|b| **b != 0)
        .map(|b| {
            if b.is_ascii() {
                char::from(*b)
            } else {
                '\u{FFFD}'
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use skyframe_core::link::params::ParamTable;
    use skyframe_core::tasks::control::{ControlSettings, define_params};

    #[test]
    fn every_shipped_parameter_has_a_distinct_id_of_at_most_16_characters() {
        let mut table = ParamTable::new();
        define_params(&mut table, &ControlSettings::default()).expect("defined");
        let mut ids = Vec::new();
        for i in 0..table.len() {
            let name = table
                .by_index(i)
                .expect("param")
                .name()
                .as_str()
                .to_string();
            let id = mavlink_id(&name);
            assert!(id.len() <= ID_LEN, "{name} -> {id}");
            assert!(!ids.contains(&id), "{name} -> {id} twice");
            ids.push(id);
        }
        // The documented mapping (docs/mavlink.md), spot-checked.
        assert_eq!(mavlink_id("control.roll_kp"), "CTL_ROLL_KP");
        assert_eq!(mavlink_id("control.speed_pitch_kp"), "CTL_SPD_PITCH_KP");
        assert_eq!(mavlink_id("control.stab_pitch_deg"), "CTL_STB_PTCH_DEG");
        assert_eq!(mavlink_id("control.trim_elevator"), "CTL_TRIM_ELEV");
        assert_eq!(mavlink_id("control.trim_throttle"), "CTL_TRIM_THR");
        assert_eq!(mavlink_id("control.max_pitch_deg"), "CTL_MAX_PTCH_DEG");
        assert_eq!(mavlink_id("control.cruise_mps"), "CTL_CRUISE_MPS");
    }

    #[test]
    fn overlong_names_are_cut_with_a_hash_and_stay_distinct() {
        let a = mavlink_id("navigation.something_much_too_long_a");
        let b = mavlink_id("navigation.something_much_too_long_b");
        assert_eq!(a.len(), ID_LEN);
        assert_eq!(&a[..13], "NAV_SOMETHING");
        assert_ne!(a, b);
        assert_eq!(mavlink_id("plain"), "PLAIN");
    }

    #[test]
    fn values_encode_by_c_cast_and_decode_only_when_exact() {
        assert_eq!(encode_value(Value::F32(0.25)), 0.25);
        assert_eq!(encode_value(Value::I32(-7)), -7.0);
        assert_eq!(encode_value(Value::U32(100_000)), 100_000.0);
        assert_eq!(encode_value(Value::Bool(true)), 1.0);
        assert_eq!(decode_value(3.0, ValueType::I32), Some(Value::I32(3)));
        assert_eq!(decode_value(3.5, ValueType::I32), None);
        assert_eq!(decode_value(-1.0, ValueType::U32), None);
        assert_eq!(decode_value(1.0, ValueType::Bool), Some(Value::Bool(true)));
        assert_eq!(decode_value(2.0, ValueType::Bool), None);
        assert_eq!(decode_value(f32::NAN, ValueType::F32), None);
        assert_eq!(decode_value(0.5, ValueType::F32), Some(Value::F32(0.5)));
        assert_eq!(
            param_type(ValueType::F32),
            MavParamType::MAV_PARAM_TYPE_REAL32
        );
    }

    #[test]
    fn ids_read_from_nul_padded_bytes() {
        let mut raw = [0u8; 16];
        raw[..11].copy_from_slice(b"CTL_ROLL_KP");
        assert_eq!(id_from_bytes(&raw), "CTL_ROLL_KP");
        assert_eq!(id_from_bytes(b"ABCDEFGHIJKLMNOP"), "ABCDEFGHIJKLMNOP");
        assert_eq!(id_from_bytes(&[0xFF, b'A']), "\u{FFFD}A");
    }
}
