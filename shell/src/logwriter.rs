//! The log writer thread: the only code that touches log files.
//!
//! Each log stream (one per task, plus the executive's timing records) has its own rtrb byte
//! ring. Producers push whole binary records (`log-format.md`) or nothing: a record that does
//! not fit is dropped and counted, the frame never waits. The writer drains the rings into
//! files, flushing to the OS every `flush_every` and forcing to disk (`fsync`) every
//! `fsync_every`, so after `kill -9` everything flushed survives and after a power cut
//! everything up to the last fsync does; the converter reads the rest up to the torn tail.
//!
//! Files rotate at `rotate_bytes`: the old file gets an End Data record and the new one a
//! Begin Data record plus the stream's format declarations, so every file stands alone.
//! A write error (disk full) stops that stream with a visible flag; everything else keeps
//! going.

use crate::platform::FreeSpaceProbe;
use crate::textlog::{TextStream, Written};
use skyframe_core::comm::LogHealthCell;
use skyframe_core::link::messages::LogHealth;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use skyframe_core::logfmt::record::kind::{
    BEGIN_DATA, BYTE_ARRAY, BYTE_ARRAY_LEGACY, DATA_BLOCK, END_DATA, FORMAT_COMMENT,
    FORMAT_DEFINITION,
};

#[derive(Clone, Debug)]
pub struct WriterConfig {
    /// The flight's directory (created if missing).
    pub dir: PathBuf,
    pub rotate_bytes: u64,
    pub flush_every: Duration,
    pub fsync_every: Duration,
    /// How long the writer sleeps when every ring is empty.
    pub idle_poll: Duration,
    /// Measures the free space where the log is written (`None`: reported unknown).
    pub free_space: Option<FreeSpaceProbe>,
    /// Where the writer reports the log's health (free space, losses) for telemetry.
    pub health: Option<Arc<LogHealthCell>>,
}

impl WriterConfig {
    pub fn new(dir: PathBuf) -> Self {
        Self {
            dir,
            rotate_bytes: 64 * 1024 * 1024,
            flush_every: Duration::from_millis(100),
            fsync_every: Duration::from_secs(1),
            idle_poll: Duration::from_millis(5),
            free_space: None,
            health: None,
        }
    }
}

/// Counters of one stream, shared lock-free with the executive (health, telemetry).
#[derive(Debug, Default)]
pub struct StreamStatus {
    pub records_written: AtomicU64,
    /// Records known to be on disk: written before the last successful fsync.
    pub records_synced: AtomicU64,
    pub bytes_written: AtomicU64,
    /// Records the producer could not fit into the ring.
    pub records_dropped: AtomicU64,
    /// Records that never reached the disk: drained while the stream was suspended or had
    /// failed, or in the buffer a failed write took with it.
    pub records_lost: AtomicU64,
    /// Set once the stream can write nothing more (a text stream's write failed, or a file
    /// could not be closed).
    pub failed: AtomicBool,
    /// A write failed (a full disk): the stream is suspended and retries every
    /// [`RESUME_RETRY`]; cleared when it writes again.
    pub suspended: AtomicBool,
    /// Times the stream was suspended.
    pub suspensions: AtomicU32,
    /// Files this stream has written (1 + rotations).
    pub files: AtomicU32,
    /// Bytes in the ring that started no record (a producer bug), skipped.
    pub garbage_bytes: AtomicU64,
}

/// The producer end of a stream: push whole records, never wait.
pub struct LogStream {
    producer: rtrb::Producer<u8>,
    pub status: Arc<StreamStatus>,
    wait_when_full: bool,
}

impl LogStream {
    /// In virtual time, wait for the writer instead of dropping: there is no deadline to
    /// miss, and a deterministic run must log every record.
    pub fn set_wait_when_full(&mut self, wait: bool) {
        self.wait_when_full = wait;
    }

