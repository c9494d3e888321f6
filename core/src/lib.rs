//! skyframe's flight core.
//!
//! `no_std`, no heap, no OS: everything here runs inside the cyclic executive's frames and
//! never blocks. The data's path through the crate:
//!
//! - [`schedule`]: the frame table, built at compile time from `schedule.toml`;
//! - [`executive`]: steps the tasks frame by frame, measures them, applies overrun policies,
//!   keeps health and emits one timing record per frame;
//! - [`comm`]: the lock-free ways tasks hand data to each other and to the shell;
//! - [`devices`]: the GPS, IMU and servo board wire protocols, bytes to SI-unit frames and
//!   back;
//! - [`estimation`]: the alignment and the error-state EKF behind the estimator task;
//! - [`control`]: PID loops, the successive-loop autopilot, missions and flight modes;
//! - [`tasks`]: the tasks the schedule names;
//! - [`logfmt`]: the binary flight log: encoding records, reading and printing them;
//! - [`link`]: the vehicle–ground protocol: messages, encoding, command authentication;
//! - [`horizon`]: roll and pitch from a camera frame (edges, Hough, sky/ground validation).
//!
//! The OS side (threads, files, sockets, timers) lives in `skyframe-shell` and the
//! `platform-*` crates, behind the traits in [`executive::clock`] and [`comm`].
#![no_std]

#[cfg(any(test, feature = "schedule-file"))]
extern crate std;

#[macro_use]
pub mod angles;
pub mod comm;
pub mod control;
pub mod devices;
pub mod estimation;
pub mod executive;
pub mod facade;
pub mod horizon;
pub mod link;
pub mod logfmt;
pub mod schedule;
pub mod stats;
pub mod tasks;
