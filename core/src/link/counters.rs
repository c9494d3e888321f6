//! The link's counters: sent in every executive status, logged in `link.bin`.

use super::auth::gate::RejectReason;
use super::wire::{Reader, WireError, Writer};
use crate::logfmt::{LogRecord, Value};

crate::log_record! {
    /// The link's counters, sent in every executive status and logged (`link.bin`) once a
    /// second and at the end, so what was refused and why is in the flight's log, not only
    /// on the ground. Saturating `u32`s; the field order is the wire order
    /// (`docs/link-protocol.md`) and the log's column order.
    ///
    /// The command side counts every datagram the gate sees: `received` equals `accepted`
    /// plus the sum of the rejection counters.
    #[derive(Eq)]
    #[cfg_attr(feature = "defmt", derive(defmt::Format))]
    pub struct LinkCounters {
        received: u32 = "%u",
        accepted: u32 = "%u",
        bad_crc: u32 = "%u",
        /// Bad length, magic, version or flags, a payload that does not decode, or not a
        /// command at all.
        malformed: u32 = "%u",
        wrong_vehicle: u32 = "%u",
        unsigned: u32 = "%u",
        bad_signature: u32 = "%u",
        /// Authentic, but from another run of the vehicle (a recording replayed, or a ground
        /// station that has not heard the vehicle since it restarted).
        wrong_run: u32 = "%u",
        /// Duplicate or too old for the sender's replay window.
        replayed: u32 = "%u",
        /// A new sender when every replay window is taken.
        too_many_senders: u32 = "%u",
        out_of_range: u32 = "%u",
        unknown_param: u32 = "%u",
        wrong_type: u32 = "%u",
        /// Telemetry datagrams handed to the socket, and ones it refused (counted by the
        /// sender, not the gate).
        telemetry_sent: u32 = "%u",
        telemetry_send_failed: u32 = "%u",
        /// Dropped unread by the shell because their source sent more than its share
        /// ([`crate::link::ingress`]): a flood, counted, never queued.
        rate_limited: u32 = "%u",
    }
}

/// Number of `u32` counters on the wire.
pub const LINK_COUNTERS: usize = 16;

impl LinkCounters {
    /// Rejected commands of every kind.
    pub fn rejected(&self) -> u32 {
        [
            self.rate_limited,
            self.bad_crc,
            self.malformed,
            self.wrong_vehicle,
            self.unsigned,
            self.bad_signature,
            self.wrong_run,
            self.replayed,
            self.too_many_senders,
            self.out_of_range,
            self.unknown_param,
            self.wrong_type,
        ]
        .iter()
        .fold(0u32, |sum, &count| sum.saturating_add(count))
    }

    /// On the wire in the declaration's order, which is `link.bin`'s column order too
    /// (`docs/link-protocol.md`).
    pub(crate) fn encode(&self, w: &mut Writer<'_>) -> Result<(), WireError> {
        let mut result = Ok(());
        self.each_value(&mut |value| {
            if let (Ok(()), Value::U32(count)) = (&result, value) {
                result = w.u32(count);
            }
        });
        result
    }

    pub(crate) fn decode(r: &mut Reader<'_>) -> Result<Self, WireError> {
        Ok(Self {
            received: r.u32()?,
            accepted: r.u32()?,
            bad_crc: r.u32()?,
            malformed: r.u32()?,
            wrong_vehicle: r.u32()?,
            unsigned: r.u32()?,
            bad_signature: r.u32()?,
            wrong_run: r.u32()?,
            replayed: r.u32()?,
            too_many_senders: r.u32()?,
            out_of_range: r.u32()?,
            unknown_param: r.u32()?,
            wrong_type: r.u32()?,
            telemetry_sent: r.u32()?,
            telemetry_send_failed: r.u32()?,
            rate_limited: r.u32()?,
        })
    }

    pub(crate) fn count(&mut self, reason: RejectReason) {
        let counter = match reason {
            RejectReason::BadCrc => &mut self.bad_crc,
            RejectReason::Malformed => &mut self.malformed,
            RejectReason::WrongVehicle => &mut self.wrong_vehicle,
            RejectReason::Unsigned => &mut self.unsigned,
            RejectReason::BadSignature => &mut self.bad_signature,
            RejectReason::WrongRun => &mut self.wrong_run,
            RejectReason::Replayed => &mut self.replayed,
            RejectReason::TooManySenders => &mut self.too_many_senders,
            RejectReason::OutOfRange => &mut self.out_of_range,
            RejectReason::UnknownParam => &mut self.unknown_param,
            RejectReason::WrongType => &mut self.wrong_type,
        };
        *counter = counter.saturating_add(1);
    }
}
