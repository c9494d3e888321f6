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
//!
//! The shell does not open ports itself: the platform hands it a [`SerialOpener`] (Linux
//! opens ttys with the `serialport` crate, QNX through termios, which `serialport` does not
//! support), and the thread only needs what [`SerialIo`] promises.

use std::io::{Read, Write};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicU32, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

/// An open serial port, as the I/O thread uses it.
///
/// `read` waits at most about [`READ_POLL`] for bytes; when none came it returns an error of
/// kind `TimedOut` or `WouldBlock` (both mean "no bytes yet", not a failure). `Ok(0)` means
/// the other end hung up. Every other error loses the port, and the thread reopens it.
pub trait SerialIo: Read + Write + Send {
    /// Fails once the port no longer points at a live device. Some vanished devices (an
    /// unplugged USB adapter) leave reads silent instead of failing them; the thread asks
    /// after every read.
    fn check_alive(&mut self) -> std::io::Result<()>;
}

/// Opens `config`'s port with the read timeout [`SerialIo`] asks for. A plain function,
/// not a method of the platform: each port's thread calls it again after every loss, so it
/// must travel to that thread without borrowing the platform.
pub type SerialOpener = fn(&PortConfig) -> std::io::Result<Box<dyn SerialIo>>;

/// The opener of platforms without serial ports (virtual time, the simulator): every open
/// fails, saying so.
pub fn no_serial_ports(config: &PortConfig) -> std::io::Result<Box<dyn SerialIo>> {
    Err(std::io::Error::new(
        std::io::ErrorKind::Unsupported,
        format!(
            "this platform has no serial ports (asked for {})",
            config.path.display()
        ),
    ))
}

/// One configured serial device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PortConfig {
    /// What the device is (`imu`, `gps`, `servo`): names the thread and the messages.
    pub device: String,
    pub path: PathBuf,
    pub baud: u32,
}

/// How long a read waits for bytes before the thread looks at its tx ring and stop flag.
/// Openers give their ports this read timeout.
pub const READ_POLL: Duration = Duration::from_millis(5);
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

/// Starts the I/O thread of one port, which opens it (and reopens it after a loss) with
/// `open`. The thread runs until `stop` is set; its `JoinHandle` returns once the last queued
/// output byte had its chance to be written.
pub fn spawn_port(
    config: PortConfig,
    open: SerialOpener,
    stop: Arc<AtomicBool>,
) -> std::io::Result<(PortHandle, JoinHandle<()>)> {
    let (rx_in, rx_out) = rtrb::RingBuffer::new(RX_RING);
    let (tx_in, tx_out) = rtrb::RingBuffer::new(TX_RING);
    let status = Arc::new(PortStatus::default());
    let thread_status = Arc::clone(&status);
    let join = std::thread::Builder::new()
        .name(format!("serial-{}", config.device))
        .stack_size(256 * 1024)
        .spawn(move || port_thread(config, open, rx_in, tx_out, &thread_status, &stop))?;
    Ok((
        PortHandle {
            rx: rx_out,
            tx: tx_in,
            status,
        },
        join,
    ))
}

fn port_thread(
    config: PortConfig,
    open: SerialOpener,
    mut rx: rtrb::Producer<u8>,
    mut tx: rtrb::Consumer<u8>,
    status: &PortStatus,
    stop: &AtomicBool,
) {
    let mut port: Option<Box<dyn SerialIo>> = None;
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
        match pump(p.as_mut(), &mut buf, &mut rx, &mut tx, status) {
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
        let _ = write_pending(p.as_mut(), &mut tx, status);
    }
    status.set_state(PortState::Closed);
}

/// One read (waiting at most `READ_POLL`) and the queued writes.
fn pump(
    port: &mut dyn SerialIo,
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
        // No bytes within the read timeout (ports say it either way).
        Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
        Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
        Err(e) => return Err(e),
    }
    write_pending(port, tx, status)?;
    // A vanished device can stay silent without erroring reads.
    port.check_alive()
}

fn write_pending(
    port: &mut dyn SerialIo,
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
pub fn check_opens(config: &PortConfig, open: SerialOpener) -> Result<(), String> {
    open(config).map(drop).map_err(|e| {
        format!(
            "devices.{}.port = {}: cannot open: {e}",
            config.device,
            config.path.display(),
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
        Ok(crate::ring::read_into(&mut self.0, buf))
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
