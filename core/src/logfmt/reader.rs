//! An incremental, bounded, resynchronising record reader.
//!
//! Bytes go in by chunks ([`LogReader::space`] + [`LogReader::commit`], then
//! [`LogReader::finish`] at the end of the input); [`LogReader::next_event`] yields records and
//! problems with their file offsets, in file order. Memory is fixed: one window of
//! [`READ_BUFFER_LEN`] bytes (room for the longest record) and one parsed format per index,
//! so a multi-GB file streams through in constant space.
//!
//! Damage never stops the reader. A record header that cannot be right (unknown type, index or
//! length the type forbids, `tv_nsec` ≥ 10⁹), a data block whose length contradicts its
//! format, and a record running past the end of the input are reported, and the reader then
//! resynchronises: it scans forward byte by byte for the next offset where a well-formed
//! record starts. During that scan "well-formed" is strict (complete, valid time, a data block
//! whose format is known and whose length matches it, a format that parses, and followed by
//! another record header or the end of the input), so garbage is unlikely to pass for a
//! record. Problems that leave the framing intact (data before its
//! format, data of an invalid format) skip just that record.

use super::format::{Format, FormatError, trim_nuls};
use super::record::{HEADER_LEN, MAX_RECORD_LEN, TIME_LEN, Time, kind};

/// Size of the reader's window: the longest record plus room to read ahead.
pub const READ_BUFFER_LEN: usize = MAX_RECORD_LEN + 4096;

const FORMAT_SLOTS: usize = 256;

/// A well-formed record, borrowed from the reader's window.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Record<'a> {
    BeginData {
        time: Time,
    },
    EndData {
        time: Time,
    },
    /// `text` without trailing NULs (UTF-8 when written by the spec; not checked).
    FormatComment {
        index: u8,
        text: &'a [u8],
    },
    /// `text` without trailing NULs; `format` is `None` when the format is invalid (reported
    /// as a problem right after this record).
    FormatDefinition {
        index: u8,
        text: &'a [u8],
        format: Option<&'a Format>,
    },
    DataBlock {
        index: u8,
        time: Time,
        data: &'a [u8],
        format: &'a Format,
    },
    /// `type_byte` is 0xBA or 0xDA.
    ByteArray {
        index: u8,
        time: Time,
        bytes: &'a [u8],
        format: &'a Format,
        type_byte: u8,
    },
}

/// What is wrong at a problem's offset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ProblemKind {
    /// Not one of the record types.
    UnknownType { type_byte: u8 },
    /// A format index or length the record type does not allow (e.g. a Data Block of index
    /// 0, an End Data with a length).
    BadHeader { type_byte: u8, index: u8, len: u16 },
    /// A TIME whose `tv_nsec` is not below 10⁹.
    BadTime { type_byte: u8, nsec: u32 },
    /// The last record is cut short: the input ends inside it (power lost mid-write).
    Truncated {
        type_byte: u8,
        needed: usize,
        available: usize,
    },
    /// The record's length runs past the end of the input, yet well-formed records follow
    /// it: the length (or the header) is damaged.
    LengthPastEnd {
        type_byte: u8,
        needed: usize,
        available: usize,
    },
    /// A data block whose length differs from the sum of its format's fields.
    DataLengthMismatch { index: u8, len: u16, expected: u16 },
    /// A data block or byte array whose index has no format yet.
    UndefinedFormat { index: u8 },
    /// A Format Definition whose format string is invalid.
    InvalidFormat { index: u8, error: FormatError },
    /// A data block or byte array of an invalid format: skipped, never guessed.
    DataOfInvalidFormat { index: u8 },
    /// A byte array whose format is not exactly one one-byte conversion.
    NotByteArrayFormat { index: u8 },
    /// The input ends without a final End Data: the file was not closed cleanly.
    NotClosedCleanly,
}

impl ProblemKind {
    /// Whether the reader may resynchronise after this problem (it distrusts the framing),
    /// rather than skip one record by its length. A data block of the wrong length is skipped
    /// by its length when another record header follows it, else resynchronised.
    pub fn resynchronises(self) -> bool {
        matches!(
            self,
            ProblemKind::UnknownType { .. }
                | ProblemKind::BadHeader { .. }
                | ProblemKind::BadTime { .. }
                | ProblemKind::Truncated { .. }
                | ProblemKind::LengthPastEnd { .. }
                | ProblemKind::DataLengthMismatch { .. }
        )
    }
}

