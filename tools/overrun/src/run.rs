//! `run -- COMMAND…`: starts a flight, follows its `executive.bin` as it grows, shows a
//! one-line live status on a terminal, and prints the report when the flight ends.
//!
//! The flight directory: the first new subdirectory (one holding an `executive.bin`) of the
//! command's `--log-dir DIR` (default `flights`, the flight binary's default) that was not
//! there before the start; when the child prints "flight directory: PATH" (skyframe's
//! summary does, at the end) and that is another directory, PATH wins. The child's stdout
//! and stderr are copied to stderr line by line, so stdout holds only the report.
//!
//! Ctrl-C (SIGINT) or SIGTERM does not kill the tool: the flight is asked to stop (the signal
//! is passed on once; from a terminal it has it already), ends its logs cleanly, and the
//! report of what it flew is printed as after any other end.

use std::collections::HashSet;
use std::fs::File;
use std::io::{self, BufRead, BufReader, IsTerminal, Write};
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use skyframe_core::executive::timing::flags;
use skyframe_core::logfmt::LogReader;

use crate::read::{FrameCollector, feed};
use crate::{Outcome, OutputOptions, finish};

const FLIGHT_DIR_PREFIX: &str = "flight directory: ";
const POLL: Duration = Duration::from_millis(50);
const STATUS_EVERY: Duration = Duration::from_millis(200);

/// The `--log-dir` of a flight command line (default `flights`).
pub fn log_dir_of(args: &[String]) -> PathBuf {
    let mut it = args.iter();
    while let Some(arg) = it.next() {
        if arg == "--log-dir" {
            if let Some(dir) = it.next() {
                return PathBuf::from(dir);
            }
        } else if let Some(dir) = arg.strip_prefix("--log-dir=") {
            return PathBuf::from(dir);
        }
    }
    PathBuf::from("flights")
}

fn subdirs(dir: &Path) -> HashSet<PathBuf> {
    std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(Result::ok)
                .map(|e| e.path())
                .filter(|p| p.is_dir())
                .collect()
        })
        .unwrap_or_default()
}

/// A flight's `executive.bin`, read as it grows.
struct Follow {
    dir: PathBuf,
    path: PathBuf,
    file: File,
    reader: LogReader,
    collector: FrameCollector,
}

impl Follow {
    fn open(dir: &Path) -> Option<Follow> {
        let path = dir.join("executive.bin");
        let file = File::open(&path).ok()?;
        Some(Follow {
            dir: dir.to_path_buf(),
            collector: FrameCollector::new(&path),
            path,
            file,
            reader: LogReader::new(),
        })
    }

    /// Reads the bytes written since the last poll.
    fn poll(&mut self) -> io::Result<()> {
        loop {
            let count = feed(&mut self.file, &mut self.reader)?;
            while let Some(event) = self.reader.next_event() {
                self.collector.event(event);
            }
            if count == 0 {
                return Ok(());
            }
        }
    }

    /// Reads the rest and the file's tail.
    fn finish(&mut self) -> io::Result<()> {
        self.poll()?;
        self.reader.finish();
        while let Some(event) = self.reader.next_event() {
            self.collector.event(event);
        }
        Ok(())
    }
}

/// Running totals for the live status line.
#[derive(Default)]
struct Live {
    seen: usize,
    late: u64,
    overrun: u64,
    missed: u64,
    max_latency_ns: u32,
}

impl Live {
    fn update(&mut self, collector: &FrameCollector) {
        for f in collector.frames.iter().skip(self.seen) {
            self.late += u64::from(f.flags & flags::LATE != 0);
            self.overrun += u64::from(f.flags & flags::OVERRUN != 0);
            self.missed += u64::from(f.missed_before);
            self.max_latency_ns = self.max_latency_ns.max(f.start_latency_ns);
        }
        self.seen = collector.frames.len();
    }

    fn line(&self) -> String {
        format!(
            "frames {}, late {}, overruns {}, missed {}, max start latency {:.1} us",
            self.seen,
            self.late,
            self.overrun,
            self.missed,
            f64::from(self.max_latency_ns) / 1000.0
        )
    }
}

