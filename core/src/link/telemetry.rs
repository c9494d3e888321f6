//! When the vehicle sends what (`docs/link-protocol.md`, "Vehicle → ground"): each task's
//! data at its own interval with its column names now and then, one task's status per second
//! in rotation, the executive's status every 2 s. The shell's telemetry sender asks
//! [`TelemetrySchedule::next_due`] what is due, builds that message, and sends it.

use super::frame::Envelope;
use crate::schedule::analysis::MAX_TASKS;

/// A task's data interval until the ground changes it: the seed's 1 Hz.
pub const DEFAULT_TELEMETRY_INTERVAL_MS: u32 = 1_000;
/// One task's status per this interval, in rotation.
pub const TASK_STATUS_INTERVAL_MS: u32 = 1_000;
pub const EXECUTIVE_STATUS_INTERVAL_MS: u32 = 2_000;
/// A task's column names (with its latest values) are repeated this often while its data is
/// sent, so that a ground station that starts listening late, restarts or comes back after a
/// link loss has every name within 2 s. It costs about 2.5 kB/s for the shipped schedule.
pub const TASK_FORMAT_INTERVAL_MS: u32 = 1_500;

const NS_PER_MS: u64 = 1_000_000;

/// Something the telemetry sender should send now.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Due {
    ExecutiveStatus,
    TaskStatus { task_index: u8 },
    TaskFormat { task_index: u8 },
    TaskData { task_index: u8 },
}

/// The telemetry timetable of one run.
#[derive(Clone, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TelemetrySchedule {
    task_count: usize,
    /// 0: the task's data is not sent.
    interval_ms: [u32; MAX_TASKS],
    data_due_ns: [u64; MAX_TASKS],
    format_due_ns: [u64; MAX_TASKS],
    status_due_ns: u64,
    next_status_task: usize,
    executive_due_ns: u64,
}

impl TelemetrySchedule {
    /// Every task at the default interval; everything is due at `now_ns`.
    pub fn new(task_count: usize, now_ns: u64) -> Self {
        Self {
            task_count: task_count.min(MAX_TASKS),
            interval_ms: [DEFAULT_TELEMETRY_INTERVAL_MS; MAX_TASKS],
            data_due_ns: [now_ns; MAX_TASKS],
            format_due_ns: [now_ns; MAX_TASKS],
            status_due_ns: now_ns,
            next_status_task: 0,
            executive_due_ns: now_ns,
        }
    }

    /// A task's data interval (0: not sent); `None` past the last task.
    pub fn interval_ms(&self, task_index: usize) -> Option<u32> {
        self.interval_ms
            .get(task_index)
            .copied()
            .filter(|_| task_index < self.task_count)
    }

    /// Applies an accepted `SetTelemetryRate` (the gate has range-checked it). The new
    /// interval starts now, with the column names first. `false` past the last task.
    pub fn set_interval(&mut self, task_index: usize, interval_ms: u32, now_ns: u64) -> bool {
        if task_index >= self.task_count {
            return false;
        }
        let (Some(interval), Some(data_due), Some(format_due)) = (
            self.interval_ms.get_mut(task_index),
            self.data_due_ns.get_mut(task_index),
            self.format_due_ns.get_mut(task_index),
        ) else {
            return false;
        };
        *interval = interval_ms;
        *data_due = now_ns;
        *format_due = now_ns;
        true
    }

    /// The next thing due at `now_ns`, rescheduled as it is handed out: call until `None`.
    /// Status comes before data; a task's format before its data.
    pub fn next_due(&mut self, now_ns: u64) -> Option<Due> {
        if now_ns >= self.executive_due_ns {
            self.executive_due_ns =
                next_time(self.executive_due_ns, EXECUTIVE_STATUS_INTERVAL_MS, now_ns);
            return Some(Due::ExecutiveStatus);
        }
        if self.task_count > 0 && now_ns >= self.status_due_ns {
            self.status_due_ns = next_time(self.status_due_ns, TASK_STATUS_INTERVAL_MS, now_ns);
            let task = self.next_status_task;
            self.next_status_task = (task + 1) % self.task_count;
            return Some(Due::TaskStatus {
                task_index: task_index(task)?,
            });
        }
        for task in 0..self.task_count {
            let interval = self.interval_ms.get(task).copied().unwrap_or(0);
            if interval == 0 {
                continue;
            }
            if let Some(due) = self
                .format_due_ns
                .get_mut(task)
                .filter(|due| now_ns >= **due)
            {
                *due = next_time(*due, TASK_FORMAT_INTERVAL_MS, now_ns);
                return Some(Due::TaskFormat {
                    task_index: task_index(task)?,
                });
            }
            if let Some(due) = self.data_due_ns.get_mut(task).filter(|due| now_ns >= **due) {
                *due = next_time(*due, interval, now_ns);
                return Some(Due::TaskData {
                    task_index: task_index(task)?,
                });
            }
        }
        None
    }
}

fn task_index(task: usize) -> Option<u8> {
    u8::try_from(task).ok()
}

