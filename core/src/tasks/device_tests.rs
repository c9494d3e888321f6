//! Device tasks against mocked ports: bytes in, frames published, records logged, counters
//! kept, commands out.

use super::gps::GpsTask;
use super::imu::ImuTask;
use super::servo::{PilotInput, ServoTask};
use super::test_support::{MS, SetClock, run_frames};
use crate::comm::LatestSlot;
use crate::control::controls::ComputerCommand;
use crate::control::controls::Controls;
use crate::devices::gps::{GpsConfig, GpsFix, SentenceKind, Talker, encode_sentence};
use crate::devices::imu::{
    IMU_FRAME_LEN, ImuMeasurement, ImuSample, ImuStatus, SlowSlot, encode_imu_frame,
};
use crate::devices::servo::{
    BoardStatus, PILOT_FRAME_LEN, PilotReport, ServoCommandDecoder, encode_pilot_frame,
};
use crate::devices::test_support::MockPort;
use crate::executive::{Executive, Task};
use crate::logfmt::RecordSink;
use crate::logfmt::printf::render_data_block;
use crate::logfmt::reader::{Event, LogReader, Record, read_slice};
use crate::schedule::{FrameTable, OverrunPolicy, TaskSlot};
use core::cell::{Cell, RefCell};
use std::string::String;
use std::vec::Vec;

/// A port the test keeps feeding while a task owns it.
struct Shared<'a>(&'a RefCell<MockPort>);

impl embedded_io::ErrorType for Shared<'_> {
    type Error = crate::devices::test_support::MockError;
}
impl embedded_io::ReadReady for Shared<'_> {
    fn read_ready(&mut self) -> Result<bool, Self::Error> {
        self.0.borrow_mut().read_ready()
    }
}
impl embedded_io::Read for Shared<'_> {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        embedded_io::Read::read(&mut *self.0.borrow_mut(), buf)
    }
}
impl embedded_io::WriteReady for Shared<'_> {
    fn write_ready(&mut self) -> Result<bool, Self::Error> {
        self.0.borrow_mut().write_ready()
    }
}
impl embedded_io::Write for Shared<'_> {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        embedded_io::Write::write(&mut *self.0.borrow_mut(), buf)
    }
    fn flush(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}

/// Everything the task logged.
struct Capture<'a>(&'a RefCell<Vec<u8>>);
impl RecordSink for Capture<'_> {
    fn push_record(&mut self, record: &[u8]) -> bool {
        self.0.borrow_mut().extend_from_slice(record);
        true
    }
}

/// The text lines of record `index`, in order.
fn rows_of(rows: &[(u8, String)], index: u8) -> Vec<&str> {
    rows.iter()
        .filter(|(i, _)| *i == index)
        .map(|(_, t)| t.as_str())
        .collect()
}

/// Data blocks as `(index, text)` lines, plus the count of reader problems.
fn logged(bytes: &[u8]) -> (Vec<(u8, String)>, usize) {
    let mut reader = LogReader::new();
    let mut rows = Vec::new();
    let mut problems = 0;
    let mut definitions: Vec<(u8, String)> = Vec::new();
    read_slice(&mut reader, bytes, |event| match event {
        Event::Record {
            record: Record::FormatDefinition { index, text, .. },
            ..
        } => {
            definitions.push((index, String::from_utf8_lossy(text).into_owned()));
        }
        Event::Record {
            record:
                Record::DataBlock {
                    index,
                    data,
                    format,
                    ..
                },
            ..
        } => {
            let definition = definitions
                .iter()
                .rev()
                .find(|(i, _)| *i == index)
                .map(|(_, t)| t.as_str());
            let mut text = String::new();
            render_data_block(&mut text, definition.unwrap_or(""), format, data).expect("renders");
            rows.push((index, text));
        }
        Event::Problem(p)
            if !matches!(p.kind, crate::logfmt::reader::ProblemKind::NotClosedCleanly) =>
        {
            problems += 1
        }
        _ => {}
    });
    (rows, problems)
}

static ONE_SLOT: [TaskSlot; 1] = [TaskSlot {
    name: "device",
    period_ns: 10 * MS,
    offset_ns: 0,
    budget_ns: 5 * MS,
    on_overrun: OverrunPolicy::Log,
}];
static EVERY_FRAME: FrameTable = FrameTable {
    minor_frame_ns: 10 * MS,
    margin_ns: MS,
    late_start_ns: MS,
    tasks: &ONE_SLOT,
    frames: &[1],
    utilisation_ppm: 0,
};

