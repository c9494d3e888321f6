//! The estimator and control tasks against their slots: samples in, estimates and commands
//! out, records logged, modes decided, gains read from a shared parameter table.

use super::control::{CONTROL_INDEX, ControlSettings, ControlTask, GAINS_INDEX, define_params};
use super::estimator::{EstimatorTask, HEALTH_INDEX, SD_INDEX, STATE_INDEX};
use super::servo::PilotInput;
use crate::comm::LatestSlot;
use crate::control::controls::ComputerCommand;
use crate::control::controls::Controls;
use crate::control::mission::{Mission, Waypoint};
use crate::control::mode::FlightMode;
use crate::control::mode::ModeReason;
use crate::devices::gps::GpsFix;
use crate::devices::imu::{ImuMeasurement, ImuSample};
use crate::devices::servo::{BoardStatus, ControlMode, PilotReport};
use crate::estimation::alignment::AlignmentConfig;
use crate::estimation::{Estimate, EstimatorConfig, HeadingSource, HealthReason, Phase};
use crate::executive::{HealthBoard, Task, TaskContext};
use crate::horizon::HorizonAttitude;
use crate::link::messages::{Name, Value};
use crate::link::params::ParamTable;
use crate::logfmt::RecordSink;
use crate::logfmt::reader::{Event, LogReader, Record, read_slice};
use core::cell::RefCell;
use std::vec::Vec;

const MS: u64 = 1_000_000;

struct Capture<'a>(&'a RefCell<Vec<u8>>);
impl RecordSink for Capture<'_> {
    fn push_record(&mut self, record: &[u8]) -> bool {
        self.0.borrow_mut().extend_from_slice(record);
        true
    }
}

/// Data blocks per format index, and the count of reader problems.
fn blocks(bytes: &[u8]) -> (Vec<u8>, usize) {
    let mut reader = LogReader::new();
    let mut indices = Vec::new();
    let mut problems = 0;
    read_slice(&mut reader, bytes, |event| match event {
        Event::Record {
            record: Record::DataBlock { index, .. },
            ..
        } => indices.push(index),
        Event::Problem(p)
            if !matches!(p.kind, crate::logfmt::reader::ProblemKind::NotClosedCleanly) =>
        {
            problems += 1
        }
        _ => {}
    });
    (indices, problems)
}

fn cx(health: &HealthBoard, now_ns: u64) -> TaskContext<'_> {
    TaskContext {
        now_ns,
        frame: now_ns / (10 * MS),
        task: 0,
        health,
        log_time_origin_ns: 0,
    }
}

fn at_rest(counter: u8, t_ns: u64) -> ImuSample {
    ImuSample {
        counter,
        received_ns: t_ns,
        measurement: ImuMeasurement {
            rate_radps: [0.001, -0.002, 0.0005],
            specific_force_mps2: [0.0, 0.0, -9.80665],
            ..Default::default()
        },
    }
}

fn fix(t_ns: u64) -> GpsFix {
    GpsFix {
        received_ns: t_ns,
        valid: true,
        latitude_deg: Some(46.5),
        longitude_deg: Some(6.6),
        altitude_msl_m: Some(400.0),
        velocity_ned_mps: [Some(0.0), Some(0.0), Some(0.0)],
        ..Default::default()
    }
}

fn quick_config() -> EstimatorConfig {
    EstimatorConfig {
        alignment: AlignmentConfig {
            samples: 100,
            ..Default::default()
        },
        heading: HeadingSource::Configured { yaw_rad: 0.5 },
        ..Default::default()
    }
}