    /// Queues one encoded record; `false` (and a count) when it does not fit whole.
    pub fn push_record(&mut self, record: &[u8]) -> bool {
        if self.wait_when_full {
            while self.producer.slots() < record.len()
                && record.len() <= self.producer.buffer().capacity()
                && !self.producer.is_abandoned()
            {
                std::thread::yield_now();
            }
        }
        if self.producer.slots() < record.len() {
            self.status.records_dropped.fetch_add(1, Ordering::Relaxed);
            return false;
        }
        match self.producer.write_chunk_uninit(record.len()) {
            Ok(chunk) => {
                chunk.fill_from_iter(record.iter().copied());
                true
            }
            Err(_) => {
                self.status.records_dropped.fetch_add(1, Ordering::Relaxed);
                false
            }
        }
    }
}

impl skyframe_core::logfmt::RecordSink for LogStream {
    fn push_record(&mut self, record: &[u8]) -> bool {
        LogStream::push_record(self, record)
    }
}

/// A stream as the writer thread sees it.
struct Drain {
    name: String,
    consumer: rtrb::Consumer<u8>,
    status: Arc<StreamStatus>,
    /// Format definitions and comments seen so far, re-emitted at the top of rotated files.
    declarations: Vec<u8>,
    /// Bytes read from the ring that do not yet make a whole record.
    pending: Vec<u8>,
    file: Option<BufWriter<File>>,
    file_bytes: u64,
    sequence: u32,
    last_time: [u8; 8],
    /// A Begin Data was written and its End not yet: a task is logging into this stream.
    section_open: bool,
    /// Bytes of the current file that reached the OS whole (at the last successful flush):
    /// what a failed write truncates back to, so no record is ever left half-written.
    durable_len: u64,
    /// Records written into the buffer since that flush.
    unflushed_records: u64,
    /// Suspended since (a write failed); the file is kept, positioned at `durable_len`.
    suspended: Option<(Instant, File)>,
    /// Some: this stream is written as CSV text instead of binary.
    text: Option<TextStream>,
}

/// How a stream is written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StreamMode {
    /// `<name>.bin` in the binary log format (the default: smaller, faster).
    Binary,
    /// `<name>.<index>.csv`, the very lines `skyframe-log to-csv` prints.
    Text,
}

/// How often the writer measures the free space and reports the log's health.
pub const HEALTH_EVERY: Duration = Duration::from_secs(2);
/// Below this many seconds of logging at the rate measured so far, the writer warns (once).
pub const LOW_SPACE_WARNING_S: f64 = 60.0;

/// The writer's view of the disk: measured every [`HEALTH_EVERY`], reported through
/// `config.health`, and a warning once the space left is less than a minute of logging.
struct SpaceWatch {
    started: Instant,
    last: Option<Instant>,
    warned: bool,
}

impl SpaceWatch {
    fn new() -> Self {
        Self {
            started: Instant::now(),
            last: None,
            warned: false,
        }
    }

    fn update(&mut self, config: &WriterConfig, drains: &[Drain]) {
        if self.last.is_some_and(|t| t.elapsed() < HEALTH_EVERY) {
            return;
        }
        self.last = Some(Instant::now());
        let free = config.free_space.and_then(|probe| probe(&config.dir).ok());
        let lost: u64 = drains
            .iter()
            .map(|d| d.status.records_lost.load(Ordering::Relaxed))
            .sum();
        let suspended = drains
            .iter()
            .filter(|d| d.status.suspended.load(Ordering::Relaxed))
            .count();
        if let Some(health) = &config.health {
            health.set(LogHealth {
                free_mib: free.map_or(LogHealth::UNKNOWN, |b| {
                    u32::try_from(b / (1024 * 1024)).unwrap_or(LogHealth::UNKNOWN - 1)
                }),
                records_lost: u32::try_from(lost).unwrap_or(u32::MAX),
                streams_suspended: u8::try_from(suspended).unwrap_or(u8::MAX),
            });
        }
        let written: u64 = drains
            .iter()
            .map(|d| d.status.bytes_written.load(Ordering::Relaxed))
            .sum();
        let elapsed = self.started.elapsed().as_secs_f64();
        if let Some(free) = free
            && !self.warned
            && elapsed >= 10.0
        {
            let rate = written as f64 / elapsed;
            if rate > 0.0 && (free as f64) < rate * LOW_SPACE_WARNING_S {
                self.warned = true;
                log::warn!(
                    "log {}: {} kB free, about {:.0} s of logging left at {:.0} kB/s",
                    config.dir.display(),
                    free / 1024,
                    free as f64 / rate,
                    rate / 1024.0
                );
            }
        }
    }
}

