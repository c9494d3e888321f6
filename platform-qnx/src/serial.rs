//! Serial ports through POSIX termios (the `serialport` crate does not support QNX).
//!
//! Portable code: it runs on Linux too, where the tests drive it against pseudo-terminals.
//! A port is opened raw, 8N1, without modem control or flow control, exclusive; a read waits
//! for bytes with `poll` for at most [`READ_POLL`] and says `TimedOut` when none came.
//!
//! libc rather than nix (nix does not build for QNX): each call has a small safe wrapper in
//! [`sys`], the one place with `unsafe`.

use skyframe_shell::serial::{PortConfig, READ_POLL, SerialIo};
use std::fs::File;
use std::io::{Error, ErrorKind, Read, Write};
use std::os::fd::{AsRawFd, RawFd};
use std::os::unix::fs::OpenOptionsExt;
use std::path::Path;

/// An open termios serial port.
pub struct TermiosPort {
    file: File,
}

/// Opens `config`'s port: the QNX [`skyframe_shell::serial::SerialOpener`].
pub fn open(config: &PortConfig) -> std::io::Result<Box<dyn SerialIo>> {
    Ok(Box::new(TermiosPort::open(&config.path, config.baud)?))
}

/// The termios speed for `baud`. termios takes symbolic speeds (`B9600`), whose values
/// differ between systems (Linux numbers them; QNX uses the literal rate from 57600 up), so
/// the named constants of the platform's libc are used, never the number.
pub fn speed(baud: u32) -> Option<libc::speed_t> {
    Some(match baud {
        1200 => libc::B1200,
        2400 => libc::B2400,
        4800 => libc::B4800,
        9600 => libc::B9600,
        19200 => libc::B19200,
        38400 => libc::B38400,
        57600 => libc::B57600,
        115200 => libc::B115200,
        // libc declares no faster rate for QNX.
        #[cfg(not(target_os = "nto"))]
        230400 => libc::B230400,
        _ => return None,
    })
}

/// Says which file a termios call failed on, and in words when it is not a terminal at all
/// (a typo pointing at a regular file or /dev/null).
fn termios_error(path: &Path, call: &str, e: Error) -> Error {
    if e.raw_os_error() == Some(libc::ENOTTY) {
        Error::new(
            ErrorKind::InvalidInput,
            format!("{} is not a terminal ({call}: {e})", path.display()),
        )
    } else {
        Error::new(e.kind(), format!("{}: {call}: {e}", path.display()))
    }
}

impl TermiosPort {
    pub fn open(path: &Path, baud: u32) -> std::io::Result<Self> {
        let speed = speed(baud).ok_or_else(|| {
            Error::new(
                ErrorKind::InvalidInput,
                format!("{baud} baud is not a rate this port supports"),
            )
        })?;
        // O_NOCTTY: a serial port never becomes our controlling terminal (a hang-up would
        // send us SIGHUP). O_NONBLOCK: the open must not wait for a carrier (DCD) on a port
        // with modem control; it is cleared below, once CLOCAL makes the line ignore DCD.
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(libc::O_NOCTTY | libc::O_NONBLOCK)
            .open(path)?;
        let fd = file.as_raw_fd();
        let mut tio = sys::tcgetattr(fd).map_err(|e| termios_error(path, "tcgetattr", e))?;
        sys::cfmakeraw(&mut tio);
        sys::cfsetspeed(&mut tio, speed).map_err(|e| termios_error(path, "cfsetspeed", e))?;
        // 8N1, receiver on, modem lines ignored (CLOCAL). cfmakeraw leaves the character
        // size 8 and parity off; stop bits and flow control are ours to clear.
        tio.c_cflag |= libc::CLOCAL | libc::CREAD | libc::CS8;
        tio.c_cflag &= !(libc::CSTOPB | libc::PARENB | HARDWARE_FLOW_CONTROL);
        tio.c_iflag &= !(libc::IXON | libc::IXOFF | libc::IXANY);
        // A read returns what is waiting, at once: poll(2) does the waiting, with a timeout.
        tio.c_cc[libc::VMIN] = 0;
        tio.c_cc[libc::VTIME] = 0;
        sys::tcsetattr(fd, &tio).map_err(|e| termios_error(path, "tcsetattr", e))?;
        // Further opens of the tty fail with EBUSY (except by root on Linux): two programs
        // must not both read a device and each get half its bytes.
        sys::exclusive(fd).map_err(|e| termios_error(path, "TIOCEXCL", e))?;
        // Blocking writes from here on: a full output queue waits instead of failing the
        // port with EAGAIN.
        sys::clear_nonblock(fd).map_err(|e| termios_error(path, "fcntl", e))?;
        Ok(Self { file })
    }
}