#[test]
fn estimator_task_aligns_publishes_and_logs() {
    let (imu, gps, horizon, out) = (
        LatestSlot::new(),
        LatestSlot::new(),
        LatestSlot::new(),
        LatestSlot::<Estimate>::new(),
    );
    let bytes = RefCell::new(Vec::new());
    let health = HealthBoard::new(1);
    let mut task = EstimatorTask::new(
        quick_config(),
        Capture(&bytes),
        &imu,
        &gps,
        Some(&horizon),
        &out,
    );
    task.init(&mut cx(&health, 0)).expect("init");
    let mut seen_aligning = false;
    for k in 1..=400u64 {
        let t = k * 10 * MS;
        imu.publish(at_rest(k as u8, t));
        if k % 10 == 0 {
            gps.publish(fix(t));
        }
        if k % 50 == 0 && k > 200 {
            // Level, from an image taken 300 ms ago.
            horizon.publish(HorizonAttitude {
                roll_rad: 0.0,
                pitch_rad: 0.0,
                confidence: 0.8,
                capture_t_ns: t - 300 * MS,
            });
        }
        task.step(&mut cx(&health, t)).expect("step");
        let e = out.peek().expect("published");
        if k < 100 {
            seen_aligning |= e.health.phase == Phase::Aligning && !e.health.healthy;
        }
    }
    assert!(seen_aligning);
    let e = out.peek().expect("published");
    assert!(e.health.healthy, "{:?}", e.health.reason);
    assert!((e.yaw_rad - 0.5).abs() < 0.01);
    assert!(e.roll_rad.abs() < 0.01 && e.pitch_rad.abs() < 0.01);
    assert!((e.gyro_bias_radps[0] - 0.001).abs() < 2e-4);
    assert_eq!(e.health.counters.horizon_accepted, 4);

    // The IMU falls silent: after 5 steps the estimate says so.
    for k in 401..=410u64 {
        task.step(&mut cx(&health, k * 10 * MS)).expect("step");
    }
    let e = out.peek().expect("published");
    assert_eq!(
        (e.health.healthy, e.health.reason),
        (false, HealthReason::NoImu)
    );
    assert_eq!(task.imu_missed(), 10);
    task.shutdown(&mut cx(&health, 4_200 * MS));

    let (indices, problems) = blocks(&bytes.borrow());
    assert_eq!(problems, 0);
    let count = |i: u8| indices.iter().filter(|&&x| x == i).count();
    assert_eq!(count(STATE_INDEX), 410);
    assert_eq!(count(SD_INDEX), 410);
    // Once a second, plus the changes: aligning → running/reconverging… → ok → no IMU.
    assert!(
        (5..=10).contains(&count(HEALTH_INDEX)),
        "{}",
        count(HEALTH_INDEX)
    );
    assert_eq!(health.log_dropped(0), 0);
}

fn pilot(mode: ControlMode, aileron_us: u16, t_ns: u64) -> PilotInput {
    let report = PilotReport {
        pilot_us: [aileron_us, 1500, 1500, 1500, 1500, 1500, 1500, 1500],
        switch_us: if mode == ControlMode::Auto {
            1900
        } else {
            1100
        },
        logic_battery_v: 12.0,
        servo_battery_v: 6.0,
        status: BoardStatus(0),
    };
    PilotInput {
        sticks: super::servo::sticks_of(&report),
        mode: report.requested_mode(),
        report,
        received_ns: t_ns,
    }
}

fn healthy_estimate(t_ns: u64, healthy: bool) -> Estimate {
    let mut e = crate::estimation::Estimator::new(quick_config()).estimate();
    e.t_ns = t_ns;
    e.velocity_ned_mps = [25.0, 0.0, 0.0];
    e.position_ned_m = [0.0, 0.0, -100.0];
    e.health.healthy = healthy;
    e.health.reason = if healthy {
        HealthReason::Ok
    } else {
        HealthReason::NoGps
    };
    e
}

/// What a control task is built on: its input and output slots, the parameter table with
/// the `control.*` parameters defined, a health board and its log's bytes.
struct ControlBench {
    estimate: LatestSlot<Estimate>,
    pilot_slot: LatestSlot<PilotInput>,
    requested: LatestSlot<FlightMode>,
    out: LatestSlot<ComputerCommand>,
    params: RefCell<ParamTable>,
    health: HealthBoard,
    bytes: RefCell<Vec<u8>>,
}

impl ControlBench {
    fn new() -> Self {
        let mut table = ParamTable::new();
        define_params(&mut table, &ControlSettings::default()).expect("fits");
        Self {
            estimate: LatestSlot::new(),
            pilot_slot: LatestSlot::new(),
            requested: LatestSlot::new(),
            out: LatestSlot::new(),
            params: RefCell::new(table),
            health: HealthBoard::new(1),
            bytes: RefCell::new(Vec::new()),
        }
    }

