//! Serial ports: one I/O thread per device moves bytes between the port and two rtrb rings.
//!
//! ```text
//! port ──read──▶ rx ring ──▶ device task (core, never blocks)
//! port ◀─write── tx ring ◀── device task
//! ```
//!
//! A port that errors or vanishes (a USB adapter unplugged) puts the device in the `Lost`
//! state; the thread keeps trying to open the same path and data resumes by itself when it
//! comes back. Nothing restarts: the rings, the task and the executive carry on.

use serialport::{SerialPort, TTYPort};
use std::io::{Read, Write};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicU32, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

/// One configured serial device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PortConfig {
    /// What the device is (`imu`, `gps`, `servo`): names the thread and the messages.
    pub device: String,
    pub path: PathBuf,
    pub baud: u32,
}

/// How long a read waits for bytes before the thread looks at its tx ring and stop flag.
const READ_POLL: Duration = Duration::from_millis(5);
/// Pause between attempts to reopen a lost port.
const REOPEN_EVERY: Duration = Duration::from_millis(100);
/// Ring sizes: a second of the fastest device (IMU, ~4 kB/s) with room to spare.
pub const RX_RING: usize = 16 * 1024;
pub const TX_RING: usize = 4 * 1024;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum PortState {
    /// Never opened yet.
    Opening = 0,
    Open = 1,
    /// Was open (or never could be) and failed; being reopened.
    Lost = 2,
    /// The thread has ended.
    Closed = 3,
}

/// Counters and state of one port, shared lock-free with the executive thread.
#[derive(Debug, Default)]
pub struct PortStatus {
    state: AtomicU8,
    /// Successful opens (1 after the first, +1 per recovery).
    pub opens: AtomicU32,
    /// Times the port was lost after being open.
    pub losses: AtomicU32,
    /// Failed open attempts.
    pub open_failures: AtomicU32,
    pub bytes_in: AtomicU64,
    pub bytes_out: AtomicU64,
    /// Bytes read from the port that the rx ring had no room for (the task fell behind).
    pub bytes_dropped: AtomicU64,
}

impl PortStatus {
    pub fn state(&self) -> PortState {
        match self.state.load(Ordering::Relaxed) {
            0 => PortState::Opening,
            1 => PortState::Open,
            2 => PortState::Lost,
            _ => PortState::Closed,
        }
    }

    fn set_state(&self, state: PortState) {
        self.state.store(state as u8, Ordering::Relaxed);
    }
}

/// The device side of a running port: what the task reads and writes.
pub struct PortHandle {
    pub rx: rtrb::Consumer<u8>,
    pub tx: rtrb::Producer<u8>,
    pub status: Arc<PortStatus>,
}

/// Starts the I/O thread of one port. The thread runs until `stop` is set; its `JoinHandle`
/// returns once the last queued output byte had its chance to be written.
pub fn spawn_port(
    config: PortConfig,
    stop: Arc<AtomicBool>,
) -> std::io::Result<(PortHandle, JoinHandle<()>)> {
    let (rx_in, rx_out) = rtrb::RingBuffer::new(RX_RING);
    let (tx_in, tx_out) = rtrb::RingBuffer::new(TX_RING);
    let status = Arc::new(PortStatus::default());
    let thread_status = Arc::clone(&status);
    let join = std::thread::Builder::new()
        .name(format!("serial-{}", config.device))
        .stack_size(256 * 1024)
        .spawn(move || port_thread(config, rx_in, tx_out, &thread_status, &stop))?;
    Ok((
        PortHandle {
            rx: rx_out,
            tx: tx_in,
            status,
        },
        join,
    ))
}

fn open(config: &PortConfig) -> serialport::Result<TTYPort> {
    serialport::new(config.path.to_string_lossy(), config.baud)
        .timeout(READ_POLL)
        .open_native()
}

fn port_thread(
    config: PortConfig,
    mut rx: rtrb::Producer<u8>,
    mut tx: rtrb::Consumer<u8>,
    status: &PortStatus,
    stop: &AtomicBool,
) {
    let mut port: Option<TTYPort> = None;
    let mut buf = [0u8; 1024];
    let mut reported_failure = false;
    while !stop.load(Ordering::Relaxed) {
        let Some(p) = port.as_mut() else {
            match open(&config) {
                Ok(p) => {
                    status.opens.fetch_add(1, Ordering::Relaxed);
                    status.set_state(PortState::Open);
                    if reported_failure {
                        log::warn!("{}: {} is back", config.device, config.path.display());
                    }
                    reported_failure = false;
                    port = Some(p);
                }
                Err(e) => {
                    status.open_failures.fetch_add(1, Ordering::Relaxed);
                    if status.state() == PortState::Opening {
                        status.set_state(PortState::Lost);
                    }
                    if !reported_failure {
                        log::warn!(
                            "{}: cannot open {}: {e}; retrying every {} ms",
                            config.device,
                            config.path.display(),
                            REOPEN_EVERY.as_millis()
                        );
                        reported_failure = true;
                    }
                    std::thread::sleep(REOPEN_EVERY);
                }
            }
            continue;
        };
        match pump(p, &mut buf, &mut rx, &mut tx, status) {
            Ok(()) => {}
            Err(e) => {
                log::warn!("{}: {} lost: {e}", config.device, config.path.display());
                status.losses.fetch_add(1, Ordering::Relaxed);
                status.set_state(PortState::Lost);
                reported_failure = true;
                port = None;
            }
        }
    }
    // Last output (e.g. a failsafe servo command queued at shutdown) goes out if it can.
    if let Some(p) = port.as_mut() {
        let _ = write_pending(p, &mut tx, status);
    }
    status.set_state(PortState::Closed);
}

