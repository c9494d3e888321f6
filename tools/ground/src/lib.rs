//! The skyframe ground station: a model of the vehicles heard, the link to them, the
//! scriptable commands and the terminal UI. `docs/link-protocol.md` is the wire contract.

pub mod model;