/// Hardware flow control bits of `c_cflag`: our devices have no RTS/CTS wired, and a port
/// waiting for CTS would hold back the servo commands.
#[cfg(not(target_os = "nto"))]
const HARDWARE_FLOW_CONTROL: libc::tcflag_t = libc::CRTSCTS;
/// QNX splits it into input (IHFLOW) and output (OHFLOW) flow control.
#[cfg(target_os = "nto")]
const HARDWARE_FLOW_CONTROL: libc::tcflag_t = libc::IHFLOW | libc::OHFLOW;

/// Poll events that mean the device is gone or the descriptor is of no use.
const GONE: libc::c_short = libc::POLLHUP | libc::POLLERR | libc::POLLNVAL;

/// The timeout of one read, in poll(2)'s milliseconds.
fn read_timeout_ms() -> libc::c_int {
    libc::c_int::try_from(READ_POLL.as_millis()).unwrap_or(libc::c_int::MAX)
}

impl Read for TermiosPort {
    /// Waits up to [`READ_POLL`] for bytes: `TimedOut` when none came, `Ok(0)` when the
    /// device hung up.
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let events = sys::poll_in(self.file.as_raw_fd(), read_timeout_ms())?;
        if events & libc::POLLIN != 0 {
            return self.file.read(buf);
        }
        if events & GONE != 0 {
            return Ok(0);
        }
        Err(Error::new(
            ErrorKind::TimedOut,
            "no bytes within the read timeout",
        ))
    }
}

