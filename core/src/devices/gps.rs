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

/// What a sentence adds to its epoch: a partial fix plus what it says about validity.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Update {
    fix: GpsFix,
    /// `Some(false)` when the sentence says there is no fix; `Some(true)` when it vouches
    /// for one.
    validity: Option<bool>,
    speed_knots: Option<f64>,
    course_deg: Option<f64>,
    vertical_up_mps: Option<f64>,
}

/// The epoch being assembled.
#[derive(Clone, Copy, Debug, Default)]
struct Epoch {
    update: Update,
}

macro_rules! newer_wins {
    ($into:expr, $from:expr; $($field:ident),* $(,)?) => {
        $( if $from.$field.is_some() { $into.$field = $from.$field; } )*
    };
}

impl Epoch {
    fn is_empty(&self) -> bool {
        self.update.fix.sentences.is_empty()
    }

    fn merge(&mut self, kind: SentenceKind, new: &Update) {
        let fix = &mut self.update.fix;
        fix.sentences = fix.sentences.with(kind);
        newer_wins!(fix, new.fix;
            utc_time_ms, utc_date, quality, dimension, satellites, latitude_deg, longitude_deg,
            altitude_msl_m, altitude_ellipsoid_m, geoid_separation_m, pdop, hdop, vdop);
        for (into, from) in fix.position_sd_m.iter_mut().zip(new.fix.position_sd_m) {
            if from.is_some() {
                *into = from;
            }
        }
        let update = &mut self.update;
        newer_wins!(update, new; speed_knots, course_deg, vertical_up_mps);
        // One "no fix" in an epoch is enough to distrust the whole epoch.
        update.validity = match (update.validity, new.validity) {
            (Some(false), _) | (_, Some(false)) => Some(false),
            (Some(true), _) | (_, Some(true)) => Some(true),
            (None, None) => None,
        };
    }

    fn finish(&self) -> GpsFix {
        let update = &self.update;
        let mut fix = update.fix;
        let separation = fix.geoid_separation_m.map(f64::from);
        if fix.altitude_msl_m.is_none() {
            fix.altitude_msl_m = fix
                .altitude_ellipsoid_m
                .zip(separation)
                .map(|(ellipsoid, separation)| ellipsoid - separation);
        }
        if fix.altitude_ellipsoid_m.is_none() {
            fix.altitude_ellipsoid_m = fix
                .altitude_msl_m
                .zip(separation)
                .map(|(msl, separation)| msl + separation);
        }
        let speed_mps = update
            .speed_knots
            .map(|knots| knots * METRES_PER_SECOND_PER_KNOT);
        let course_rad = update.course_deg.map(f64::to_radians);
        fix.ground_speed_mps = speed_mps.map(|speed| speed as f32);
        fix.course_rad = course_rad.map(|course| course as f32);
        let horizontal = match (speed_mps, course_rad) {
            (Some(speed), Some(course)) => {
                Some((speed * libm::cos(course), speed * libm::sin(course)))
            }
            // Receivers leave the course empty when standing still.
            (Some(0.0), None) => Some((0.0, 0.0)),
            _ => None,
        };
        fix.velocity_ned_mps = [
            horizontal.map(|(north, _)| north as f32),
            horizontal.map(|(_, east)| east as f32),
            update.vertical_up_mps.map(|up| -up as f32),
        ];
        fix.valid = update.validity == Some(true)
            && fix.latitude_deg.is_some()
            && fix.longitude_deg.is_some()
            && fix.quality.is_none_or(FixQuality::is_measured_fix)
            && fix.dimension != Some(FixDimension::NoFix);
        fix
    }
}

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

/// Decodes a GPS receiver's byte stream into [`GpsFix`]es.
///
/// Staleness means the receiver is silent or garbled: a receiver without a fix still sends
/// good sentences and is not stale; [`GpsFix::valid`] says whether it has a fix.
#[derive(Clone, Debug)]
pub struct NmeaDecoder {
    config: GpsConfig,
    line: Vec<u8, MAX_SENTENCE_LEN>,
    in_sentence: bool,
    epoch: Epoch,
    stats: DecoderStats,
    staleness: Staleness,
}

impl Default for NmeaDecoder {
    fn default() -> Self {
        Self::new(GpsConfig::default())
    }
}

