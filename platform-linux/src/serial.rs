//! Serial ports on Linux, through the `serialport` crate (the shell's I/O threads use them
//! as [`SerialIo`]).

use serialport::{SerialPort, TTYPort};
use skyframe_shell::serial::{PortConfig, READ_POLL, SerialIo};
use std::io::{Read, Write};

/// A tty opened by `serialport` (exclusive, raw, 8N1, reads time out after `READ_POLL`).
pub struct LinuxPort(TTYPort);

/// Opens `config`'s tty: the Linux [`skyframe_shell::serial::SerialOpener`].
pub fn open(config: &PortConfig) -> std::io::Result<Box<dyn SerialIo>> {
    let port = serialport::new(config.path.to_string_lossy(), config.baud)
        .timeout(READ_POLL)
        .open_native()?;
    Ok(Box::new(LinuxPort(port)))
}

impl Read for LinuxPort {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.0.read(buf)
    }
}

impl Write for LinuxPort {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.write(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.0.flush()
    }
}

impl SerialIo for LinuxPort {
    /// Asking the driver for its input queue fails once the file descriptor no longer points
    /// at a live tty.
    fn check_alive(&mut self) -> std::io::Result<()> {
        self.0
            .bytes_to_read()
            .map(drop)
            .map_err(std::io::Error::from)
    }
}
