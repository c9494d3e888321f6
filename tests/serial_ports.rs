//! The shell's serial I/O threads on real pseudo-terminals: bytes both ways, a port that
//! vanishes and comes back under the same path, a port missing at start. Each test runs
//! with both platform openers: Linux's (the serialport crate) and QNX's termios port, which
//! is portable POSIX code and runs here too.

use serialport::TTYPort;
use skyframe_shell::serial::{PortConfig, PortHandle, PortState, SerialOpener, spawn_port};
use skyframe_tests::pty::{self, point};
use skyframe_tests::scratch;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// A pty whose slave end the shell opens by path; the test holds the master (the "device").
fn device() -> (TTYPort, PathBuf) {
    pty::device(Duration::from_millis(20))
}

fn wait_for(what: &str, mut done: impl FnMut() -> bool) {
    let start = Instant::now();
    while !done() {
        assert!(
            start.elapsed() < Duration::from_secs(5),
            "timed out waiting for {what}"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn drain(handle: &mut PortHandle, want: usize) -> Vec<u8> {
    let mut got = Vec::new();
    wait_for("bytes from the port", || {
        while let Ok(b) = handle.rx.pop() {
            got.push(b);
        }
        got.len() >= want
    });
    got
}

fn start(
    path: &Path,
    open: SerialOpener,
) -> (PortHandle, std::thread::JoinHandle<()>, Arc<AtomicBool>) {
    let stop = Arc::new(AtomicBool::new(false));
    let config = PortConfig {
        device: "imu".into(),
        path: path.to_path_buf(),
        baud: 115_200,
    };
    let (handle, join) = spawn_port(config, open, Arc::clone(&stop)).expect("thread");
    (handle, join, stop)
}

fn bytes_flow_both_ways(open: SerialOpener, _opener: &str) {
    let (mut master, path) = device();
    let (mut handle, join, stop) = start(&path, open);
    wait_for("open", || handle.status.state() == PortState::Open);
    master
        .write_all(b"$GPGGA,hello*00\r\n")
        .expect("device writes");
    assert_eq!(drain(&mut handle, 17), b"$GPGGA,hello*00\r\n");
    for b in b"servo!" {
        handle.tx.push(*b).expect("room");
    }
    let mut out = Vec::new();
    wait_for("bytes to the device", || {
        let mut buf = [0u8; 64];
        if let Ok(n) = master.read(&mut buf) {
            out.extend_from_slice(&buf[..n]);
        }
        out.len() >= 6
    });
    assert_eq!(out, b"servo!");
    stop.store(true, Ordering::Relaxed);
    join.join().expect("thread ends");
    assert_eq!(handle.status.state(), PortState::Closed);
    assert_eq!(handle.status.bytes_in.load(Ordering::Relaxed), 17);
    assert_eq!(handle.status.bytes_out.load(Ordering::Relaxed), 6);
}

fn unplugged_port_is_lost_then_resumes_when_the_path_comes_back(open: SerialOpener, opener: &str) {
    let dir = scratch(&format!("serial-replug-{opener}"));
    let link = dir.join("ttyUSB-imu");
    let (mut first, first_path) = device();
    point(&link, &first_path);
    let (mut handle, join, stop) = start(&link, open);
    wait_for("open", || handle.status.state() == PortState::Open);
    first.write_all(b"before").expect("write");
    assert_eq!(drain(&mut handle, 6), b"before");

    drop(first); // unplugged: the slave side sees a hang-up
    wait_for("lost", || handle.status.state() == PortState::Lost);
    assert_eq!(handle.status.losses.load(Ordering::Relaxed), 1);

    let (mut second, second_path) = device();
    point(&link, &second_path);
    wait_for("reopened", || handle.status.state() == PortState::Open);
    assert_eq!(handle.status.opens.load(Ordering::Relaxed), 2);
    second.write_all(b"after").expect("write");
    assert_eq!(drain(&mut handle, 5), b"after");
    stop.store(true, Ordering::Relaxed);
    join.join().expect("thread ends");
}

fn a_port_missing_at_start_is_retried_until_it_appears(open: SerialOpener, opener: &str) {
    let dir = scratch(&format!("serial-late-{opener}"));
    let link = dir.join("ttyS-gps");
    let (mut handle, join, stop) = start(&link, open);
    wait_for("open attempts", || {
        handle.status.open_failures.load(Ordering::Relaxed) >= 2
    });
    assert_eq!(handle.status.state(), PortState::Lost);
    let (mut dev, path) = device();
    point(&link, &path);
    wait_for("open", || handle.status.state() == PortState::Open);
    dev.write_all(b"x").expect("write");
    assert_eq!(drain(&mut handle, 1), b"x");
    stop.store(true, Ordering::Relaxed);
    join.join().expect("thread ends");
}

fn a_full_rx_ring_counts_what_it_could_not_take(open: SerialOpener, _opener: &str) {
    let (mut master, path) = device();
    let (handle, join, stop) = start(&path, open);
    wait_for("open", || handle.status.state() == PortState::Open);
    let block = vec![0x55u8; 4096];
    let total = skyframe_shell::serial::RX_RING + 8 * 1024;
    let mut sent = 0;
    while sent < total {
        master.write_all(&block).expect("write");
        sent += block.len();
    }
    wait_for("all bytes read", || {
        handle.status.bytes_in.load(Ordering::Relaxed) as usize >= total
    });
    let dropped = handle.status.bytes_dropped.load(Ordering::Relaxed) as usize;
    assert_eq!(
        dropped,
        total - skyframe_shell::serial::RX_RING,
        "nothing vanishes uncounted"
    );
    assert_eq!(handle.rx.slots(), skyframe_shell::serial::RX_RING);
    stop.store(true, Ordering::Relaxed);
    join.join().expect("thread ends");
}

/// Each test above, once per opener (named, so that their scratch directories differ).
macro_rules! with_each_opener {
    ($($test:ident),* $(,)?) => {
        mod serialport_opener {
            $(#[test]
            fn $test() {
                super::$test(skyframe_linux::serial::open, "serialport");
            })*
        }
        mod termios_opener {
            $(#[test]
            fn $test() {
                super::$test(skyframe_qnx::serial::open, "termios");
            })*
        }
    };
}

with_each_opener!(
    bytes_flow_both_ways,
    unplugged_port_is_lost_then_resumes_when_the_path_comes_back,
    a_port_missing_at_start_is_retried_until_it_appears,
    a_full_rx_ring_counts_what_it_could_not_take
);
