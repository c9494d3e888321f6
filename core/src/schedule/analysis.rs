//! Feasibility analysis of a static schedule.
//!
//! One implementation serves three callers: the core's build script (which turns
//! `schedule.toml` into the `const` frame table and refuses to build an infeasible one),
//! `skyframe check-schedule` at run time, and the tests. It is `no_std`, allocation-free and
//! has no dependencies, so the build script can include this file with `#[path]`.
//!
//! A schedule is feasible when, in this order:
//! 1. it is well formed: 1..=32 tasks with unique names (each one the task registry has, when
//!    the caller passes its names: the shell's registry is checked against the shipped
//!    schedule when the shell builds), non-zero periods and budgets, periods and offsets that
//!    are whole multiples of the minor frame, offsets inside their period, dependencies that
//!    name known tasks;
//! 2. the dependencies (`after`) have no cycle, so every frame has one producer → consumer
//!    order;
//! 3. in every minor frame the budgets of the tasks released there fit in the frame less the
//!    margin (the cyclic executive never lets a frame's work run into the next frame);
//! 4. rate-monotonic response-time analysis, non-preemptive (a task cannot be interrupted,
//!    so it may be blocked by the longest lower-priority budget), gives every task a
//!    worst-case response time within its period.

use core::fmt;

/// Tasks renamed on 2026-11-25, old name first, so that a task is named for the stream it
/// writes: `logging` wrote `health.bin`, and `health`, the watchdog, wrote `watchdog.bin`.
/// A schedule file with the old names (it names `logging` and no `watchdog`) still reads,
/// with a warning, until the release after next; `--inject-overrun` takes `logging` the same
/// way. `health` alone cannot be told apart, so it always means the new task.
pub const RENAMED_TASKS: [(&str, &str); 2] = [("logging", "health"), ("health", "watchdog")];

/// The new name of a task named by its old one, where the old name can only mean that task
/// (`logging` → `health`): for `--inject-overrun` and scenario faults, which name one task.
pub fn renamed_task(name: &str) -> Option<&'static str> {
    RENAMED_TASKS
        .iter()
        .find(|(old, _)| *old == name && !RENAMED_TASKS.iter().any(|(_, new)| new == old))
        .map(|(_, new)| *new)
}

/// Most tasks a schedule may have: the frame table keeps a task set as a `u32` bit mask.
pub const MAX_TASKS: usize = 32;
/// Most minor frames in one major frame (e.g. a 1 ms minor frame with a 1 s task).
pub const MAX_MINOR_FRAMES: usize = 1000;

/// What the executive does when a task overruns (its budget, or its frame).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OverrunPolicy {
    /// Record the overrun in health and the timing log; keep stepping the task.
    Log,
    /// Record it and drop the task's next release, giving the frame time back.
    Skip,
    /// Record it, then `recover` and `init` the task before its next release.
    Reset,
}

impl OverrunPolicy {
    pub fn parse(text: &str) -> Option<Self> {
        match text {
            "log" => Some(Self::Log),
            "skip" => Some(Self::Skip),
            "reset" => Some(Self::Reset),
            _ => None,
        }
    }

    pub fn as_str(self) -> &'static str {
        match self {
            Self::Log => "log",
            Self::Skip => "skip",
            Self::Reset => "reset",
        }
    }
}

/// One task as written in `schedule.toml`, times in nanoseconds.
#[derive(Clone, Copy, Debug)]
pub struct TaskInput<'a> {
    pub name: &'a str,
    pub period_ns: u64,
    pub offset_ns: u64,
    pub budget_ns: u64,
    pub on_overrun: OverrunPolicy,
    /// Tasks that must run before this one in any frame they share.
    pub after: &'a [&'a str],
}

/// Executive-wide settings from the `[executive]` table.
#[derive(Clone, Copy, Debug)]
pub struct ExecutiveInput {
    /// Time every minor frame keeps free for the executive and jitter.
    pub margin_ns: u64,
    /// A frame that starts later than this after its release is counted late.
    pub late_start_ns: u64,
    /// Minor frame length; `None` means the gcd of the periods.
    pub minor_frame_ns: Option<u64>,
}