impl Write for TermiosPort {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.file.write(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

impl SerialIo for TermiosPort {
    /// A hung-up tty (the device unplugged, a pty's other end closed) reports POLLHUP.
    fn check_alive(&mut self) -> std::io::Result<()> {
        if sys::poll_in(self.file.as_raw_fd(), 0)? & GONE != 0 {
            return Err(Error::new(ErrorKind::BrokenPipe, "the device hung up"));
        }
        Ok(())
    }
}

/// Safe wrappers of the libc calls the port makes. Each takes a descriptor the caller keeps
/// open for the duration of the call, and returns the OS error as it was.
#[allow(unsafe_code)]
mod sys {
    use super::RawFd;
    use std::io::Error;

    fn check(rc: libc::c_int) -> std::io::Result<libc::c_int> {
        if rc == -1 {
            Err(Error::last_os_error())
        } else {
            Ok(rc)
        }
    }

    pub fn tcgetattr(fd: RawFd) -> std::io::Result<libc::termios> {
        // SAFETY: termios is a plain C struct of integers and arrays of them, for which all
        // zero bytes are a valid value; tcgetattr overwrites it.
        let mut tio: libc::termios = unsafe { std::mem::zeroed() };
        // SAFETY: `tio` is valid for writes and outlives the call, which keeps no pointer.
        check(unsafe { libc::tcgetattr(fd, &mut tio) })?;
        Ok(tio)
    }

    pub fn tcsetattr(fd: RawFd, tio: &libc::termios) -> std::io::Result<()> {
        // SAFETY: `tio` is a valid termios that outlives the call, which only reads it.
        check(unsafe { libc::tcsetattr(fd, libc::TCSANOW, tio) }).map(drop)
    }

    pub fn cfmakeraw(tio: &mut libc::termios) {
        // SAFETY: `tio` is a valid termios; cfmakeraw only changes its flags. (It returns
        // int on QNX and nothing on Linux; there is nothing to check either way.)
        unsafe { libc::cfmakeraw(tio) };
    }

    pub fn cfsetspeed(tio: &mut libc::termios, speed: libc::speed_t) -> std::io::Result<()> {
        // SAFETY: `tio` is a valid termios; the calls only write its speed fields.
        check(unsafe { libc::cfsetispeed(tio, speed) })?;
        // SAFETY: as above.
        check(unsafe { libc::cfsetospeed(tio, speed) }).map(drop)
    }

    pub fn exclusive(fd: RawFd) -> std::io::Result<()> {
        // SAFETY: TIOCEXCL takes no argument and touches no memory of ours.
        check(unsafe { libc::ioctl(fd, libc::TIOCEXCL as _) }).map(drop)
    }

    pub fn clear_nonblock(fd: RawFd) -> std::io::Result<()> {
        // SAFETY: F_GETFL and F_SETFL take and return integer flags only.
        let flags = check(unsafe { libc::fcntl(fd, libc::F_GETFL) })?;
        // SAFETY: as above.
        check(unsafe { libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK) }).map(drop)
    }

    /// Waits up to `timeout_ms` for `fd` to be readable; the events that came (0: none).
    pub fn poll_in(fd: RawFd, timeout_ms: libc::c_int) -> std::io::Result<libc::c_short> {
        let mut fds = [libc::pollfd {
            fd,
            events: libc::POLLIN,
            revents: 0,
        }];
        // SAFETY: `fds` is a valid array of one pollfd that outlives the call.
        let n = check(unsafe { libc::poll(fds.as_mut_ptr(), 1, timeout_ms) })?;
        let [ready] = fds;
        Ok(if n == 0 { 0 } else { ready.revents })
    }
}

/// On pseudo-terminals, on Linux (the tests do not run on QNX, and nix, which makes the
/// ptys, does not build there).
#[cfg(all(test, not(target_os = "nto")))]
mod tests {
    use super::*;
    use nix::pty::openpty;
    use std::os::fd::OwnedFd;
    use std::path::PathBuf;
    use std::time::{Duration, Instant};

    /// A pseudo-terminal: the master (the "device", held by the test) and the slave's path
    /// (what the port opens). The slave descriptor openpty returns is closed, as a real
    /// device has no other opener.
    fn device() -> (File, PathBuf) {
        let pty = openpty(None, None).expect("openpty");
        let path = nix::unistd::ttyname(&pty.slave).expect("slave name");
        let master: OwnedFd = pty.master;
        // The device side raw too, so bytes cross unchanged both ways.
        let fd = master.as_raw_fd();
        let mut tio = sys::tcgetattr(fd).expect("master termios");
        sys::cfmakeraw(&mut tio);
        sys::tcsetattr(fd, &tio).expect("master raw");
        (File::from(master), path)
    }

    fn read_exactly(port: &mut TermiosPort, want: usize) -> Vec<u8> {
        let start = Instant::now();
        let mut got = Vec::new();
        let mut buf = [0u8; 256];
        while got.len() < want {
            assert!(start.elapsed() < Duration::from_secs(5), "got {got:?}");
            match port.read(&mut buf) {
                Ok(0) => panic!("hung up"),
                Ok(n) => got.extend_from_slice(&buf[..n]),
                Err(e) if e.kind() == ErrorKind::TimedOut => {}
                Err(e) => panic!("read: {e}"),
            }
        }
        got
    }

