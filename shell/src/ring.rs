//! rtrb rings as the core's [`Sink`]: the lock-free hand-over from the executive thread to
//! the shell's I/O threads.

use skyframe_core::comm::Sink;

/// The producer end of an rtrb ring, as seen by the core.
pub struct RingSink<T> {
    producer: rtrb::Producer<T>,
    wait_when_full: bool,
}

impl<T> RingSink<T> {
    /// A full ring refuses the item (the core counts the drop): real time never waits.
    pub fn new(producer: rtrb::Producer<T>) -> Self {
        Self {
            producer,
            wait_when_full: false,
        }
    }

    /// A full ring makes the producer wait for the consumer. Only for virtual time, where
    /// the executive outruns any consumer and waiting costs no deadline.
    pub fn waiting(producer: rtrb::Producer<T>) -> Self {
        Self {
            producer,
            wait_when_full: true,
        }
    }
}

impl<T> Sink<T> for RingSink<T> {
    fn try_send(&mut self, item: T) -> Result<(), T> {
        let mut item = item;
        loop {
            match self.producer.push(item) {
                Ok(()) => return Ok(()),
                Err(rtrb::PushError::Full(back))
                    if self.wait_when_full && !self.producer.is_abandoned() =>
                {
                    item = back;
                    std::thread::yield_now();
                }
                Err(rtrb::PushError::Full(back)) => return Err(back),
            }
        }
    }
}

/// Moves what is waiting in `ring`, up to `buf.len()` bytes, into the front of `buf`; returns
/// how many (possibly 0). The bytes may wrap around the ring's end: both halves are copied.
pub fn read_into(ring: &mut rtrb::Consumer<u8>, buf: &mut [u8]) -> usize {
    let n = ring.slots().min(buf.len());
    if let Ok(chunk) = ring.read_chunk(n) {
        let (a, b) = chunk.as_slices();
        let (head, tail) = buf.split_at_mut(a.len().min(n));
        head.copy_from_slice(a);
        if let Some(tail) = tail.get_mut(..b.len()) {
            tail.copy_from_slice(b);
        }
        chunk.commit_all();
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn real_time_sink_refuses_when_full_and_virtual_sink_waits_for_the_consumer() {
        let (producer, _consumer) = rtrb::RingBuffer::new(2);
        let mut sink = RingSink::new(producer);
        assert_eq!(sink.try_send(1), Ok(()));
        assert_eq!(sink.try_send(2), Ok(()));
        assert_eq!(sink.try_send(3), Err(3));

        let (producer, mut consumer) = rtrb::RingBuffer::new(2);
        let mut sink = RingSink::waiting(producer);
        std::thread::scope(|s| {
            s.spawn(move || {
                for i in 0..100 {
                    assert_eq!(sink.try_send(i), Ok(()));
                }
            });
            let mut got = Vec::new();
            while got.len() < 100 {
                if let Ok(v) = consumer.pop() {
                    got.push(v);
                }
            }
            assert_eq!(got, (0..100).collect::<Vec<_>>());
        });
    }
}
