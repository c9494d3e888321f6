//! Test helper: logs records as fast as the writer takes them, until killed. Every 10 ms it
//! prints `synced N` — the number of records the writer has fsynced — so a test can kill it
//! at any moment and check that at least those records survive.
//!
//! Usage: log-stress DIR [FSYNC_MS]

use skyframe_shell::logwriter::{LogWriter, WriterConfig};
use std::io::Write;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

fn main() {
    let mut args = std::env::args().skip(1);
    let Some(dir) = args.next() else {
        eprintln!("usage: log-stress DIR [FSYNC_MS]");
        std::process::exit(2);
    };
    let fsync_ms = args.next().and_then(|a| a.parse().ok()).unwrap_or(20);
    let config = WriterConfig {
        flush_every: Duration::from_millis(5),
        fsync_every: Duration::from_millis(fsync_ms),
        rotate_bytes: u64::MAX,
        ..WriterConfig::new(dir.into())
    };
    let mut writer = LogWriter::new(config);
    let mut stream = writer.stream("stress", 1 << 16);
    let Ok(_handle) = writer.start() else {
        eprintln!("log-stress: cannot start the writer");
        std::process::exit(1);
    };
    let format = b"%u,%u";
    let mut def = vec![0xFD, 1];
    def.extend_from_slice(&(format.len() as u16).to_le_bytes());
    def.extend_from_slice(format);
    stream.push_record(&def);
    let mut sequence: u32 = 0;
    let mut last_report = Instant::now();
    let stdout = std::io::stdout();
    loop {
        // Data block: header, TIME (sequence as seconds), then (sequence, !sequence).
        let mut r = [0u8; 20];
        r[0] = 0xDB;
        r[1] = 1;
        r[2] = 8;
        r[4..8].copy_from_slice(&(sequence as i32).to_le_bytes());
        r[12..16].copy_from_slice(&sequence.to_le_bytes());
        r[16..20].copy_from_slice(&(!sequence).to_le_bytes());
        if stream.push_record(&r) {
            sequence = sequence.wrapping_add(1);
        } else {
            std::thread::yield_now();
        }
        if last_report.elapsed() >= Duration::from_millis(10) {
            let synced = stream.status.records_synced.load(Ordering::Relaxed);
            let _ = writeln!(stdout.lock(), "synced {synced}");
            last_report = Instant::now();
        }
    }
}
