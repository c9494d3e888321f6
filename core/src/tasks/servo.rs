//! The servo task: the seed's order — computer commands out first, then the board's report
//! of the pilot's sticks, switch and batteries in (thesis §4.3.2). Publishes the pilot's
//! report for the controller, logs both directions (`docs/log-streams.md`, `servo.bin`).
//!
//! Until a controller publishes commands, the task still sends a frame every step, with
//! `autopilot_ready` clear: the board keeps the pilot in control and knows the computer is
//! alive.

use super::device_status::DeviceStatusLog;
use super::task_log::TaskLog;
use crate::comm::{LatestSlot, SlotReader};
use crate::control::controls::{ComputerCommand, Controls};
use crate::devices::DecoderStats;
use crate::devices::port::{CommandWriter, drain};
use crate::devices::servo::{
    ChannelCommand, ControlMode, PILOT_CHANNELS, PilotFrame, PilotReport, ServoCommand,
    ServoDecoder, pulse_us_to_surface, pulse_us_to_throttle,
};
use crate::executive::{Task, TaskContext, TaskFault};
use crate::logfmt::RecordSink;
use embedded_io::{Read, ReadReady, Write, WriteReady};

crate::log_record! {
    /// Each pilot report from the servo board (format 1).
    pub struct ServoPilotLog {
        counter: u8 = "%hhu",
        ch1_us: u16 = "%hu",
        ch2_us: u16 = "%hu",
        ch3_us: u16 = "%hu",
        ch4_us: u16 = "%hu",
        ch5_us: u16 = "%hu",
        ch6_us: u16 = "%hu",
        ch7_us: u16 = "%hu",
        ch8_us: u16 = "%hu",
        auto: bool = "%hhu",
        aileron: f32 = "%.3f",
        elevator: f32 = "%.3f",
        throttle: f32 = "%.3f",
        rudder: f32 = "%.3f",
        batt_avionics_v: f32 = "%.3f",
        batt_servo_v: f32 = "%.3f",
    }
}
crate::log_record! {
    /// Each command sent to the servo board (format 2).
    pub struct ServoCommandLog {
        ready: bool = "%hhu",
        aileron_cmd: f32 = "%.3f",
        elevator_cmd: f32 = "%.3f",
        throttle_cmd: f32 = "%.3f",
        rudder_cmd: f32 = "%.3f",
    }
}
pub const PILOT_INDEX: u8 = 1;
pub const COMMAND_INDEX: u8 = 2;
pub const STATUS_INDEX: u8 = 3;

/// Receiver channels of the four controls: the airframe's wiring (Futaba order: 1 aileron,
/// 2 elevator, 3 throttle, 4 rudder). Channels 5–8 are passed through unchanged.
pub const AILERON_CHANNEL: usize = 0;
pub const ELEVATOR_CHANNEL: usize = 1;
pub const THROTTLE_CHANNEL: usize = 2;
pub const RUDDER_CHANNEL: usize = 3;

pub const MAX_BYTES_PER_STEP: usize = 512;

/// The pilot's side as the board reported it, in the controls' units.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PilotInput {
    pub report: PilotReport,
    pub received_ns: u64,
    pub sticks: Controls,
    pub mode: ControlMode,
}

pub fn sticks_of(report: &PilotReport) -> Controls {
    let ch = |i: usize| report.pilot_us.get(i).copied().unwrap_or(0);
    Controls {
        aileron: pulse_us_to_surface(ch(AILERON_CHANNEL)),
        elevator: pulse_us_to_surface(ch(ELEVATOR_CHANNEL)),
        throttle: pulse_us_to_throttle(ch(THROTTLE_CHANNEL)),
        rudder: pulse_us_to_surface(ch(RUDDER_CHANNEL)),
    }
}

/// The channel commands for `command`, with the pilot's last channels 5–8 passed through.
fn channels(
    command: &ComputerCommand,
    pilot: Option<&PilotReport>,
) -> [ChannelCommand; PILOT_CHANNELS] {
    let c = command.controls;
    let mut out = [ChannelCommand::Surface(0.0); PILOT_CHANNELS];
    for (i, slot) in out.iter_mut().enumerate() {
        *slot = match i {
            AILERON_CHANNEL => ChannelCommand::Surface(c.aileron),
            ELEVATOR_CHANNEL => ChannelCommand::Surface(c.elevator),
            THROTTLE_CHANNEL => ChannelCommand::Throttle(c.throttle),
            RUDDER_CHANNEL => ChannelCommand::Surface(c.rudder),
            other => ChannelCommand::Surface(
                pilot
                    .and_then(|p| p.pilot_us.get(other).copied())
                    .map_or(0.0, pulse_us_to_surface),
            ),
        };
    }
    out
}