/// One interval after the last due time, so the rate does not drift with the caller's
/// jitter; but never in the past, so a sender that fell behind does not burst to catch up.
fn next_time(due_ns: u64, interval_ms: u32, now_ns: u64) -> u64 {
    let interval_ns = u64::from(interval_ms).saturating_mul(NS_PER_MS);
    let next = due_ns.saturating_add(interval_ns);
    if next > now_ns {
        next
    } else {
        now_ns.saturating_add(interval_ns)
    }
}

/// Envelopes of the vehicle's datagrams: its ids and one sequence number for all of them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VehicleEnvelopes {
    vehicle_id: u16,
    run_id: u32,
    next_sequence: u32,
}

impl VehicleEnvelopes {
    pub const fn new(vehicle_id: u16, run_id: u32) -> Self {
        Self {
            vehicle_id,
            run_id,
            next_sequence: 1,
        }
    }

    /// The envelope of the next datagram, made at `t_ns` on the executive clock.
    pub fn next(&mut self, t_ns: u64) -> Envelope {
        let sequence = self.next_sequence;
        // Telemetry is not replay-checked by the vehicle; wrapping after 4·10⁹ datagrams
        // only confuses a ground station's loss count.
        self.next_sequence = self.next_sequence.wrapping_add(1);
        Envelope {
            vehicle_id: self.vehicle_id,
            sender_id: 0,
            run_id: self.run_id,
            sequence,
            t_ns,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    const MS: u64 = NS_PER_MS;

    fn drain(schedule: &mut TelemetrySchedule, now_ns: u64) -> Vec<Due> {
        core::iter::from_fn(|| schedule.next_due(now_ns)).collect()
    }

    #[test]
    fn everything_is_due_at_the_start_then_at_its_own_rate() {
        let mut s = TelemetrySchedule::new(2, 0);
        assert_eq!(
            drain(&mut s, 0),
            [
                Due::ExecutiveStatus,
                Due::TaskStatus { task_index: 0 },
                Due::TaskFormat { task_index: 0 },
                Due::TaskData { task_index: 0 },
                Due::TaskFormat { task_index: 1 },
                Due::TaskData { task_index: 1 },
            ]
        );
        assert_eq!(drain(&mut s, 999 * MS), []);
        assert_eq!(
            drain(&mut s, 1000 * MS),
            [
                Due::TaskStatus { task_index: 1 },
                Due::TaskData { task_index: 0 },
                Due::TaskData { task_index: 1 },
            ]
        );
        assert_eq!(
            drain(&mut s, 2000 * MS),
            [
                Due::ExecutiveStatus,
                Due::TaskStatus { task_index: 0 },
                // The columns again, 1.5 s after the first (due at 1.5 s, asked at 2 s).
                Due::TaskFormat { task_index: 0 },
                Due::TaskData { task_index: 0 },
                Due::TaskFormat { task_index: 1 },
                Due::TaskData { task_index: 1 },
            ]
        );
    }

    #[test]
    fn a_new_interval_starts_now_with_the_columns_and_zero_stops_the_data() {
        let mut s = TelemetrySchedule::new(2, 0);
        drain(&mut s, 0);
        assert!(s.set_interval(1, 100, 50 * MS));
        assert!(s.set_interval(0, 0, 50 * MS));
        assert!(!s.set_interval(2, 100, 50 * MS));
        assert_eq!(s.interval_ms(1), Some(100));
        assert_eq!(s.interval_ms(2), None);
        assert_eq!(
            drain(&mut s, 50 * MS),
            [
                Due::TaskFormat { task_index: 1 },
                Due::TaskData { task_index: 1 }
            ]
        );
        let data_1 = (1..=9)
            .flat_map(|k| drain(&mut s, 50 * MS + k * 100 * MS))
            .filter(|d| *d == Due::TaskData { task_index: 1 })
            .count();
        assert_eq!(data_1, 9);
        // Columns again 1.5 s later.
        assert!(drain(&mut s, 1_550 * MS).contains(&Due::TaskFormat { task_index: 1 }));
        assert!(!drain(&mut s, 20_000 * MS).contains(&Due::TaskData { task_index: 0 }));
    }

    #[test]
    fn a_late_sender_does_not_burst() {
        let mut s = TelemetrySchedule::new(1, 0);
        drain(&mut s, 0);
        // Five seconds late: one of each, not five.
        let late = drain(&mut s, 5_500 * MS);
        assert_eq!(
            late.iter()
                .filter(|d| **d == Due::TaskData { task_index: 0 })
                .count(),
            1
        );
        assert_eq!(drain(&mut s, 6_000 * MS), []);
        assert_eq!(
            drain(&mut s, 6_500 * MS),
            [
                Due::TaskStatus { task_index: 0 },
                Due::TaskData { task_index: 0 }
            ]
        );
    }

    #[test]
    fn no_tasks_means_only_executive_status() {
        let mut s = TelemetrySchedule::new(0, 0);
        assert_eq!(drain(&mut s, 0), [Due::ExecutiveStatus]);
    }

    #[test]
    fn vehicle_envelopes_count_up_from_one() {
        let mut e = VehicleEnvelopes::new(7, 99);
        let a = e.next(10);
        let b = e.next(20);
        assert_eq!(
            (a.vehicle_id, a.sender_id, a.run_id, a.sequence, a.t_ns),
            (7, 0, 99, 1, 10)
        );
        assert_eq!((b.sequence, b.t_ns), (2, 20));
    }
}