/// Flies `task` alone in every 10 ms frame of a mock clock: started, `script`ed, shut down.
/// Returns the clock's time at the end.
fn fly_alone(task: &mut dyn Task, script: impl FnOnce(&mut Alone<'_, '_, '_>)) -> u64 {
    let clock = SetClock(Cell::new(0));
    let mut exec = Executive::new(&EVERY_FRAME, &clock);
    let mut tasks: [&mut dyn Task; 1] = [task];
    exec.start(&mut tasks, 0).expect("start");
    script(&mut Alone {
        clock: &clock,
        exec: &mut exec,
        tasks: &mut tasks,
    });
    exec.shutdown(&mut tasks);
    clock.0.get()
}

/// The flight of [`fly_alone`], for its script.
struct Alone<'r, 'c, 't> {
    clock: &'c SetClock,
    exec: &'r mut Executive<&'c SetClock>,
    tasks: &'r mut [&'t mut dyn Task; 1],
}

impl Alone<'_, '_, '_> {
    fn frames(&mut self, n: u64) {
        run_frames(self.exec, self.clock, self.tasks, n);
    }
    fn degraded(&self) -> Option<&'static str> {
        self.exec.health().degraded(0)
    }
    fn now_ns(&self) -> u64 {
        self.clock.0.get()
    }
}

fn imu_frame(counter: u8, p: f32) -> [u8; IMU_FRAME_LEN] {
    let m = ImuMeasurement {
        rate_radps: [p, -0.2, 0.05],
        specific_force_mps2: [0.0, 0.0, -9.80665],
        status: ImuStatus(0),
    };
    let mut out = [0u8; IMU_FRAME_LEN];
    encode_imu_frame(
        counter,
        &m,
        SlowSlot {
            index: counter % 100,
            byte: 0,
        },
        &mut out,
    );
    out
}

#[test]
fn imu_task_publishes_and_logs_every_sample_and_counts_garbage() {
    let port = RefCell::new(MockPort::default());
    let log = RefCell::new(Vec::new());
    let samples: LatestSlot<ImuSample> = LatestSlot::new();
    let mut imu = ImuTask::new(Shared(&port), Capture(&log), 50 * MS, &samples);
    fly_alone(&mut imu, |alone| {
        for counter in 0..5u8 {
            let mut p = port.borrow_mut();
            p.received
                .extend(imu_frame(counter, 0.1 * f32::from(counter)));
            p.received.extend(b"\x00garbage\xa5");
            drop(p);
            alone.frames(1);
        }
    });
    let last = samples.peek().expect("a sample");
    assert_eq!(last.counter, 4);
    assert!((last.measurement.rate_radps[0] - 0.4).abs() < 1e-3);
    assert!(imu.stats().framing_errors > 0 || imu.stats().bytes_discarded > 0);
    assert_eq!(imu.stats().frames, 5);
    let (rows, problems) = logged(&log.borrow());
    assert_eq!(problems, 0);
    let fast: Vec<&str> = rows_of(&rows, 1);
    assert_eq!(fast.len(), 5);
    assert_eq!(
        fast[2], "2,0.2000,-0.2000,0.0500,0.0000,0.0000,-9.8050,0",
        "5e-3 m/s² wire steps"
    );
    let status: Vec<&str> = rows_of(&rows, 3);
    assert_eq!(status.len(), 2, "once at the first step, once at shutdown");
    assert!(status[1].starts_with("5,0,"), "{}", status[1]);
}

#[test]
fn imu_task_reports_a_silent_device_stale() {
    let port = RefCell::new(MockPort::default());
    let log = RefCell::new(Vec::new());
    let samples: LatestSlot<ImuSample> = LatestSlot::new();
    let mut imu = ImuTask::new(Shared(&port), Capture(&log), 50 * MS, &samples);
    let mut fresh_at = 0;
    let end_ns = fly_alone(&mut imu, |alone| {
        port.borrow_mut().received.extend(imu_frame(0, 0.0));
        alone.frames(3);
        fresh_at = alone.now_ns();
        assert_eq!(alone.degraded(), None);
        alone.frames(10);
        assert_eq!(alone.degraded(), Some("device stale"), "stale within 50 ms");
        port.borrow_mut().received.extend(imu_frame(1, 0.0));
        alone.frames(1);
        assert_eq!(alone.degraded(), None, "fresh again with the next frame");
        alone.frames(10);
    });
    assert!(!imu.is_stale(fresh_at));
    assert!(imu.is_stale(end_ns));
    let (rows, _) = logged(&log.borrow());
    let last_status = rows.iter().rev().find(|(i, _)| *i == 3).expect("status");
    assert!(
        last_status.1.ends_with(",1"),
        "stale flag set: {}",
        last_status.1
    );
}

fn gps_epoch(latitude: f64, time_ms: u32, out: &mut Vec<u8>) {
    let fix = GpsFix {
        utc_time_ms: Some(time_ms),
        valid: true,
        satellites: Some(9),
        latitude_deg: Some(latitude),
        longitude_deg: Some(-71.09),
        altitude_msl_m: Some(120.5),
        hdop: Some(0.9),
        ..GpsFix::default()
    };
    let mut buf = [0u8; 128];
    for kind in [SentenceKind::Gga, SentenceKind::Rmc] {
        let n = encode_sentence(kind, Talker::Gp, &fix, &mut buf).expect("fits");
        out.extend_from_slice(&buf[..n]);
    }
}