    #[test]
    fn bytes_cross_both_ways_unchanged() {
        let (mut master, path) = device();
        let mut port = TermiosPort::open(&path, 115_200).expect("open");
        // Every byte value, including CR, LF, XON/XOFF and ^C, which a cooked tty would eat.
        let all: Vec<u8> = (0..=255).collect();
        master.write_all(&all).expect("device writes");
        assert_eq!(read_exactly(&mut port, 256), all);
        port.write_all(b"$PMTK,servo\r\n").expect("port writes");
        let mut out = [0u8; 13];
        master.read_exact(&mut out).expect("device reads");
        assert_eq!(&out, b"$PMTK,servo\r\n");
        port.check_alive().expect("alive");
    }

    #[test]
    fn a_read_without_bytes_times_out_after_about_the_poll_interval() {
        let (_master, path) = device();
        let mut port = TermiosPort::open(&path, 9600).expect("open");
        let start = Instant::now();
        let e = port.read(&mut [0u8; 16]).expect_err("no bytes");
        let waited = start.elapsed();
        assert_eq!(e.kind(), ErrorKind::TimedOut);
        assert!(waited >= READ_POLL - Duration::from_millis(1), "{waited:?}");
        assert!(waited < Duration::from_millis(500), "{waited:?}");
        port.check_alive().expect("still alive");
    }

    #[test]
    fn a_device_that_goes_away_is_seen_as_hung_up() {
        let (master, path) = device();
        let mut port = TermiosPort::open(&path, 57_600).expect("open");
        port.check_alive().expect("alive while the device is there");
        drop(master);
        let e = port.check_alive().expect_err("gone");
        assert_eq!(e.kind(), ErrorKind::BrokenPipe);
        // The I/O thread's read sees it too: a hang-up (0) or the tty's EIO, never "no bytes".
        match port.read(&mut [0u8; 16]) {
            Ok(0) => {}
            Err(e) => assert_ne!(e.kind(), ErrorKind::TimedOut, "{e}"),
            Ok(n) => panic!("read {n} bytes from a closed device"),
        }
    }

    #[test]
    fn bad_paths_and_rates_say_what_is_wrong() {
        let missing = TermiosPort::open(Path::new("/dev/ttyNOPE0"), 115_200)
            .err()
            .expect("missing device");
        assert_eq!(missing.kind(), ErrorKind::NotFound);

        let not_a_tty = TermiosPort::open(Path::new("/dev/null"), 115_200)
            .err()
            .expect("not a tty");
        assert_eq!(not_a_tty.kind(), ErrorKind::InvalidInput);
        assert!(
            not_a_tty
                .to_string()
                .contains("/dev/null is not a terminal"),
            "{not_a_tty}"
        );

        let (_master, path) = device();
        let rate = TermiosPort::open(&path, 123_456).err().expect("odd rate");
        assert!(rate.to_string().contains("123456 baud"), "{rate}");
    }

    #[test]
    fn the_port_is_raw_at_the_asked_speed_and_ignores_modem_lines() {
        let (_master, path) = device();
        let port = TermiosPort::open(&path, 19_200).expect("open");
        let tio = sys::tcgetattr(port.file.as_raw_fd()).expect("termios");
        assert_eq!(tio.c_lflag & (libc::ICANON | libc::ECHO | libc::ISIG), 0);
        assert_ne!(tio.c_cflag & libc::CLOCAL, 0);
        assert_ne!(tio.c_cflag & libc::CREAD, 0);
        assert_eq!(tio.c_cflag & libc::CSIZE, libc::CS8);
        assert_eq!(
            tio.c_cflag & (libc::PARENB | libc::CSTOPB | libc::CRTSCTS),
            0
        );
        assert_eq!(speed_of(&tio), libc::B19200);
    }

    #[allow(unsafe_code)]
    fn speed_of(tio: &libc::termios) -> libc::speed_t {
        // SAFETY: `tio` is a valid termios; cfgetospeed only reads it.
        unsafe { libc::cfgetospeed(tio) }
    }
}