    /// The task with the default settings, initialised at time 0.
    fn task<'a>(&'a self, mission: Option<&'a Mission>) -> ControlTask<'a, Capture<'a>> {
        let mut task = ControlTask::new(
            ControlSettings::default(),
            Capture(&self.bytes),
            &self.estimate,
            &self.pilot_slot,
            &self.requested,
            mission,
            &self.params,
            &self.out,
        );
        task.init(&mut cx(&self.health, 0)).expect("init");
        task
    }
}

#[test]
fn control_task_modes_gains_and_logs() {
    let bench = ControlBench::new();
    let ControlBench {
        estimate,
        pilot_slot,
        requested,
        out,
        params,
        health,
        bytes,
    } = &bench;
    let mut task = bench.task(None);
    let clock = core::cell::Cell::new(0u64);
    let step = |task: &mut ControlTask<'_, Capture<'_>>| {
        clock.set(clock.get() + 20 * MS);
        task.step(&mut cx(health, clock.get())).expect("step");
        (
            out.peek().expect("published"),
            *task.last_step().expect("ran"),
        )
    };

    // No pilot report: manual, not ready.
    estimate.publish(healthy_estimate(20 * MS, true));
    let (c, s) = step(&mut task);
    assert_eq!(
        (c.ready, s.decision.reason),
        (false, ModeReason::NoPilotReport)
    );

    // Switch on auto, nothing requested: stabilise. Right stick → right roll command.
    pilot_slot.publish(pilot(ControlMode::Auto, 1900, 40 * MS));
    estimate.publish(healthy_estimate(40 * MS, true));
    let (c, s) = step(&mut task);
    assert_eq!(s.decision.mode, FlightMode::Stabilise);
    assert!(c.ready && c.controls.aileron > 0.0, "{c:?}");
    assert!(s.targets.roll_rad > 0.2);

    // Auto without a mission: holds, ready.
    requested.publish(FlightMode::Auto);
    estimate.publish(healthy_estimate(60 * MS, true));
    let (c, s) = step(&mut task);
    assert_eq!(
        (s.decision.mode, s.decision.reason, c.ready),
        (FlightMode::Auto, ModeReason::AutoWithoutMission, true)
    );
    assert!((s.targets.altitude_m - 100.0).abs() < 1e-3);

    // The estimator turns unhealthy: manual at once, and says why.
    estimate.publish(healthy_estimate(80 * MS, false));
    let (c, s) = step(&mut task);
    assert_eq!(
        (s.decision.mode, s.decision.reason, c.ready),
        (FlightMode::Manual, ModeReason::EstimatorUnhealthy, false)
    );

    // A stale estimate counts as unhealthy too.
    estimate.publish(healthy_estimate(80 * MS, true));
    clock.set(clock.get() + 200 * MS);
    pilot_slot.publish(pilot(ControlMode::Auto, 1500, clock.get()));
    let (c, s) = step(&mut task);
    let t = clock.get();
    assert_eq!(
        (s.decision.reason, c.ready),
        (ModeReason::EstimatorUnhealthy, false)
    );

    // The pilot's switch wins, whatever was requested: sticks pass through.
    estimate.publish(healthy_estimate(t + 20 * MS, true));
    pilot_slot.publish(pilot(ControlMode::Manual, 1100, t + 20 * MS));
    let (c, s) = step(&mut task);
    assert_eq!(
        (s.decision.reason, c.ready),
        (ModeReason::PilotSwitch, false)
    );
    assert!(c.controls.aileron < -0.5);

    // A gain changes over the link: applied and logged once.
    let name = Name::new("control.roll_kp").expect("name");
    params.borrow_mut().set(&name, Value::F32(2.5));
    step(&mut task);
    assert_eq!(task.settings().gains.roll.kp, 2.5);
    step(&mut task);
    // The table busy in another task's hands: no panic, gains kept.
    {
        let _held = params.borrow_mut();
        step(&mut task);
    }
    assert_eq!(task.settings().gains.roll.kp, 2.5);
    task.shutdown(&mut cx(health, 10_000 * MS));
    assert_eq!(out.peek(), Some(ComputerCommand::default()));

    let (indices, problems) = blocks(&bytes.borrow());
    assert_eq!(problems, 0);
    let count = |i: u8| indices.iter().filter(|&&x| x == i).count();
    assert_eq!(count(CONTROL_INDEX), 9);
    assert_eq!(count(GAINS_INDEX), 2, "initial gains + one change");
    let _ = Controls::default();
}