/// A suspended stream (its disk was full) tries to write again this often.
pub const RESUME_RETRY: Duration = Duration::from_secs(1);

/// Starts the writer thread. Add streams with [`LogWriter::stream`] before `start`.
pub struct LogWriter {
    config: WriterConfig,
    drains: Vec<Drain>,
}

/// The running writer: stop it to drain every ring, close and fsync every file.
pub struct WriterHandle {
    stop: Arc<AtomicBool>,
    abandoned: Arc<AtomicBool>,
    closed: Arc<AtomicBool>,
    join: Option<JoinHandle<Vec<PathBuf>>>,
}

/// Closes the log from another thread when the run cannot end normally (a stop request while
/// a task is stuck in its step): the writer drains what the rings hold — whole records only,
/// as tasks push them — writes each file's End, fsyncs and closes them.
#[derive(Clone)]
pub struct EmergencyClose {
    stop: Arc<AtomicBool>,
    abandoned: Arc<AtomicBool>,
    closed: Arc<AtomicBool>,
}

impl EmergencyClose {
    /// Asks the writer to close every file and waits up to `wait` for it; `true` once closed.
    pub fn close(&self, wait: Duration) -> bool {
        // The tasks will not write their End Data: the writer ends their sections itself.
        self.abandoned.store(true, Ordering::Release);
        self.stop.store(true, Ordering::Release);
        let until = Instant::now() + wait;
        while Instant::now() < until {
            if self.closed.load(Ordering::Acquire) {
                return true;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        self.closed.load(Ordering::Acquire)
    }
}

impl LogWriter {
    pub fn new(config: WriterConfig) -> Self {
        Self {
            config,
            drains: Vec::new(),
        }
    }

    /// A new stream writing `<dir>/<name>.bin` (then `<name>.1.bin`, … on rotation), with a
    /// ring of `ring_bytes`.
    pub fn stream(&mut self, name: &str, ring_bytes: usize) -> LogStream {
        self.stream_as(name, ring_bytes, StreamMode::Binary)
    }

    /// A new stream written as `mode` says.
    pub fn stream_as(&mut self, name: &str, ring_bytes: usize, mode: StreamMode) -> LogStream {
        let (producer, consumer) = rtrb::RingBuffer::new(ring_bytes);
        let status = Arc::new(StreamStatus::default());
        self.drains.push(Drain {
            name: name.to_string(),
            consumer,
            status: Arc::clone(&status),
            declarations: Vec::new(),
            pending: Vec::new(),
            file: None,
            file_bytes: 0,
            sequence: 0,
            last_time: [0; 8],
            section_open: false,
            durable_len: 0,
            unflushed_records: 0,
            suspended: None,
            text: (mode == StreamMode::Text).then(|| TextStream::new(name)),
        });
        LogStream {
            producer,
            status,
            wait_when_full: false,
        }
    }

    pub fn start(self) -> std::io::Result<WriterHandle> {
        std::fs::create_dir_all(&self.config.dir)?;
        let stop = Arc::new(AtomicBool::new(false));
        let closed = Arc::new(AtomicBool::new(false));
        let abandoned = Arc::new(AtomicBool::new(false));
        let (thread_stop, thread_closed, thread_abandoned) = (
            Arc::clone(&stop),
            Arc::clone(&closed),
            Arc::clone(&abandoned),
        );
        let join = std::thread::Builder::new()
            .name("log-writer".into())
            .spawn(move || {
                let files =
                    writer_thread(self.config, self.drains, &thread_stop, &thread_abandoned);
                thread_closed.store(true, Ordering::Release);
                files
            })?;
        Ok(WriterHandle {
            stop,
            abandoned,
            closed,
            join: Some(join),
        })
    }
}

impl WriterHandle {
    pub fn emergency_close(&self) -> EmergencyClose {
        EmergencyClose {
            stop: Arc::clone(&self.stop),
            abandoned: Arc::clone(&self.abandoned),
            closed: Arc::clone(&self.closed),
        }
    }

    /// Drains every ring, writes, fsyncs and closes every file; returns the files written.
    pub fn finish(mut self) -> Vec<PathBuf> {
        self.stop.store(true, Ordering::Release);
        self.join
            .take()
            .and_then(|j| j.join().ok())
            .unwrap_or_default()
    }
}

impl Drop for WriterHandle {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(j) = self.join.take() {
            let _ = j.join();
        }
    }
}

/// What the bytes at the head of a ring hold.
enum Head {
    /// Not enough bytes for the record's header or body yet.
    Incomplete,
    /// A whole record of this many bytes.
    Record(usize),
    /// A byte that starts no record. Producers only push records they encoded, so this is a
    /// bug upstream; the byte is skipped and counted rather than written or wedging the ring.
    Garbage,
}

fn head(bytes: &[u8]) -> Head {
    let Some(&[kind, _, lo, hi]) = bytes.get(..4) else {
        return Head::Incomplete;
    };
    let n = usize::from(u16::from_le_bytes([lo, hi]));
    let len = match kind {
        BEGIN_DATA | END_DATA => 12,
        FORMAT_COMMENT | FORMAT_DEFINITION => 4 + n,
        DATA_BLOCK | BYTE_ARRAY | BYTE_ARRAY_LEGACY => 12 + n,
        _ => return Head::Garbage,
    };
    if bytes.len() >= len {
        Head::Record(len)
    } else {
        Head::Incomplete
    }
}

fn marker(kind: u8, time: [u8; 8]) -> [u8; 12] {
    let mut r = [0u8; 12];
    r[0] = kind;
    r[4..].copy_from_slice(&time);
    r
}

impl Drain {
    fn path(&self, dir: &Path) -> PathBuf {
        if self.sequence == 0 {
            dir.join(format!("{}.bin", self.name))
        } else {
            dir.join(format!("{}.{}.bin", self.name, self.sequence))
        }
    }

