//! The std shell around the flight core.
//!
//! The core steps tasks; the shell gives them an OS to live on: the executive thread (with
//! whatever real-time settings the platform grants), the threads that move bytes between
//! rings and devices, files and sockets, and the `skyframe` command line. Platform crates
//! (`platform-linux`, `platform-qnx`, `platform-sim`) provide the timer and the device
//! back ends through [`platform::Platform`].

pub mod bench;
pub mod bench_parsers;
pub mod check_schedule;
pub mod cli;
pub mod cyclictest;
pub mod executive_log;
pub mod flight;
pub mod flightdir;
pub mod host;
pub mod idle;
pub mod link;
pub mod logwriter;
pub mod mavlink;
pub mod mission;
pub mod platform;
pub mod replay;
pub mod ring;
pub mod score;
pub mod serial;
pub mod simflight;
pub mod soak;
pub mod speedup;
pub mod stats;
pub mod summary;
pub mod tasks;
pub mod textlog;
pub mod vehicle;