#[test]
fn control_task_flies_the_mission_in_auto() {
    let bench = ControlBench::new();
    let mission = Mission::new(&[Waypoint {
        north_m: 0.0,
        east_m: 1000.0,
        altitude_m: 120.0,
        airspeed_mps: 22.0,
    }])
    .expect("fits");
    let mut task = bench.task(Some(&mission));
    bench.requested.publish(FlightMode::Auto);
    bench
        .pilot_slot
        .publish(pilot(ControlMode::Auto, 1500, 20 * MS));
    bench.estimate.publish(healthy_estimate(20 * MS, true));
    task.step(&mut cx(&bench.health, 20 * MS)).expect("step");
    let s = *task.last_step().expect("ran");
    assert_eq!(
        (s.decision.mode, s.decision.reason, s.waypoint),
        (FlightMode::Auto, ModeReason::Requested, 0)
    );
    // The waypoint is east of a north-flying airplane: turn right, climb, 22 m/s.
    assert!(s.targets.roll_rad > 0.0 && s.command.controls.aileron > 0.0);
    assert!((s.targets.course_rad - core::f32::consts::FRAC_PI_2).abs() < 1e-3);
    assert_eq!(
        (s.targets.altitude_m, s.targets.airspeed_mps),
        (120.0, 22.0)
    );
    assert!(s.command.ready);
}

#[test]
fn control_task_flies_a_mission_put_in_force_in_flight() {
    use crate::control::mission_store::MissionStore;
    let bench = ControlBench::new();
    let wp = |n: f32, e: f32, alt: f32, v: f32| Waypoint {
        north_m: n,
        east_m: e,
        altitude_m: alt,
        airspeed_mps: v,
    };
    let first = Mission::new(&[wp(0.0, 1000.0, 120.0, 22.0)]).expect("fits");
    let store = RefCell::new(MissionStore::new(Some(&first)));
    let mut task = bench.task(None).flying_missions_from(&store);
    bench.requested.publish(FlightMode::Auto);
    let mut t = 0;
    let mut step = |task: &mut ControlTask<'_, Capture<'_>>| {
        t += 20 * MS;
        bench.pilot_slot.publish(pilot(ControlMode::Auto, 1500, t));
        bench.estimate.publish(healthy_estimate(t, true));
        task.step(&mut cx(&bench.health, t)).expect("step");
        *task.last_step().expect("ran")
    };
    // The store's mission at start: east, 120 m, 22 m/s.
    let s = step(&mut task);
    assert_eq!((s.decision.mode, s.waypoint), (FlightMode::Auto, 0));
    assert!((s.targets.course_rad - core::f32::consts::FRAC_PI_2).abs() < 1e-3);
    assert_eq!(
        (s.targets.altitude_m, s.targets.airspeed_mps),
        (120.0, 22.0)
    );
    // A new mission in flight: west, then south; flown from its first waypoint.
    {
        let mut st = store.borrow_mut();
        st.stage(0, 2, wp(0.0, -1000.0, 200.0, 27.0))
            .expect("item 0");
        st.stage(1, 2, wp(-1000.0, 0.0, 300.0, 30.0))
            .expect("item 1");
        st.commit(2, 30.0, 150.0, true).expect("commit");
    }
    let s = step(&mut task);
    assert_eq!(s.waypoint, 0);
    assert!((s.targets.course_rad + core::f32::consts::FRAC_PI_2).abs() < 1e-3);
    assert_eq!(
        (s.targets.altitude_m, s.targets.airspeed_mps),
        (200.0, 27.0)
    );
    // Set current: the second waypoint, south.
    store.borrow_mut().set_current(1).expect("exists");
    let s = step(&mut task);
    assert_eq!(s.waypoint, 1);
    assert!((s.targets.course_rad.abs() - core::f32::consts::PI).abs() < 1e-3);
    assert_eq!(
        (s.targets.altitude_m, s.targets.airspeed_mps),
        (300.0, 30.0)
    );
    // While the store is busy, the mission of the last step.
    {
        let _busy = store.borrow_mut();
        let s = step(&mut task);
        assert_eq!((s.waypoint, s.targets.altitude_m), (1, 300.0));
    }
    // Cleared: no mission, so AUTO is not flown on a mission (no waypoint).
    store.borrow_mut().clear();
    let s = step(&mut task);
    assert_eq!(s.waypoint, u8::MAX);
}