/// Why a checksummed sentence's contents were refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct InvalidField;

type FieldResult<T> = Result<T, InvalidField>;

impl NmeaDecoder {
    pub const fn new(config: GpsConfig) -> Self {
        Self {
            config,
            line: Vec::new(),
            in_sentence: false,
            epoch: Epoch {
                update: Update {
                    fix: GpsFix {
                        received_ns: 0,
                        sentences: SentenceSet(0),
                        utc_time_ms: None,
                        utc_date: None,
                        valid: false,
                        quality: None,
                        dimension: None,
                        satellites: None,
                        latitude_deg: None,
                        longitude_deg: None,
                        altitude_msl_m: None,
                        altitude_ellipsoid_m: None,
                        geoid_separation_m: None,
                        ground_speed_mps: None,
                        course_rad: None,
                        velocity_ned_mps: [None; 3],
                        pdop: None,
                        hdop: None,
                        vdop: None,
                        position_sd_m: [None; 3],
                    },
                    validity: None,
                    speed_knots: None,
                    course_deg: None,
                    vertical_up_mps: None,
                },
            },
            stats: DecoderStats::new(),
            staleness: Staleness::new(config.stale_timeout_ns),
        }
    }

    pub fn stats(&self) -> &DecoderStats {
        &self.stats
    }

    pub fn staleness(&self) -> &Staleness {
        &self.staleness
    }

    pub fn push(&mut self, bytes: &[u8], now_ns: u64, mut out: impl FnMut(GpsFix)) {
        for &byte in bytes {
            self.push_byte(byte, now_ns, &mut out);
        }
        if self.staleness.update(now_ns) {
            bump(&mut self.stats.stale_events);
        }
    }

    /// Emits the epoch in progress, if any (end of a log, or a receiver gone quiet).
    pub fn flush(&mut self, mut out: impl FnMut(GpsFix)) {
        self.emit_epoch(&mut out);
    }

    fn push_byte(&mut self, byte: u8, now_ns: u64, out: &mut dyn FnMut(GpsFix)) {
        match byte {
            b'$' => {
                if self.in_sentence {
                    // The previous sentence never ended: cut short by noise or a restart.
                    bump(&mut self.stats.framing_errors);
                    self.discard_line();
                }
                self.in_sentence = true;
            }
            b'\r' | b'\n' => {
                if self.in_sentence {
                    self.end_of_line(now_ns, out);
                }
            }
            _ if !self.in_sentence => bump(&mut self.stats.bytes_discarded),
            0x20..=0x7E => {
                if self.line.push(byte).is_err() {
                    bump(&mut self.stats.overflows);
                    bump(&mut self.stats.bytes_discarded);
                    self.discard_line();
                }
            }
            _ => {
                bump(&mut self.stats.framing_errors);
                bump(&mut self.stats.bytes_discarded);
                self.discard_line();
            }
        }
    }

    /// Drops the sentence in progress, counting its bytes and its `$`.
    fn discard_line(&mut self) {
        bump_by(&mut self.stats.bytes_discarded, self.line.len() + 1);
        self.line.clear();
        self.in_sentence = false;
    }

    fn end_of_line(&mut self, now_ns: u64, out: &mut dyn FnMut(GpsFix)) {
        let verdict = check_sentence(&self.line);
        match verdict {
            LineVerdict::Framing => {
                bump(&mut self.stats.framing_errors);
                self.discard_line();
                return;
            }
            LineVerdict::BadChecksum => {
                bump(&mut self.stats.bad_checksum);
                self.discard_line();
                return;
            }
            LineVerdict::Good { body_len } => {
                let body = self.line.get(..body_len).unwrap_or_default();
                match parse_sentence(body) {
                    Ok(Some((kind, update))) => {
                        bump(&mut self.stats.frames);
                        self.staleness.mark_valid(now_ns);
                        self.accept(kind, &update, now_ns, out);
                    }
                    Ok(None) => bump(&mut self.stats.ignored),
                    Err(InvalidField) => bump(&mut self.stats.invalid_payload),
                }
            }
        }
        self.line.clear();
        self.in_sentence = false;
    }

