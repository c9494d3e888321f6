//! Counts of what the shell's socket thread drops before it queues a datagram for the
//! telemetry task: datagrams that fail [`screen_command`](super::auth::screen_command)
//! (forged, damaged, not for us) and floods over a source's share. The socket thread drains
//! the socket as fast as it fills; the task's command budget is spent on genuine commands
//! only. The task adds these counts to its own ([`LinkCounters`]), so the ground and
//! `link.bin` show one set of counters.

use super::auth::RejectReason;
use super::counters::LinkCounters;
use core::sync::atomic::{AtomicU32, Ordering};

#[derive(Debug, Default)]
pub struct IngressCounters {
    bad_crc: AtomicU32,
    malformed: AtomicU32,
    wrong_vehicle: AtomicU32,
    unsigned: AtomicU32,
    bad_signature: AtomicU32,
    rate_limited: AtomicU32,
}

impl IngressCounters {
    pub const fn new() -> Self {
        Self {
            bad_crc: AtomicU32::new(0),
            malformed: AtomicU32::new(0),
            wrong_vehicle: AtomicU32::new(0),
            unsigned: AtomicU32::new(0),
            bad_signature: AtomicU32::new(0),
            rate_limited: AtomicU32::new(0),
        }
    }

    /// A datagram dropped by the screen. Reasons the screen never gives are not counted.
    pub fn screened_out(&self, reason: RejectReason) {
        let counter = match reason {
            RejectReason::BadCrc => &self.bad_crc,
            RejectReason::Malformed => &self.malformed,
            RejectReason::WrongVehicle => &self.wrong_vehicle,
            RejectReason::Unsigned => &self.unsigned,
            RejectReason::BadSignature => &self.bad_signature,
            _ => return,
        };
        bump(counter);
    }

    /// A datagram dropped unread: its source is over its share.
    pub fn rate_limited(&self) {
        bump(&self.rate_limited);
    }

    /// `counters` (the gate's) with the drops before the queue added: every datagram the
    /// vehicle received, and why each refused one was.
    pub fn added_to(&self, counters: &LinkCounters) -> LinkCounters {
        let get = |c: &AtomicU32| c.load(Ordering::Relaxed);
        let (bad_crc, malformed, wrong_vehicle, unsigned, bad_signature, rate_limited) = (
            get(&self.bad_crc),
            get(&self.malformed),
            get(&self.wrong_vehicle),
            get(&self.unsigned),
            get(&self.bad_signature),
            get(&self.rate_limited),
        );
        let dropped = [
            bad_crc,
            malformed,
            wrong_vehicle,
            unsigned,
            bad_signature,
            rate_limited,
        ]
        .iter()
        .fold(0u32, |sum, &c| sum.saturating_add(c));
        LinkCounters {
            received: counters.received.saturating_add(dropped),
            bad_crc: counters.bad_crc.saturating_add(bad_crc),
            malformed: counters.malformed.saturating_add(malformed),
            wrong_vehicle: counters.wrong_vehicle.saturating_add(wrong_vehicle),
            unsigned: counters.unsigned.saturating_add(unsigned),
            bad_signature: counters.bad_signature.saturating_add(bad_signature),
            rate_limited: counters.rate_limited.saturating_add(rate_limited),
            ..*counters
        }
    }
}

fn bump(counter: &AtomicU32) {
    // Saturating: a counter that has reached u32::MAX stays there.
    let _ = counter.fetch_update(Ordering::Relaxed, Ordering::Relaxed, |c| c.checked_add(1));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drops_before_the_queue_add_to_the_gates_counters() {
        let ingress = IngressCounters::new();
        ingress.screened_out(RejectReason::BadSignature);
        ingress.screened_out(RejectReason::BadSignature);
        ingress.screened_out(RejectReason::BadCrc);
        ingress.screened_out(RejectReason::Replayed); // not the screen's: ignored
        ingress.rate_limited();
        let gate = LinkCounters {
            received: 5,
            accepted: 4,
            bad_signature: 1,
            ..LinkCounters::default()
        };
        let all = ingress.added_to(&gate);
        assert_eq!(all.received, 9);
        assert_eq!(all.accepted, 4);
        assert_eq!(all.bad_signature, 3);
        assert_eq!(all.bad_crc, 1);
        assert_eq!(all.rate_limited, 1);
        assert_eq!(all.replayed, 0);
        assert_eq!(all.rejected(), 5);
    }
}
