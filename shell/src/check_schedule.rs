//! `skyframe check-schedule [FILE]`: the build script's validator, at run time, with the
//! frame table printed for people.

use skyframe_core::schedule::analysis::{
    Analysis, ErrorReport, ExecutiveInput, TaskInput, analyse,
};
use skyframe_core::schedule::file::ScheduleFile;
use skyframe_core::schedule::{FrameTable, TaskSlot};
use skyframe_input_files::{CONFIG_LIMIT, read_text};
use std::fmt::Write as _;
use std::path::Path;

/// The outcome of checking a file: the text to print and whether the schedule is feasible.
#[derive(Debug)]
pub struct Checked {
    pub report: String,
    pub feasible: bool,
}

/// Reads and checks a schedule file. `Err` is a one-line reason the file could not be read
/// or parsed (the caller exits 2); an infeasible schedule is `Ok` with `feasible: false`.
pub fn check_file(path: &Path) -> Result<Checked, String> {
    check_file_with(path, crate::tasks::REGISTRY)
}

/// [`check_file`] against another registry (one with a task added).
pub fn check_file_with(
    path: &Path,
    registry: &[crate::tasks::TaskEntry],
) -> Result<Checked, String> {
    let text = read_text(path, "schedule", CONFIG_LIMIT)?;
    let file = ScheduleFile::parse(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    let exec = file.executive_input();
    let names = crate::tasks::task_names(registry);
    let warnings: String = file
        .renamed
        .iter()
        .map(|note| format!("warning: {}: {note}\n", path.display()))
        .collect();
    let checked = file.with_inputs(|tasks| {
        // A name skyframe has no task for first: the clearest message. A registered task
        // the schedule leaves out after the timing analysis, which a partial schedule can
        // still be checked for.
        let scheduled: Vec<&str> = tasks.iter().map(|t| t.name).collect();
        if let Some(mismatch) = crate::tasks::unknown_task(&scheduled, registry) {
            return Checked {
                report: format!("{}: {mismatch}\n", path.display()),
                feasible: false,
            };
        }
        match analyse(tasks, &exec, Some(&names)) {
            Ok(analysis) => match crate::tasks::unscheduled_task(&scheduled, registry) {
                Some(mismatch) => Checked {
                    report: format!("{}: {mismatch}\n", path.display()),
                    feasible: false,
                },
                None => Checked {
                    report: render(path, tasks, &exec, &analysis),
                    feasible: true,
                },
            },
            Err(error) => Checked {
                report: format!(
                    "{}: infeasible schedule: {}\n",
                    path.display(),
                    ErrorReport { error, tasks }
                ),
                feasible: false,
            },
        }
    });
    Ok(Checked {
        report: warnings + &checked.report,
        ..checked
    })
}

/// The frame table of a schedule file, for flying a schedule other than the shipped one with
/// a registry of its own (the tests that add a task show the recipe this way): the same
/// analysis as the build script, the table leaked for the process's life as the shipped one
/// is `'static`. `Err` is one line: unreadable, malformed, infeasible, or names that
/// `registry` does not match.
pub fn load_frame_table(
    path: &Path,
    registry: &[crate::tasks::TaskEntry],
) -> Result<&'static FrameTable, String> {
    let text = read_text(path, "schedule", CONFIG_LIMIT)?;
    let file = ScheduleFile::parse(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    for note in &file.renamed {
        log::warn!("{}: {note}", path.display());
    }
    let exec = file.executive_input();
    file.with_inputs(|tasks| {
        let scheduled: Vec<&str> = tasks.iter().map(|t| t.name).collect();
        if let Some(mismatch) = crate::tasks::schedule_mismatch(&scheduled, registry) {
            return Err(format!("{}: {mismatch}", path.display()));
        }
        let names = crate::tasks::task_names(registry);
        let a = analyse(tasks, &exec, Some(&names)).map_err(|error| {
            format!(
                "{}: infeasible schedule: {}",
                path.display(),
                ErrorReport { error, tasks }
            )
        })?;
        let slots: Vec<TaskSlot> = a
            .order
            .iter()
            .take(a.task_count)
            .filter_map(|&i| tasks.get(usize::from(i)))
            .map(|t| TaskSlot {
                name: Box::leak(t.name.to_string().into_boxed_str()),
                period_ns: t.period_ns,
                offset_ns: t.offset_ns,
                budget_ns: t.budget_ns,
                on_overrun: t.on_overrun,
            })
            .collect();
        let frames: Vec<u32> = (0..a.minor_frames)
            .map(|frame| a.frame_mask_in_order(frame))
            .collect();
        Ok(&*Box::leak(Box::new(FrameTable {
            minor_frame_ns: a.minor_frame_ns,
            margin_ns: exec.margin_ns,
            late_start_ns: exec.late_start_ns,
            tasks: Box::leak(slots.into_boxed_slice()),
            frames: Box::leak(frames.into_boxed_slice()),
            utilisation_ppm: a.utilisation_ppm,
        })))
    })
}

fn ms(ns: u64) -> String {
    if ns % 1_000_000 == 0 {
        format!("{} ms", ns / 1_000_000)
    } else {
        format!("{:.1} ms", ns as f64 / 1e6)
    }
}

fn render(path: &Path, tasks: &[TaskInput<'_>], exec: &ExecutiveInput, a: &Analysis) -> String {
    let mut s = String::new();
    let (busiest, busiest_load) = a.busiest_frame();
    let _ = writeln!(
        s,
        "{}: {} tasks, minor frame {}, major frame {} ({} minor frames), margin {} us",
        path.display(),
        tasks.len(),
        ms(a.minor_frame_ns),
        ms(a.major_frame_ns),
        a.minor_frames,
        exec.margin_ns / 1000
    );
    let _ = writeln!(
        s,
        "utilisation {:.1} %; busiest frame {busiest}: {} us of {} us available ({:.1} % of the frame)",
        a.utilisation_ppm as f64 / 1e4,
        busiest_load / 1000,
        a.frame_limit_ns / 1000,
        busiest_load as f64 * 100.0 / a.minor_frame_ns as f64,
    );
    let _ = writeln!(
        s,
        "feasible: every frame fits, every response time is within its period\n"
    );

    let _ = writeln!(
        s,
        "{:<4} {:<10} {:>9} {:>9} {:>9} {:<6} {:<12} {:>6} {:>11}",
        "run", "task", "period", "offset", "budget", "policy", "after", "U %", "response us"
    );
    let order = a.order.iter().take(a.task_count).map(|&i| usize::from(i));
    for (position, i) in order.clone().enumerate() {
        let Some(t) = tasks.get(i) else { continue };
        let after = if t.after.is_empty() {
            "-".to_string()
        } else {
            t.after.join(",")
        };
        let _ = writeln!(
            s,
            "{:<4} {:<10} {:>9} {:>9} {:>9} {:<6} {:<12} {:>6.2} {:>11}",
            position + 1,
            t.name,
            ms(t.period_ns),
            ms(t.offset_ns),
            format!("{} us", t.budget_ns / 1000),
            t.on_overrun.as_str(),
            after,
            t.budget_ns as f64 * 100.0 / t.period_ns as f64,
            a.response_ns.get(i).copied().unwrap_or(0) / 1000,
        );
    }

    let _ = write!(s, "\n{:>5} {:>9} ", "frame", "start");
    let names: Vec<&str> = order
        .clone()
        .filter_map(|i| tasks.get(i).map(|t| t.name))
        .collect();
    for name in &names {
        let _ = write!(s, " {name}");
    }
    let _ = writeln!(s, " {:>8} {:>6} {:>8}", "load us", "load %", "slack us");
    for frame in 0..a.minor_frames {
        let set = a.frame_tasks.get(frame).copied().unwrap_or(0);
        let load = a.frame_load_ns.get(frame).copied().unwrap_or(0);
        let _ = write!(s, "{frame:>5} {:>9} ", ms(frame as u64 * a.minor_frame_ns));
        for (name, i) in names.iter().zip(order.clone()) {
            let mark = if set & (1 << i) != 0 { "#" } else { "." };
            let _ = write!(s, " {mark:^width$}", width = name.len());
        }
        let _ = writeln!(
            s,
            " {:>8} {:>6.1} {:>8}",
            load / 1000,
            load as f64 * 100.0 / a.minor_frame_ns as f64,
            (a.minor_frame_ns - load) / 1000
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(name: &str, text: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("skyframe-check-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let path = dir.join(name);
        std::fs::write(&path, text).expect("write schedule");
        path
    }

    #[test]
    fn shipped_schedule_prints_every_frame_and_task() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../schedule.toml");
        let checked = check_file(&path).expect("readable");
        assert!(checked.feasible, "{}", checked.report);
        let r = &checked.report;
        assert!(r.contains("8 tasks, minor frame 10 ms, major frame 100 ms (10 minor frames)"));
        assert!(r.contains("utilisation 29.8 %"));
        // imu's row, then the frame rows with imu in every frame.
        assert!(r.lines().any(|l| l.starts_with("1    imu ")));
        let frames: Vec<&str> = r
            .lines()
            .filter(|l| l.trim_start().starts_with(char::is_numeric) && l.contains(" ms "))
            .collect();
        assert!(frames.len() >= 10);
    }

    #[test]
    fn a_schedule_with_the_old_task_names_reads_with_a_warning_per_rename() {
        use skyframe_core::schedule::SHIPPED;
        let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../schedule.toml");
        let text = std::fs::read_to_string(&shipped).expect("shipped schedule");
        // The shipped file as it was before the rename: `logging` the snapshots, `health`
        // the watchdog.
        let old = text
            .replace("name = \"health\",   ", "name = \"logging\",  ")
            .replace("name = \"watchdog\", ", "name = \"health\",   ");
        assert_ne!(old, text);
        let path = write("old-names.toml", &old);
        let checked = check_file(&path).expect("readable");
        assert!(checked.feasible, "{}", checked.report);
        for rename in [
            "`logging` is now called `health`",
            "`health` is now called `watchdog`",
        ] {
            assert!(
                checked
                    .report
                    .lines()
                    .any(|l| l.starts_with("warning: ") && l.contains(rename)),
                "{}",
                checked.report
            );
        }
        // Each old entry keeps its timing under its new name: the same table as shipped.
        let table = load_frame_table(&path, crate::tasks::REGISTRY).expect("loads");
        assert_eq!(table.tasks, SHIPPED.tasks);
        assert_eq!(table.frames, SHIPPED.frames);
    }

    #[test]
    fn over_full_frame_is_infeasible_and_named() {
        let path = write(
            "overfull.toml",
            r#"
tasks = [
  { name = "imu", period_ms = 10, budget_us = 6000, on_overrun = "log" },
  { name = "gps", period_ms = 100, offset_ms = 40, budget_us = 3500, on_overrun = "log" },
]
[executive]
margin_us = 1000
late_start_us = 500
"#,
        );
        let checked = check_file(&path).expect("readable");
        assert!(!checked.feasible);
        assert!(
            checked.report.contains("minor frame 4 is over-full: budgets 9500 us > frame less margin 9 ms (tasks: imu, gps)"),
            "{}",
            checked.report
        );
    }

    #[test]
    fn the_shipped_file_loads_as_the_table_the_build_made() {
        use skyframe_core::schedule::SHIPPED;
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../schedule.toml");
        let table = load_frame_table(&path, crate::tasks::REGISTRY).expect("loads");
        assert_eq!(table.tasks, SHIPPED.tasks);
        assert_eq!(table.frames, SHIPPED.frames);
        assert_eq!(
            (table.minor_frame_ns, table.margin_ns, table.late_start_ns),
            (
                SHIPPED.minor_frame_ns,
                SHIPPED.margin_ns,
                SHIPPED.late_start_ns
            )
        );
        assert_eq!(table.utilisation_ppm, SHIPPED.utilisation_ppm);
    }

    #[test]
    fn a_name_with_no_task_is_refused_naming_the_registry() {
        let shipped =
            std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../schedule.toml"))
                .expect("shipped schedule");
        let baro = shipped.replace(
            "tasks = [\n",
            "tasks = [\n  { name = \"baro\", period_ms = 50, budget_us = 200, on_overrun = \"log\" },\n",
        );
        let checked = check_file(&write("baro.toml", &baro)).expect("readable");
        assert!(!checked.feasible);
        assert!(
            checked.report.contains(
                "baro.toml: task `baro` is in the schedule but skyframe has no such task \
                 (registered in shell/src/tasks.rs: imu, gps, servo, estimator, control, \
                 telemetry, health, watchdog)"
            ),
            "{}",
            checked.report
        );
        let without_gps: String = shipped
            .lines()
            .filter(|l| !l.contains("name = \"gps\""))
            .map(|l| format!("{l}\n"))
            .collect();
        let checked = check_file(&write("no-gps.toml", &without_gps)).expect("readable");
        assert!(!checked.feasible);
        assert!(
            checked.report.contains(
                "task `gps` is registered (shell/src/tasks.rs) but the schedule does not run it"
            ),
            "{}",
            checked.report
        );
    }

    #[test]
    fn unreadable_and_malformed_files_say_where() {
        let missing = check_file(Path::new("/nonexistent/schedule.toml")).expect_err("error");
        assert!(
            missing.starts_with("schedule /nonexistent/schedule.toml: "),
            "{missing}"
        );
        let path = write(
            "typo.toml",
            "tasks = []\n[executive]\nmargin_us = 1\nlate_start_us = 1\nslack = 3\n",
        );
        let e = check_file(&path).expect_err("error");
        assert!(
            e.contains("typo.toml") && e.contains("line 5") && e.contains("slack"),
            "{e}"
        );
        assert!(!e.contains('\n'), "one line: {e}");
        let path = write(
            "policy.toml",
            "tasks = [{ name = \"imu\", period_ms = 10, budget_us = 1, on_overrun = \"panic\" }]\n[executive]\nmargin_us = 1\nlate_start_us = 1\n",
        );
        let e = check_file(&path).expect_err("error");
        assert!(e.contains("on_overrun = \"panic\""), "{e}");
    }
}
