//! rtrb rings as the core's [`Sink`]: the lock-free hand-over from the executive thread to
//! the shell's I/O threads.

use skyframe_core::comm::Sink;

/// The producer end of an rtrb ring, as seen by the core.
pub struct RingSink<T>(pub rtrb::Producer<T>);

impl<T> Sink<T> for RingSink<T> {
    fn try_send(&mut self, item: T) -> Result<(), T> {
        self.0.push(item).map_err(|rtrb::PushError::Full(item)| item)
    }
}
