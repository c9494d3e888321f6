//! The skyframe ground station: a model of the vehicles heard, the link to them, the
//! scriptable commands and the terminal UI. `docs/link-protocol.md` is the wire contract.

pub mod bench;
pub mod cli;
pub mod exit;
pub mod fake_vehicle;
pub mod json;
pub mod key;
pub mod model;
pub mod net;
pub mod ui;
pub mod values;