    fn accept(
        &mut self,
        kind: SentenceKind,
        update: &Update,
        now_ns: u64,
        out: &mut dyn FnMut(GpsFix),
    ) {
        let current = &self.epoch.update.fix;
        let time_changed = matches!(
            (current.utc_time_ms, update.fix.utc_time_ms),
            (Some(epoch_time), Some(time)) if epoch_time != time
        );
        let repeated = kind != SentenceKind::Gsa && current.sentences.contains(kind);
        if !self.epoch.is_empty() && (time_changed || repeated) {
            self.emit_epoch(out);
        }
        if self.epoch.is_empty() {
            self.epoch.update.fix.received_ns = now_ns;
        }
        self.epoch.merge(kind, update);
        if self.config.epoch_end == Some(kind) {
            self.emit_epoch(out);
        }
    }

    fn emit_epoch(&mut self, out: &mut dyn FnMut(GpsFix)) {
        if !self.epoch.is_empty() {
            out(self.epoch.finish());
        }
        self.epoch = Epoch::default();
    }
}

impl Decoder for NmeaDecoder {
    type Frame = GpsFix;

    fn push(&mut self, bytes: &[u8], now_ns: u64, out: &mut dyn FnMut(GpsFix)) {
        NmeaDecoder::push(self, bytes, now_ns, out)
    }

    fn stats(&self) -> &DecoderStats {
        &self.stats
    }

    fn is_stale(&self, now_ns: u64) -> bool {
        self.staleness.is_stale(now_ns)
    }
}

enum LineVerdict {
    /// The sentence body (before `*`) is `line[..body_len]` and its checksum matched.
    Good {
        body_len: usize,
    },
    BadChecksum,
    Framing,
}

/// The NMEA checksum: XOR of every byte between `$` and `*`.
pub fn nmea_checksum(body: &[u8]) -> u8 {
    body.iter().fold(0, |acc, &byte| acc ^ byte)
}

fn hex_digit(byte: u8) -> Option<u8> {
    match byte {
        b'0'..=b'9' => Some(byte - b'0'),
        b'A'..=b'F' => Some(byte - b'A' + 10),
        b'a'..=b'f' => Some(byte - b'a' + 10),
        _ => None,
    }
}

fn check_sentence(line: &[u8]) -> LineVerdict {
    let Some(star) = line.iter().rposition(|&b| b == b'*') else {
        return LineVerdict::Framing;
    };
    let Some((body, checksum_field)) = line.split_at_checked(star) else {
        return LineVerdict::Framing;
    };
    let expected = match checksum_field {
        [b'*', high, low] => match (hex_digit(*high), hex_digit(*low)) {
            (Some(high), Some(low)) => (high << 4) | low,
            _ => return LineVerdict::Framing,
        },
        _ => return LineVerdict::Framing,
    };
    if nmea_checksum(body) == expected {
        LineVerdict::Good { body_len: star }
    } else {
        LineVerdict::BadChecksum
    }
}

/// The fields of a sentence body, with a cursor. Reading past the last field gives empty
/// fields, which is what receivers that omit trailing fields mean.
struct Fields<'a> {
    rest: Option<&'a [u8]>,
}

impl<'a> Fields<'a> {
    fn new(body: &'a [u8]) -> Self {
        Self { rest: Some(body) }
    }