/// Why a schedule is infeasible. Task sets are bit masks over the input order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScheduleError {
    NoTasks,
    TooManyTasks {
        count: usize,
    },
    DuplicateTask {
        task: usize,
    },
    UnknownTask {
        task: usize,
    },
    UnknownDependency {
        task: usize,
        dependency_index: usize,
    },
    ZeroPeriod {
        task: usize,
    },
    ZeroBudget {
        task: usize,
    },
    PeriodNotMultipleOfMinorFrame {
        task: usize,
        minor_frame_ns: u64,
    },
    OffsetNotMultipleOfMinorFrame {
        task: usize,
        minor_frame_ns: u64,
    },
    OffsetOutsidePeriod {
        task: usize,
    },
    MarginTooLarge {
        margin_ns: u64,
        minor_frame_ns: u64,
    },
    TooManyMinorFrames {
        major_frame_ns: u64,
        minor_frame_ns: u64,
    },
    DependencyCycle {
        tasks: u32,
    },
    FrameOverfull {
        frame: usize,
        tasks: u32,
        load_ns: u64,
        limit_ns: u64,
    },
    ResponseTimeExceedsPeriod {
        task: usize,
        response_ns: u64,
    },
}

/// The frame table and the figures `check-schedule` prints.
#[derive(Clone, Debug)]
pub struct Analysis {
    pub minor_frame_ns: u64,
    pub major_frame_ns: u64,
    pub minor_frames: usize,
    /// Task indices (into the input) in execution order; `order[..task_count]` is valid.
    pub order: [u8; MAX_TASKS],
    pub task_count: usize,
    /// For each minor frame, the set of input task indices released in it.
    pub frame_tasks: [u32; MAX_MINOR_FRAMES],
    /// For each minor frame, the sum of the budgets released in it.
    pub frame_load_ns: [u64; MAX_MINOR_FRAMES],
    /// Worst-case response time per input task (rate-monotonic, non-preemptive).
    pub response_ns: [u64; MAX_TASKS],
    /// Sum of budget/period, in parts per million.
    pub utilisation_ppm: u64,
    /// Frame length less margin: the most work one frame may hold.
    pub frame_limit_ns: u64,
}

impl Analysis {
    /// The frame table in execution order: bit `i` of a frame's mask is `order[i]`.
    pub fn frame_mask_in_order(&self, frame: usize) -> u32 {
        let Some(&tasks) = self.frame_tasks.get(frame) else {
            return 0;
        };
        let mut mask = 0u32;
        for (slot, &task) in self.order.iter().take(self.task_count).enumerate() {
            if tasks & (1u32 << task) != 0 {
                mask |= 1u32 << slot;
            }
        }
        mask
    }

    /// Largest per-frame load, and the frame it is in.
    pub fn busiest_frame(&self) -> (usize, u64) {
        let mut best = (0, 0);
        for (frame, &load) in self
            .frame_load_ns
            .iter()
            .take(self.minor_frames)
            .enumerate()
        {
            if load > best.1 {
                best = (frame, load);
            }
        }
        best
    }
}

pub fn gcd(mut a: u64, mut b: u64) -> u64 {
    while b != 0 {
        let t = a % b;
        a = b;
        b = t;
    }
    a
}

/// Least common multiple, saturating (a saturated major frame is refused as too long).
pub fn lcm(a: u64, b: u64) -> u64 {
    if a == 0 || b == 0 {
        return 0;
    }
    (a / gcd(a, b)).saturating_mul(b)
}

/// Does a task with this period and offset run in the minor frame starting at `start_ns`?
pub fn released_at(start_ns: u64, period_ns: u64, offset_ns: u64) -> bool {
    period_ns != 0 && start_ns % period_ns == offset_ns
}

