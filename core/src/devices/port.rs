//! Serial ports as the tasks see them: `embedded_io` traits used so that nothing waits.
//!
//! `Read::read` blocks until at least one byte is there, so [`drain`] only calls it after
//! `ReadReady` said bytes are waiting, and stops after a byte budget so a babbling device
//! cannot eat a frame's time. `Write::write` blocks when the transmitter is full, so
//! [`CommandWriter`] only writes after `WriteReady` and keeps the unsent tail of a frame for
//! the next call.

use super::Decoder;
use super::framing::MAX_FRAME_LEN;
use super::servo::{COMMAND_FRAME_LEN, ServoCommand, encode_servo_command};
use embedded_io::{Read, ReadReady, Write, WriteReady};
use heapless::Vec;

/// Bytes read per `read` call: small enough for a task's stack.
pub const READ_CHUNK_LEN: usize = 64;

/// Feeds `decoder` what `port` already holds, at most `max_bytes`, without blocking; returns
/// how many bytes it read. Staleness is evaluated at `now_ns` even when nothing arrived.
///
/// A port error ends the drain; bytes read before it have been decoded.
pub fn drain<P, D>(
    port: &mut P,
    decoder: &mut D,
    now_ns: u64,
    max_bytes: usize,
    out: &mut dyn FnMut(D::Frame),
) -> Result<usize, P::Error>
where
    P: Read + ReadReady,
    D: Decoder,
{
    let mut scratch = [0u8; READ_CHUNK_LEN];
    let mut total = 0usize;
    let result = loop {
        if total >= max_bytes {
            break Ok(total);
        }
        match port.read_ready() {
            Ok(true) => {}
            Ok(false) => break Ok(total),
            Err(error) => break Err(error),
        }
        let want = (max_bytes - total).min(READ_CHUNK_LEN);
        let Some(chunk) = scratch.get_mut(..want) else {
            break Ok(total);
        };
        match port.read(chunk) {
            // End of stream (a closed pipe in simulation): nothing more this frame.
            Ok(0) => break Ok(total),
            Ok(n) => {
                decoder.push(chunk.get(..n).unwrap_or_default(), now_ns, out);
                total = total.saturating_add(n);
            }
            Err(error) => break Err(error),
        }
    };
    // An empty push evaluates staleness at `now_ns` after the bytes just fed.
    decoder.push(&[], now_ns, out);
    result
}

/// What a [`CommandWriter`] has done.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WriterStats {
    /// Frames written completely.
    pub frames_sent: u32,
    /// Frames replaced by a newer one before their first byte went out: commands are
    /// latest-value data, so an old one is worth nothing once a new one exists.
    pub frames_superseded: u32,
    /// Frames refused by [`CommandWriter::submit`] for being longer than a frame can be.
    pub frames_rejected: u32,
}

/// Sends command frames through a port that may only accept part of one at a time.
///
/// At most two frames are held: the one going out (never interrupted: a half-sent frame
/// followed by another would be garbage to the board) and the newest waiting behind it.
#[derive(Clone, Debug, Default)]
pub struct CommandWriter {
    in_flight: Vec<u8, MAX_FRAME_LEN>,
    sent: usize,
    waiting: Option<Vec<u8, MAX_FRAME_LEN>>,
    counter: u8,
    stats: WriterStats,
}

impl CommandWriter {
    pub const fn new() -> Self {
        Self {
            in_flight: Vec::new(),
            sent: 0,
            waiting: None,
            counter: 0,
            stats: WriterStats {
                frames_sent: 0,
                frames_superseded: 0,
                frames_rejected: 0,
            },
        }
    }

    pub fn stats(&self) -> &WriterStats {
        &self.stats
    }

    /// True when nothing is left to send.
    pub fn is_idle(&self) -> bool {
        self.sent >= self.in_flight.len() && self.waiting.is_none()
    }

    /// Queues an encoded frame to go out as soon as the port takes it. Returns false (and
    /// counts it) when the frame is too long to hold.
    pub fn submit(&mut self, frame: &[u8]) -> bool {
        let Ok(frame) = Vec::from_slice(frame) else {
            super::bump(&mut self.stats.frames_rejected);
            return false;
        };
        if self.sent == 0 && !self.in_flight.is_empty() {
            super::bump(&mut self.stats.frames_superseded);
            self.in_flight = frame;
        } else if self.sent >= self.in_flight.len() {
            self.in_flight = frame;
            self.sent = 0;
        } else {
            if self.waiting.is_some() {
                super::bump(&mut self.stats.frames_superseded);
            }
            self.waiting = Some(frame);
        }
        true
    }

    /// Encodes `command` with this writer's frame counter and queues it.
    pub fn submit_servo_command(&mut self, command: &ServoCommand) -> bool {
        let mut frame = [0u8; COMMAND_FRAME_LEN];
        let len = encode_servo_command(self.counter, command, &mut frame);
        self.counter = self.counter.wrapping_add(1);
        self.submit(frame.get(..len).unwrap_or_default())
    }

    /// Writes as much as the port accepts without blocking.
    pub fn poll<P: Write + WriteReady>(&mut self, port: &mut P) -> Result<(), P::Error> {
        loop {
            if self.sent >= self.in_flight.len() {
                let Some(next) = self.waiting.take() else {
                    return Ok(());
                };
                self.in_flight = next;
                self.sent = 0;
            }
            if !port.write_ready()? {
                return Ok(());
            }
            let unsent = self.in_flight.get(self.sent..).unwrap_or_default();
            let written = port.write(unsent)?;
            if written == 0 {
                return Ok(());
            }
            self.sent = self.sent.saturating_add(written);
            if self.sent >= self.in_flight.len() {
                super::bump(&mut self.stats.frames_sent);
                self.in_flight.clear();
                self.sent = 0;
            }
        }
    }
}

#[cfg(test)]
mod tests;