    fn open(&mut self, dir: &Path, files: &mut Vec<PathBuf>) -> std::io::Result<()> {
        let path = self.path(dir);
        let file = File::create(&path)?;
        // The new directory entry must survive a power cut too.
        File::open(dir).and_then(|d| d.sync_all())?;
        let mut w = BufWriter::with_capacity(64 * 1024, file);
        if self.sequence > 0 {
            w.write_all(&self.declarations)?;
            w.write_all(&marker(BEGIN_DATA, self.last_time))?;
            self.file_bytes = self.declarations.len() as u64 + 12;
        } else {
            self.file_bytes = 0;
        }
        self.status.files.fetch_add(1, Ordering::Relaxed);
        files.push(path);
        self.file = Some(w);
        self.durable_len = 0;
        Ok(())
    }

    /// A write or flush failed (a full disk, most likely): drop what the buffer held, cut
    /// the file back to its last whole record, count the records lost, and keep the file to
    /// try again in [`RESUME_RETRY`]. The flight goes on.
    fn suspend(&mut self, error: &std::io::Error) {
        let lost = self.unflushed_records;
        self.status.records_lost.fetch_add(lost, Ordering::Relaxed);
        self.status.records_written.fetch_sub(
            lost.min(self.status.records_written.load(Ordering::Relaxed)),
            Ordering::Relaxed,
        );
        self.unflushed_records = 0;
        self.file_bytes = self.durable_len;
        let parked = self.file.take().and_then(|w| {
            // The buffer's bytes are not written again (into_parts does not flush).
            let (mut file, _lost) = w.into_parts();
            file.set_len(self.durable_len)
                .and_then(|()| std::io::Seek::seek(&mut file, std::io::SeekFrom::End(0)))
                .ok()
                .map(|_| file)
        });
        if self.suspended.is_none() {
            self.status.suspensions.fetch_add(1, Ordering::Relaxed);
            log::error!(
                "log {}: write failed ({error}): suspended, {lost} records lost; retrying every \
                 {} s",
                self.name,
                RESUME_RETRY.as_secs()
            );
        }
        self.status.suspended.store(true, Ordering::Relaxed);
        match parked {
            Some(file) => self.suspended = Some((Instant::now(), file)),
            None => {
                // The file itself is unusable: nothing to resume into.
                log::error!(
                    "log {}: the file cannot be cut back: logging stopped",
                    self.name
                );
                self.suspended = None;
                self.status.failed.store(true, Ordering::Relaxed);
            }
        }
    }