impl core::fmt::Display for ProblemKind {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            ProblemKind::UnknownType { type_byte } => {
                write!(f, "unknown record type 0x{type_byte:02X}")
            }
            ProblemKind::BadHeader {
                type_byte,
                index,
                len,
            } => write!(
                f,
                "record type 0x{type_byte:02X} cannot have format index {index} and length {len}"
            ),
            ProblemKind::BadTime { type_byte, nsec } => write!(
                f,
                "record type 0x{type_byte:02X} has tv_nsec {nsec} (not below 1000000000)"
            ),
            ProblemKind::Truncated {
                type_byte,
                needed,
                available,
            } => write!(
                f,
                "truncated record: type 0x{type_byte:02X} needs {needed} bytes but the file ends \
                 after {available}"
            ),
            ProblemKind::LengthPastEnd {
                type_byte,
                needed,
                available,
            } => write!(
                f,
                "record type 0x{type_byte:02X} claims {needed} bytes, past the end of the file \
                 ({available} left), but records follow it: damaged length"
            ),
            ProblemKind::DataLengthMismatch {
                index,
                len,
                expected,
            } => write!(
                f,
                "data block of format {index} has {len} bytes, its format needs {expected}"
            ),
            ProblemKind::UndefinedFormat { index } => {
                write!(f, "data of format {index} before its format definition")
            }
            ProblemKind::InvalidFormat { index, error } => {
                write!(f, "format {index} is invalid: {error}")
            }
            ProblemKind::DataOfInvalidFormat { index } => {
                write!(f, "data of invalid format {index} skipped")
            }
            ProblemKind::NotByteArrayFormat { index } => write!(
                f,
                "byte array of format {index}, which is not a single one-byte conversion"
            ),
            ProblemKind::NotClosedCleanly => {
                write!(f, "no final End Data: the file was not closed cleanly")
            }
        }
    }
}

/// A problem at `offset`; reading went on at `resume_offset` (the next record read, or the
/// end of the input).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Problem {
    pub offset: u64,
    pub kind: ProblemKind,
    pub resume_offset: u64,
}

