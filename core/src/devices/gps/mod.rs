//! GPS: NMEA 0183 `GGA`, `RMC`, `VTG`, `GSA`, `GST` and Ashtech `$PASHR,POS`, merged into one
//! [`GpsFix`] per receiver epoch.
//!
//! # Why our own parser, for every sentence
//!
//! The `nmea` crate (0.7, AeroRust) was evaluated. It is no_std and allocation-free with
//! `default-features = false`, and it parses all five NMEA sentences. We use it only as a
//! dev-dependency, to cross-check our fields on the same bytes in tests and to benchmark
//! against, because for the flight path:
//!
//! - `$PASHR,POS` is not among its sentences, and its `SENTENCE_MAX_LEN` of 102 characters is
//!   below what a full-precision POS line reaches, so a second parser has to exist anyway;
//!   one parser for all six sentences keeps one set of rules for empty fields (= no fix),
//!   range checks and units, which is where the epoch merge needs them to agree;
//! - it parses one complete sentence from a `&str`; the byte-level work (line assembly,
//!   resync, bounded buffers, counting each kind of problem separately) is ours regardless;
//! - it would add nom, chrono, arrayvec, num-traits and a second heapless major version to
//!   the flight binary, and its newest release (0.8) needs a newer Rust than our MSRV;
//! - its results are f32/chrono types we would convert again, sentence by sentence.
//!
//! The parser here is a single pass over the fields with no backtracking, so it is at least
//! not slower; the benchmark that compares both on the same bytes is a later issue.
//!
//! # Epochs
//!
//! A receiver sends several sentences per epoch. Sentences with a UTC time (GGA, RMC, GST,
//! POS) belong to the epoch of that time; VTG and GSA carry none and join the epoch in
//! progress. An epoch is emitted when the next one visibly starts: a different UTC time, or
//! a sentence type the epoch already has (GSA excepted: multi-constellation receivers send
//! one per constellation). That costs one epoch of latency, so when the receiver is
//! programmed to end each epoch with a known sentence, name it in
//! [`GpsConfig::epoch_end`] and the fix goes out as soon as that sentence arrives.

use super::{Decoder, DecoderStats, Staleness, bump, bump_by};
use core::fmt::Write as _;
use heapless::{String, Vec};

/// Longest sentence accepted, between `$` and the line end (checksum included). NMEA allows
/// 80; Ashtech POS lines run past 100.
pub const MAX_SENTENCE_LEN: usize = 128;
/// Default staleness timeout: ten epochs at 10 Hz.
pub const DEFAULT_STALE_TIMEOUT_NS: u64 = 1_000_000_000;

const METRES_PER_SECOND_PER_KNOT: f64 = 1852.0 / 3600.0;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SentenceKind {
    Gga,
    Rmc,
    Vtg,
    Gsa,
    Gst,
    /// Ashtech `$PASHR,POS`.
    AshtechPos,
}

impl SentenceKind {
    /// Every kind, in the order a receiver configured as core's `GpsConfig` sends an epoch
    /// (Ashtech POS last: it ends the epoch).
    pub const ALL: [Self; 6] = [
        Self::Gga,
        Self::Rmc,
        Self::Vtg,
        Self::Gsa,
        Self::Gst,
        Self::AshtechPos,
    ];

    const fn bit(self) -> u8 {
        match self {
            SentenceKind::Gga => 1 << 0,
            SentenceKind::Rmc => 1 << 1,
            SentenceKind::Vtg => 1 << 2,
            SentenceKind::Gsa => 1 << 3,
            SentenceKind::Gst => 1 << 4,
            SentenceKind::AshtechPos => 1 << 5,
        }
    }
}

/// Which sentences contributed to a fix.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SentenceSet(pub u8);

impl SentenceSet {
    pub const fn contains(self, kind: SentenceKind) -> bool {
        self.0 & kind.bit() != 0
    }
    pub const fn with(self, kind: SentenceKind) -> Self {
        Self(self.0 | kind.bit())
    }
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }
}

/// The receiver's solution type (GGA quality, POS mode).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FixQuality {
    NoFix,
    Autonomous,
    /// Code differential (RTCM, SBAS).
    Differential,
    RtkFloat,
    RtkFixed,
    /// Dead reckoning: not a measurement, so not a valid fix.
    Estimated,
    /// Manual input, simulation or a code we do not know: not a valid fix.
    Other(u8),
}