    fn next_field(&mut self) -> &'a [u8] {
        let Some(rest) = self.rest else {
            return &[];
        };
        let split = rest
            .iter()
            .position(|&b| b == b',')
            .and_then(|comma| rest.split_at_checked(comma));
        match split {
            Some((field, tail)) => {
                self.rest = tail.get(1..);
                field
            }
            None => {
                self.rest = None;
                rest
            }
        }
    }

    fn skip(&mut self, n: usize) {
        for _ in 0..n {
            self.next_field();
        }
    }

    /// A decimal number with optional sign and point, within `range`; empty is `None`.
    fn number(&mut self, range: core::ops::RangeInclusive<f64>) -> FieldResult<Option<f64>> {
        let field = self.next_field();
        if field.is_empty() {
            return Ok(None);
        }
        parse_decimal(field)
            .filter(|value| range.contains(value))
            .map(Some)
            .ok_or(InvalidField)
    }

    fn small_integer(&mut self) -> FieldResult<Option<u8>> {
        let field = self.next_field();
        if field.is_empty() {
            return Ok(None);
        }
        if !field.iter().all(u8::is_ascii_digit) {
            return Err(InvalidField);
        }
        let text = core::str::from_utf8(field).map_err(|_| InvalidField)?;
        text.parse::<u8>().map(Some).map_err(|_| InvalidField)
    }

    fn character(&mut self) -> FieldResult<Option<u8>> {
        match self.next_field() {
            [] => Ok(None),
            [single] => Ok(Some(*single)),
            _ => Err(InvalidField),
        }
    }

    /// `hhmmss[.s…]` → milliseconds of the day.
    fn utc_time(&mut self) -> FieldResult<Option<u32>> {
        let field = self.next_field();
        if field.is_empty() {
            return Ok(None);
        }
        let (whole, fraction) = match field.iter().position(|&b| b == b'.') {
            Some(point) => (field.get(..point), field.get(point + 1..)),
            None => (Some(field), Some(&[][..])),
        };
        let (Some(whole), Some(fraction)) = (whole, fraction) else {
            return Err(InvalidField);
        };
        let [h1, h0, m1, m0, s1, s0] = whole else {
            return Err(InvalidField);
        };
        let two = |tens: u8, ones: u8| -> FieldResult<u32> {
            if tens.is_ascii_digit() && ones.is_ascii_digit() {
                Ok(u32::from(tens - b'0') * 10 + u32::from(ones - b'0'))
            } else {
                Err(InvalidField)
            }
        };
        let (hours, minutes, seconds) = (two(*h1, *h0)?, two(*m1, *m0)?, two(*s1, *s0)?);
        // 60 s is a leap second.
        if hours > 23 || minutes > 59 || seconds > 60 || !fraction.iter().all(u8::is_ascii_digit) {
            return Err(InvalidField);
        }
        let millis = fraction
            .iter()
            .chain(core::iter::repeat(&b'0'))
            .take(3)
            .fold(0u32, |acc, digit| {
                acc * 10 + u32::from(digit.wrapping_sub(b'0'))
            });
        Ok(Some(
            ((hours * 60 + minutes) * 60 + seconds) * 1000 + millis,
        ))
    }

    /// `ddmmyy`; years 80–99 are 1980–1999 (GPS time starts in 1980).
    fn utc_date(&mut self) -> FieldResult<Option<UtcDate>> {
        let field = self.next_field();
        if field.is_empty() {
            return Ok(None);
        }
        let [d1, d0, m1, m0, y1, y0] = field else {
            return Err(InvalidField);
        };
        if ![d1, d0, m1, m0, y1, y0].iter().all(|b| b.is_ascii_digit()) {
            return Err(InvalidField);
        }
        let two = |tens: u8, ones: u8| (tens - b'0') * 10 + (ones - b'0');
        let (day, month, year) = (two(*d1, *d0), two(*m1, *m0), two(*y1, *y0));
        if !(1..=31).contains(&day) || !(1..=12).contains(&month) {
            return Err(InvalidField);
        }
        let year = if year >= 80 {
            1900 + u16::from(year)
        } else {
            2000 + u16::from(year)
        };
        Ok(Some(UtcDate { year, month, day }))
    }

    /// `ddmm.mmmm,N` or `dddmm.mmmm,E` → signed degrees. Both empty is `None`; one without
    /// the other is invalid.
    fn angle(&mut self, max_degrees: f64, positive: u8, negative: u8) -> FieldResult<Option<f64>> {
        let value = self.number(0.0..=max_degrees * 100.0)?;
        let hemisphere = self.character()?;
        let (value, hemisphere) = match (value, hemisphere) {
            (None, None) => return Ok(None),
            (Some(value), Some(hemisphere)) => (value, hemisphere),
            _ => return Err(InvalidField),
        };
        // `as` truncates toward zero: the whole degrees of a non-negative value.
        let degrees = (value / 100.0) as u32;
        let minutes = value - f64::from(degrees) * 100.0;
        let angle = f64::from(degrees) + minutes / 60.0;
        if minutes >= 60.0 || angle > max_degrees {
            return Err(InvalidField);
        }
        match hemisphere {
            h if h == positive => Ok(Some(angle)),
            h if h == negative => Ok(Some(-angle)),
            _ => Err(InvalidField),
        }
    }

    fn position(&mut self, update: &mut Update) -> FieldResult<()> {
        update.fix.latitude_deg = self.angle(90.0, b'N', b'S')?;
        update.fix.longitude_deg = self.angle(180.0, b'E', b'W')?;
        Ok(())
    }
}

