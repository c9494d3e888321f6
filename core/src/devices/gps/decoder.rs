//! The decoder: bytes to lines, lines to sentences, sentences to epochs, with every
//! problem counted by kind.

use super::*;

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
pub(super) struct InvalidField;

pub(super) type FieldResult<T> = Result<T, InvalidField>;

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

    pub(super) fn push_byte(&mut self, byte: u8, now_ns: u64, out: &mut dyn FnMut(GpsFix)) {
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
    pub(super) fn discard_line(&mut self) {
        bump_by(&mut self.stats.bytes_discarded, self.line.len() + 1);
        self.line.clear();
        self.in_sentence = false;
    }

    pub(super) fn end_of_line(&mut self, now_ns: u64, out: &mut dyn FnMut(GpsFix)) {
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

    pub(super) fn accept(
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

    pub(super) fn emit_epoch(&mut self, out: &mut dyn FnMut(GpsFix)) {
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
