//! Parameters the ground can read and set while the vehicle runs: a fixed-capacity table of
//! named, typed values, each with an inclusive range.

use super::messages::{Name, ParamValue, Value, ValueType};
use heapless::Vec;

/// Most parameters one table holds (the "changed" set is a `u64` bit mask).
pub const MAX_PARAMS: usize = 64;

/// One parameter. Value, minimum and maximum always have the same type, and the value is
/// always within the range.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Param {
    name: Name,
    value: Value,
    min: Value,
    max: Value,
}

impl Param {
    pub fn name(&self) -> &Name {
        &self.name
    }
    pub fn value(&self) -> Value {
        self.value
    }
    pub fn min(&self) -> Value {
        self.min
    }
    pub fn max(&self) -> Value {
        self.max
    }
    pub fn value_type(&self) -> ValueType {
        self.value.value_type()
    }
}

/// Why a parameter could not be added to a table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DefineError {
    Full,
    Duplicate,
    /// Empty, longer than 32 bytes, or a character outside `A-Z a-z 0-9 _ . -`.
    BadName,
    /// Value, minimum and maximum are not of one type.
    TypeMismatch,
    /// The default is outside its own range, or the range is empty.
    OutOfRange,
}

/// What a set (or the check before one) did.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SetParamResult {
    Accepted { in_force: Value },
    OutOfRange { in_force: Value },
    WrongType { in_force: Value },
    Unknown,
}

impl SetParamResult {
    /// The value in force after the set, for the acknowledgement.
    pub fn in_force(&self) -> Option<Value> {
        match *self {
            SetParamResult::Accepted { in_force }
            | SetParamResult::OutOfRange { in_force }
            | SetParamResult::WrongType { in_force } => Some(in_force),
            SetParamResult::Unknown => None,
        }
    }
}

#[derive(Clone, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ParamTable {
    params: Vec<Param, MAX_PARAMS>,
    /// Bit per index: changed since the last [`ParamTable::take_changed`].
    changed: u64,
}

impl ParamTable {
    pub const fn new() -> Self {
        Self {
            params: Vec::new(),
            changed: 0,
        }
    }

    /// Adds a parameter and returns its index.
    pub fn define(
        &mut self,
        name: &str,
        value: Value,
        min: Value,
        max: Value,
    ) -> Result<u16, DefineError> {
        let name = Name::new(name)
            .filter(|n| !n.is_empty())
            .ok_or(DefineError::BadName)?;
        if self.index_of(&name).is_some() {
            return Err(DefineError::Duplicate);
        }
        match value.within(&min, &max) {
            None => return Err(DefineError::TypeMismatch),
            Some(false) => return Err(DefineError::OutOfRange),
            Some(true) => {}
        }
        let index = u16::try_from(self.params.len()).map_err(|_| DefineError::Full)?;
        self.params
            .push(Param {
                name,
                value,
                min,
                max,
            })
            .map_err(|_| DefineError::Full)?;
        Ok(index)
    }

    pub fn len(&self) -> usize {
        self.params.len()
    }

    pub fn is_empty(&self) -> bool {
        self.params.is_empty()
    }

    pub fn index_of(&self, name: &Name) -> Option<usize> {
        self.params.iter().position(|p| p.name == *name)
    }

    pub fn get(&self, name: &str) -> Option<&Param> {
        let name = Name::new(name)?;
        self.params.iter().find(|p| p.name == name)
    }

    pub fn by_index(&self, index: usize) -> Option<&Param> {
        self.params.get(index)
    }

    pub fn iter(&self) -> impl Iterator<Item = &Param> {
        self.params.iter()
    }

    /// What [`set`](Self::set) would do, without doing it.
    pub fn check(&self, name: &Name, value: &Value) -> SetParamResult {
        match self.index_of(name).and_then(|i| self.params.get(i)) {
            None => SetParamResult::Unknown,
            Some(param) => check_param(param, value),
        }
    }

    /// Sets a parameter if the name is known, the type matches and the value is in range;
    /// otherwise changes nothing. Marks the parameter changed if its value did.
    pub fn set(&mut self, name: &Name, value: Value) -> SetParamResult {
        let Some(index) = self.index_of(name) else {
            return SetParamResult::Unknown;
        };
        let Some(param) = self.params.get_mut(index) else {
            return SetParamResult::Unknown;
        };
        let result = check_param(param, &value);
        if let SetParamResult::Accepted { .. } = result {
            if !param.value.same_bits(&value) {
                self.changed |= 1u64 << index;
            }
            param.value = value;
        }
        result
    }

    /// The next parameter changed since it was last taken (lowest index first), clearing
    /// its mark: the link sends a [`ParamValue`] for each.
    pub fn take_changed(&mut self) -> Option<usize> {
        if self.changed == 0 {
            return None;
        }
        let index = self.changed.trailing_zeros();
        self.changed &= !(1u64 << index);
        usize::try_from(index).ok()
    }