/// A plain decimal (`-12.345`, `7`, `.5`): no exponents, no `inf`/`nan`, so every accepted
/// value is finite.
fn parse_decimal(field: &[u8]) -> Option<f64> {
    let digits = field
        .strip_prefix(b"-")
        .or_else(|| field.strip_prefix(b"+"))
        .unwrap_or(field);
    let mut seen_point = false;
    let mut seen_digit = false;
    for &byte in digits {
        match byte {
            b'0'..=b'9' => seen_digit = true,
            b'.' if !seen_point => seen_point = true,
            _ => return None,
        }
    }
    if !seen_digit {
        return None;
    }
    core::str::from_utf8(field)
        .ok()?
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
}

const SPEED_KNOTS: core::ops::RangeInclusive<f64> = 0.0..=10_000.0;
const COURSE_DEG: core::ops::RangeInclusive<f64> = 0.0..=360.0;
const DOP: core::ops::RangeInclusive<f64> = 0.0..=100.0;
const ALTITUDE_M: core::ops::RangeInclusive<f64> = -100_000.0..=100_000.0;
const GEOID_SEPARATION_M: core::ops::RangeInclusive<f64> = -1_000.0..=1_000.0;
const SD_M: core::ops::RangeInclusive<f64> = 0.0..=1.0e6;
const VERTICAL_SPEED_MPS: core::ops::RangeInclusive<f64> = -10_000.0..=10_000.0;

fn to_f32(value: Option<f64>) -> Option<f32> {
    value.map(|v| v as f32)
}

/// Parses a checksummed body (without `$` and `*hh`). `Ok(None)`: not a sentence we use.
fn parse_sentence(body: &[u8]) -> FieldResult<Option<(SentenceKind, Update)>> {
    let mut fields = Fields::new(body);
    let address = fields.next_field();
    let kind = match address {
        b"PASHR" => {
            if fields.next_field() != b"POS" {
                return Ok(None);
            }
            SentenceKind::AshtechPos
        }
        [b'G', b'P' | b'N' | b'L', rest @ ..] => match rest {
            b"GGA" => SentenceKind::Gga,
            b"RMC" => SentenceKind::Rmc,
            b"VTG" => SentenceKind::Vtg,
            b"GSA" => SentenceKind::Gsa,
            b"GST" => SentenceKind::Gst,
            _ => return Ok(None),
        },
        _ => return Ok(None),
    };
    let mut update = Update::default();
    match kind {
        SentenceKind::Gga => parse_gga(&mut fields, &mut update)?,
        SentenceKind::Rmc => parse_rmc(&mut fields, &mut update)?,
        SentenceKind::Vtg => parse_vtg(&mut fields, &mut update)?,
        SentenceKind::Gsa => parse_gsa(&mut fields, &mut update)?,
        SentenceKind::Gst => parse_gst(&mut fields, &mut update)?,
        SentenceKind::AshtechPos => parse_ashtech_pos(&mut fields, &mut update)?,
    }
    update.fix.sentences = SentenceSet::default().with(kind);
    Ok(Some((kind, update)))
}

/// `GGA,time,lat,N,lon,E,quality,satellites,hdop,altitude,M,separation,M,age,station`
fn parse_gga(fields: &mut Fields<'_>, update: &mut Update) -> FieldResult<()> {
    update.fix.utc_time_ms = fields.utc_time()?;
    fields.position(update)?;
    let quality = fields.small_integer()?.map(FixQuality::from_gga);
    update.fix.quality = quality;
    update.validity = quality.map(FixQuality::is_measured_fix);
    update.fix.satellites = fields.small_integer()?;
    update.fix.hdop = to_f32(fields.number(DOP)?);
    update.fix.altitude_msl_m = fields.number(ALTITUDE_M)?;
    fields.skip(1);
    update.fix.geoid_separation_m = to_f32(fields.number(GEOID_SEPARATION_M)?);
    Ok(())
}