    /// Suspended long enough: write into the kept file again (its declarations and a Begin
    /// Data first if none of them reached it), and flush at once to find out whether there is
    /// room. `false` while still suspended.
    fn try_resume(&mut self) -> bool {
        let Some((since, _)) = &self.suspended else {
            return true;
        };
        if since.elapsed() < RESUME_RETRY {
            return false;
        }
        let Some((_, file)) = self.suspended.take() else {
            return false;
        };
        let mut w = BufWriter::with_capacity(64 * 1024, file);
        let mut head = Vec::new();
        if self.durable_len == 0 {
            head.extend_from_slice(&self.declarations);
            if self.section_open {
                head.extend_from_slice(&marker(BEGIN_DATA, self.last_time));
            }
        }
        let result = w.write_all(&head).and_then(|()| w.flush());
        self.file = Some(w);
        match result {
            Ok(()) => {
                self.file_bytes = self.durable_len + head.len() as u64;
                self.durable_len = self.file_bytes;
                self.status.suspended.store(false, Ordering::Relaxed);
                log::warn!(
                    "log {}: writing again ({} records lost in all)",
                    self.name,
                    self.status.records_lost.load(Ordering::Relaxed)
                );
                true
            }
            Err(e) => {
                self.suspend(&e);
                false
            }
        }
    }

    fn close(&mut self) -> std::io::Result<()> {
        if let Some(text) = self.text.as_mut() {
            text.close()?;
        }
        if let Some((_, file)) = self.suspended.take() {
            // Cut back to whole records when it was suspended: all that is left is to sync.
            return file.sync_all();
        }
        if let Some(mut w) = self.file.take() {
            let written = self.status.records_written.load(Ordering::Relaxed);
            w.flush()?;
            w.get_ref().sync_all()?;
            self.status.records_synced.store(written, Ordering::Relaxed);
        }
        Ok(())
    }

    fn write_record(
        &mut self,
        record: &[u8],
        config: &WriterConfig,
        files: &mut Vec<PathBuf>,
    ) -> std::io::Result<()> {
        match record.first() {
            Some(&FORMAT_DEFINITION) | Some(&FORMAT_COMMENT) => {
                self.declarations.extend_from_slice(record)
            }
            Some(&k) if k != FORMAT_DEFINITION && record.len() >= 12 => {
                if let Some(t) = record.get(4..12) {
                    self.last_time.copy_from_slice(t);
                }
                match k {
                    BEGIN_DATA => self.section_open = true,
                    END_DATA => self.section_open = false,
                    _ => {}
                }
            }
            _ => {}
        }
        if let Some(text) = self.text.as_mut() {
            let outcome = text.write(record, &config.dir, config.rotate_bytes, files)?;
            if let Written::Unrenderable = outcome {
                self.status.records_lost.fetch_add(1, Ordering::Relaxed);
            } else {
                self.status.records_written.fetch_add(1, Ordering::Relaxed);
            }
            return Ok(());
        }
        if self.file.is_none() {
            self.open(&config.dir, files)?;
        }
        if let Some(w) = self.file.as_mut() {
            w.write_all(record)?;
        }
        self.unflushed_records += 1;
        self.file_bytes += record.len() as u64;
        self.status
            .bytes_written
            .fetch_add(record.len() as u64, Ordering::Relaxed);
        self.status.records_written.fetch_add(1, Ordering::Relaxed);
        if self.file_bytes >= config.rotate_bytes {
            if let Some(w) = self.file.as_mut() {
                w.write_all(&marker(END_DATA, self.last_time))?;
            }
            self.close()?;
            self.unflushed_records = 0;
            self.sequence += 1;
            self.open(&config.dir, files)?;
        }
        Ok(())
    }

