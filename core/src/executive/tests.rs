//! Executive tests against a mock clock: each timing fault injected on purpose, each policy.

use super::*;
use crate::schedule::{FrameTable, OverrunPolicy, TaskSlot};
use core::cell::{Cell, RefCell};
use std::vec::Vec;

const MS: u64 = 1_000_000;
const US: u64 = 1_000;

/// Time that only moves when told to.
#[derive(Default)]
struct MockClock {
    now: Cell<u64>,
}

impl MockClock {
    fn advance(&self, ns: u64) {
        self.now.set(self.now.get() + ns);
    }
    fn set(&self, ns: u64) {
        self.now.set(ns);
    }
}

impl Clock for MockClock {
    fn now_ns(&self) -> u64 {
        self.now.get()
    }
    fn spin_until(&self, t_ns: u64) {
        if t_ns > self.now.get() {
            self.now.set(t_ns);
        }
    }
}

impl FrameTimer for MockClock {
    fn sleep_until(&self, t_ns: u64) {
        self.spin_until(t_ns);
    }
}

/// Every call a task gets, in order, across all tasks.
type Journal = RefCell<Vec<(&'static str, &'static str, u64)>>;

/// A task that advances the mock clock by a scripted amount per step.
struct Scripted<'a> {
    name: &'static str,
    clock: &'a MockClock,
    journal: &'a Journal,
    /// Step duration for a given frame.
    cost: fn(u64) -> u64,
    fail_step_in_frame: Option<u64>,
    fail_init_times: u32,
}

impl<'a> Scripted<'a> {
    fn new(
        name: &'static str,
        clock: &'a MockClock,
        journal: &'a Journal,
        cost: fn(u64) -> u64,
    ) -> Self {
        Self {
            name,
            clock,
            journal,
            cost,
            fail_step_in_frame: None,
            fail_init_times: 0,
        }
    }
    fn note(&self, what: &'static str, frame: u64) {
        self.journal.borrow_mut().push((self.name, what, frame));
    }
}

impl Task for Scripted<'_> {
    fn init(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        self.note("init", cx.frame);
        if self.fail_init_times > 0 {
            self.fail_init_times -= 1;
            return Err(TaskFault::new("device absent"));
        }
        Ok(())
    }
    fn step(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        self.note("step", cx.frame);
        self.clock.advance((self.cost)(cx.frame));
        if self.fail_step_in_frame == Some(cx.frame) {
            return Err(TaskFault::new("checksum storm"));
        }
        Ok(())
    }
    fn recover(&mut self, cx: &mut TaskContext<'_>) {
        self.note("recover", cx.frame);
    }
    fn shutdown(&mut self, cx: &mut TaskContext<'_>) {
        self.note("shutdown", cx.frame);
    }
}

/// fast: 10 ms; slow: 20 ms after fast; odd: 20 ms at offset 10. Minor frame 10 ms.
static TASKS: [TaskSlot; 3] = [
    TaskSlot {
        name: "fast",
        period_ns: 10 * MS,
        offset_ns: 0,
        budget_ns: 1000 * US,
        on_overrun: OverrunPolicy::Log,
    },
    TaskSlot {
        name: "slow",
        period_ns: 20 * MS,
        offset_ns: 0,
        budget_ns: 2000 * US,
        on_overrun: OverrunPolicy::Skip,
    },
    TaskSlot {
        name: "odd",
        period_ns: 20 * MS,
        offset_ns: 10 * MS,
        budget_ns: 2000 * US,
        on_overrun: OverrunPolicy::Reset,
    },
];
static TABLE: FrameTable = FrameTable {
    minor_frame_ns: 10 * MS,
    margin_ns: 2 * MS,
    late_start_ns: MS,
    tasks: &TASKS,
    frames: &[0b011, 0b101],
    utilisation_ppm: 0,
};

struct Recorder(Vec<FrameRecord>);

impl Sink<FrameRecord> for Recorder {
    fn try_send(&mut self, item: FrameRecord) -> Result<(), FrameRecord> {
        self.0.push(item);
        Ok(())
    }
}