/// One read (waiting at most `READ_POLL`) and the queued writes.
fn pump(
    port: &mut TTYPort,
    buf: &mut [u8],
    rx: &mut rtrb::Producer<u8>,
    tx: &mut rtrb::Consumer<u8>,
    status: &PortStatus,
) -> std::io::Result<()> {
    match port.read(buf) {
        // A tty read of 0 bytes after poll said readable: the other end hung up.
        Ok(0) => {
            return Err(std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                "hung up",
            ));
        }
        Ok(n) => {
            let bytes = buf.get(..n).unwrap_or_default();
            status.bytes_in.fetch_add(n as u64, Ordering::Relaxed);
            let room = rx.slots().min(n);
            if let Ok(chunk) = rx.write_chunk_uninit(room) {
                chunk.fill_from_iter(bytes.iter().copied());
            }
            if room < n {
                status
                    .bytes_dropped
                    .fetch_add((n - room) as u64, Ordering::Relaxed);
            }
        }
        Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
        Err(e) => return Err(e),
    }
    write_pending(port, tx, status)?;
    // A vanished device can stay silent without erroring reads; asking the driver for its
    // input queue fails once the file descriptor no longer points at a live tty.
    port.bytes_to_read().map_err(std::io::Error::from)?;
    Ok(())
}

fn write_pending(
    port: &mut TTYPort,
    tx: &mut rtrb::Consumer<u8>,
    status: &PortStatus,
) -> std::io::Result<()> {
    let pending = tx.slots();
    if pending == 0 {
        return Ok(());
    }
    if let Ok(chunk) = tx.read_chunk(pending) {
        let (a, b) = chunk.as_slices();
        port.write_all(a)?;
        port.write_all(b)?;
        chunk.commit_all();
        status
            .bytes_out
            .fetch_add(pending as u64, Ordering::Relaxed);
    }
    Ok(())
}

/// Both rings of a device as one embedded-io port, for the device task that owns it: reads
/// take what is waiting, writes queue what fits; neither ever waits.
pub struct DevicePort {
    pub rx: RingReader,
    pub tx: RingWriter,
}

impl DevicePort {
    pub fn new(rx: rtrb::Consumer<u8>, tx: rtrb::Producer<u8>) -> Self {
        Self {
            rx: RingReader(rx),
            tx: RingWriter(tx),
        }
    }
}

impl embedded_io::ErrorType for DevicePort {
    type Error = core::convert::Infallible;
}

impl embedded_io::ReadReady for DevicePort {
    fn read_ready(&mut self) -> Result<bool, Self::Error> {
        self.rx.read_ready()
    }
}

impl embedded_io::Read for DevicePort {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        self.rx.read(buf)
    }
}

impl embedded_io::WriteReady for DevicePort {
    fn write_ready(&mut self) -> Result<bool, Self::Error> {
        self.tx.write_ready()
    }
}

impl embedded_io::Write for DevicePort {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        self.tx.write(buf)
    }

    fn flush(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}

/// Opens and closes `config`'s port once, to say at start — in one line naming the device
/// and the path — when it cannot be opened at all (a typo in vehicle.toml). Later losses are
/// the I/O thread's to retry.
pub fn check_opens(config: &PortConfig) -> Result<(), String> {
    open(config).map(drop).map_err(|e| {
        format!(
            "devices.{}.port = {}: cannot open: {}",
            config.device,
            config.path.display(),
            e.description
        )
    })
}

/// The rx ring as an embedded-io byte source for a device task: `read_ready` says whether
/// bytes are waiting, `read` takes what is there and never waits.
pub struct RingReader(pub rtrb::Consumer<u8>);

/// The tx ring as an embedded-io byte sink: `write` queues what fits and never waits.
pub struct RingWriter(pub rtrb::Producer<u8>);

impl embedded_io::ErrorType for RingReader {
    type Error = core::convert::Infallible;
}

impl embedded_io::ReadReady for RingReader {
    fn read_ready(&mut self) -> Result<bool, Self::Error> {
        Ok(self.0.slots() > 0)
    }
}

impl embedded_io::Read for RingReader {
    /// Copies what is waiting (possibly nothing: call after `read_ready`).
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        let n = self.0.slots().min(buf.len());
        if let Ok(chunk) = self.0.read_chunk(n) {
            let (a, b) = chunk.as_slices();
            let (head, tail) = buf.split_at_mut(a.len().min(n));
            head.copy_from_slice(a);
            if let Some(tail) = tail.get_mut(..b.len()) {
                tail.copy_from_slice(b);
            }
            chunk.commit_all();
        }
        Ok(n)
    }
}

impl embedded_io::ErrorType for RingWriter {
    type Error = core::convert::Infallible;
}

impl embedded_io::WriteReady for RingWriter {
    fn write_ready(&mut self) -> Result<bool, Self::Error> {
        Ok(self.0.slots() > 0)
    }
}

impl embedded_io::Write for RingWriter {
    /// Queues as much as fits; the caller counts what did not.
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        let n = self.0.slots().min(buf.len());
        if let Ok(chunk) = self.0.write_chunk_uninit(n) {
            chunk.fill_from_iter(buf.iter().copied());
        }
        Ok(n)
    }

    fn flush(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}