    /// Moves everything in the ring to the file. Returns whether anything was read.
    fn drain(&mut self, config: &WriterConfig, files: &mut Vec<PathBuf>) -> bool {
        let available = self.consumer.slots();
        if available == 0 {
            return false;
        }
        if let Ok(chunk) = self.consumer.read_chunk(available) {
            let (a, b) = chunk.as_slices();
            self.pending.extend_from_slice(a);
            self.pending.extend_from_slice(b);
            chunk.commit_all();
        }
        let mut at = 0;
        let pending = std::mem::take(&mut self.pending);
        loop {
            let rest = pending.get(at..).unwrap_or_default();
            let len = match head(rest) {
                Head::Incomplete => break,
                Head::Garbage => {
                    self.status.garbage_bytes.fetch_add(1, Ordering::Relaxed);
                    at += 1;
                    continue;
                }
                Head::Record(len) => len,
            };
            let Some(record) = rest.get(..len) else { break };
            if self.status.failed.load(Ordering::Relaxed) || !self.try_resume() {
                self.status.records_lost.fetch_add(1, Ordering::Relaxed);
                // Declarations still count: a file resumed from nothing needs them.
                if matches!(record.first(), Some(&FORMAT_DEFINITION | &FORMAT_COMMENT)) {
                    self.declarations.extend_from_slice(record);
                }
            } else if let Err(e) = self.write_record(record, config, files) {
                self.status.records_lost.fetch_add(1, Ordering::Relaxed);
                if self.text.is_some() {
                    log::error!(
                        "log {}: write failed, logging stopped for this stream: {e}",
                        self.name
                    );
                    self.status.failed.store(true, Ordering::Relaxed);
                    self.file = None;
                } else {
                    self.suspend(&e);
                }
            }
            at += len;
        }
        self.pending = pending.get(at..).map(<[u8]>::to_vec).unwrap_or_default();
        true
    }