pub struct ServoTask<'a, P, S: RecordSink> {
    port: P,
    decoder: ServoDecoder,
    writer: CommandWriter,
    log: TaskLog<S>,
    status: DeviceStatusLog,
    commands: SlotReader<'a, ComputerCommand>,
    pilot: &'a LatestSlot<PilotInput>,
    last_pilot: Option<PilotReport>,
}

impl<'a, P, S> ServoTask<'a, P, S>
where
    P: Read + ReadReady + Write + WriteReady,
    S: RecordSink,
{
    pub fn new(
        port: P,
        log: S,
        stale_timeout_ns: u64,
        commands: &'a LatestSlot<ComputerCommand>,
        pilot: &'a LatestSlot<PilotInput>,
    ) -> Self {
        Self {
            port,
            decoder: ServoDecoder::new(stale_timeout_ns),
            writer: CommandWriter::new(),
            log: TaskLog::new(log),
            status: DeviceStatusLog::new(STATUS_INDEX),
            commands: commands.reader(),
            pilot,
            last_pilot: None,
        }
    }

    pub fn stats(&self) -> &DecoderStats {
        self.decoder.stats()
    }

    fn send_command(&mut self, cx: &TaskContext<'_>) -> Result<(), TaskFault> {
        let command = self.commands.read().map(|l| l.value).unwrap_or_default();
        let frame = ServoCommand::from_channels(
            channels(&command, self.last_pilot.as_ref()),
            command.ready,
        );
        self.writer.submit_servo_command(&frame);
        let c = command.controls;
        let record = ServoCommandLog {
            ready: command.ready,
            aileron_cmd: c.aileron,
            elevator_cmd: c.elevator,
            throttle_cmd: c.throttle,
            rudder_cmd: c.rudder,
        };
        self.log.log(cx, COMMAND_INDEX, &record);
        self.writer
            .poll(&mut self.port)
            .map_err(|_| TaskFault::new("servo port error"))
    }
}

impl<P, S> Task for ServoTask<'_, P, S>
where
    P: Read + ReadReady + Write + WriteReady,
    S: RecordSink,
{
    fn init(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        self.status
            .open(&mut self.log, cx, "servo log format", |log| {
                log.declare::<ServoPilotLog>(cx, PILOT_INDEX)?;
                log.declare::<ServoCommandLog>(cx, COMMAND_INDEX)
            })
    }

    fn step(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        let cx = &*cx;
        self.send_command(cx)?;
        let Self {
            port,
            decoder,
            log,
            pilot,
            last_pilot,
            ..
        } = self;
        let drained = drain(
            port,
            decoder,
            cx.now_ns,
            MAX_BYTES_PER_STEP,
            &mut |frame: PilotFrame| {
                let report = frame.report;
                let sticks = sticks_of(&report);
                let mode = report.requested_mode();
                *last_pilot = Some(report);
                pilot.publish(PilotInput {
                    report,
                    received_ns: frame.received_ns,
                    sticks,
                    mode,
                });
                // Constant indices into `[u16; 8]`: checked when compiled, no panic path.
                let ch = report.pilot_us;
                let record = ServoPilotLog {
                    counter: frame.counter,
                    ch1_us: ch[0],
                    ch2_us: ch[1],
                    ch3_us: ch[2],
                    ch4_us: ch[3],
                    ch5_us: ch[4],
                    ch6_us: ch[5],
                    ch7_us: ch[6],
                    ch8_us: ch[7],
                    auto: mode == ControlMode::Auto,
                    aileron: sticks.aileron,
                    elevator: sticks.elevator,
                    throttle: sticks.throttle,
                    rudder: sticks.rudder,
                    batt_avionics_v: report.logic_battery_v,
                    batt_servo_v: report.servo_battery_v,
                };
                log.log(cx, PILOT_INDEX, &record);
            },
        );
        self.status.after_step(
            &mut self.log,
            cx,
            &self.decoder,
            drained,
            "servo port error",
        )
    }

    fn recover(&mut self, cx: &mut TaskContext<'_>) {
        self.status.close(&mut self.log, cx, &self.decoder);
    }

    fn shutdown(&mut self, cx: &mut TaskContext<'_>) {
        // Last words to the board: hand the airplane back to the pilot.
        let frame = ServoCommand::from_channels(
            channels(&ComputerCommand::default(), self.last_pilot.as_ref()),
            false,
        );
        self.writer.submit_servo_command(&frame);
        let _ = self.writer.poll(&mut self.port);
        self.recover(cx);
    }
}