/// An IMU that falls silent for 2 s and comes back with its frame counter one on (it did not
/// count while its link was down, as the simulated one does): the receive times tell the
/// task the outage, and the filter bridges it instead of taking it for one 10 ms frame.
/// The filter's clock then stands at the new sample, its tilt σ has grown by the outage
/// (0.05 rad/s × 1.99 s on top of what it had), and the estimate waits for the GPS to
/// narrow it and agree before it is healthy again.
#[test]
fn an_imu_outage_the_counter_missed_is_timed_by_the_receive_times() {
    let (imu, gps, out) = (
        LatestSlot::new(),
        LatestSlot::new(),
        LatestSlot::<Estimate>::new(),
    );
    let bytes = RefCell::new(Vec::new());
    let health = HealthBoard::new(1);
    let mut task = EstimatorTask::new(quick_config(), Capture(&bytes), &imu, &gps, None, &out);
    task.init(&mut cx(&health, 0)).expect("init");
    let step = |task: &mut EstimatorTask<'_, Capture<'_>>, counter: u8, t: u64| {
        imu.publish(at_rest(counter, t));
        if (t / (10 * MS)) % 10 == 0 {
            gps.publish(fix(t));
        }
        task.step(&mut cx(&health, t)).expect("step");
    };
    for k in 1..=400u64 {
        step(&mut task, k as u8, k * 10 * MS);
    }
    assert!(out.peek().expect("estimate").health.healthy);
    let tilt_sd = |task: &EstimatorTask<'_, Capture<'_>>| {
        let p = task.estimator().ekf().expect("running").covariance();
        p[(6, 6)].sqrt()
    };
    let before = tilt_sd(&task);
    // 200 frames of silence; the next frame's counter follows the last one's.
    let resumed_ns = 600 * 10 * MS;
    for k in 401..600u64 {
        task.step(&mut cx(&health, k * 10 * MS)).expect("step");
    }
    step(&mut task, (400 + 1) as u8, resumed_ns);
    let ekf = task.estimator().ekf().expect("running");
    assert_eq!(ekf.time_ns(), resumed_ns);
    assert_eq!(ekf.counters().imu_rejected, 0);
    let grown = tilt_sd(&task);
    let added = ekf.config().gap_rate_sd_radps * 1.99;
    assert!(
        (grown - (before * before + added * added).sqrt()).abs() < 0.01,
        "tilt σ {grown} after {before}"
    );
    // 5.7° of tilt σ: beyond the 5° the estimate may be healthy with.
    let e = out.peek().expect("estimate");
    assert_eq!(
        (e.health.healthy, e.health.reason),
        (false, HealthReason::AttitudeUncertain)
    );
    let mut reasons = Vec::new();
    for k in 601..=900u64 {
        step(&mut task, k as u8, k * 10 * MS);
        let reason = out.peek().expect("estimate").health.reason;
        if reasons.last() != Some(&reason) {
            reasons.push(reason);
        }
    }
    // The GPS narrows the tilt, then ten accepted fixes, then healthy.
    assert_eq!(
        reasons,
        [
            HealthReason::AttitudeUncertain,
            HealthReason::ReconvergingAfterReset,
            HealthReason::Ok
        ]
    );
}
