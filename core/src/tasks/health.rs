//! The health task: a health snapshot of every task, once a second, into `health.bin`
//! (`docs/log-streams.md`), so a flight's log shows when a task started overrunning or
//! resetting, not just the totals at the end.

use super::task_log::TaskLog;
use crate::executive::{Task, TaskContext, TaskFault};
use crate::logfmt::RecordSink;

pub const HEALTH_FORMAT_INDEX: u8 = 1;
crate::log_record! {
    /// One task's health snapshot, each task once a second.
    pub struct TaskHealthLog {
        task: u8 = "%hhu",
        initialised: bool = "%hhu",
        running: bool = "%hhu",
        in_frame: bool = "%hhu",
        alive: bool = "%hhu",
        releases: u64 = "%llu",
        overruns_budget: u32 = "%u",
        overruns_frame: u32 = "%u",
        overruns_missed: u32 = "%u",
        skipped: u32 = "%u",
        resets: u32 = "%u",
        faults: u32 = "%u",
        exec_mean_us: f32 = "%.1f",
        exec_max_us: f32 = "%.1f",
        log_dropped: u32 = "%u",
        degraded: bool = "%hhu",
    }
}

pub struct HealthTask<S: RecordSink> {
    log: TaskLog<S>,
    interval_ns: u64,
    next_snapshot_ns: u64,
}

impl<S: RecordSink> HealthTask<S> {
    /// Snapshots every `interval_ns` (1 s in flight).
    pub fn new(sink: S, interval_ns: u64) -> Self {
        Self {
            log: TaskLog::new(sink),
            interval_ns: interval_ns.max(1),
            next_snapshot_ns: 0,
        }
    }

    fn snapshot(&mut self, cx: &TaskContext<'_>) {
        let health = cx.health;
        for index in 0..health.task_count() {
            let Some(h) = health.task(index) else {
                continue;
            };
            let alive = health.alive(index);
            let dropped = health.log_dropped(index);
            let degraded = health.degraded(index).is_some();
            let record = TaskHealthLog {
                task: index as u8,
                initialised: h.initialised,
                running: h.running,
                in_frame: h.in_frame,
                alive,
                releases: h.releases,
                overruns_budget: h.overruns.budget,
                overruns_frame: h.overruns.frame,
                overruns_missed: h.overruns.missed,
                skipped: h.skipped,
                resets: h.resets,
                faults: h.faults,
                exec_mean_us: h.exec.mean_ns() as f32 / 1e3,
                exec_max_us: h.exec.max_ns as f32 / 1e3,
                log_dropped: dropped,
                degraded,
            };
            self.log.log(cx, HEALTH_FORMAT_INDEX, &record);
        }
    }
}

impl<S: RecordSink> Task for HealthTask<S> {
    fn init(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        self.log
            .declare::<TaskHealthLog>(cx, HEALTH_FORMAT_INDEX)
            .map_err(|_| TaskFault::new("health log format"))?;
        self.log.begin(cx);
        self.next_snapshot_ns = cx.now_ns;
        Ok(())
    }

    fn step(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        if cx.now_ns >= self.next_snapshot_ns {
            self.snapshot(cx);
            // Keep the 1 s grid even if a release came late; never schedule in the past.
            self.next_snapshot_ns = self
                .next_snapshot_ns
                .saturating_add(self.interval_ns)
                .max(cx.now_ns.saturating_add(1));
        }
        Ok(())
    }

    fn shutdown(&mut self, cx: &mut TaskContext<'_>) {
        self.snapshot(cx);
        self.log.end(cx);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::executive::Executive;
    use crate::logfmt::reader::{Event, LogReader, Record, read_slice};
    use crate::schedule::{FrameTable, TaskSlot};
    use crate::tasks::test_support::{Idle, MS, SetClock, run_frames, slot};
    use core::cell::Cell;
    use std::vec::Vec;

    /// A ring with room for `capacity` records, keeping what it takes.
    struct Ring {
        bytes: Vec<u8>,
        records: usize,
        capacity: usize,
    }
    impl RecordSink for &mut Ring {
        fn push_record(&mut self, record: &[u8]) -> bool {
            if self.records == self.capacity {
                return false;
            }
            self.records += 1;
            self.bytes.extend_from_slice(record);
            true
        }
    }

    static SLOTS: [TaskSlot; 2] = [slot("imu", 10, 0), slot("health", 100, 0)];
    static TABLE: FrameTable = FrameTable {
        minor_frame_ns: 10 * MS,
        margin_ns: MS,
        late_start_ns: MS,
        tasks: &SLOTS,
        frames: &[0b11, 0b01, 0b01, 0b01, 0b01, 0b01, 0b01, 0b01, 0b01, 0b01],
        utilisation_ppm: 0,
    };

    fn fly(ring: &mut Ring, seconds: u64) -> (u32, u64) {
        let clock = SetClock(Cell::new(0));
        let mut imu = Idle;
        let mut health = HealthTask::new(ring, 1000 * MS);
        let mut exec = Executive::new(&TABLE, &clock);
        exec.set_log_time_origin(1_000_000_000_000);
        let mut tasks: [&mut dyn Task; 2] = [&mut imu, &mut health];
        exec.start(&mut tasks, 0).expect("start");
        run_frames(&mut exec, &clock, &mut tasks, seconds * 100);
        exec.shutdown(&mut tasks);
        (
            exec.health().log_dropped(1),
            exec.health().task(0).map_or(0, |h| h.releases),
        )
    }

    #[test]
    fn snapshots_every_task_each_second_readable_by_the_reader() {
        let mut ring = Ring {
            bytes: Vec::new(),
            records: 0,
            capacity: usize::MAX,
        };
        let (dropped, _) = fly(&mut ring, 3);
        assert_eq!(dropped, 0);
        let mut reader = LogReader::new();
        let mut rows = Vec::new();
        let mut problems = 0;
        let mut begins = 0;
        read_slice(&mut reader, &ring.bytes, |event| match event {
            Event::Record {
                record: Record::DataBlock { time, data, .. },
                ..
            } => rows.push((time.sec, data.to_vec())),
            Event::Record {
                record: Record::BeginData { time },
                ..
            } => {
                begins += 1;
                assert_eq!(time.sec, 1000);
            }
            Event::Problem(_) => problems += 1,
            _ => {}
        });
        assert_eq!((problems, begins), (0, 1));
        // Snapshots at 0, 1, 2 s and at shutdown: 4 × 2 tasks.
        assert_eq!(rows.len(), 8);
        assert_eq!(rows[2].0, 1001, "TIME = origin + executive clock");
        assert_eq!(rows[2].1[0], 0, "first row of a snapshot is task 0");
        // imu's releases at the 1 s snapshot: frames 0..=100 ran before the health task in frame 100.
        let releases = u64::from_le_bytes(rows[2].1[5..13].try_into().expect("8 bytes"));
        assert_eq!(releases, 101);
    }

    #[test]
    fn a_full_ring_counts_every_dropped_record_in_health() {
        let mut ring = Ring {
            bytes: Vec::new(),
            records: 0,
            capacity: 4,
        };
        let (dropped, _) = fly(&mut ring, 2);
        // Pushes: the declaration (definition and comment in one push), begin, 3 snapshots
        // (0 s, 1 s, shutdown) of 2 rows, end = 9. The ring takes 4: 5 are counted.
        assert_eq!(ring.records, 4);
        assert_eq!(dropped, 5);
    }
}