/// `RMC,time,status,lat,N,lon,E,speed_kn,course,date,magvar,E[,mode[,nav_status]]`
fn parse_rmc(fields: &mut Fields<'_>, update: &mut Update) -> FieldResult<()> {
    update.fix.utc_time_ms = fields.utc_time()?;
    let status = fields.character()?;
    fields.position(update)?;
    update.speed_knots = fields.number(SPEED_KNOTS)?;
    update.course_deg = fields.number(COURSE_DEG)?;
    update.fix.utc_date = fields.utc_date()?;
    fields.skip(2);
    let mode = fields.character()?;
    update.validity = match (status, mode) {
        (Some(b'V'), _) | (_, Some(b'N')) => Some(false),
        (Some(b'A'), _) => Some(true),
        (None, _) => None,
        _ => return Err(InvalidField),
    };
    Ok(())
}

/// `VTG,course,T,course_magnetic,M,speed_kn,N,speed_kmh,K[,mode]`
fn parse_vtg(fields: &mut Fields<'_>, update: &mut Update) -> FieldResult<()> {
    let course = fields.number(COURSE_DEG)?;
    fields.skip(3);
    let speed = fields.number(SPEED_KNOTS)?;
    fields.skip(3);
    // Mode `N` (not valid): the velocity is not worth merging.
    if fields.character()? != Some(b'N') {
        update.course_deg = course;
        update.speed_knots = speed;
    }
    Ok(())
}

/// `GSA,selection,mode,sv×12,pdop,hdop,vdop[,system]`
fn parse_gsa(fields: &mut Fields<'_>, update: &mut Update) -> FieldResult<()> {
    fields.skip(1);
    update.fix.dimension = match fields.small_integer()? {
        None => None,
        Some(1) => Some(FixDimension::NoFix),
        Some(2) => Some(FixDimension::TwoD),
        Some(3) => Some(FixDimension::ThreeD),
        Some(_) => return Err(InvalidField),
    };
    if update.fix.dimension == Some(FixDimension::NoFix) {
        update.validity = Some(false);
    }
    fields.skip(12);
    update.fix.pdop = to_f32(fields.number(DOP)?);
    update.fix.hdop = to_f32(fields.number(DOP)?);
    update.fix.vdop = to_f32(fields.number(DOP)?);
    Ok(())
}

/// `GST,time,rms,sd_major,sd_minor,orientation,sd_lat,sd_lon,sd_alt`
fn parse_gst(fields: &mut Fields<'_>, update: &mut Update) -> FieldResult<()> {
    update.fix.utc_time_ms = fields.utc_time()?;
    fields.skip(4);
    let north = to_f32(fields.number(SD_M)?);
    let east = to_f32(fields.number(SD_M)?);
    let down = to_f32(fields.number(SD_M)?);
    update.fix.position_sd_m = [north, east, down];
    Ok(())
}

/// `PASHR,POS,mode,satellites,time,lat,N,lon,E,height,reserved,course,speed_kn,
/// vertical_mps,pdop,hdop,vdop,tdop,firmware` (Ashtech DG14/DG16 manual, table 6.36).
/// The height is above the ellipsoid; vertical velocity is positive up.
fn parse_ashtech_pos(fields: &mut Fields<'_>, update: &mut Update) -> FieldResult<()> {
    let mode = fields.small_integer()?;
    update.fix.satellites = fields.small_integer()?;
    update.fix.utc_time_ms = fields.utc_time()?;
    fields.position(update)?;
    update.fix.altitude_ellipsoid_m = fields.number(ALTITUDE_M)?;
    fields.skip(1);
    update.course_deg = fields.number(COURSE_DEG)?;
    update.speed_knots = fields.number(SPEED_KNOTS)?;
    update.vertical_up_mps = fields.number(VERTICAL_SPEED_MPS)?;
    update.fix.pdop = to_f32(fields.number(DOP)?);
    update.fix.hdop = to_f32(fields.number(DOP)?);
    update.fix.vdop = to_f32(fields.number(DOP)?);
    // POS has no "no fix" code: an empty position is how it says so.
    let has_position = update.fix.latitude_deg.is_some() && update.fix.longitude_deg.is_some();
    let quality = mode.map(FixQuality::from_ashtech);
    update.fix.quality = if has_position {
        quality
    } else {
        Some(FixQuality::NoFix)
    };
    update.validity = Some(has_position && quality.is_some_and(FixQuality::is_measured_fix));
    Ok(())
}

// ---------------------------------------------------------------------------------------
// Encoders: what the simulator sends, byte for byte what a receiver would.