/// What the reader found next.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Event<'a> {
    Record { offset: u64, record: Record<'a> },
    Problem(Problem),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum SlotState {
    Undefined,
    Valid,
    Invalid,
}

/// A record's framing as read from its header.
#[derive(Clone, Copy)]
struct Frame {
    type_byte: u8,
    index: u8,
    len: u16,
    total: usize,
    time: Time,
}

enum FrameCheck {
    Whole(Frame),
    /// The window holds fewer than `needed` bytes of the record.
    Incomplete {
        type_byte: u8,
        needed: usize,
    },
    Bad(ProblemKind),
}

/// The streaming reader. See the module documentation.
pub struct LogReader {
    window: [u8; READ_BUFFER_LEN],
    /// The unread bytes are `window[start..end]`.
    start: usize,
    end: usize,
    /// File offset of `window[0]`.
    window_offset: u64,
    input_ended: bool,
    formats: [Format; FORMAT_SLOTS],
    states: [SlotState; FORMAT_SLOTS],
    /// A problem whose resynchronisation is still scanning: (offset, kind).
    resyncing: Option<(u64, ProblemKind)>,
    /// A problem to yield before reading on (an invalid format after its record).
    queued: Option<Problem>,
    last_type: Option<u8>,
    end_reported: bool,
}

impl Default for LogReader {
    fn default() -> Self {
        Self::new()
    }
}

impl LogReader {
    pub fn new() -> Self {
        Self {
            window: [0; READ_BUFFER_LEN],
            start: 0,
            end: 0,
            window_offset: 0,
            input_ended: false,
            formats: [Format::EMPTY; FORMAT_SLOTS],
            states: [SlotState::Undefined; FORMAT_SLOTS],
            resyncing: None,
            queued: None,
            last_type: None,
            end_reported: false,
        }
    }

    /// Forgets everything, to read another file.
    pub fn reset(&mut self) {
        self.start = 0;
        self.end = 0;
        self.window_offset = 0;
        self.input_ended = false;
        self.states = [SlotState::Undefined; FORMAT_SLOTS];
        self.resyncing = None;
        self.queued = None;
        self.last_type = None;
        self.end_reported = false;
    }

    /// Where to put the next input bytes; call [`commit`](Self::commit) with how many were
    /// written. Empty only while [`next_event`](Self::next_event) still has events to give.
    pub fn space(&mut self) -> &mut [u8] {
        if self.start > 0 {
            self.window.copy_within(self.start..self.end, 0);
            self.window_offset += self.start as u64;
            self.end -= self.start;
            self.start = 0;
        }
        self.window.get_mut(self.end..).unwrap_or(&mut [])
    }

    /// Accepts `count` bytes written into [`space`](Self::space).
    pub fn commit(&mut self, count: usize) {
        self.end = self.end.saturating_add(count).min(READ_BUFFER_LEN);
    }

    /// Declares the end of the input: what remains is read as the file's tail.
    pub fn finish(&mut self) {
        self.input_ended = true;
    }

    /// File offset of the next unread byte.
    pub fn offset(&self) -> u64 {
        self.window_offset + self.start as u64
    }

    /// The current format of `index`, if it is defined and valid.
    pub fn format(&self, index: u8) -> Option<&Format> {
        let slot = usize::from(index);
        match self.states.get(slot) {
            Some(SlotState::Valid) => self.formats.get(slot),
            _ => None,
        }
    }

    /// The next record or problem; `None` when more input is needed (or, after
    /// [`finish`](Self::finish), when the input is exhausted).
    pub fn next_event(&mut self) -> Option<Event<'_>> {
        if let Some(problem) = self.queued.take() {
            return Some(Event::Problem(problem));
        }
        loop {
            if let Some((offset, kind)) = self.resyncing {
                if !self.scan_for_record()? {
                    continue;
                }
                self.resyncing = None;
                let kind = match kind {
                    // Records after a "truncated" one: it was not the tail, its length lied.
                    ProblemKind::Truncated {
                        type_byte,
                        needed,
                        available,
                    } if self.start < self.end => ProblemKind::LengthPastEnd {
                        type_byte,
                        needed,
                        available,
                    },
                    kind => kind,
                };
                return Some(Event::Problem(Problem {
                    offset,
                    kind,
                    resume_offset: self.offset(),
                }));
            }
            if self.start >= self.end {
                return self.end_of_input();
            }
            let offset = self.offset();
            let frame = match self.frame_at(self.start) {
                FrameCheck::Whole(frame) => frame,
                FrameCheck::Incomplete { type_byte, needed } => {
                    if self.can_wait() {
                        return None;
                    }
                    let available = self.end - self.start;
                    self.start_resync(
                        offset,
                        ProblemKind::Truncated {
                            type_byte,
                            needed,
                            available,
                        },
                    );
                    continue;
                }
                FrameCheck::Bad(kind) => {
                    self.start_resync(offset, kind);
                    continue;
                }
            };
            if let Some(kind) = self.content_problem(&frame) {
                let trust_length = match kind {
                    // A wrong length is either a writer's mistake (the next record follows
                    // it: skip by the length) or a damaged length field (resynchronise).
                    ProblemKind::DataLengthMismatch { .. } => {
                        self.successor_plausible(self.start + frame.total)?
                    }
                    kind => !kind.resynchronises(),
                };
                if !trust_length {
                    self.start_resync(offset, kind);
                    continue;
                }
                self.start += frame.total;
                return Some(Event::Problem(Problem {
                    offset,
                    kind,
                    resume_offset: self.offset(),
                }));
            }
            return Some(self.accept(offset, frame));
        }
    }

    fn can_wait(&self) -> bool {
        !self.input_ended && self.end - self.start < READ_BUFFER_LEN
    }

    fn start_resync(&mut self, offset: u64, kind: ProblemKind) {
        self.resyncing = Some((offset, kind));
        self.start += 1;
    }

    /// Moves `start` to the next well-formed record or the end of the input: `Some(true)`
    /// when done, `None` when more input is needed first.
    fn scan_for_record(&mut self) -> Option<bool> {
        while self.start < self.end {
            match self.frame_at(self.start) {
                FrameCheck::Whole(frame) => {
                    // The successor check is O(1); `plausible` may parse a whole format, so
                    // it runs only on candidates that passed the cheap test.
                    if self.successor_plausible(self.start + frame.total)? && self.plausible(&frame)
                    {
                        return Some(true);
                    }
                    self.start += 1;
                }
                FrameCheck::Incomplete { .. } if self.can_wait() => return None,
                _ => self.start += 1,
            }
        }
        if self.input_ended { Some(true) } else { None }
    }

    /// Whether what follows a resynchronisation candidate (at window position `at`) starts
    /// like a record too, or is the end of the input; `None` when more input is needed. Two
    /// records in a row are far less likely by chance than one.
    fn successor_plausible(&self, at: usize) -> Option<bool> {
        let available = self.end.saturating_sub(at);
        match self.frame_at(at) {
            FrameCheck::Whole(_) => Some(true),
            FrameCheck::Bad(_) => Some(false),
            // The header and time are there and fine; only the body is still to come.
            FrameCheck::Incomplete { .. } if available >= HEADER_LEN + TIME_LEN => Some(true),
            FrameCheck::Incomplete { .. } if self.can_wait() => None,
            // The end of the input, or a truncated tail: nothing contradicts the candidate.
            FrameCheck::Incomplete { .. } => Some(true),
        }
    }

    /// Reads the framing of the record at window position `at`.
    fn frame_at(&self, at: usize) -> FrameCheck {
        let bytes = self.window.get(at..self.end).unwrap_or(&[]);
        let Some(&type_byte) = bytes.first() else {
            return FrameCheck::Incomplete {
                type_byte: 0,
                needed: HEADER_LEN,
            };
        };
        let timed = match type_byte {
            kind::BEGIN_DATA
            | kind::END_DATA
            | kind::DATA_BLOCK
            | kind::BYTE_ARRAY
            | kind::BYTE_ARRAY_LEGACY => true,
            kind::FORMAT_COMMENT | kind::FORMAT_DEFINITION => false,
            _ => return FrameCheck::Bad(ProblemKind::UnknownType { type_byte }),
        };
        let Some(&[_, index, l0, l1]) = bytes.first_chunk::<HEADER_LEN>() else {
            return FrameCheck::Incomplete {
                type_byte,
                needed: HEADER_LEN,
            };
        };
        let len = u16::from_le_bytes([l0, l1]);
        let marker = matches!(type_byte, kind::BEGIN_DATA | kind::END_DATA);
        let header_ok = if marker {
            index == 0 && len == 0
        } else {
            index != 0
        };
        if !header_ok {
            return FrameCheck::Bad(ProblemKind::BadHeader {
                type_byte,
                index,
                len,
            });
        }
        let fixed = if timed {
            HEADER_LEN + TIME_LEN
        } else {
            HEADER_LEN
        };
        let total = fixed + usize::from(len);
        let mut time = Time::default();
        if timed {
            let Some(time_bytes) = bytes
                .get(HEADER_LEN..fixed)
                .and_then(|b| <[u8; TIME_LEN]>::try_from(b).ok())
            else {
                return FrameCheck::Incomplete {
                    type_byte,
                    needed: total,
                };
            };
            time = Time::from_bytes(time_bytes);
            if !time.is_valid() {
                return FrameCheck::Bad(ProblemKind::BadTime {
                    type_byte,
                    nsec: time.nsec,
                });
            }
        }
        if bytes.len() < total {
            return FrameCheck::Incomplete {
                type_byte,
                needed: total,
            };
        }
        FrameCheck::Whole(Frame {
            type_byte,
            index,
            len,
            total,
            time,
        })
    }

    fn state(&self, index: u8) -> SlotState {
        self.states
            .get(usize::from(index))
            .copied()
            .unwrap_or(SlotState::Undefined)
    }

    /// What is wrong with a well-framed record's content, in normal reading.
    fn content_problem(&self, frame: &Frame) -> Option<ProblemKind> {
        let index = frame.index;
        let data_record = matches!(
            frame.type_byte,
            kind::DATA_BLOCK | kind::BYTE_ARRAY | kind::BYTE_ARRAY_LEGACY
        );
        if !data_record {
            return None;
        }
        match self.state(index) {
            SlotState::Undefined => return Some(ProblemKind::UndefinedFormat { index }),
            SlotState::Invalid => return Some(ProblemKind::DataOfInvalidFormat { index }),
            SlotState::Valid => {}
        }
        let format = self.formats.get(usize::from(index))?;
        if frame.type_byte == kind::DATA_BLOCK {
            let expected = u16::try_from(format.data_len()).unwrap_or(u16::MAX);
            (frame.len != expected).then_some(ProblemKind::DataLengthMismatch {
                index,
                len: frame.len,
                expected,
            })
        } else {
            (!format.is_byte_array_format()).then_some(ProblemKind::NotByteArrayFormat { index })
        }
    }

    /// Whether a record found while resynchronising looks like one a writer made.
    fn plausible(&self, frame: &Frame) -> bool {
        let body = self
            .window
            .get(self.start + HEADER_LEN..self.start + frame.total)
            .unwrap_or(&[]);
        match frame.type_byte {
            kind::FORMAT_DEFINITION => Format::parse_bytes(body).is_ok(),
            kind::FORMAT_COMMENT => core::str::from_utf8(trim_nuls(body)).is_ok(),
            kind::BEGIN_DATA | kind::END_DATA => true,
            _ => self.content_problem(frame).is_none(),
        }
    }

    /// Consumes a good record and yields it.
    fn accept(&mut self, offset: u64, frame: Frame) -> Event<'_> {
        let record_start = self.start;
        self.start += frame.total;
        self.last_type = Some(frame.type_byte);
        let index = frame.index;
        let slot = usize::from(index);
        if frame.type_byte == kind::FORMAT_DEFINITION {
            let text = self
                .window
                .get(record_start + HEADER_LEN..self.start)
                .unwrap_or(&[]);
            let parsed = Format::parse_bytes(text);
            let state = match parsed {
                Ok(format) => {
                    if let Some(stored) = self.formats.get_mut(slot) {
                        *stored = format;
                    }
                    SlotState::Valid
                }
                Err(error) => {
                    self.queued = Some(Problem {
                        offset,
                        kind: ProblemKind::InvalidFormat { index, error },
                        resume_offset: offset + frame.total as u64,
                    });
                    SlotState::Invalid
                }
            };
            if let Some(stored) = self.states.get_mut(slot) {
                *stored = state;
            }
        }
        let fixed = match frame.type_byte {
            kind::FORMAT_COMMENT | kind::FORMAT_DEFINITION => HEADER_LEN,
            _ => HEADER_LEN + TIME_LEN,
        };
        let body = self
            .window
            .get(record_start + fixed..self.start)
            .unwrap_or(&[]);
        let format = match self.states.get(slot) {
            Some(SlotState::Valid) => self.formats.get(slot),
            _ => None,
        };
        let record = match (frame.type_byte, format) {
            (kind::BEGIN_DATA, _) => Record::BeginData { time: frame.time },
            (kind::END_DATA, _) => Record::EndData { time: frame.time },
            (kind::FORMAT_COMMENT, _) => Record::FormatComment {
                index,
                text: trim_nuls(body),
            },
            (kind::FORMAT_DEFINITION, format) => Record::FormatDefinition {
                index,
                text: trim_nuls(body),
                format,
            },
            (kind::DATA_BLOCK, Some(format)) => Record::DataBlock {
                index,
                time: frame.time,
                data: body,
                format,
            },
            (type_byte, Some(format)) => Record::ByteArray {
                index,
                time: frame.time,
                bytes: body,
                format,
                type_byte,
            },
            // Unreachable: `content_problem` refused data records without a valid format.
            // Yielding the framing as a comment-less marker would lie, so report it instead.
            (_, None) => {
                return Event::Problem(Problem {
                    offset,
                    kind: ProblemKind::UndefinedFormat { index },
                    resume_offset: self.offset(),
                });
            }
        };
        Event::Record { offset, record }
    }

    fn end_of_input(&mut self) -> Option<Event<'_>> {
        if !self.input_ended || self.end_reported {
            return None;
        }
        self.end_reported = true;
        if self.last_type == Some(kind::END_DATA) {
            return None;
        }
        let offset = self.offset();
        Some(Event::Problem(Problem {
            offset,
            kind: ProblemKind::NotClosedCleanly,
            resume_offset: offset,
        }))
    }
}

/// Feeds a whole byte slice through `reader` (in window-sized chunks) and hands every event
/// to `on_event`; for tests, fuzzing and small in-memory logs.
pub fn read_slice(reader: &mut LogReader, mut bytes: &[u8], mut on_event: impl FnMut(Event<'_>)) {
    loop {
        let space = reader.space();
        let count = space.len().min(bytes.len());
        if let (Some(dst), Some(src)) = (space.get_mut(..count), bytes.get(..count)) {
            dst.copy_from_slice(src);
        }
        reader.commit(count);
        bytes = bytes.get(count..).unwrap_or(&[]);
        if bytes.is_empty() {
            reader.finish();
        }
        while let Some(event) = reader.next_event() {
            on_event(event);
        }
        if bytes.is_empty() {
            return;
        }
    }
}
