//! Reading the logs: the executive's frame records from `executive.bin`, the TIMEs of the
//! device logs' samples. Both go through the core's streaming reader, so a damaged file
//! yields what is readable plus a list of problems.

use std::io;
use std::path::{Path, PathBuf};

use skyframe_core::executive::FrameRecord;
use skyframe_core::logfmt::{
    Event, LogReader, Record, decode_frame_record, frame_record_task_names,
};

/// A problem found while reading, as one stderr line.
#[derive(Clone, Debug)]
pub struct Damage {
    pub path: PathBuf,
    pub line: String,
}

pub use skyframe_logtable::{feed, problem_line, time_ns};

/// Collects the frame records of one `executive.bin`, event by event (so it also follows a
/// growing file).
pub struct FrameCollector {
    path: PathBuf,
    /// Task names of each format index whose comment is a frame log's.
    names: Vec<Option<Vec<String>>>,
    /// The task names of the first frame log format found.
    pub tasks: Vec<String>,
    pub frames: Vec<FrameRecord>,
    pub damage: Vec<Damage>,
}

impl FrameCollector {
    pub fn new(path: &Path) -> Self {
        Self {
            path: path.to_path_buf(),
            names: vec![None; 256],
            tasks: Vec::new(),
            frames: Vec::new(),
            damage: Vec::new(),
        }
    }

    /// Whether a frame log format was found.
    pub fn found_format(&self) -> bool {
        !self.tasks.is_empty() || self.names.iter().any(Option::is_some)
    }

    fn damaged(&mut self, line: String) {
        self.damage.push(Damage {
            path: self.path.clone(),
            line,
        });
    }

    pub fn event(&mut self, event: Event<'_>) {
        match event {
            Event::Problem(problem) => {
                let line = problem_line(&self.path, &problem);
                self.damaged(line);
            }
            Event::Record { offset, record } => match record {
                Record::FormatDefinition { index, .. } => {
                    // A new definition: its comment (next) says whether it is a frame log.
                    if let Some(slot) = self.names.get_mut(usize::from(index)) {
                        *slot = None;
                    }
                }
                Record::FormatComment { index, text } => {
                    let names = std::str::from_utf8(text)
                        .ok()
                        .and_then(frame_record_task_names)
                        .map(|names| names.map(str::to_string).collect::<Vec<_>>());
                    if let Some(names) = names {
                        if self.tasks.is_empty() {
                            self.tasks = names.clone();
                        }
                        if let Some(slot) = self.names.get_mut(usize::from(index)) {
                            *slot = Some(names);
                        }
                    }
                }
                Record::DataBlock {
                    index,
                    data,
                    format,
                    ..
                } => {
                    let Some(Some(names)) = self.names.get(usize::from(index)) else {
                        return;
                    };
                    if *names != self.tasks {
                        let line = format!(
                            "{}: offset {offset}: frame records of another task list ({}) skipped",
                            self.path.display(),
                            names.join(",")
                        );
                        self.damaged(line);
                        return;
                    }
                    match decode_frame_record(format, data) {
                        Some(record) => self.frames.push(record),
                        None => {
                            let line = format!(
                                "{}: offset {offset}: data block of format {index} is not a frame record; skipped",
                                self.path.display()
                            );
                            self.damaged(line);
                        }
                    }
                }
                _ => {}
            },
        }
    }
}

/// Collects the TIMEs (ns) of the data blocks of one format index.
pub struct TimeCollector {
    path: PathBuf,
    index: u8,
    pub times_ns: Vec<i64>,
    pub damage: Vec<Damage>,
}

impl TimeCollector {
    pub fn new(path: &Path, index: u8) -> Self {
        Self {
            path: path.to_path_buf(),
            index,
            times_ns: Vec::new(),
            damage: Vec::new(),
        }
    }

    pub fn event(&mut self, event: Event<'_>) {
        match event {
            Event::Problem(problem) => self.damage.push(Damage {
                path: self.path.clone(),
                line: problem_line(&self.path, &problem),
            }),
            Event::Record {
                record: Record::DataBlock { index, time, .. },
                ..
            } if index == self.index => self.times_ns.push(time_ns(time)),
            Event::Record { .. } => {}
        }
    }
}

/// Streams `path` through a fresh reader, calling `on_event` for every event in file order.
pub fn read_file(
    path: &Path,
    reader: &mut LogReader,
    on_event: impl FnMut(Event<'_>),
) -> io::Result<()> {
    skyframe_logtable::read_file(path, reader, |_| {}, on_event)
}

/// The device logs whose sample periods the report gives: (device, file, format index).
pub const DEVICE_LOGS: [(&str, &str, u8); 3] = [
    ("imu", "imu.bin", 1),
    ("gps", "gps.bin", 1),
    ("servo", "servo.bin", 1),
];

/// Each device's sample TIMEs (ns).
pub type DeviceTimes = Vec<(String, Vec<i64>)>;

/// Reads the sample TIMEs of the device logs present in `dir`; also the problems found and
/// the files that could not be read.
pub fn read_devices(dir: &Path, reader: &mut LogReader) -> (DeviceTimes, Vec<Damage>, Vec<String>) {
    let mut devices = Vec::new();
    let mut damage = Vec::new();
    let mut unreadable = Vec::new();
    for (device, file, index) in DEVICE_LOGS {
        let path = dir.join(file);
        if !path.is_file() {
            continue;
        }
        let mut collector = TimeCollector::new(&path, index);
        match read_file(&path, reader, |e| collector.event(e)) {
            Ok(()) => {
                damage.append(&mut collector.damage);
                devices.push((device.to_string(), collector.times_ns));
            }
            Err(e) => unreadable.push(format!("{}: cannot read: {e}", path.display())),
        }
    }
    (devices, damage, unreadable)
}