pub fn analyse(
    tasks: &[TaskInput<'_>],
    exec: &ExecutiveInput,
    catalogue: Option<&[&str]>,
) -> Result<Analysis, ScheduleError> {
    check_well_formed(tasks, catalogue)?;

    let mut minor = 0u64;
    let mut major = 1u64;
    for t in tasks {
        minor = gcd(minor, t.period_ns);
        major = lcm(major, t.period_ns);
    }
    if let Some(configured) = exec.minor_frame_ns {
        minor = configured;
    }
    for (i, t) in tasks.iter().enumerate() {
        if minor == 0 || t.period_ns % minor != 0 {
            return Err(ScheduleError::PeriodNotMultipleOfMinorFrame {
                task: i,
                minor_frame_ns: minor,
            });
        }
        if t.offset_ns % minor != 0 {
            return Err(ScheduleError::OffsetNotMultipleOfMinorFrame {
                task: i,
                minor_frame_ns: minor,
            });
        }
    }
    if exec.margin_ns >= minor {
        return Err(ScheduleError::MarginTooLarge {
            margin_ns: exec.margin_ns,
            minor_frame_ns: minor,
        });
    }
    let minor_frames = major / minor;
    if minor_frames as usize > MAX_MINOR_FRAMES || major == u64::MAX {
        return Err(ScheduleError::TooManyMinorFrames {
            major_frame_ns: major,
            minor_frame_ns: minor,
        });
    }
    let minor_frames = minor_frames as usize;

    let (order, task_count) = execution_order(tasks)?;

    let limit = minor - exec.margin_ns;
    let mut frame_tasks = [0u32; MAX_MINOR_FRAMES];
    let mut frame_load_ns = [0u64; MAX_MINOR_FRAMES];
    for (frame, (set, load)) in frame_tasks
        .iter_mut()
        .zip(frame_load_ns.iter_mut())
        .take(minor_frames)
        .enumerate()
    {
        let start = frame as u64 * minor;
        for (i, t) in tasks.iter().enumerate() {
            if released_at(start, t.period_ns, t.offset_ns) {
                *set |= 1 << i;
                *load = load.saturating_add(t.budget_ns);
            }
        }
        if *load > limit {
            return Err(ScheduleError::FrameOverfull {
                frame,
                tasks: *set,
                load_ns: *load,
                limit_ns: limit,
            });
        }
    }

    let response_ns = response_times(tasks)?;
    let utilisation_ppm = tasks
        .iter()
        .map(|t| t.budget_ns.saturating_mul(1_000_000) / t.period_ns)
        .sum();

    Ok(Analysis {
        minor_frame_ns: minor,
        major_frame_ns: major,
        minor_frames,
        order,
        task_count,
        frame_tasks,
        frame_load_ns,
        response_ns,
        utilisation_ppm,
        frame_limit_ns: limit,
    })
}

fn index_of(tasks: &[TaskInput<'_>], name: &str) -> Option<usize> {
    tasks.iter().position(|t| t.name == name)
}

fn check_well_formed(
    tasks: &[TaskInput<'_>],
    catalogue: Option<&[&str]>,
) -> Result<(), ScheduleError> {
    if tasks.is_empty() {
        return Err(ScheduleError::NoTasks);
    }
    if tasks.len() > MAX_TASKS {
        return Err(ScheduleError::TooManyTasks { count: tasks.len() });
    }
    for (i, t) in tasks.iter().enumerate() {
        if index_of(tasks, t.name) != Some(i) {
            return Err(ScheduleError::DuplicateTask { task: i });
        }
        if catalogue.is_some_and(|names| !names.contains(&t.name)) {
            return Err(ScheduleError::UnknownTask { task: i });
        }
        if let Some(d) = t
            .after
            .iter()
            .position(|dep| index_of(tasks, dep).is_none())
        {
            return Err(ScheduleError::UnknownDependency {
                task: i,
                dependency_index: d,
            });
        }
        if t.period_ns == 0 {
            return Err(ScheduleError::ZeroPeriod { task: i });
        }
        if t.budget_ns == 0 {
            return Err(ScheduleError::ZeroBudget { task: i });
        }
        if t.offset_ns >= t.period_ns {
            return Err(ScheduleError::OffsetOutsidePeriod { task: i });
        }
    }
    Ok(())
}

/// Kahn's topological sort over `after`; among ready tasks the shorter period goes first
/// (rate-monotonic), then the order of the file.
fn execution_order(tasks: &[TaskInput<'_>]) -> Result<([u8; MAX_TASKS], usize), ScheduleError> {
    let n = tasks.len();
    let mut preds = [0u32; MAX_TASKS];
    for (i, t) in tasks.iter().enumerate() {
        for dep in t.after {
            if let Some(d) = index_of(tasks, dep) {
                preds[i] |= 1 << d;
            }
        }
    }
    let mut order = [0u8; MAX_TASKS];
    let mut placed = 0u32;
    for slot in order.iter_mut().take(n) {
        let mut best: Option<usize> = None;
        for i in 0..n {
            let ready = placed & (1 << i) == 0 && preds[i] & !placed == 0;
            if ready && best.is_none_or(|b| tasks[i].period_ns < tasks[b].period_ns) {
                best = Some(i);
            }
        }
        let Some(next) = best else {
            let all = if n == 32 { u32::MAX } else { (1u32 << n) - 1 };
            return Err(ScheduleError::DependencyCycle {
                tasks: all & !placed,
            });
        };
        *slot = next as u8;
        placed |= 1 << next;
    }
    Ok((order, n))
}

/// Rate-monotonic priority: shorter period first, then file order.
fn higher_priority(tasks: &[TaskInput<'_>], a: usize, b: usize) -> bool {
    (tasks[a].period_ns, a) < (tasks[b].period_ns, b)
}

/// R = B + C + Σ_hp ⌈R/Tj⌉·Cj iterated to its fixed point, with B the longest lower-priority
/// budget (a started task is never interrupted).
fn response_times(tasks: &[TaskInput<'_>]) -> Result<[u64; MAX_TASKS], ScheduleError> {
    let mut out = [0u64; MAX_TASKS];
    for (i, task) in tasks.iter().enumerate() {
        let blocking = (0..tasks.len())
            .filter(|&j| higher_priority(tasks, i, j))
            .map(|j| tasks[j].budget_ns)
            .max()
            .unwrap_or(0);
        let mut response = blocking.saturating_add(task.budget_ns);
        loop {
            let mut next = blocking.saturating_add(task.budget_ns);
            for (j, other) in tasks.iter().enumerate() {
                if higher_priority(tasks, j, i) {
                    let releases = response.div_ceil(other.period_ns);
                    next = next.saturating_add(releases.saturating_mul(other.budget_ns));
                }
            }
            if next > task.period_ns {
                return Err(ScheduleError::ResponseTimeExceedsPeriod {
                    task: i,
                    response_ns: next,
                });
            }
            if next == response {
                break;
            }
            response = next;
        }
        if let Some(slot) = out.get_mut(i) {
            *slot = response;
        }
    }
    Ok(out)
}

/// Names of the tasks in a bit mask, comma separated.
pub struct TaskNames<'a> {
    pub tasks: &'a [TaskInput<'a>],
    pub set: u32,
}

impl fmt::Display for TaskNames<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut first = true;
        for (i, t) in self.tasks.iter().enumerate() {
            if self.set & (1 << i) != 0 {
                if !first {
                    f.write_str(", ")?;
                }
                f.write_str(t.name)?;
                first = false;
            }
        }
        Ok(())
    }
}

/// A [`ScheduleError`] with the task names filled in, for people.
pub struct ErrorReport<'a> {
    pub error: ScheduleError,
    pub tasks: &'a [TaskInput<'a>],
}

