//! The validator against hand-made schedules, and against an independent re-derivation of
//! feasibility on random task sets.

use super::analysis::*;
use proptest::prelude::*;
use std::string::ToString;
use std::vec::Vec;

/// The names these tests schedule (the shell's registry holds the real ones).
const TASK_NAMES: &[&str] = &[
    "imu",
    "gps",
    "servo",
    "estimator",
    "control",
    "telemetry",
    "health",
    "watchdog",
];

const MS: u64 = 1_000_000;
const US: u64 = 1_000;

fn task(name: &'static str, period_ms: u64, offset_ms: u64, budget_us: u64) -> TaskInput<'static> {
    TaskInput {
        name,
        period_ns: period_ms * MS,
        offset_ns: offset_ms * MS,
        budget_ns: budget_us * US,
        on_overrun: OverrunPolicy::Log,
        after: &[],
    }
}

fn exec(margin_us: u64) -> ExecutiveInput {
    ExecutiveInput {
        margin_ns: margin_us * US,
        late_start_ns: 500 * US,
        minor_frame_ns: None,
    }
}

fn report(tasks: &[TaskInput<'_>], e: &ExecutiveInput) -> std::string::String {
    match analyse(tasks, e, Some(TASK_NAMES)) {
        Ok(_) => "ok".to_string(),
        Err(error) => ErrorReport { error, tasks }.to_string(),
    }
}

#[test]
fn minor_frame_is_gcd_and_major_frame_lcm() {
    let tasks = [
        task("imu", 10, 0, 300),
        task("servo", 20, 0, 300),
        task("gps", 100, 30, 500),
    ];
    let a = analyse(&tasks, &exec(1000), Some(TASK_NAMES)).expect("feasible");
    assert_eq!(
        (a.minor_frame_ns, a.major_frame_ns, a.minor_frames),
        (10 * MS, 100 * MS, 10)
    );
    // gps (index 2) runs in frame 3 only, servo in even frames.
    assert_eq!(a.frame_tasks[3], 0b101);
    assert_eq!(a.frame_tasks[4], 0b011);
    assert_eq!(a.frame_load_ns[3], 800 * US);
    // 300/10 + 300/20 + 500/100 = 3 + 1.5 + 0.5 = 5 %
    assert_eq!(a.utilisation_ppm, 50_000);
}

#[test]
fn over_full_frame_names_the_frame_and_its_tasks() {
    let tasks = [
        task("imu", 10, 0, 3000),
        task("estimator", 10, 0, 4000),
        task("gps", 100, 20, 2500),
    ];
    let text = report(&tasks, &exec(1000));
    assert_eq!(
        text,
        "minor frame 2 is over-full: budgets 9500 us > frame less margin 9 ms (tasks: imu, estimator, gps)"
    );
}

#[test]
fn each_structural_error_is_named() {
    let e = exec(1000);
    assert_eq!(
        report(&[task("imu", 10, 0, 100), task("imu", 10, 0, 100)], &e),
        "task `imu` is listed twice"
    );
    assert!(report(&[task("camera", 10, 0, 100)], &e).starts_with("unknown task `camera`"));
    assert_eq!(
        report(&[task("imu", 10, 10, 100)], &e),
        "task `imu`: offset must be less than its period"
    );
    assert_eq!(
        report(&[task("imu", 10, 0, 0)], &e),
        "task `imu` has budget 0"
    );
    assert_eq!(report(&[], &e), "the schedule has no tasks");
    let fixed = ExecutiveInput {
        minor_frame_ns: Some(20 * MS),
        ..e
    };
    assert_eq!(
        report(&[task("imu", 10, 0, 100)], &fixed),
        "task `imu`: period 10 ms is not a multiple of the minor frame (20 ms)"
    );
    let fine = ExecutiveInput {
        minor_frame_ns: Some(10 * MS),
        ..e
    };
    assert_eq!(
        report(&[task("imu", 20, 5, 100)], &fine),
        "task `imu`: offset 5 ms is not a multiple of the minor frame (10 ms)"
    );
    assert_eq!(
        report(&[task("imu", 10, 0, 100)], &exec(10_000)),
        "margin 10 ms leaves no time in the 10 ms minor frame"
    );
    let mut dep = task("control", 10, 0, 100);
    dep.after = &["estimator"];
    assert_eq!(
        report(&[dep], &e),
        "task `control` runs after unknown task `estimator`: it is not in the schedule"
    );
}

#[test]
fn dependency_cycle_is_refused_with_the_tasks_in_it() {
    let mut a = task("imu", 10, 0, 100);
    let mut b = task("estimator", 10, 0, 100);
    let mut c = task("control", 10, 0, 100);
    let d = task("servo", 10, 0, 100);
    a.after = &["control"];
    b.after = &["imu"];
    c.after = &["estimator"];
    assert_eq!(
        report(&[a, b, c, d], &exec(1000)),
        "dependency cycle among tasks: imu, estimator, control"
    );
}

#[test]
fn order_follows_dependencies_then_rate() {
    let mut servo = task("servo", 20, 0, 100);
    servo.after = &["control"];
    let mut control = task("control", 20, 0, 100);
    control.after = &["estimator"];
    let mut estimator = task("estimator", 10, 0, 100);
    estimator.after = &["imu"];
    let tasks = [
        servo,
        task("gps", 100, 0, 100),
        control,
        estimator,
        task("imu", 10, 0, 100),
    ];
    let a = analyse(&tasks, &exec(1000), Some(TASK_NAMES)).expect("feasible");
    let names: Vec<_> = a.order[..a.task_count]
        .iter()
        .map(|&i| tasks[i as usize].name)
        .collect();
    assert_eq!(names, ["imu", "estimator", "control", "servo", "gps"]);
    // Bits of the in-order mask follow the execution order.
    assert_eq!(a.frame_mask_in_order(0), 0b11111);
    assert_eq!(a.frame_mask_in_order(1), 0b00011);
}

#[test]
fn response_times_include_blocking_and_higher_rate_interference() {
    // gps (8 ms, lowest priority) can block imu once: R_imu = 8 + 2 = 10 ms. gps itself is
    // hit by imu once per 10 ms: R = 8 + 2 = 10 ms.
    let ok = [task("imu", 10, 0, 2000), task("gps", 100, 50, 8000)];
    let a = analyse(&ok, &exec(0), Some(TASK_NAMES)).expect("feasible");
    assert_eq!(a.response_ns[0], 10 * MS);
    assert_eq!(a.response_ns[1], 10 * MS);
    let three = [
        task("imu", 10, 0, 2000),
        task("servo", 20, 10, 3000),
        task("gps", 100, 20, 5000),
    ];
    let a = analyse(&three, &exec(0), Some(TASK_NAMES)).expect("feasible");
    // servo: B = 5, C = 3, imu: R = 5 + 3 + ceil(R/10)·2: 8 -> 10 -> 10 (fixed point).
    assert_eq!(a.response_ns[1], 10 * MS);
    let bad = [task("imu", 10, 0, 2000), task("gps", 100, 50, 8500)];
    assert_eq!(
        report(&bad, &exec(0)),
        "minor frame 5 is over-full: budgets 10500 us > frame less margin 10 ms (tasks: imu, gps)"
    );
    let tasks = [task("imu", 10, 0, 2000)];
    let text = ErrorReport {
        error: ScheduleError::ResponseTimeExceedsPeriod {
            task: 0,
            response_ns: 12 * MS,
        },
        tasks: &tasks,
    }
    .to_string();
    assert_eq!(
        text,
        "task `imu`: worst-case response time 12 ms exceeds its period 10 ms (rate-monotonic response-time analysis)"
    );
}

#[test]
fn shipped_schedule_is_feasible() {
    let text = include_str!("../../../schedule.toml");
    let file: toml::Table = toml_parse(text);
    assert!(file.contains_key("tasks") && file.contains_key("executive"));
    let t = &super::SHIPPED;
    assert!(t.utilisation_ppm > 0 && t.utilisation_ppm < 1_000_000);
    assert_eq!(t.major_frame_ns() % t.minor_frame_ns, 0);
}

fn toml_parse(text: &str) -> toml::Table {
    text.parse().expect("schedule.toml parses")
}

// --- property test: the analysis against an independent brute-force model ---------------

/// Feasibility recomputed from first principles: simulate one major frame release by
/// release; and the response-time recurrence written as a plain search.
fn independently_feasible(tasks: &[(u64, u64, u64)], margin: u64) -> bool {
    // (period, offset, budget) in µs; minor frame is the gcd of the periods.
    let minor = tasks.iter().fold(0, |g, t| gcd(g, t.0));
    let major = tasks.iter().fold(1, |l, t| lcm(l, t.0));
    if margin >= minor || major / minor > MAX_MINOR_FRAMES as u64 {
        return false;
    }
    if tasks.iter().any(|t| t.1 % minor != 0) {
        return false;
    }
    let mut time = 0;
    while time < major {
        let load: u64 = tasks
            .iter()
            .filter(|t| time % t.0 == t.1)
            .map(|t| t.2)
            .sum();
        if load > minor - margin {
            return false;
        }
        time += minor;
    }
    // Response time: smallest R with R = B + C + Σ_hp ceil(R/T)·C, searched upward.
    for (i, t) in tasks.iter().enumerate() {
        let prio = |j: usize| (tasks[j].0, j);
        let blocking = (0..tasks.len())
            .filter(|&j| prio(j) > prio(i))
            .map(|j| tasks[j].2)
            .max()
            .unwrap_or(0);
        let demand = |r: u64| -> u64 {
            blocking
                + t.2
                + (0..tasks.len())
                    .filter(|&j| prio(j) < prio(i))
                    .map(|j| r.div_ceil(tasks[j].0) * tasks[j].2)
                    .sum::<u64>()
        };
        let mut r = blocking + t.2;
        while demand(r) > r {
            r = demand(r);
            if r > t.0 {
                return false;
            }
        }
        if r > t.0 {
            return false;
        }
    }
    true
}

proptest! {
    #[test]
    fn analysis_accepts_exactly_the_feasible_task_sets(
        raw in prop::collection::vec((0usize..4, 0u64..10, 1u64..4000), 1..6),
        margin in 0u64..3000,
    ) {
        const PERIODS: [u64; 4] = [5_000, 10_000, 20_000, 50_000];
        let tasks_us: Vec<(u64, u64, u64)> = raw
            .iter()
            .map(|&(p, o, b)| {
                let period = PERIODS[p];
                // Offsets on a 5 ms grid, sometimes off-grid for the error path.
                let offset = if o == 9 { 2_500 % period } else { (o * 5_000) % period };
                (period, offset, b)
            })
            .collect();
        let inputs: Vec<TaskInput<'_>> = tasks_us
            .iter()
            .zip(TASK_NAMES)
            .map(|(&(p, o, b), &name)| TaskInput {
                name,
                period_ns: p * US,
                offset_ns: o * US,
                budget_ns: b * US,
                on_overrun: OverrunPolicy::Log,
                after: &[],
            })
            .collect();
        let e = ExecutiveInput { margin_ns: margin * US, late_start_ns: 0, minor_frame_ns: None };
        let ours = analyse(&inputs, &e, Some(TASK_NAMES)).is_ok();
        prop_assert_eq!(ours, independently_feasible(&tasks_us, margin), "{:?} margin {}", tasks_us, margin);
    }
}