fn exit_code_of(status: std::process::ExitStatus) -> u8 {
    match (status.code(), status.signal()) {
        (Some(code), _) => u8::try_from(code).unwrap_or(1).max(1),
        (None, Some(signal)) => u8::try_from(128 + signal).unwrap_or(1),
        (None, None) => 1,
    }
}

/// Asks the flight to stop as Ctrl-C would (skyframe ends the run cleanly on SIGINT).
fn stop_child(pid: u32) {
    use nix::sys::signal::{Signal, kill};
    use nix::unistd::Pid;
    let Ok(pid) = i32::try_from(pid) else { return };
    if let Err(e) = kill(Pid::from_raw(pid), Signal::SIGINT) {
        eprintln!("run: cannot pass the interrupt on to the flight (pid {pid}): {e}");
    }
}

pub fn run(command: &[String], output: &OutputOptions) -> ExitCode {
    let Some((program, args)) = command.split_first() else {
        eprintln!("run: no command given after --");
        return ExitCode::from(2);
    };
    let log_dir = log_dir_of(args);
    let before = subdirs(&log_dir);
    let interrupted = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        if let Err(e) = signal_hook::flag::register(signal, Arc::clone(&interrupted)) {
            eprintln!("run: cannot catch signal {signal}: {e}; Ctrl-C will end without a report");
        }
    }
    let mut passed_on = false;
    let mut child = match Command::new(program)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
    {
        Ok(child) => child,
        Err(e) => {
            eprintln!("{program}: cannot start: {e}");
            return ExitCode::from(2);
        }
    };
    let (tx, rx) = mpsc::channel::<String>();
    let mut copiers = Vec::new();
    let pipes: [Option<Box<dyn io::Read + Send>>; 2] = [
        child
            .stdout
            .take()
            .map(|p| Box::new(p) as Box<dyn io::Read + Send>),
        child
            .stderr
            .take()
            .map(|p| Box::new(p) as Box<dyn io::Read + Send>),
    ];
    for pipe in pipes.into_iter().flatten() {
        let tx = tx.clone();
        copiers.push(std::thread::spawn(move || {
            for line in BufReader::new(pipe).lines() {
                let Ok(line) = line else { break };
                if tx.send(line).is_err() {
                    break;
                }
            }
        }));
    }
    drop(tx);
    let tty = io::stderr().is_terminal();
    let mut printed: Option<PathBuf> = None;
    let mut follow: Option<Follow> = None;
    let mut live = Live::default();
    let mut last_status = Instant::now();
    let mut status_shown = false;
    let take_line = |line: String, status_shown: &mut bool, printed: &mut Option<PathBuf>| {
        if *status_shown {
            eprint!("\r\x1b[K");
            *status_shown = false;
        }
        if let Some(at) = line.find(FLIGHT_DIR_PREFIX) {
            let dir = line
                .get(at + FLIGHT_DIR_PREFIX.len()..)
                .unwrap_or("")
                .trim();
            *printed = Some(PathBuf::from(dir));
        }
        eprintln!("{line}");
    };
    let status = loop {
        while let Ok(line) = rx.try_recv() {
            take_line(line, &mut status_shown, &mut printed);
        }
        if follow.is_none() {
            let mut fresh: Vec<PathBuf> = subdirs(&log_dir)
                .difference(&before)
                .filter(|d| d.join("executive.bin").is_file())
                .cloned()
                .collect();
            fresh.sort();
            follow = fresh.first().and_then(|d| Follow::open(d));
        }
        if let Some(f) = follow.as_mut() {
            if let Err(e) = f.poll() {
                eprintln!("{}: cannot read: {e}", f.path.display());
            }
            live.update(&f.collector);
        }
        if tty && follow.is_some() && last_status.elapsed() >= STATUS_EVERY {
            eprint!("\r\x1b[K{}", live.line());
            let _ = io::stderr().flush();
            status_shown = true;
            last_status = Instant::now();
        }
        if interrupted.load(Ordering::Relaxed) && !passed_on {
            passed_on = true;
            stop_child(child.id());
        }
        match child.try_wait() {
            Ok(Some(status)) => break Some(status),
            Ok(None) => std::thread::sleep(POLL),
            Err(e) => {
                eprintln!("{program}: cannot wait for it: {e}");
                break None;
            }
        }
    };
    for copier in copiers {
        let _ = copier.join();
    }
    while let Ok(line) = rx.try_recv() {
        take_line(line, &mut status_shown, &mut printed);
    }
    if status_shown {
        eprint!("\r\x1b[K");
    }
    // The printed flight directory wins over the one guessed from --log-dir.
    if let Some(dir) = &printed
        && follow.as_ref().is_none_or(|f| f.dir != *dir)
    {
        follow = Follow::open(dir);
    }
    let failed = status.filter(|s| !s.success()).map(exit_code_of);
    let outcome = match follow {
        Some(mut f) => match f.finish() {
            Ok(()) => {
                let Follow {
                    dir,
                    path,
                    collector,
                    ..
                } = f;
                finish(&path, Some(&dir), collector, output)
            }
            Err(e) => {
                eprintln!("{}: cannot read: {e}", f.path.display());
                Outcome::Failed
            }
        },
        None => {
            eprintln!(
                "{}: no flight directory with an executive.bin appeared (looked in the command's --log-dir)",
                log_dir.display()
            );
            Outcome::Failed
        }
    };
    match (failed, status) {
        (Some(code), _) => ExitCode::from(code),
        (None, None) => ExitCode::from(1),
        (None, Some(_)) => match outcome {
            Outcome::Whole => ExitCode::SUCCESS,
            Outcome::Damaged => ExitCode::from(3),
            Outcome::Failed => ExitCode::from(2),
        },
    }
}