impl FixQuality {
    fn from_gga(code: u8) -> Self {
        match code {
            0 => Self::NoFix,
            1 => Self::Autonomous,
            2 | 3 => Self::Differential,
            4 => Self::RtkFixed,
            5 => Self::RtkFloat,
            6 => Self::Estimated,
            other => Self::Other(other),
        }
    }

    /// The GGA fix-quality digit (logs carry it as a number).
    pub fn gga_code(self) -> u8 {
        match self {
            Self::NoFix => 0,
            Self::Autonomous => 1,
            Self::Differential => 2,
            Self::RtkFixed => 4,
            Self::RtkFloat => 5,
            Self::Estimated => 6,
            Self::Other(code) => code,
        }
    }

    fn from_ashtech(code: u8) -> Self {
        match code {
            0 => Self::Autonomous,
            1 | 9 | 10 => Self::Differential,
            2 | 12 | 22 => Self::RtkFloat,
            3 | 13 | 23 => Self::RtkFixed,
            5 => Self::Estimated,
            other => Self::Other(other),
        }
    }

    fn ashtech_code(self) -> u8 {
        match self {
            Self::NoFix | Self::Autonomous => 0,
            Self::Differential => 1,
            Self::RtkFloat => 2,
            Self::RtkFixed => 3,
            Self::Estimated => 5,
            Self::Other(code) => code,
        }
    }

    pub fn is_measured_fix(self) -> bool {
        matches!(
            self,
            Self::Autonomous | Self::Differential | Self::RtkFloat | Self::RtkFixed
        )
    }
}

/// GSA's fix mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FixDimension {
    NoFix,
    TwoD,
    ThreeD,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UtcDate {
    pub year: u16,
    pub month: u8,
    pub day: u8,
}

/// Everything one receiver epoch said. Fields the receiver left empty (no fix, or sentences
/// it was not programmed to send) are `None`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GpsFix {
    /// `now_ns` of the `push` that completed the epoch's first sentence.
    pub received_ns: u64,
    pub sentences: SentenceSet,
    /// UTC time of day of the epoch, in milliseconds.
    pub utc_time_ms: Option<u32>,
    pub utc_date: Option<UtcDate>,
    /// A measured position, and no sentence of the epoch said otherwise.
    pub valid: bool,
    pub quality: Option<FixQuality>,
    pub dimension: Option<FixDimension>,
    pub satellites: Option<u8>,
    /// WGS-84, degrees (conventions.md), north positive.
    pub latitude_deg: Option<f64>,
    /// WGS-84, degrees, east positive.
    pub longitude_deg: Option<f64>,
    pub altitude_msl_m: Option<f64>,
    /// Height above the WGS-84 ellipsoid (what POS reports).
    pub altitude_ellipsoid_m: Option<f64>,
    /// Geoid height above the ellipsoid (GGA): ellipsoid height = MSL altitude + this.
    pub geoid_separation_m: Option<f32>,
    pub ground_speed_mps: Option<f32>,
    /// Course over ground, true north, clockwise.
    pub course_rad: Option<f32>,
    /// North, east, down. N/E come from speed and course; down only from POS.
    pub velocity_ned_mps: [Option<f32>; 3],
    pub pdop: Option<f32>,
    pub hdop: Option<f32>,
    pub vdop: Option<f32>,
    /// 1-σ position error north, east, down (GST).
    pub position_sd_m: [Option<f32>; 3],
}

mod decoder;
mod encode;
mod epoch;
mod fields;
mod line;
mod sentences;

pub use decoder::NmeaDecoder;
use decoder::*;
pub use encode::{Talker, encode_sentence};
use epoch::*;
use fields::*;
pub use line::nmea_checksum;
use line::*;
use sentences::*;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GpsConfig {
    pub stale_timeout_ns: u64,
    /// The sentence the receiver is programmed to send last in each epoch, if any.
    pub epoch_end: Option<SentenceKind>,
}

impl Default for GpsConfig {
    fn default() -> Self {
        Self {
            stale_timeout_ns: DEFAULT_STALE_TIMEOUT_NS,
            epoch_end: None,
        }
    }
}

#[cfg(test)]
mod tests;