    /// The telemetry message reporting the parameter at `index`.
    pub fn report(&self, index: usize) -> Option<ParamValue> {
        let param = self.params.get(index)?;
        Some(ParamValue {
            index: u16::try_from(index).ok()?,
            count: u16::try_from(self.params.len()).ok()?,
            name: param.name,
            value: param.value,
            min: param.min,
            max: param.max,
        })
    }
}

fn check_param(param: &Param, value: &Value) -> SetParamResult {
    let in_force = param.value;
    match value.within(&param.min, &param.max) {
        None => SetParamResult::WrongType { in_force },
        Some(false) => SetParamResult::OutOfRange { in_force },
        Some(true) => SetParamResult::Accepted { in_force: *value },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table() -> ParamTable {
        let mut t = ParamTable::new();
        t.define(
            "roll_gain",
            Value::F32(0.5),
            Value::F32(0.0),
            Value::F32(2.0),
        )
        .expect("define");
        t.define(
            "log_imu",
            Value::Bool(true),
            Value::Bool(false),
            Value::Bool(true),
        )
        .expect("define");
        t.define(
            "max_bank_deg",
            Value::I32(30),
            Value::I32(5),
            Value::I32(60),
        )
        .expect("define");
        t
    }

    fn name(text: &str) -> Name {
        Name::new(text).expect("valid name")
    }

    #[test]
    fn define_refuses_bad_tables() {
        let mut t = table();
        let v = Value::U32(1);
        assert_eq!(t.define("roll_gain", v, v, v), Err(DefineError::Duplicate));
        assert_eq!(t.define("", v, v, v), Err(DefineError::BadName));
        assert_eq!(t.define("has space", v, v, v), Err(DefineError::BadName));
        assert_eq!(
            t.define("x", v, Value::I32(0), v),
            Err(DefineError::TypeMismatch)
        );
        assert_eq!(
            t.define("x", Value::U32(5), Value::U32(0), Value::U32(4)),
            Err(DefineError::OutOfRange)
        );
        assert_eq!(
            t.define("x", Value::F32(f32::NAN), Value::F32(0.0), Value::F32(1.0)),
            Err(DefineError::OutOfRange)
        );
        let mut full = ParamTable::new();
        let mut text = [0u8; 3];
        for i in 0..MAX_PARAMS {
            text = [b'p', b'0' + (i / 10) as u8, b'0' + (i % 10) as u8];
            let n = core::str::from_utf8(&text).expect("ascii");
            assert_eq!(full.define(n, v, v, v), Ok(i as u16));
        }
        assert_eq!(full.define("last", v, v, v), Err(DefineError::Full));
        assert_ne!(text, [0; 3]);
    }

    #[test]
    fn set_checks_name_type_and_range_and_reports_the_value_in_force() {
        let mut t = table();
        let gain = name("roll_gain");
        // Each set in turn, and what it answers: the value in force after it.
        let in_force = Value::F32(1.5);
        for (value, answer) in [
            (in_force, SetParamResult::Accepted { in_force }),
            (Value::F32(2.5), SetParamResult::OutOfRange { in_force }),
            (
                Value::F32(f32::NAN),
                SetParamResult::OutOfRange { in_force },
            ),
            (Value::I32(1), SetParamResult::WrongType { in_force }),
        ] {
            assert_eq!(t.set(&gain, value), answer, "{value:?}");
        }
        assert_eq!(
            t.set(&name("yaw_gain"), Value::F32(1.0)),
            SetParamResult::Unknown
        );
        assert_eq!(t.get("roll_gain").map(Param::value), Some(Value::F32(1.5)));
        // Range ends are inclusive.
        assert!(matches!(
            t.set(&name("max_bank_deg"), Value::I32(60)),
            SetParamResult::Accepted { .. }
        ));
        assert!(matches!(
            t.check(&name("max_bank_deg"), &Value::I32(61)),
            SetParamResult::OutOfRange { .. }
        ));
    }

    #[test]
    fn changes_are_reported_once_and_only_real_changes() {
        let mut t = table();
        assert_eq!(t.take_changed(), None);
        t.set(&name("log_imu"), Value::Bool(true)); // same value: no change
        assert_eq!(t.take_changed(), None);
        t.set(&name("max_bank_deg"), Value::I32(45));
        t.set(&name("roll_gain"), Value::F32(1.0));
        t.set(&name("roll_gain"), Value::F32(3.0)); // refused: no change
        assert_eq!(t.take_changed(), Some(0));
        assert_eq!(t.take_changed(), Some(2));
        assert_eq!(t.take_changed(), None);
        let report = t.report(2).expect("report");
        assert_eq!(
            (report.index, report.count, report.name, report.value),
            (2, 3, name("max_bank_deg"), Value::I32(45))
        );
        assert_eq!(t.report(3), None);
    }
}