#[test]
fn gps_task_publishes_each_epoch_and_logs_missing_values_as_nan() {
    let port = RefCell::new(MockPort::default());
    let log = RefCell::new(Vec::new());
    let fixes: LatestSlot<GpsFix> = LatestSlot::new();
    let mut gps = GpsTask::new(Shared(&port), Capture(&log), GpsConfig::default(), &fixes);
    fly_alone(&mut gps, |alone| {
        for (i, lat) in [42.36, 42.37, 42.38].into_iter().enumerate() {
            let mut bytes = Vec::new();
            gps_epoch(lat, 1000 * i as u32, &mut bytes);
            port.borrow_mut().received.extend(bytes);
            alone.frames(10);
        }
    });
    // The third epoch ends only when a fourth begins: two are out.
    let fix = fixes.peek().expect("fix");
    assert!((fix.latitude_deg.unwrap_or(0.0) - 42.37).abs() < 1e-6);
    let (rows, problems) = logged(&log.borrow());
    assert_eq!(problems, 0);
    let logged_fixes: Vec<&str> = rows_of(&rows, 1);
    assert_eq!(logged_fixes.len(), 2);
    assert!(
        logged_fixes[0].starts_with("1,1,9,42.36000000,-71.09000000,120.500,"),
        "{}",
        logged_fixes[0]
    );
    assert!(
        logged_fixes[0].contains(",nan,"),
        "PDOP was never sent: {}",
        logged_fixes[0]
    );
}

fn pilot_frame(counter: u8, aileron_us: u16, switch_us: u16) -> [u8; PILOT_FRAME_LEN] {
    let report = PilotReport {
        pilot_us: [aileron_us, 1500, 1100, 1500, 1500, 1500, 1500, 1500],
        switch_us,
        logic_battery_v: 11.9,
        servo_battery_v: 4.95,
        status: BoardStatus(0),
    };
    let mut out = [0u8; PILOT_FRAME_LEN];
    encode_pilot_frame(counter, &report, &mut out);
    out
}

#[test]
fn servo_task_sends_commands_first_then_reads_the_pilot() {
    let port = RefCell::new(MockPort {
        write_room: 1 << 20,
        ..MockPort::default()
    });
    let log = RefCell::new(Vec::new());
    let commands: LatestSlot<ComputerCommand> = LatestSlot::new();
    let pilot: LatestSlot<PilotInput> = LatestSlot::new();
    let mut servo = ServoTask::new(Shared(&port), Capture(&log), 100 * MS, &commands, &pilot);
    fly_alone(&mut servo, |alone| {
        port.borrow_mut()
            .received
            .extend(pilot_frame(7, 1900, 1000));
        alone.frames(1);
        commands.publish(ComputerCommand {
            controls: Controls {
                aileron: 0.5,
                elevator: -0.25,
                throttle: 0.75,
                rudder: 0.0,
            },
            ready: true,
        });
        port.borrow_mut()
            .received
            .extend(pilot_frame(8, 1900, 2000));
        alone.frames(1);
    });
    let input = pilot.peek().expect("pilot");
    assert_eq!(input.report.switch_us, 2000);
    assert_eq!(input.mode, crate::devices::servo::ControlMode::Auto);
    assert!(
        (input.sticks.aileron - 0.8).abs() < 0.01,
        "1900 us is +0.8: {}",
        input.sticks.aileron
    );

    // Three command frames went out: idle (not ready), the computer's, the hand-back.
    let mut decoder = ServoCommandDecoder::new(100 * MS);
    let mut sent = Vec::new();
    decoder.push(&port.borrow().transmitted, 0, |f| sent.push(f.command));
    assert_eq!(sent.len(), 3);
    assert!(!sent[0].autopilot_ready && sent[1].autopilot_ready && !sent[2].autopilot_ready);
    assert_eq!(sent[1].channels_us[0], 1750, "aileron +0.5");
    assert_eq!(
        sent[1].channels_us[2], 1750,
        "throttle 0.75 over 1000-2000 us"
    );
    let (rows, problems) = logged(&log.borrow());
    assert_eq!(problems, 0);
    let pilots: Vec<&str> = rows_of(&rows, 1);
    assert_eq!(pilots.len(), 2);
    assert!(
        pilots[1].starts_with("8,1900,1500,1100,1500,1500,1500,1500,1500,1,0.800,"),
        "{}",
        pilots[1]
    );
    assert!(pilots[1].ends_with(",11.900,4.950"), "{}", pilots[1]);
    let sent_log: Vec<&str> = rows_of(&rows, 2);
    assert_eq!(sent_log[1], "1,0.500,-0.250,0.750,0.000");
}
