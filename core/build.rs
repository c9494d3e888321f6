//! Turns `schedule.toml` into the core's `const` frame table, or fails the build saying which
//! frame and which tasks make the schedule infeasible.
//!
//! The schedule file is `../schedule.toml` unless `SKYFRAME_SCHEDULE` names another.

#[allow(dead_code)]
#[path = "src/schedule/analysis.rs"]
mod analysis;

#[allow(dead_code)]
#[path = "src/schedule/file.rs"]
mod file;

use analysis::ErrorReport;
use std::fmt::Write as _;
use std::path::PathBuf;

fn main() {
    println!("cargo::rerun-if-env-changed=SKYFRAME_SCHEDULE");
    let path = match std::env::var_os("SKYFRAME_SCHEDULE") {
        Some(p) => PathBuf::from(p),
        // Read at run time, not baked in with `env!`: a build script compiled in one checkout
        // can be reused (same hash) by another sharing the target directory.
        None => PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default())
            .join("../schedule.toml"),
    };
    println!("cargo::rerun-if-changed={}", path.display());

    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| fail(&format!("cannot read {}: {e}", path.display())));
    let schedule = file::ScheduleFile::parse(&text)
        .unwrap_or_else(|e| fail(&format!("{}: {e}", path.display())));
    for note in &schedule.renamed {
        println!("cargo::warning={}: {note}", path.display());
    }
    let exec = schedule.executive_input();

    let generated = schedule.with_inputs(|tasks| {
        // Task names are the shell registry's to check (shell/src/tasks.rs, when it builds).
        let result = analysis::analyse(tasks, &exec, None);
        let a = result.unwrap_or_else(|error| {
            fail(&format!(
                "{}: infeasible schedule: {}",
                path.display(),
                ErrorReport { error, tasks }
            ))
        });
        println!(
            "cargo::warning=schedule {}: {} tasks, minor frame {} us, {} minor frames, \
             utilisation {}.{}%, busiest frame {} at {} us of {} us",
            path.display(),
            tasks.len(),
            a.minor_frame_ns / 1000,
            a.minor_frames,
            a.utilisation_ppm / 10_000,
            (a.utilisation_ppm / 1000) % 10,
            a.busiest_frame().0,
            a.busiest_frame().1 / 1000,
            a.frame_limit_ns / 1000,
        );
        render(tasks, &exec, &a)
    });

    let out = PathBuf::from(std::env::var_os("OUT_DIR").unwrap_or_default()).join("frame_table.rs");
    if let Err(e) = std::fs::write(&out, generated) {
        fail(&format!("cannot write {}: {e}", out.display()));
    }
}

fn render(
    tasks: &[analysis::TaskInput<'_>],
    exec: &analysis::ExecutiveInput,
    a: &analysis::Analysis,
) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "/// The frame table built from the shipped `schedule.toml`."
    );
    let _ = writeln!(s, "pub const SHIPPED: FrameTable = FrameTable {{");
    let _ = writeln!(s, "    minor_frame_ns: {},", a.minor_frame_ns);
    let _ = writeln!(s, "    margin_ns: {},", exec.margin_ns);
    let _ = writeln!(s, "    late_start_ns: {},", exec.late_start_ns);
    let _ = writeln!(s, "    tasks: &[");
    for &i in &a.order[..a.task_count] {
        let t = &tasks[i as usize];
        let policy = match t.on_overrun {
            analysis::OverrunPolicy::Log => "Log",
            analysis::OverrunPolicy::Skip => "Skip",
            analysis::OverrunPolicy::Reset => "Reset",
        };
        let _ = writeln!(
            s,
            "        TaskSlot {{ name: {:?}, period_ns: {}, offset_ns: {}, budget_ns: {}, \
             on_overrun: OverrunPolicy::{policy} }},",
            t.name, t.period_ns, t.offset_ns, t.budget_ns
        );
    }
    let _ = writeln!(s, "    ],");
    let _ = writeln!(s, "    frames: &[");
    for frame in 0..a.minor_frames {
        let _ = writeln!(s, "        {:#034b},", a.frame_mask_in_order(frame));
    }
    let _ = writeln!(s, "    ],");
    let _ = writeln!(s, "    utilisation_ppm: {},", a.utilisation_ppm);
    let _ = writeln!(s, "}};");
    let _ = writeln!(s, "/// Number of tasks in [`SHIPPED`].");
    let _ = writeln!(s, "pub const SHIPPED_TASKS: usize = {};", a.task_count);
    s
}

/// Ends the build with one readable line (cargo shows build-script errors with context).
fn fail(message: &str) -> ! {
    println!("cargo::error={message}");
    eprintln!("error: {message}");
    std::process::exit(1);
}