/// The talker id an encoded sentence goes out with.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Talker {
    /// GPS only.
    #[default]
    Gp,
    /// Multi-constellation.
    Gn,
    /// GLONASS.
    Gl,
}

impl Talker {
    fn as_str(self) -> &'static str {
        match self {
            Talker::Gp => "GP",
            Talker::Gn => "GN",
            Talker::Gl => "GL",
        }
    }
}

type Body = String<MAX_SENTENCE_LEN>;

/// `hhmmss.ss`, or nothing.
fn write_time(body: &mut Body, time_ms: Option<u32>) -> core::fmt::Result {
    if let Some(ms) = time_ms {
        let seconds = ms / 1000;
        write!(
            body,
            "{:02}{:02}{:02}.{:02}",
            seconds / 3600 % 24,
            seconds / 60 % 60,
            seconds % 60,
            ms % 1000 / 10
        )?;
    }
    Ok(())
}

/// `ddmm.mmmmmm,N` with integer arithmetic, so the minutes never round up to 60.
fn write_angle(
    body: &mut Body,
    angle_deg: Option<f64>,
    degree_digits: usize,
    positive: char,
    negative: char,
) -> core::fmt::Result {
    let Some(angle) = angle_deg else {
        return body.write_str(",");
    };
    let micro_minutes = libm::round(libm::fabs(angle) * 60.0e6) as u64;
    let degrees = micro_minutes / 60_000_000;
    let minutes = micro_minutes % 60_000_000 / 1_000_000;
    let fraction = micro_minutes % 1_000_000;
    let hemisphere = if angle < 0.0 { negative } else { positive };
    write!(
        body,
        "{degrees:0degree_digits$}{minutes:02}.{fraction:06},{hemisphere}"
    )
}

fn write_opt<T: core::fmt::Display>(body: &mut Body, value: Option<T>) -> core::fmt::Result {
    match value {
        Some(value) => write!(body, "{value}"),
        None => Ok(()),
    }
}

fn write_fixed(body: &mut Body, value: Option<f64>, decimals: usize) -> core::fmt::Result {
    match value {
        Some(value) => write!(body, "{value:.decimals$}"),
        None => Ok(()),
    }
}

fn speed_knots(fix: &GpsFix) -> Option<f64> {
    fix.ground_speed_mps
        .map(|speed| f64::from(speed) / METRES_PER_SECOND_PER_KNOT)
}

fn course_deg(fix: &GpsFix) -> Option<f64> {
    fix.course_rad.map(|course| {
        let degrees = f64::from(course).to_degrees();
        if degrees < 0.0 {
            degrees + 360.0
        } else {
            degrees
        }
    })
}