    fn flush(&mut self, sync: bool) {
        if self.status.failed.load(Ordering::Relaxed) {
            return;
        }
        let written = self.status.records_written.load(Ordering::Relaxed);
        let text = self.text.as_mut().map_or(Ok(()), |t| t.flush(sync));
        let result = text.and_then(|()| {
            self.file.as_mut().map_or(Ok(()), |w| {
                w.flush()?;
                if sync {
                    w.get_ref().sync_data()
                } else {
                    Ok(())
                }
            })
        });
        if result.is_ok() {
            self.durable_len = self.file_bytes;
            self.unflushed_records = 0;
            if sync {
                self.status.records_synced.store(written, Ordering::Relaxed);
            }
        }
        if let Err(e) = result {
            if self.text.is_some() {
                log::error!(
                    "log {}: flush failed, logging stopped for this stream: {e}",
                    self.name
                );
                self.status.failed.store(true, Ordering::Relaxed);
                self.file = None;
            } else {
                self.suspend(&e);
            }
        }
    }
}

fn writer_thread(
    config: WriterConfig,
    mut drains: Vec<Drain>,
    stop: &AtomicBool,
    abandoned: &AtomicBool,
) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let mut last_flush = Instant::now();
    let mut last_sync = Instant::now();
    let mut space = SpaceWatch::new();
    loop {
        space.update(&config, &drains);
        // Read the flag before draining: whatever was pushed before it was set is drained.
        let stopping = stop.load(Ordering::Acquire);
        let mut busy = false;
        for d in &mut drains {
            busy |= d.drain(&config, &mut files);
        }
        let sync = last_sync.elapsed() >= config.fsync_every;
        if sync || last_flush.elapsed() >= config.flush_every {
            for d in &mut drains {
                d.flush(sync);
            }
            last_flush = Instant::now();
            if sync {
                last_sync = Instant::now();
            }
        }
        if stopping {
            break;
        }
        if !busy {
            std::thread::sleep(config.idle_poll);
        }
    }
    let abandoned = abandoned.load(Ordering::Acquire);
    for d in &mut drains {
        if abandoned
            && d.section_open
            && d.text.is_none()
            && let Some(w) = d.file.as_mut()
            && let Err(e) = w.write_all(&marker(END_DATA, d.last_time))
        {
            log::error!("log {}: ending the section failed: {e}", d.name);
            d.status.failed.store(true, Ordering::Relaxed);
        }
        if !d.status.failed.load(Ordering::Relaxed)
            && let Err(e) = d.close()
        {
            log::error!("log {}: closing failed: {e}", d.name);
            d.status.failed.store(true, Ordering::Relaxed);
        }
    }
    files
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_writer_reports_free_space_and_losses_for_telemetry() {
        fn five_gib(_: &Path) -> std::io::Result<u64> {
            Ok(5 * 1024 * 1024 * 1024)
        }
        let dir = std::env::temp_dir().join(format!("skyframe-health-{}", std::process::id()));
        let health = Arc::new(LogHealthCell::new());
        assert_eq!(health.get().free_mib, LogHealth::UNKNOWN);
        let mut writer = LogWriter::new(WriterConfig {
            free_space: Some(five_gib),
            health: Some(Arc::clone(&health)),
            ..WriterConfig::new(dir.clone())
        });
        let _stream = writer.stream("imu", 4096);
        let handle = writer.start().expect("starts");
        let start = Instant::now();
        while health.get().free_mib == LogHealth::UNKNOWN
            && start.elapsed() < Duration::from_secs(2)
        {
            std::thread::sleep(Duration::from_millis(5));
        }
        handle.finish();
        assert_eq!(
            health.get(),
            LogHealth {
                free_mib: 5 * 1024,
                records_lost: 0,
                streams_suspended: 0
            }
        );
        let _ = std::fs::remove_dir_all(dir);
    }

    fn time(sec: i32, nsec: u32) -> [u8; 8] {
        let mut t = [0u8; 8];
        t[..4].copy_from_slice(&sec.to_le_bytes());
        t[4..].copy_from_slice(&nsec.to_le_bytes());
        t
    }

    fn declaration(kind: u8, index: u8, text: &str) -> Vec<u8> {
        let mut r = vec![kind, index];
        r.extend_from_slice(&(text.len() as u16).to_le_bytes());
        r.extend_from_slice(text.as_bytes());
        r
    }

    fn data(index: u8, sec: i32, value: u32) -> Vec<u8> {
        let mut r = vec![DATA_BLOCK, index, 4, 0];
        r.extend_from_slice(&time(sec, 0));
        r.extend_from_slice(&value.to_le_bytes());
        r
    }

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("skyframe-logw-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    fn config(dir: &Path) -> WriterConfig {
        WriterConfig {
            idle_poll: Duration::from_millis(1),
            ..WriterConfig::new(dir.to_path_buf())
        }
    }

    #[test]
    fn records_reach_the_file_in_order_and_whole() {
        let dir = scratch("order");
        let mut writer = LogWriter::new(config(&dir));
        let mut imu = writer.stream("imu", 4096);
        let handle = writer.start().expect("starts");
        let mut expected = Vec::new();
        for r in [
            declaration(FORMAT_DEFINITION, 1, "%u"),
            declaration(FORMAT_COMMENT, 1, "n"),
            marker(BEGIN_DATA, time(1, 0)).to_vec(),
        ] {
            assert!(imu.push_record(&r));
            expected.extend_from_slice(&r);
        }
        for i in 0..500 {
            let r = data(1, 2, i);
            while !imu.push_record(&r) {
                std::thread::sleep(Duration::from_millis(1));
            }
            expected.extend_from_slice(&r);
        }
        let files = handle.finish();
        assert_eq!(files, vec![dir.join("imu.bin")]);
        assert_eq!(std::fs::read(dir.join("imu.bin")).expect("file"), expected);
        assert_eq!(imu.status.records_written.load(Ordering::Relaxed), 503);
    }

