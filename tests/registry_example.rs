//! Adding a task is three edits: the task's own code (here, in this file), its line in a
//! schedule (`tests/schedules/with-example.toml`) and its registry line (the `TaskEntry`
//! below). With nothing else changed, the task appears in the schedule analysis, flies in the
//! simulated airplane, writes its own log that `skyframe-log to-csv` converts, and its values
//! reach the ground on the live link — equal to what it logged.

use skyframe_core::executive::{Task, TaskContext, TaskFault};
use skyframe_core::link::frame::{Verify, decode_datagram};
use skyframe_core::link::messages::{Message, TaskData, Telemetry, Value as LinkValue};
use skyframe_core::logfmt::LogRecord;
use skyframe_core::logfmt::RecordSink;
use skyframe_core::tasks::task_log::TaskLog;
use skyframe_logtable::{load_stream, time_ns};
use skyframe_shell::check_schedule::{check_file_with, load_frame_table};
use skyframe_shell::flight::{Devices, FlightPlan, LinkPlan, LogSettings, fly};
use skyframe_shell::host::RunOptions;
use skyframe_shell::simflight::VirtualTime;
use skyframe_shell::tasks::{FlightTask, Needs, REGISTRY, TaskEntry, Wiring};
use skyframe_shell::vehicle::LogConfig;
use skyframe_sim::scenario::Scenario;
use skyframe_sim::world::SimWorld;
use skyframe_tests::{csv_rows, scratch, to_csv, workspace};
use std::collections::BTreeMap;
use std::net::UdpSocket;
use std::os::unix::fs::PermissionsExt;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

// --- The task's own file -----------------------------------------------------------------

skyframe_core::log_record! {
    /// What the example task logs each step: a counter and a slow wave.
    pub struct ExampleLog {
        step: u32 = "%u",
        wave: f32 = "%.4f",
    }
}

const EXAMPLE_INDEX: u8 = 1;

struct ExampleTask<S: RecordSink> {
    log: TaskLog<S>,
    steps: u32,
}

impl<S: RecordSink> Task for ExampleTask<S> {
    fn init(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        self.log
            .declare::<ExampleLog>(cx, EXAMPLE_INDEX)
            .map_err(|_| TaskFault::new("example log format"))?;
        self.log.begin(cx);
        Ok(())
    }

    fn step(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        self.steps += 1;
        let record = ExampleLog {
            step: self.steps,
            wave: (cx.now_ns as f64 * 1e-9).sin() as f32,
        };
        self.log.log(cx, EXAMPLE_INDEX, &record);
        Ok(())
    }

    fn shutdown(&mut self, cx: &mut TaskContext<'_>) {
        self.log.end(cx);
    }
}

impl<S: RecordSink> FlightTask for ExampleTask<S> {}

fn build_example<'w>(w: &mut Wiring<'w>) -> Result<Box<dyn FlightTask + 'w>, String> {
    Ok(Box::new(ExampleTask {
        log: TaskLog::new(w.tapped_log()?),
        steps: 0,
    }))
}

// --- The registry line -------------------------------------------------------------------

const EXAMPLE: TaskEntry = TaskEntry {
    name: "example",
    log: "example",
    needs: Needs::Nothing,
    build: build_example,
};

// --- The proof ---------------------------------------------------------------------------