struct Harness<'a> {
    clock: &'a MockClock,
    exec: Executive<&'a MockClock>,
    records: Recorder,
}

impl<'a> Harness<'a> {
    fn new(clock: &'a MockClock) -> Self {
        Self {
            clock,
            exec: Executive::new(&TABLE, clock),
            records: Recorder(Vec::new()),
        }
    }
    /// Sleeps to the next release, optionally late by `late_ns`, and runs the frame.
    fn frame(&mut self, tasks: &mut [&mut dyn Task], late_ns: u64) -> FrameRecord {
        self.clock.set(self.exec.next_release_ns() + late_ns);
        self.exec.run_frame(tasks, &mut self.records)
    }
    fn health(&self, i: usize) -> TaskHealth {
        *self.exec.health().task(i).expect("task")
    }
}

/// `(task, frame)` of every call of one kind (`"step"`, `"init"`, …), in order.
fn calls(journal: &Journal, what: &str) -> Vec<(&'static str, u64)> {
    journal
        .borrow()
        .iter()
        .filter(|(_, w, _)| *w == what)
        .map(|(name, _, frame)| (*name, *frame))
        .collect()
}

/// The table's three tasks, named as in `TASKS`, with the given step costs.
fn three<'a>(
    clock: &'a MockClock,
    journal: &'a Journal,
    costs: [fn(u64) -> u64; 3],
) -> [Scripted<'a>; 3] {
    let [fast, slow, odd] = costs;
    [
        Scripted::new("fast", clock, journal, fast),
        Scripted::new("slow", clock, journal, slow),
        Scripted::new("odd", clock, journal, odd),
    ]
}

fn cheap(_: u64) -> u64 {
    100 * US
}