    #[test]
    fn a_full_ring_drops_whole_records_and_counts_them() {
        let dir = scratch("full");
        let mut writer = LogWriter::new(config(&dir));
        let mut gps = writer.stream("gps", 40);
        // Writer not started: the ring fills. 16-byte records: two fit in 40 bytes, not three.
        assert!(gps.push_record(&data(1, 0, 1)));
        assert!(gps.push_record(&data(1, 0, 2)));
        assert!(!gps.push_record(&data(1, 0, 3)));
        assert_eq!(gps.status.records_dropped.load(Ordering::Relaxed), 1);
        let files = writer.start().expect("starts").finish();
        let bytes = std::fs::read(&files[0]).expect("file");
        assert_eq!(bytes.len(), 32, "two whole records, no partial third");
    }

    #[test]
    fn rotation_makes_every_file_stand_alone() {
        let dir = scratch("rotate");
        let mut writer = LogWriter::new(WriterConfig {
            rotate_bytes: 200,
            ..config(&dir)
        });
        let mut s = writer.stream("servo", 8192);
        let def = declaration(FORMAT_DEFINITION, 1, "%u");
        let com = declaration(FORMAT_COMMENT, 1, "n");
        s.push_record(&def);
        s.push_record(&com);
        s.push_record(&marker(BEGIN_DATA, time(1, 0)));
        for i in 0..40 {
            s.push_record(&data(1, 10 + i as i32, i));
        }
        s.push_record(&marker(END_DATA, time(60, 0)));
        let files = writer.start().expect("starts").finish();
        assert!(files.len() >= 3, "{files:?}");
        let mut values = Vec::new();
        for (n, f) in files.iter().enumerate() {
            let bytes = std::fs::read(f).expect("file");
            assert_eq!(bytes[0], FORMAT_DEFINITION, "{f:?} starts with its formats");
            if n > 0 {
                let begin = def.len() + com.len();
                assert_eq!(bytes[begin], BEGIN_DATA, "{f:?}");
            }
            assert_eq!(bytes[bytes.len() - 12], END_DATA, "{f:?} closed cleanly");
            let mut at = 0;
            while at < bytes.len() {
                let Head::Record(len) = head(&bytes[at..]) else {
                    panic!("torn record in {f:?}")
                };
                if bytes[at] == DATA_BLOCK {
                    values.push(u32::from_le_bytes(
                        bytes[at + 12..at + 16].try_into().expect("4"),
                    ));
                }
                at += len;
            }
        }
        assert_eq!(
            values,
            (0..40).collect::<Vec<_>>(),
            "nothing lost or repeated across files"
        );
    }

    #[test]
    fn a_write_error_stops_only_that_stream_and_is_flagged() {
        let dir = scratch("full-disk");
        std::fs::create_dir_all(&dir).expect("dir");
        // /dev/full accepts the open and fails every write with ENOSPC, like a full disk.
        std::os::unix::fs::symlink("/dev/full", dir.join("imu.bin")).expect("symlink");
        let mut writer = LogWriter::new(config(&dir));
        let mut imu = writer.stream("imu", 4096);
        let mut gps = writer.stream("gps", 4096);
        let handle = writer.start().expect("starts");
        for i in 0..10 {
            assert!(imu.push_record(&data(1, 0, i)));
            assert!(gps.push_record(&data(1, 0, i)));
        }
        std::thread::sleep(Duration::from_millis(300));
        for i in 0..10 {
            assert!(
                imu.push_record(&data(1, 1, i)),
                "a failed stream still drains its ring"
            );
        }
        handle.finish();
        assert!(imu.status.failed.load(Ordering::Relaxed));
        assert!(imu.status.records_lost.load(Ordering::Relaxed) >= 10);
        assert!(!gps.status.failed.load(Ordering::Relaxed));
        assert_eq!(std::fs::read(dir.join("gps.bin")).expect("gps").len(), 160);
    }
}