#[test]
fn a_task_added_through_the_registry_is_analysed_flown_logged_converted_and_sent() {
    let mut registry = REGISTRY.to_vec();
    registry.push(EXAMPLE);
    let schedule = workspace().join("tests/schedules/with-example.toml");

    // The schedule analysis has it, with its release times.
    let checked = check_file_with(&schedule, &registry).expect("readable");
    assert!(checked.feasible, "{}", checked.report);
    assert!(
        checked
            .report
            .lines()
            .any(|l| l.contains(" example ") && l.contains("50 ms")),
        "{}",
        checked.report
    );
    // Without its registry line the same schedule is refused, by name.
    let refused = check_file_with(&schedule, REGISTRY).expect("readable");
    assert!(!refused.feasible);
    assert!(
        refused
            .report
            .contains("task `example` is in the schedule but skyframe has no such task"),
        "{}",
        refused.report
    );
    let table = load_frame_table(&schedule, &registry).expect("feasible");
    let example_index = table.task_index("example").expect("in the table") as u8;

    // It flies in the simulated airplane, with the link to a ground on 127.0.0.1.
    let dir = scratch("registry-example");
    let key = dir.join("link.key");
    std::fs::write(&key, format!("{}\n", "5e".repeat(32))).expect("key");
    std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o600)).expect("chmod");
    let ground = UdpSocket::bind("127.0.0.1:0").expect("ground socket");
    ground
        .set_read_timeout(Some(Duration::from_millis(20)))
        .expect("timeout");
    let ground_address = ground.local_addr().expect("address");
    let listening = Arc::new(AtomicBool::new(true));
    let receiver = {
        let listening = Arc::clone(&listening);
        std::thread::spawn(move || {
            let mut received: Vec<Telemetry> = Vec::new();
            let mut buf = [0u8; 2048];
            while listening.load(Ordering::Relaxed) {
                let Ok(n) = ground.recv(&mut buf) else {
                    continue;
                };
                if let Ok((_, Message::Telemetry(t))) = decode_datagram(&buf[..n], Verify::No) {
                    received.push(t);
                }
            }
            received
        })
    };
    let scenario =
        Scenario::load(&workspace().join("scenarios/takeoff-circuit.toml")).expect("scenario");
    let stop = AtomicBool::new(false);
    let report = fly(
        &VirtualTime,
        table,
        FlightPlan {
            log_dir: &dir,
            log: LogSettings::from_config(&LogConfig::default(), &[]),
            devices: Devices::Sim(Box::new(
                SimWorld::from_scenario(&scenario, Some(3)).expect("the built-in plant"),
            )),
            link: Some(LinkPlan {
                key: Some(key),
                commands: "127.0.0.1:0".parse().expect("address"),
                commands_is_default: false,
                telemetry: vec![ground_address],
                vehicle_id: 1,
                sign_telemetry: false,
                network: true,
            }),
            mission: None,
            registry: &registry,
            mavlink: None,
            parameters: Vec::new(),
            options: RunOptions::new(Some(Duration::from_secs(20)), &stop),
        },
    )
    .expect("flies");
    std::thread::sleep(Duration::from_millis(200));
    listening.store(false, Ordering::Relaxed);
    let received = receiver.join().expect("receiver");

    // Its own log, which the converter reads.
    let log = report.flight_dir.join("example.bin");
    let stream = load_stream(&log, |p| panic!("{}: {p:?}", log.display())).expect("reads");
    let logged = stream.table(EXAMPLE_INDEX).expect("its records");
    assert_eq!(logged.columns, ["step", "wave"]);
    // 20 s at 50 ms: 400 releases, the first at 20 ms.
    assert_eq!(logged.times_ns.len(), 400, "one record a release");
    let csv = to_csv(&[&log], &dir.join("csv")).join("example.1.csv");
    let rows = csv_rows(&csv);
    assert_eq!(rows.len(), 400);
    for (i, row) in rows.iter().enumerate() {
        assert_eq!(row[1], (i + 1) as f64, "step column of row {i}");
        let t_s = row[0];
        assert!(
            (row[2] - t_s.sin()).abs() < 1e-3,
            "wave at {t_s} s: {}",
            row[2]
        );
    }

    // On the link: its name, its columns, and values equal to the logged record.
    let named = received.iter().any(|t| {
        matches!(t, Telemetry::TaskStatus(s)
            if s.task_index == example_index && s.name.as_str() == "example")
    });
    assert!(named, "the example task's status with its name");
    let columns: BTreeMap<u8, String> = received
        .iter()
        .filter_map(|t| match t {
            Telemetry::TaskFormat(f) if f.task_index == example_index => Some((
                f.format_index,
                String::from_utf8_lossy(&f.columns).into_owned(),
            )),
            _ => None,
        })
        .collect();
    assert_eq!(
        columns.get(&EXAMPLE_INDEX).map(String::as_str),
        Some(ExampleLog::FORMAT.columns)
    );
    let data: Vec<&TaskData> = received
        .iter()
        .filter_map(|t| match t {
            Telemetry::TaskData(d) if d.task_index == example_index => Some(d),
            _ => None,
        })
        .collect();
    assert!(
        data.len() >= 10,
        "{} example records on the link",
        data.len()
    );
    for d in data {
        let t = time_ns(d.time);
        let row = logged
            .times_ns
            .iter()
            .position(|&logged_t| logged_t == t)
            .unwrap_or_else(|| panic!("{}: no logged record at that time", d.time));
        let [LinkValue::U32(step), LinkValue::F32(wave)] = d.values.as_slice() else {
            panic!("{:?}", d.values);
        };
        assert_eq!(f64::from(*step), logged.values[0][row]);
        assert_eq!(f64::from(*wave), logged.values[1][row]);
    }
}