/// The table's three tasks with these step costs and `setup` applied, started at time 0, then
/// handed to `test` with their harness and the journal of their calls.
fn started(
    costs: [fn(u64) -> u64; 3],
    setup: impl FnOnce(&mut [Scripted<'_>; 3]),
    test: impl FnOnce(&mut Harness<'_>, &mut [&mut dyn Task; 3], &Journal),
) {
    let clock = MockClock::default();
    let journal = Journal::default();
    let mut scripted = three(&clock, &journal, costs);
    setup(&mut scripted);
    let mut tasks = scripted.each_mut().map(|t| t as &mut dyn Task);
    let mut h = Harness::new(&clock);
    h.exec.start(&mut tasks, 0).expect("start");
    test(&mut h, &mut tasks, &journal);
}

#[test]
fn frames_release_the_table_tasks_in_order() {
    let clock = MockClock::default();
    let journal = Journal::default();
    let mut scripted = three(&clock, &journal, [cheap, cheap, cheap]);
    let mut tasks = scripted.each_mut().map(|t| t as &mut dyn Task);
    let mut h = Harness::new(&clock);
    h.exec.start(&mut tasks, 5 * MS).expect("start");
    for _ in 0..4 {
        h.frame(&mut tasks, 0);
    }
    let steps = calls(&journal, "step");
    assert_eq!(
        steps,
        [
            ("fast", 0),
            ("slow", 0),
            ("fast", 1),
            ("odd", 1),
            ("fast", 2),
            ("slow", 2),
            ("fast", 3),
            ("odd", 3)
        ]
    );
    let r = &h.records.0;
    assert_eq!(r.len(), 4);
    assert_eq!(r[1].release_ns, 15 * MS);
    assert_eq!(r[1].ran, 0b101);
    assert_eq!(r[1].exec_ns[0], 100_000);
    assert_eq!(r[1].work_ns, 200_000);
    assert_eq!(r[1].overhead_ns, 0);
    assert_eq!(r[1].flags, 0);
    let fast = h.health(0);
    assert!(fast.initialised && fast.running && fast.in_frame);
    assert_eq!(
        (fast.releases, fast.exec.count, fast.overruns.total()),
        (4, 4, 0)
    );
}

#[test]
fn budget_overrun_with_log_policy_is_counted_and_the_task_keeps_running() {
    started(
        [
            |f| {
                if f == 1 { 1500 * US } else { 100 * US }
            },
            cheap,
            cheap,
        ],
        |_| {},
        |h, tasks, _| {
            h.frame(tasks, 0);
            let r = h.frame(tasks, 0);
            assert_eq!(r.over_budget, 0b001);
            assert!(!h.health(0).in_frame);
            let r = h.frame(tasks, 0);
            assert_eq!(r.ran & 1, 1, "log policy keeps the next release");
            let fast = h.health(0);
            assert_eq!(fast.overruns.budget, 1);
            assert_eq!(fast.exec.max_ns, 1500 * US);
            assert_eq!(
                fast.exec.histogram[10], 1,
                "150 % of budget lands in the 100-200 % bucket"
            );
            assert!(fast.in_frame);
        },
    );
}

#[test]
fn skip_policy_drops_exactly_the_next_release() {
    started(
        [
            cheap,
            |f| {
                if f == 0 { 2500 * US } else { 100 * US }
            },
            cheap,
        ],
        |_| {},
        |h, tasks, _| {
            let records: Vec<_> = (0..6).map(|_| h.frame(tasks, 0)).collect();
            assert_eq!(records[0].over_budget, 0b010);
            assert_eq!(records[2].skipped, 0b010, "frame 2 is slow's next release");
            assert_eq!(records[2].ran & 0b010, 0);
            assert_eq!(
                records[4].ran & 0b010,
                0b010,
                "the release after that runs again"
            );
            let slow = h.health(1);
            assert_eq!((slow.releases, slow.skipped, slow.exec.count), (3, 1, 2));
        },
    );
}

#[test]
fn reset_policy_runs_recover_then_init_before_the_next_release() {
    started(
        [cheap, cheap, |f| if f == 1 { 3 * MS } else { 100 * US }],
        |_| {},
        |h, tasks, journal| {
            let records: Vec<_> = (0..4).map(|_| h.frame(tasks, 0)).collect();
            assert_eq!(records[1].over_budget, 0b100);
            assert_eq!(records[3].reset, 0b100);
            let odd_calls: Vec<_> = journal
                .borrow()
                .iter()
                .filter(|(n, _, _)| *n == "odd")
                .map(|(_, what, frame)| (*what, *frame))
                .collect();
            assert_eq!(
                odd_calls,
                [
                    ("init", 0),
                    ("step", 1),
                    ("recover", 3),
                    ("init", 3),
                    ("step", 3)
                ]
            );
            let odd = h.health(2);
            assert_eq!((odd.resets, odd.overruns.budget), (1, 1));
            assert!(odd.initialised && odd.in_frame);
        },
    );
}

#[test]
fn frame_overrun_is_charged_to_the_task_running_at_the_deadline_and_delays_the_next_frame() {
    // fast takes 6 ms then slow 5 ms in frame 0: the 10 ms deadline passes inside slow.
    started(
        [
            |f| {
                if f == 0 { 6 * MS } else { 100 * US }
            },
            |f| {
                if f == 0 { 5 * MS } else { 100 * US }
            },
            cheap,
        ],
        |_| {},
        |h, tasks, _| {
            let r0 = h.frame(tasks, 0);
            assert_eq!(r0.flags & timing::flags::OVERRUN, timing::flags::OVERRUN);
            assert_eq!(r0.over_frame, 0b010);
            assert_eq!(r0.over_budget, 0b011);
            // The loop sleeps until frame 1 is due, but it is already 11 ms: a late start of 1 ms.
            let r1 = h.exec.run_frame(tasks, &mut h.records);
            assert_eq!(r1.frame, 1);
            assert_eq!(r1.start_latency_ns, MS as u32);
            assert_eq!(r1.missed_before, 0);
            assert_eq!(h.exec.health().frames.overrun, 1);
            assert_eq!(h.health(1).overruns.frame, 1);
            assert_eq!(h.health(0).overruns.frame, 0);
        },
    );
}

#[test]
fn late_start_beyond_threshold_is_flagged_but_not_below_it() {
    started(
        [cheap; 3],
        |_| {},
        |h, tasks, _| {
            let on_time = h.frame(tasks, 900 * US);
            let late = h.frame(tasks, 1200 * US);
            assert_eq!(on_time.flags & timing::flags::LATE, 0);
            assert_eq!(late.flags & timing::flags::LATE, timing::flags::LATE);
            assert_eq!(late.start_latency_ns, 1_200_000);
            let stats = h.exec.health().frames;
            assert_eq!((stats.late, stats.max_start_latency_ns), (1, 1200 * US));
        },
    );
}

#[test]
fn whole_missed_frames_are_skipped_and_their_releases_counted() {
    started(
        [cheap; 3],
        |_| {},
        |h, tasks, _| {
            h.frame(tasks, 0);
            // Frame 1 is due at 10 ms; wake at 43 ms: frames 1, 2, 3 are gone, frame 4 is 3 ms late.
            h.clock.set(43 * MS);
            let r = h.exec.run_frame(tasks, &mut h.records);
            assert_eq!(
                (r.frame, r.missed_before, r.start_latency_ns),
                (4, 3, 3 * MS as u32)
            );
            assert_eq!(r.ran, 0b011, "frame 4 releases fast and slow");
            assert_eq!(h.health(0).overruns.missed, 3);
            assert_eq!(h.health(1).overruns.missed, 1, "slow was due in frame 2");
            assert_eq!(
                h.health(2).overruns.missed,
                2,
                "odd was due in frames 1 and 3"
            );
            assert_eq!(h.health(0).releases, 5);
            assert_eq!(h.exec.health().frames.missed, 3);
            assert_eq!(h.exec.next_release_ns(), 50 * MS);
        },
    );
}

#[test]
fn a_failing_step_is_counted_and_reset() {
    started(
        [cheap; 3],
        |[fast, ..]| fast.fail_step_in_frame = Some(1),
        |h, tasks, _| {
            for _ in 0..3 {
                h.frame(tasks, 0);
            }
            assert!(h.exec.health().alive(0));
            let fast = h.health(0);
            assert_eq!((fast.faults, fast.resets), (1, 1));
            assert_eq!(fast.last_fault, Some("checksum storm"));
            assert!(h.records.0[2].reset & 1 == 1);
        },
    );
}

#[test]
fn failed_init_is_retried_at_each_release_and_the_task_is_not_stepped_meanwhile() {
    started(
        [cheap; 3],
        |[fast, ..]| fast.fail_init_times = 2,
        |h, tasks, _| {
            assert!(!h.health(0).initialised);
            let r0 = h.frame(tasks, 0);
            assert_eq!(r0.ran & 1, 0);
            assert!(!h.exec.health().alive(0));
            let r1 = h.frame(tasks, 0);
            assert_eq!(r1.ran & 1, 1);
            let fast = h.health(0);
            assert_eq!((fast.init_failures, fast.exec.count), (2, 1));
            assert!(fast.initialised);
            assert_eq!(fast.last_fault, Some("device absent"));
        },
    );
}

#[test]
fn injected_overrun_hits_only_the_given_frames() {
    let clock = MockClock::default();
    let journal = Journal::default();
    let mut scripted = three(&clock, &journal, [cheap, cheap, cheap]);
    let mut tasks = scripted.each_mut().map(|t| t as &mut dyn Task);
    let mut h = Harness::new(&clock);
    let mut plan = FaultPlan::new();
    plan.push(OverrunInjection {
        task: 0,
        extra_ns: 12 * MS,
        from_frame: 2,
        to_frame: 4,
        repeat_every_frames: 0,
    })
    .expect("room");
    h.exec.set_faults(plan);
    h.exec.start(&mut tasks, 0).expect("start");
    let mut over = Vec::new();
    for _ in 0..8 {
        let now = h.exec.next_release_ns().max(clock.now_ns());
        clock.set(now);
        let r = h.exec.run_frame(&mut tasks, &mut h.records);
        over.push((
            r.frame,
            r.over_budget & 1,
            r.over_frame & 1,
            r.missed_before,
        ));
    }
    // Frame 2 runs 12.1 ms: over budget and over frame; the executive wakes in frame 3 late
    // (2.2 ms), frame 3 overruns again, frame 4 wakes 4.3 ms late and is clean.
    assert_eq!(over[2], (2, 1, 1, 0));
    assert_eq!(over[3], (3, 1, 1, 0));
    assert_eq!(over[4], (4, 0, 0, 0));
    assert_eq!(h.health(0).overruns.budget, 2);
    assert_eq!(h.health(0).overruns.frame, 2);
}

#[test]
fn a_full_sink_drops_the_record_and_counts_it() {
    struct Full;
    impl Sink<FrameRecord> for Full {
        fn try_send(&mut self, item: FrameRecord) -> Result<(), FrameRecord> {
            Err(item)
        }
    }
    let clock = MockClock::default();
    let journal = Journal::default();
    let mut scripted = three(&clock, &journal, [cheap, cheap, cheap]);
    let mut tasks = scripted.each_mut().map(|t| t as &mut dyn Task);
    let mut exec = Executive::new(&TABLE, &clock);
    exec.start(&mut tasks, 0).expect("start");
    exec.run_frame(&mut tasks, &mut Full);
    exec.run_frame(&mut tasks, &mut Full);
    assert_eq!(exec.health().frames.timing_records_dropped, 2);
}

#[test]
fn run_until_sleeps_to_each_release_and_shutdown_reaches_every_task() {
    let clock = MockClock::default();
    let journal = Journal::default();
    let mut scripted = three(&clock, &journal, [cheap, cheap, cheap]);
    let mut tasks = scripted.each_mut().map(|t| t as &mut dyn Task);
    let mut exec = Executive::new(&TABLE, &clock);
    let mut records = Recorder(Vec::new());
    exec.start(&mut tasks, 0).expect("start");
    let frames = exec.run_until(&mut tasks, &mut records, |e| e.next_frame() == 10);
    assert_eq!(frames, 10);
    assert!(
        records
            .0
            .iter()
            .all(|r| r.start_latency_ns == 0 && r.flags == 0)
    );
    exec.shutdown(&mut tasks);
    let shut: Vec<_> = calls(&journal, "shutdown")
        .into_iter()
        .map(|(n, _)| n)
        .collect();
    assert_eq!(shut, ["fast", "slow", "odd"]);
    assert!(!exec.health().task(0).expect("task").running);
}

#[test]
fn start_refuses_a_task_list_that_does_not_match_the_table() {
    let clock = MockClock::default();
    let journal = Journal::default();
    let mut fast = Scripted::new("fast", &clock, &journal, cheap);
    let mut tasks: [&mut dyn Task; 1] = [&mut fast];
    let mut exec = Executive::new(&TABLE, &clock);
    assert_eq!(
        exec.start(&mut tasks, 0),
        Err(StartError::TaskCountMismatch { table: 3, given: 1 })
    );
}

#[test]
fn shipped_table_runs_the_imu_chain_in_producer_consumer_order() {
    let t = &crate::schedule::SHIPPED;
    let pos = |n| t.task_index(n).expect(n);
    assert!(pos("imu") < pos("estimator"));
    assert!(pos("estimator") < pos("control"));
    assert!(pos("control") < pos("servo"));
    assert_eq!(t.minor_frame_ns, 10 * MS);
    let imu = 1 << pos("imu");
    assert!(
        t.frames.iter().all(|f| f & imu != 0),
        "imu runs every 10 ms frame"
    );
    let gps_frames = t
        .frames
        .iter()
        .filter(|f| *f & (1 << pos("gps")) != 0)
        .count();
    assert_eq!(gps_frames as u64, t.major_frame_ns() / (100 * MS));
}