#[cfg(test)]
mod tests {
    use std::io::Write as _;

    use skyframe_core::executive::FrameRecord;
    use skyframe_core::logfmt::{
        FrameRecordFormat, MAX_RECORD_LEN, encode_begin_data, encode_end_data, encode_frame_record,
    };
    use skyframe_core::schedule::SHIPPED;

    use super::*;

    fn log_bytes(frames: u64) -> Vec<u8> {
        let log = FrameRecordFormat::new(SHIPPED.tasks).expect("format");
        let mut out = Vec::new();
        let mut buf = [0u8; MAX_RECORD_LEN];
        let n = encode_begin_data(&mut buf, 0).expect("begin");
        out.extend_from_slice(&buf[..n]);
        let n = log.encode_declaration(&mut buf, 1).expect("declaration");
        out.extend_from_slice(&buf[..n]);
        for k in 0..frames {
            let mut f = FrameRecord::empty();
            f.frame = k;
            f.start_latency_ns = u32::try_from(k).expect("small");
            f.flags = if k % 10 == 0 { flags::LATE } else { 0 };
            let n = encode_frame_record(&mut buf, 1, k, &log, &f).expect("record");
            out.extend_from_slice(&buf[..n]);
        }
        let n = encode_end_data(&mut buf, frames).expect("end");
        out.extend_from_slice(&buf[..n]);
        out
    }

    #[test]
    fn follows_a_growing_file_across_a_cut_record() {
        let dir = tempfile::tempdir().expect("tempdir");
        let bytes = log_bytes(100);
        let path = dir.path().join("executive.bin");
        let mut file = File::create(&path).expect("create");
        // Cut inside a record: the reader waits for the rest instead of calling it damage.
        let cut = bytes.len() / 2 + 3;
        file.write_all(&bytes[..cut]).expect("write");
        let mut follow = Follow::open(dir.path()).expect("opens");
        follow.poll().expect("poll");
        let first = follow.collector.frames.len();
        assert!(first > 10 && first < 100, "{first}");
        assert!(follow.collector.damage.is_empty());
        file.write_all(&bytes[cut..]).expect("write");
        follow.finish().expect("finish");
        assert_eq!(follow.collector.frames.len(), 100);
        assert!(follow.collector.damage.is_empty());
        let mut live = Live::default();
        live.update(&follow.collector);
        assert_eq!((live.seen, live.late, live.max_latency_ns), (100, 10, 99));
    }

    #[test]
    fn log_dir_from_the_command_line() {
        let args = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert_eq!(
            log_dir_of(&args(&["sim", "--log-dir", "/tmp/d"])),
            PathBuf::from("/tmp/d")
        );
        assert_eq!(
            log_dir_of(&args(&["sim", "--log-dir=x"])),
            PathBuf::from("x")
        );
        assert_eq!(log_dir_of(&args(&["sim"])), PathBuf::from("flights"));
    }
}