struct Ms(u64);

impl fmt::Display for Ms {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0 % 1_000_000 == 0 {
            write!(f, "{} ms", self.0 / 1_000_000)
        } else {
            write!(f, "{} us", self.0 / 1_000)
        }
    }
}

impl fmt::Display for ErrorReport<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = |i: usize| self.tasks.get(i).map_or("?", |t| t.name);
        match self.error {
            ScheduleError::NoTasks => write!(f, "the schedule has no tasks"),
            ScheduleError::TooManyTasks { count } => {
                write!(f, "{count} tasks: a schedule holds at most {MAX_TASKS}")
            }
            ScheduleError::DuplicateTask { task } => {
                write!(f, "task `{}` is listed twice", name(task))
            }
            ScheduleError::UnknownTask { task } => write!(
                f,
                "unknown task `{}`: skyframe has no task of that name (the registry, \
                 shell/src/tasks.rs, lists them)",
                name(task),
            ),
            ScheduleError::UnknownDependency {
                task,
                dependency_index,
            } => {
                let dep = self
                    .tasks
                    .get(task)
                    .and_then(|t| t.after.get(dependency_index))
                    .copied()
                    .unwrap_or("?");
                write!(
                    f,
                    "task `{}` runs after unknown task `{dep}`: it is not in the schedule",
                    name(task)
                )
            }
            ScheduleError::ZeroPeriod { task } => {
                write!(f, "task `{}` has period 0", name(task))
            }
            ScheduleError::ZeroBudget { task } => {
                write!(f, "task `{}` has budget 0", name(task))
            }
            ScheduleError::PeriodNotMultipleOfMinorFrame {
                task,
                minor_frame_ns,
            } => write!(
                f,
                "task `{}`: period {} is not a multiple of the minor frame ({})",
                name(task),
                Ms(self.tasks.get(task).map_or(0, |t| t.period_ns)),
                Ms(minor_frame_ns)
            ),
            ScheduleError::OffsetNotMultipleOfMinorFrame {
                task,
                minor_frame_ns,
            } => write!(
                f,
                "task `{}`: offset {} is not a multiple of the minor frame ({})",
                name(task),
                Ms(self.tasks.get(task).map_or(0, |t| t.offset_ns)),
                Ms(minor_frame_ns)
            ),
            ScheduleError::OffsetOutsidePeriod { task } => write!(
                f,
                "task `{}`: offset must be less than its period",
                name(task)
            ),
            ScheduleError::MarginTooLarge {
                margin_ns,
                minor_frame_ns,
            } => write!(
                f,
                "margin {} leaves no time in the {} minor frame",
                Ms(margin_ns),
                Ms(minor_frame_ns)
            ),
            ScheduleError::TooManyMinorFrames {
                major_frame_ns,
                minor_frame_ns,
            } => write!(
                f,
                "major frame {} / minor frame {} is more than {MAX_MINOR_FRAMES} minor frames",
                Ms(major_frame_ns),
                Ms(minor_frame_ns)
            ),
            ScheduleError::DependencyCycle { tasks } => write!(
                f,
                "dependency cycle among tasks: {}",
                TaskNames {
                    tasks: self.tasks,
                    set: tasks
                }
            ),
            ScheduleError::FrameOverfull {
                frame,
                tasks,
                load_ns,
                limit_ns,
            } => write!(
                f,
                "minor frame {frame} is over-full: budgets {} > frame less margin {} (tasks: {})",
                Ms(load_ns),
                Ms(limit_ns),
                TaskNames {
                    tasks: self.tasks,
                    set: tasks
                }
            ),
            ScheduleError::ResponseTimeExceedsPeriod { task, response_ns } => write!(
                f,
                "task `{}`: worst-case response time {} exceeds its period {} \
                 (rate-monotonic response-time analysis)",
                name(task),
                Ms(response_ns),
                Ms(self.tasks.get(task).map_or(0, |t| t.period_ns))
            ),
        }
    }
}
