//! How data leaves a task without locks or blocking: the seed's two shared-data classes.
//!
//! - A **queue** keeps every item in order (commands, log records, GPS fixes): heapless'
//!   lock-free SPSC [`Queue`], split into a producer and a consumer. A full queue refuses
//!   the item; the producer counts the drop, it never waits.
//! - A **latest-value slot** keeps only the newest value with a "fresh" flag per reader
//!   (IMU sample → estimator, estimate → control).
//!
//! Anything that leaves the core for the shell goes through a [`Sink`], so the core does not
//! care whether the other end is a heapless queue (on a microcontroller) or an rtrb ring
//! drained by an OS thread.

use core::cell::Cell;

pub use heapless::spsc::{Consumer, Producer, Queue};

/// A non-blocking destination for items: `Err` hands the item back when it is full.
pub trait Sink<T> {
    fn try_send(&mut self, item: T) -> Result<(), T>;
}

impl<T> Sink<T> for Producer<'_, T> {
    fn try_send(&mut self, item: T) -> Result<(), T> {
        self.enqueue(item)
    }
}

/// The newest value of something, shared between tasks of one executive (one thread).
///
/// Single-threaded by construction (`Cell`, so not `Sync`): tasks of a cyclic executive never
/// run at the same time, so publishing and reading need no lock and cannot tear.
pub struct LatestSlot<T: Copy> {
    value: Cell<Option<T>>,
    sequence: Cell<u32>,
}

impl<T: Copy> Default for LatestSlot<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Copy> LatestSlot<T> {
    pub const fn new() -> Self {
        Self {
            value: Cell::new(None),
            sequence: Cell::new(0),
        }
    }

    /// Replaces the value; every reader sees it as fresh once.
    pub fn publish(&self, value: T) {
        self.value.set(Some(value));
        self.sequence.set(self.sequence.get().wrapping_add(1));
    }

    /// The newest value, whether or not anyone has read it.
    pub fn peek(&self) -> Option<T> {
        self.value.get()
    }

    /// A reader with its own "fresh" flag.
    pub fn reader(&self) -> SlotReader<'_, T> {
        SlotReader {
            slot: self,
            seen: self.sequence.get(),
        }
    }
}

/// One consumer's view of a [`LatestSlot`].
pub struct SlotReader<'a, T: Copy> {
    slot: &'a LatestSlot<T>,
    seen: u32,
}

/// A value read from a slot, and whether it was published since this reader last looked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Latest<T> {
    pub value: T,
    pub fresh: bool,
}

impl<T: Copy> SlotReader<'_, T> {
    /// The newest value (fresh or not); marks it seen.
    pub fn read(&mut self) -> Option<Latest<T>> {
        let sequence = self.slot.sequence.get();
        let fresh = sequence != self.seen;
        self.seen = sequence;
        self.slot.value.get().map(|value| Latest { value, fresh })
    }

    /// The newest value only if it was published since the last read.
    pub fn take_fresh(&mut self) -> Option<T> {
        self.read().filter(|l| l.fresh).map(|l| l.value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slot_reader_sees_each_publication_fresh_once() {
        let slot = LatestSlot::new();
        let mut a = slot.reader();
        let mut b = slot.reader();
        assert_eq!(a.read(), None);
        slot.publish(1u32);
        slot.publish(2u32);
        assert_eq!(
            a.read(),
            Some(Latest {
                value: 2,
                fresh: true
            })
        );
        assert_eq!(
            a.read(),
            Some(Latest {
                value: 2,
                fresh: false
            })
        );
        assert_eq!(a.take_fresh(), None);
        assert_eq!(b.take_fresh(), Some(2));
        slot.publish(3);
        assert_eq!(a.take_fresh(), Some(3));
    }

    #[test]
    fn full_queue_hands_the_item_back() {
        let mut q: Queue<u8, 3> = Queue::new();
        let (mut p, mut c) = q.split();
        assert_eq!(p.try_send(1), Ok(()));
        assert_eq!(p.try_send(2), Ok(()));
        assert_eq!(p.try_send(3), Err(3));
        assert_eq!(c.dequeue(), Some(1));
    }
}

/// The log writer's last word on the flight log (`LogHealth`), shared lock-free from the
/// shell's writer thread to the telemetry task: three atomics, each read whole; a reader may
/// see one update's free space beside the previous one's count, which no reader needs exact.
#[derive(Debug)]
pub struct LogHealthCell {
    free_mib: core::sync::atomic::AtomicU32,
    records_lost: core::sync::atomic::AtomicU32,
    streams_suspended: core::sync::atomic::AtomicU8,
}

impl LogHealthCell {
    pub const fn new() -> Self {
        use core::sync::atomic::{AtomicU8, AtomicU32};
        Self {
            free_mib: AtomicU32::new(crate::link::messages::LogHealth::UNKNOWN),
            records_lost: AtomicU32::new(0),
            streams_suspended: AtomicU8::new(0),
        }
    }

    pub fn set(&self, health: crate::link::messages::LogHealth) {
        use core::sync::atomic::Ordering::Relaxed;
        self.free_mib.store(health.free_mib, Relaxed);
        self.records_lost.store(health.records_lost, Relaxed);
        self.streams_suspended
            .store(health.streams_suspended, Relaxed);
    }

    pub fn get(&self) -> crate::link::messages::LogHealth {
        use core::sync::atomic::Ordering::Relaxed;
        crate::link::messages::LogHealth {
            free_mib: self.free_mib.load(Relaxed),
            records_lost: self.records_lost.load(Relaxed),
            streams_suspended: self.streams_suspended.load(Relaxed),
        }
    }
}

impl Default for LogHealthCell {
    fn default() -> Self {
        Self::new()
    }
}