fn write_body(
    kind: SentenceKind,
    talker: Talker,
    fix: &GpsFix,
    body: &mut Body,
) -> core::fmt::Result {
    let t = talker.as_str();
    match kind {
        SentenceKind::Gga => {
            write!(body, "{t}GGA,")?;
            write_time(body, fix.utc_time_ms)?;
            body.write_str(",")?;
            write_angle(body, fix.latitude_deg, 2, 'N', 'S')?;
            body.write_str(",")?;
            write_angle(body, fix.longitude_deg, 3, 'E', 'W')?;
            let quality = match fix.quality {
                Some(quality) => quality,
                None if fix.valid => FixQuality::Autonomous,
                None => FixQuality::NoFix,
            };
            write!(body, ",{},", quality.gga_code())?;
            write_opt(body, fix.satellites.map(|n| n.min(99)))?;
            body.write_str(",")?;
            write_fixed(body, fix.hdop.map(f64::from), 1)?;
            body.write_str(",")?;
            write_fixed(body, fix.altitude_msl_m, 1)?;
            body.write_str(",M,")?;
            write_fixed(body, fix.geoid_separation_m.map(f64::from), 1)?;
            body.write_str(",M,,")
        }
        SentenceKind::Rmc => {
            write!(body, "{t}RMC,")?;
            write_time(body, fix.utc_time_ms)?;
            write!(body, ",{},", if fix.valid { 'A' } else { 'V' })?;
            write_angle(body, fix.latitude_deg, 2, 'N', 'S')?;
            body.write_str(",")?;
            write_angle(body, fix.longitude_deg, 3, 'E', 'W')?;
            body.write_str(",")?;
            write_fixed(body, speed_knots(fix), 3)?;
            body.write_str(",")?;
            write_fixed(body, course_deg(fix), 2)?;
            body.write_str(",")?;
            if let Some(date) = fix.utc_date {
                write!(
                    body,
                    "{:02}{:02}{:02}",
                    date.day,
                    date.month,
                    date.year % 100
                )?;
            }
            write!(body, ",,,{}", if fix.valid { 'A' } else { 'N' })
        }
        SentenceKind::Vtg => {
            write!(body, "{t}VTG,")?;
            write_fixed(body, course_deg(fix), 2)?;
            body.write_str(",T,,M,")?;
            write_fixed(body, speed_knots(fix), 3)?;
            body.write_str(",N,")?;
            write_fixed(body, fix.ground_speed_mps.map(|s| f64::from(s) * 3.6), 3)?;
            write!(body, ",K,{}", if fix.valid { 'A' } else { 'N' })
        }
        SentenceKind::Gsa => {
            let dimension = match fix.dimension {
                Some(FixDimension::ThreeD) => 3,
                Some(FixDimension::TwoD) => 2,
                Some(FixDimension::NoFix) => 1,
                None if fix.valid => 3,
                None => 1,
            };
            write!(body, "{t}GSA,A,{dimension},,,,,,,,,,,,,")?;
            write_fixed(body, fix.pdop.map(f64::from), 1)?;
            body.write_str(",")?;
            write_fixed(body, fix.hdop.map(f64::from), 1)?;
            body.write_str(",")?;
            write_fixed(body, fix.vdop.map(f64::from), 1)
        }
        SentenceKind::Gst => {
            write!(body, "{t}GST,")?;
            write_time(body, fix.utc_time_ms)?;
            body.write_str(",,,,,")?;
            for (index, sd) in fix.position_sd_m.iter().enumerate() {
                if index > 0 {
                    body.write_str(",")?;
                }
                write_fixed(body, sd.map(f64::from), 2)?;
            }
            Ok(())
        }
        SentenceKind::AshtechPos => {
            let quality = fix.quality.unwrap_or(FixQuality::Autonomous);
            body.write_str("PASHR,POS,")?;
            write!(body, "{},", quality.ashtech_code())?;
            write_opt(body, fix.satellites.map(|n| n.min(99)))?;
            body.write_str(",")?;
            write_time(body, fix.utc_time_ms)?;
            body.write_str(",")?;
            write_angle(body, fix.latitude_deg, 2, 'N', 'S')?;
            body.write_str(",")?;
            write_angle(body, fix.longitude_deg, 3, 'E', 'W')?;
            body.write_str(",")?;
            write_fixed(body, fix.altitude_ellipsoid_m, 3)?;
            body.write_str(",,")?;
            write_fixed(body, course_deg(fix), 1)?;
            body.write_str(",")?;
            write_fixed(body, speed_knots(fix), 3)?;
            body.write_str(",")?;
            let up = fix.velocity_ned_mps[2].map(|down| -f64::from(down));
            write_fixed(body, up, 3)?;
            for dop in [fix.pdop, fix.hdop, fix.vdop] {
                body.write_str(",")?;
                write_fixed(body, dop.map(f64::from), 1)?;
            }
            // TDOP and firmware version: not modelled.
            body.write_str(",,SKYF")
        }
    }
}

/// Writes one sentence (`$…*hh\r\n`) describing `fix` into `out`; returns its length, or
/// `None` when it does not fit (`out` too short, or values too large for the format).
pub fn encode_sentence(
    kind: SentenceKind,
    talker: Talker,
    fix: &GpsFix,
    out: &mut [u8],
) -> Option<usize> {
    let mut body = Body::new();
    write_body(kind, talker, fix, &mut body).ok()?;
    // The decoder's limit covers the body and `*hh`.
    if body.len() + 3 > MAX_SENTENCE_LEN {
        return None;
    }
    let checksum = nmea_checksum(body.as_bytes());
    let mut line: String<{ MAX_SENTENCE_LEN + 4 }> = String::new();
    write!(line, "${body}*{checksum:02X}\r\n").ok()?;
    let bytes = line.as_bytes();
    out.get_mut(..bytes.len())?.copy_from_slice(bytes);
    Some(bytes.len())
}

#[cfg(test)]
mod tests;
