//! The `skyframe` command line, shared by every platform's binary.
//!
//! Exit codes: 0 success; 1 the thing checked or run failed (infeasible schedule, executive
//! refused to start); 2 bad usage or unreadable input (clap uses 2 as well).

use crate::bench;
use crate::check_schedule::check_file;
use crate::flight::{Devices, FlightPlan, FlightReport, LinkPlan, LogSettings, fly, render_flight};
use crate::host::{RunOptions, TimerCheckConfig, stop_on_signals};
use crate::platform::{Platform, RtConfig};
use crate::simflight::VirtualTime;
use crate::vehicle::VehicleConfig;
use clap::{Args, Parser, Subcommand};
use skyframe_core::executive::{FaultPlan, OverrunInjection};
use skyframe_core::schedule::analysis::renamed_task;
use skyframe_core::schedule::{FrameTable, SHIPPED};
use skyframe_sim::plant::PlantKind;
use skyframe_sim::scenario::{FaultKind, Scenario};
use skyframe_sim::world::SimWorld;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

#[derive(Parser, Debug)]
#[command(
    name = "skyframe",
    version,
    about = "Flight software for small research UAVs: a static-schedule executive, its \
             simulator and its tools",
    after_help = "The frame table is compiled in from schedule.toml; `skyframe check-schedule` \
                  shows it."
)]
pub struct Cli {
    /// Say more on stderr (info-level messages).
    #[arg(short, long, global = true)]
    pub verbose: bool,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Fly the simulated airplane: the whole on-board system against simulated devices.
    Sim(SimArgs),
    /// Fly the executive with no devices (idle tasks but the watchdog and the health snapshots): the
    /// schedule, its timing and its logs alone.
    Idle(IdleArgs),
    /// Fly the real airplane: devices on the serial ports `--vehicle` names.
    Run(RunArgs),
    /// Validate a schedule file and print its frame table, load and slack.
    CheckSchedule {
        /// The schedule to check.
        #[arg(default_value = "schedule.toml")]
        file: PathBuf,
    },
    /// Measure the executive's wake-up latency and overhead against a bare timer loop.
    Bench(BenchArgs),
    /// Score a simulated flight's logs against its ground truth again (what `sim --score`
    /// prints), e.g. after the scoring changed or for a flight flown without `--score`.
    Score(ScoreArgs),
    /// Hours of virtual flight with a scenario's faults on a loop (default: every fault of
    /// scenarios/faults.toml): memory and open files must stay flat and the counters agree.
    /// Exit 1 when a check fails.
    Soak(SoakArgs),
    /// Run skyframe's estimator over a real flight log (PX4 .ulg, ArduPilot .bin) through the
    /// shipped frame table and compare it with the onboard estimate in the same log
    /// (agreement, not accuracy: the onboard estimator is not truth). docs/replay.md.
    Replay(ReplayArgs),
}

#[derive(Args, Debug)]
pub struct ReplayArgs {
    /// The flight log: PX4 ULog (.ulg) or ArduPilot DataFlash (.bin), told apart by content.
    pub log: PathBuf,
    /// Print the report as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Write figures (attitude.png, attitude_difference.png) into this directory.
    #[arg(long, value_name = "DIR")]
    pub plot: Option<PathBuf>,
    /// How the estimator starts: its own alignment, or a warm start from the onboard
    /// attitude at launch when the log never rests for 10 s (auto).
    #[arg(long, value_enum, default_value = "auto")]
    pub start: crate::replay::StartMode,
    /// The GPS latency the estimator assumes, in ms, 0..=2000 (default: its configuration's).
    #[arg(long, value_name = "MS", value_parser = parse_latency_ms)]
    pub gps_latency_ms: Option<f64>,
}

#[derive(Args, Debug, Clone)]
pub struct RealtimeArgs {
    /// SCHED_FIFO priority of the executive thread (1-99); 0 keeps the default scheduler.
    #[arg(long, default_value_t = 80, value_parser = clap::value_parser!(u8).range(0..=99))]
    pub priority: u8,
    /// Pin the executive thread to this CPU (0..=1023).
    #[arg(long, value_parser = clap::value_parser!(u16).range(0..=1023))]
    pub cpu: Option<u16>,
    /// Do not lock memory with mlockall.
    #[arg(long)]
    pub no_mlockall: bool,
    /// Let CPUs enter deep idle states between frames (by default skyframe holds
    /// /dev/cpu_dma_latency at 0 us during the run).
    #[arg(long)]
    pub allow_deep_idle: bool,
    /// QNX only: the system clock period (tick) to ask for, in microseconds; the longest
    /// period at most this long that divides the minor frame is set. 0 leaves the system's
    /// (1 ms by default, which quantises every wake-up). Linux has no tick and ignores it.
    /// 0..=1000000.
    #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u64).range(0..=1_000_000))]
    pub clock_period_us: u64,
}

impl RealtimeArgs {
    pub fn config(&self) -> RtConfig {
        RtConfig {
            fifo_priority: (self.priority > 0).then_some(self.priority),
            lock_memory: !self.no_mlockall,
            cpu: self.cpu.map(usize::from),
            cpu_dma_latency_us: (!self.allow_deep_idle).then_some(0),
            clock_period_ns: (self.clock_period_us > 0)
                .then(|| self.clock_period_us.saturating_mul(1000)),
            ..RtConfig::default()
        }
    }
}

/// What every flight takes (`sim` and `run`).
#[derive(Args, Debug)]
pub struct FlightArgs {
    /// How long to fly, in seconds (0..=10000000, about 115 days).
    #[arg(long, value_parser = parse_flight_seconds)]
    pub duration: Option<f64>,
    /// Make a task overrun on purpose: TASK:EXTRA_US@FROM..TO (minor frames since start),
    /// e.g. imu:12000@100..110; EXTRA_US 1..=10000000 (10 s), FROM < TO <= 1000000000.
    /// Repeatable.
    #[arg(long = "inject-overrun", value_name = "SPEC", value_parser = parse_injection)]
    pub inject_overrun: Vec<Injection>,
    /// Print the end-of-run summary as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Where flights are logged: each run writes into a new subdirectory named by its start
    /// time (UTC). Default: `flights`, or `[log] dir` of the vehicle file.
    #[arg(long)]
    pub log_dir: Option<PathBuf>,
    /// Waypoints the autopilot flies in AUTO (then it loiters); without a mission AUTO holds
    /// altitude, heading and airspeed.
    #[arg(long, value_name = "FILE")]
    pub mission: Option<PathBuf>,
    /// Write this stream as CSV text instead of binary: one of the flight's streams
    /// (`executive`, `health`, `watchdog`, `link`, `imu`, `gps`, `servo`, `estimator`,
    /// `control`, `truth`; `docs/log-streams.md`); a name the flight does not write is an
    /// error. Repeatable.
    #[arg(long = "text-log", value_name = "STREAM")]
    pub text_log: Vec<String>,
    /// Milliseconds of timer measurement before the first frame (0 skips the check;
    /// at most 10000).
    #[arg(long, default_value_t = 200, value_parser = clap::value_parser!(u64).range(0..=10_000))]
    pub timer_check_ms: u64,
    /// Refuse to fly when the log's disk has less free space than the flight is expected to
    /// log (about 46 kB/s for the whole programmed duration); default: warn and fly.
    #[arg(long)]
    pub require_log_space: bool,
    /// Refuse to fly when the timer check finds wake-ups later than the frame margin
    /// (default: warn and fly).
    #[arg(long)]
    pub refuse_late_timer: bool,

    /// Set a flight-computer parameter before the flight, as the ground's `set` would (same
    /// names and ranges; `skyframe-ground params` lists them): NAME=VALUE, repeatable. A
    /// scenario's `[parameters]` are applied first, these after.
    #[arg(long = "param", value_name = "NAME=VALUE", value_parser = parse_param)]
    pub param: Vec<(String, f64)>,
    #[command(flatten)]
    pub link: LinkArgs,
    #[command(flatten)]
    pub mavlink: MavlinkArgs,
    #[command(flatten)]
    pub realtime: RealtimeArgs,
}

/// The MAVLink 2 endpoint (`docs/mavlink.md`).
#[derive(Args, Debug, Clone)]
pub struct MavlinkArgs {
    /// A MAVLink 2 endpoint: udpout:HOST:PORT (send to a ground station that listens, e.g.
    /// QGroundControl on 14550; answer whoever talks back) or udpin:ADDR:PORT (listen).
    /// Repeatable. Works with or without the skyframe link.
    #[arg(id = "mavlink", long = "mavlink", value_name = "ENDPOINT", value_parser = crate::mavlink::parse_endpoint)]
    pub endpoints: Vec<crate::mavlink::Endpoint>,
    /// MAVLink system id, 1..=255 (default: the vehicle id). Component 1, the autopilot.
    #[arg(id = "mavlink_sysid", long = "mavlink-sysid", value_name = "N", value_parser = clap::value_parser!(u8).range(1..=255))]
    pub system_id: Option<u8>,
    /// MAVLink 2 signing secret (32 bytes: 64 hex digits or raw, mode 600, as --key): then
    /// unsigned, badly signed and replayed messages that change anything are dropped and
    /// counted, and everything sent is signed.
    #[arg(id = "mavlink_key", long = "mavlink-key", value_name = "FILE")]
    pub key: Option<PathBuf>,
}

impl MavlinkArgs {
    pub fn plan(
        &self,
        vehicle_id: u16,
        stop: &Arc<AtomicBool>,
    ) -> Result<Option<crate::mavlink::MavlinkPlan>, String> {
        if self.endpoints.is_empty() {
            if self.system_id.is_some() || self.key.is_some() {
                return Err("--mavlink-sysid and --mavlink-key need --mavlink ENDPOINT".into());
            }
            return Ok(None);
        }
        let system_id = match self.system_id {
            Some(id) => id,
            None => u8::try_from(vehicle_id)
                .ok()
                .filter(|id| *id != 0)
                .ok_or_else(|| {
                    format!(
                        "--mavlink-sysid N is needed: the vehicle id {vehicle_id} is not a MAVLink system id (1..=255)"
                    )
                })?,
        };
        // Read now: a bad key file is refused before anything flies.
        let key = match &self.key {
            Some(path) => Some(crate::mavlink::Secret(crate::mavlink::load_key(path)?)),
            None => None,
        };
        if key.is_none() {
            eprintln!(
                "WARNING: the MAVLink endpoint accepts commands, parameter changes and modes from \
                 anyone who can reach it (no --mavlink-key)"
            );
        }
        Ok(Some(crate::mavlink::MavlinkPlan {
            endpoints: self.endpoints.clone(),
            system_id,
            key,
            stop: Arc::clone(stop),
        }))
    }
}

/// The telemetry link (`docs/link-protocol.md`).
#[derive(Args, Debug, Clone)]
pub struct LinkArgs {
    /// The 32-byte pre-shared key file (64 hex digits, mode 600). Without it a fresh key is
    /// written into the flight directory (and its path printed).
    #[arg(long, value_name = "FILE")]
    pub key: Option<PathBuf>,
    /// Where telemetry goes (unicast or broadcast). Repeatable.
    #[arg(long, value_name = "ADDR:PORT")]
    pub telemetry: Vec<std::net::SocketAddr>,
    /// Where commands are received (telemetry is sent from here too).
    #[arg(long, value_name = "ADDR:PORT")]
    pub commands: Option<std::net::SocketAddr>,
    /// This airplane's id on the link.
    #[arg(long, default_value_t = 1)]
    pub vehicle_id: u16,
    /// Sign telemetry as well as verifying commands.
    #[arg(long)]
    pub sign_telemetry: bool,
    /// Fly without the link.
    #[arg(long)]
    pub no_link: bool,
}

impl LinkArgs {
    /// `mavlink`: a MAVLink endpoint needs the link's rings and thread even with
    /// `--no-link` (then without a socket or key file).
    pub fn plan(&self, mavlink: bool) -> Result<Option<LinkPlan>, String> {
        if self.no_link && mavlink {
            return Ok(Some(LinkPlan {
                key: None,
                commands: std::net::SocketAddr::from(([127, 0, 0, 1], 0)),
                commands_is_default: false,
                telemetry: Vec::new(),
                vehicle_id: self.vehicle_id,
                sign_telemetry: false,
                network: false,
            }));
        }
        if self.no_link {
            return Ok(None);
        }
        let default = |text: &str| text.parse().map_err(|e| format!("{text}: {e}"));
        let telemetry = if self.telemetry.is_empty() {
            vec![default(crate::link::DEFAULT_TELEMETRY)?]
        } else {
            self.telemetry.clone()
        };
        Ok(Some(LinkPlan {
            key: self.key.clone(),
            commands: match self.commands {
                Some(a) => a,
                None => default(crate::link::DEFAULT_COMMANDS)?,
            },
            commands_is_default: self.commands.is_none(),
            telemetry,
            vehicle_id: self.vehicle_id,
            sign_telemetry: self.sign_telemetry,
            network: true,
        }))
    }
}

#[derive(Args, Debug)]
pub struct SimArgs {
    /// The scenario to fly (initial state, wind, pilot timeline, faults). Default: the
    /// take-off, circuit, aerobatics and landing of scenarios/takeoff-circuit.toml.
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// Virtual time: as fast as the machine allows, deterministic for a seed.
    #[arg(long, conflicts_with = "speedup")]
    pub fast: bool,
    /// Virtual time paced at N times real time (1..=1000; ArduPilot SITL's --speedup): a
    /// ground station watches the flight accelerated. The same flight as --fast.
    #[arg(long, value_name = "N", value_parser = parse_speedup)]
    pub speedup: Option<f64>,
    /// Seed of every random process of the simulation (noise, gusts, GPS jitter); default:
    /// the scenario's.
    #[arg(long)]
    pub seed: Option<u64>,
    /// After the flight, score it against the simulator's ground truth: attitude, position
    /// and velocity errors, altitude and heading hold in AUTO, the estimator's step time, and
    /// the `ahrs` Python package's filters on the same IMU data (needs python3 with ahrs).
    #[arg(long)]
    pub score: bool,
    /// With --score: leave out the ahrs reference filters.
    #[arg(long, requires = "score")]
    pub no_reference_filters: bool,
    /// The flight model: `builtin` (our 6-DOF Aerosonde) or `jsbsim` (needs python3 with the
    /// jsbsim package). Default: the scenario's `[plant]`, else builtin.
    #[arg(long, value_name = "builtin|jsbsim")]
    pub plant: Option<String>,
    /// JSBSim's aircraft (`c172x`, `J3Cub`, … or our `skyframe-uav`; alone it implies
    /// `--plant jsbsim`); default: the scenario's, else c172x.
    #[arg(long, value_name = "NAME")]
    pub aircraft: Option<String>,
    #[command(flatten)]
    pub flight: FlightArgs,
}

#[derive(Args, Debug)]
pub struct ScoreArgs {
    /// The flight directory (`flights/<UTC start>/`) of a `skyframe sim` run.
    pub flight_dir: PathBuf,
    /// Print the score as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Leave out the ahrs reference filters.
    #[arg(long)]
    pub no_reference_filters: bool,
}

#[derive(Args, Debug)]
pub struct IdleArgs {
    #[command(flatten)]
    pub flight: FlightArgs,
}

#[derive(Args, Debug)]
pub struct SoakArgs {
    /// Hours of virtual flight (0.01..=100). 10 h takes about 3-4 min and writes about
    /// 1.6 GB of logs (removed once checked unless --keep-logs).
    #[arg(long, default_value_t = 10.0, value_parser = parse_hours)]
    pub hours: f64,
    /// The scenario whose faults are looped (every its duration); default: the faults
    /// scenario (scenarios/faults.toml).
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// Seed of the simulation (default: the scenario's).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Keep the flight's logs.
    #[arg(long)]
    pub keep_logs: bool,
    #[command(flatten)]
    pub flight: FlightArgs,
}

fn parse_latency_ms(text: &str) -> Result<f64, String> {
    number_within(text, 0.0, 2000.0, "milliseconds")
}

fn parse_speedup(text: &str) -> Result<f64, String> {
    let r = crate::speedup::SPEEDUP_RANGE;
    number_within(text, *r.start(), *r.end(), "speedup")
}

fn parse_hours(text: &str) -> Result<f64, String> {
    number_within(text, 0.01, 100.0, "hours")
}

#[derive(Args, Debug)]
pub struct RunArgs {
    /// The vehicle file: device ports and baud rates, log directory.
    #[arg(long, value_name = "FILE")]
    pub vehicle: PathBuf,
    #[command(flatten)]
    pub flight: FlightArgs,
}

#[derive(Subcommand, Debug)]
pub enum BenchWhat {
    /// Decoder throughput (MB/s) of the IMU, servo and GPS protocols, and the `nmea` crate's
    /// on the same GGA/RMC bytes.
    Parsers {
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
        /// Size of each test stream, in megabytes (0.01..=1024).
        #[arg(long, default_value_t = 5.0, value_parser = parse_megabytes)]
        megabytes: f64,
    },
}

#[derive(Args, Debug)]
#[command(args_conflicts_with_subcommands = true)]
pub struct BenchArgs {
    #[command(subcommand)]
    pub what: Option<BenchWhat>,
    /// Seconds for each of the two runs (bare loop, executive): 0.1..=3600.
    #[arg(long, default_value_t = 10.0, value_parser = parse_bench_seconds)]
    pub seconds: f64,
    /// Print one JSON object instead of the text report.
    #[arg(long)]
    pub json: bool,
    /// As for `sim`: TASK:EXTRA_US@FROM..TO. Repeatable.
    #[arg(long = "inject-overrun", value_name = "SPEC", value_parser = parse_injection)]
    pub inject_overrun: Vec<Injection>,
    /// Also run cyclictest (Debian rt-tests) with the same period, priority and CPU, and
    /// print its distribution and the ratios.
    #[arg(long)]
    pub compare_cyclictest: bool,
    #[command(flatten)]
    pub realtime: RealtimeArgs,
}

/// `--inject-overrun` as typed; resolved against the frame table later.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Injection {
    pub task: String,
    pub extra_us: u64,
    pub from_frame: u64,
    pub to_frame: u64,
    /// 0: once; else again every this many frames (`skyframe soak` loops a scenario's).
    pub repeat_every_frames: u64,
}

/// A number within `low..=high`, or a message that says the range.
fn number_within(text: &str, low: f64, high: f64, what: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(x) if (low..=high).contains(&x) => Ok(x),
        Ok(_) => Err(format!(
            "`{text}` is out of range: {what} is {low}..={high}"
        )),
        Err(_) => Err(format!("`{text}` is not a number of {what}")),
    }
}

/// The longest flight: 10⁷ s (about 115 days), past any battery.
pub const MAX_FLIGHT_S: f64 = 1e7;
/// The longest injected overrun: 10 s (a task stuck that long is what the test is about).
pub const MAX_INJECTED_US: u64 = 10_000_000;
/// The last minor frame an injection may name (about 115 days at 10 ms).
pub const MAX_INJECTED_FRAME: u64 = 1_000_000_000;

fn parse_flight_seconds(text: &str) -> Result<f64, String> {
    number_within(text, 0.0, MAX_FLIGHT_S, "seconds")
}

fn parse_bench_seconds(text: &str) -> Result<f64, String> {
    number_within(text, 0.1, 3600.0, "seconds")
}

fn parse_megabytes(text: &str) -> Result<f64, String> {
    number_within(text, 0.01, 1024.0, "megabytes")
}

/// `NAME=VALUE` of `--param`; the name and range are checked against the parameter table
/// when the flight starts.
pub fn parse_param(text: &str) -> Result<(String, f64), String> {
    let (name, value) = text
        .split_once('=')
        .ok_or_else(|| format!("`{text}`: expected NAME=VALUE, e.g. control.roll_kp=1.2"))?;
    let value: f64 = value
        .trim()
        .parse()
        .map_err(|_| format!("`{text}`: the value is not a number"))?;
    if !value.is_finite() {
        return Err(format!("`{text}`: the value is not finite"));
    }
    Ok((name.trim().to_string(), value))
}

pub fn parse_injection(text: &str) -> Result<Injection, String> {
    let bad = || format!("`{text}` is not TASK:EXTRA_US@FROM..TO (e.g. imu:12000@100..110)");
    let (task, rest) = text.split_once(':').ok_or_else(bad)?;
    let (extra, frames) = rest.split_once('@').ok_or_else(bad)?;
    let (from, to) = frames.split_once("..").ok_or_else(bad)?;
    let number = |s: &str| s.trim().parse::<u64>().map_err(|_| bad());
    let injection = Injection {
        task: task.trim().to_string(),
        extra_us: number(extra)?,
        from_frame: number(from)?,
        to_frame: number(to)?,
        repeat_every_frames: 0,
    };
    if injection.task.is_empty() || injection.to_frame <= injection.from_frame {
        return Err(bad());
    }
    check_injection_range(&injection)?;
    Ok(injection)
}

/// The documented ranges (`--help`): an overrun of at most [`MAX_INJECTED_US`] in frames up
/// to [`MAX_INJECTED_FRAME`]. Also applied to a scenario's task-overrun faults.
fn check_injection_range(i: &Injection) -> Result<(), String> {
    if !(1..=MAX_INJECTED_US).contains(&i.extra_us) {
        return Err(format!(
            "--inject-overrun {}: EXTRA_US {} is out of range 1..={MAX_INJECTED_US}",
            i.task, i.extra_us
        ));
    }
    if i.to_frame > MAX_INJECTED_FRAME {
        return Err(format!(
            "--inject-overrun {}: frame {} is past the last one, {MAX_INJECTED_FRAME}",
            i.task, i.to_frame
        ));
    }
    Ok(())
}

/// Turns typed injections into the executive's fault plan, naming the first unknown task.
pub fn fault_plan(table: &FrameTable, injections: &[Injection]) -> Result<FaultPlan, String> {
    let mut plan = FaultPlan::new();
    for i in injections {
        check_injection_range(i)?;
        let renamed = renamed_task(&i.task).filter(|_| table.task_index(&i.task).is_none());
        if let Some(new) = renamed {
            log::warn!(
                "--inject-overrun {}: task `{}` is now called `{new}`",
                i.task,
                i.task
            );
        }
        let name = renamed.unwrap_or(&i.task);
        let task = table.task_index(name).ok_or_else(|| {
            let names: Vec<&str> = table.tasks.iter().map(|t| t.name).collect();
            format!(
                "--inject-overrun: no task `{}` in the schedule ({})",
                i.task,
                names.join(", ")
            )
        })?;
        plan.push(OverrunInjection {
            task,
            extra_ns: i.extra_us.saturating_mul(1000),
            from_frame: i.from_frame,
            to_frame: i.to_frame,
            repeat_every_frames: i.repeat_every_frames,
        })
        .map_err(|_| "--inject-overrun: too many injections (8 at most)".to_string())?;
    }
    Ok(plan)
}

/// Parses the command line and runs it on `platform`.
pub fn main<P: Platform>(platform: P) -> ExitCode {
    let cli = Cli::parse();
    let level = if cli.verbose { "info" } else { "warn" };
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or(level))
        .format_timestamp(None)
        .init();
    match run(&platform, cli.command) {
        Ok(code) => code,
        Err(message) => {
            eprintln!("skyframe: {message}");
            ExitCode::from(2)
        }
    }
}

fn stop_flag() -> Result<Arc<AtomicBool>, String> {
    let stop = Arc::new(AtomicBool::new(false));
    stop_on_signals(&stop).map_err(|e| format!("cannot install signal handlers: {e}"))?;
    Ok(stop)
}

fn run<P: Platform>(platform: &P, command: Command) -> Result<ExitCode, String> {
    match command {
        Command::CheckSchedule { file } => {
            let checked = check_file(&file)?;
            if checked.feasible {
                print!("{}", checked.report);
                Ok(ExitCode::SUCCESS)
            } else {
                eprint!("{}", checked.report);
                Ok(ExitCode::from(1))
            }
        }
        Command::Bench(BenchArgs {
            what: Some(BenchWhat::Parsers { json, megabytes }),
            ..
        }) => {
            let figures = crate::bench_parsers::run(megabytes);
            if json {
                let text = serde_json::to_string_pretty(&figures).map_err(|e| e.to_string())?;
                println!("{text}");
            } else {
                println!(
                    "imu {:.1} MB/s, servo {:.1} MB/s, gps (all sentences) {:.1} MB/s; \
                     GGA/RMC ours {:.1} MB/s vs nmea crate {:.1} MB/s (x{:.2})",
                    figures.imu.mb_per_s,
                    figures.servo.mb_per_s,
                    figures.gps_all_sentences.mb_per_s,
                    figures.gga_rmc.ours_mb_per_s,
                    figures.gga_rmc.nmea_crate_mb_per_s,
                    figures.gga_rmc.ratio
                );
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Bench(args) => {
            let faults = fault_plan(&SHIPPED, &args.inject_overrun)?;
            let stop = stop_flag()?;
            let report = bench::run(
                platform,
                &SHIPPED,
                bench::BenchOptions {
                    seconds: args.seconds,
                    realtime: args.realtime.config(),
                    faults,
                    compare_cyclictest: args.compare_cyclictest,
                    stop: &stop,
                },
            )
            .map_err(|e| format!("bench: {e}"))?;
            if args.json {
                let json = serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?;
                println!("{json}");
            } else {
                print!("{}", bench::render_text(&report));
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Sim(args) => {
            let scenario = match &args.scenario {
                Some(path) => Scenario::load(path),
                None => Scenario::parse(DEFAULT_SCENARIO),
            }
            .map_err(|e| e.to_string())?;
            // --plant and --aircraft override the scenario's `[plant]`; the scenario's
            // aircraft stays only when the plant does; an aircraft other than ours alone
            // means JSBSim.
            let plant_name = match (args.plant.as_deref(), args.aircraft.as_deref()) {
                (Some(plant), _) => plant,
                (None, Some(a)) if a != "aerosonde" => "jsbsim",
                (None, _) => scenario.plant.plant_name(),
            };
            let aircraft = args
                .aircraft
                .as_deref()
                .or((plant_name == scenario.plant.plant_name()
                    && scenario.plant != PlantKind::BuiltIn)
                    .then(|| scenario.plant.aircraft_name()));
            let plant = PlantKind::from_names(plant_name, aircraft)?;
            let world = SimWorld::from_scenario_on(&scenario, args.seed, &plant)
                .map_err(|e| e.to_string())?;
            let mut flight = args.flight;
            flight.duration = flight.duration.or(Some(scenario.duration_s));
            // The scenario's airplane gains first; the command line's win.
            flight.param = scenario
                .parameters
                .iter()
                .cloned()
                .chain(flight.param)
                .collect();
            flight
                .inject_overrun
                .extend(scenario_overruns(&scenario, SHIPPED.minor_frame_ns));
            let log = crate::vehicle::LogConfig::default();
            let devices = Devices::Sim(Box::new(world));
            // Virtual time or not, the log is on this machine's disk.
            let probe = platform.free_space_probe();
            let report = if args.fast {
                // The timer check measures the OS timer, which virtual time does not use.
                flight.timer_check_ms = 0;
                fly_with(&VirtualTime, devices, &flight, &log, probe)?
            } else if let Some(speedup) = args.speedup {
                flight.timer_check_ms = 0;
                let paced = crate::speedup::PacedTime { speedup };
                fly_with(&paced, devices, &flight, &log, probe)?
            } else {
                fly_with(platform, devices, &flight, &log, probe)?
            };
            if !args.score {
                return print_flight(&report, flight.json);
            }
            let score = score_and_keep(&report.flight_dir, !args.no_reference_filters)?;
            if flight.json {
                let mut value = serde_json::to_value(&report).map_err(|e| e.to_string())?;
                if let serde_json::Value::Object(map) = &mut value {
                    map.insert(
                        "score".into(),
                        serde_json::to_value(&score).map_err(|e| e.to_string())?,
                    );
                }
                let text = serde_json::to_string_pretty(&value).map_err(|e| e.to_string())?;
                println!("{text}");
            } else {
                print!("{}", render_flight(&report));
                print!("{}", crate::score::render_score(&score));
            }
            Ok(logging_lost_exit(&report))
        }
        Command::Soak(args) => soak(platform, args),
        Command::Replay(args) => {
            let options = crate::replay::RunOptions {
                start: args.start,
                gps_latency_ms: args.gps_latency_ms,
                gps_velocity_sd_m_s: None,
            };
            let (report, series, _) = crate::replay::replay_file(&args.log, options)?;
            if let Some(dir) = &args.plot {
                let title = args
                    .log
                    .file_name()
                    .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
                for path in crate::replay::plot::write(dir, &title, &series)? {
                    eprintln!("wrote {path}");
                }
            }
            if args.json {
                let text = serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?;
                println!("{text}");
            } else {
                print!("{}", crate::replay::render(&report));
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Score(args) => {
            if !args.flight_dir.is_dir() {
                return Err(format!(
                    "{}: not a flight directory",
                    args.flight_dir.display()
                ));
            }
            let score = score_and_keep(&args.flight_dir, !args.no_reference_filters)?;
            if args.json {
                let text = serde_json::to_string_pretty(&score).map_err(|e| e.to_string())?;
                println!("{text}");
            } else {
                print!("{}", crate::score::render_score(&score));
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Idle(args) => {
            let mut flight = args.flight;
            flight.duration = flight.duration.or(Some(10.0));
            let log = crate::vehicle::LogConfig::default();
            fly_and_report(platform, Devices::None, &flight, &log)
        }
        Command::Run(args) => {
            let vehicle = VehicleConfig::load(&args.vehicle)?;
            fly_and_report(
                platform,
                Devices::Serial(&vehicle),
                &args.flight,
                &vehicle.log,
            )
        }
    }
}

/// The faults scenario, compiled in for `skyframe soak`.
const FAULTS_SCENARIO: &str = include_str!("../../scenarios/faults.toml");

/// `skyframe soak`: see [`crate::soak`].
fn soak<P: Platform>(platform: &P, args: SoakArgs) -> Result<ExitCode, String> {
    use crate::soak;
    let scenario = match &args.scenario {
        Some(path) => Scenario::load(path),
        None => Scenario::parse(FAULTS_SCENARIO),
    }
    .map_err(|e| e.to_string())?;
    if args.flight.duration.is_some() {
        return Err("soak: the flight lasts --hours; --duration is not for soak".into());
    }
    let period_s = scenario.duration_s;
    let duration_s = args.hours * 3600.0;
    let mut world = SimWorld::from_scenario(&scenario, args.seed).map_err(|e| e.to_string())?;
    world.repeat_faults_every(period_s);
    let minor = SHIPPED.minor_frame_ns;
    let period_frames = (period_s * 1e9 / minor as f64).round() as u64;
    let mut flight = args.flight;
    flight.duration = Some(duration_s);
    flight.timer_check_ms = 0;
    flight
        .inject_overrun
        .extend(
            scenario_overruns(&scenario, minor)
                .into_iter()
                .map(|i| Injection {
                    repeat_every_frames: period_frames,
                    ..i
                }),
        );
    let log_dir = flight.log_dir.clone().unwrap_or_else(|| {
        std::env::temp_dir().join(format!("skyframe-soak-{}", std::process::id()))
    });
    flight.log_dir = Some(log_dir);
    // Each silence of a device, once per loop that reached it.
    let loops_reaching = |t_s: f64| -> u64 {
        if t_s >= duration_s {
            0
        } else {
            ((duration_s - t_s) / period_s).ceil() as u64
        }
    };
    let mut expected: Vec<(&str, u64)> = Vec::new();
    for (device, name) in [
        (skyframe_sim::scenario::Device::Imu, "imu"),
        (skyframe_sim::scenario::Device::Gps, "gps"),
    ] {
        let count = scenario
            .faults
            .iter()
            .filter(|f| f.kind == FaultKind::SensorSilence && f.device == Some(device))
            .map(|f| loops_reaching(f.t_s))
            .sum();
        expected.push((name, count));
    }
    let sampler = soak::Sampler::start(Duration::from_secs(1));
    let wall = std::time::Instant::now();
    let log = crate::vehicle::LogConfig::default();
    let probe = platform.free_space_probe();
    let report = fly_with(
        &VirtualTime,
        Devices::Sim(Box::new(world)),
        &flight,
        &log,
        probe,
    )?;
    let samples = sampler.map(soak::Sampler::finish).unwrap_or_default();
    let mut checks = soak::process_checks(&samples);
    checks.extend(soak::counter_checks(&report, duration_s, minor, &expected));
    if !args.keep_logs {
        soak::discard_logs(&report.flight_dir);
    }
    let result = soak::SoakReport {
        virtual_hours: report.summary.elapsed_s / 3600.0,
        wall_s: wall.elapsed().as_secs_f64(),
        fault_period_s: period_s,
        fault_loops: loops_reaching(0.0),
        flight_dir: report.flight_dir.clone(),
        logs_kept: args.keep_logs,
        samples: samples.len(),
        ok: checks.iter().all(|c| c.ok),
        checks,
    };
    if flight.json {
        let text = serde_json::to_string_pretty(&result).map_err(|e| e.to_string())?;
        println!("{text}");
    } else {
        print!("{}", soak::render(&result));
    }
    Ok(if result.ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// The shipped default scenario, compiled in so `skyframe sim` flies from any directory.
const DEFAULT_SCENARIO: &str = include_str!("../../scenarios/takeoff-circuit.toml");

/// A scenario's task overruns as the executive's injections (frames of `minor_frame_ns`).
fn scenario_overruns(scenario: &Scenario, minor_frame_ns: u64) -> Vec<Injection> {
    let frame = |t_s: f64| (t_s * 1e9 / minor_frame_ns as f64).round().max(0.0) as u64;
    scenario
        .faults
        .iter()
        .filter(|f| f.kind == FaultKind::TaskOverrun)
        .filter_map(|f| {
            Some(Injection {
                task: f.task.clone()?,
                extra_us: f.extra_us?,
                from_frame: frame(f.t_s),
                to_frame: frame(f.t_s + f.duration_s).max(frame(f.t_s) + 1),
                repeat_every_frames: 0,
            })
        })
        .collect()
}

/// Flies with `devices`, prints the report; the flight's own failures are exit 1.
fn fly_and_report<P: Platform>(
    platform: &P,
    devices: Devices<'_>,
    args: &FlightArgs,
    log: &crate::vehicle::LogConfig,
) -> Result<ExitCode, String> {
    let report = fly_with(platform, devices, args, log, platform.free_space_probe())?;
    print_flight(&report, args.json)
}

fn print_flight(report: &FlightReport, json: bool) -> Result<ExitCode, String> {
    if json {
        let json = serde_json::to_string_pretty(report).map_err(|e| e.to_string())?;
        println!("{json}");
    } else {
        print!("{}", render_flight(report));
    }
    Ok(logging_lost_exit(report))
}

/// Exit code of a flight that lost log records (a full disk): README, exit codes.
pub const EXIT_LOGGING_LOST: u8 = 3;

/// [`EXIT_LOGGING_LOST`] with one line on stderr saying how much, if any stream lost
/// records to a failed write; success otherwise. (Records a full ring dropped are reported in
/// the summary but are not a logging failure of this kind.)
fn logging_lost_exit(report: &FlightReport) -> ExitCode {
    let lost: Vec<String> = report
        .log_streams
        .iter()
        .filter(|s| s.records_lost > 0 || s.failed)
        .map(|s| format!("{} {} records", s.name, s.records_lost))
        .collect();
    if lost.is_empty() {
        return ExitCode::SUCCESS;
    }
    eprintln!(
        "skyframe: logging was lost (disk full or write errors): {}; flight directory {}",
        lost.join(", "),
        report.flight_dir.display()
    );
    ExitCode::from(EXIT_LOGGING_LOST)
}

/// Scores the flight in `flight_dir` and writes `score.json` beside its logs, so a flight
/// keeps its score.
fn score_and_keep(
    flight_dir: &Path,
    reference_filters: bool,
) -> Result<crate::score::Score, String> {
    let estimator_budget_ns = SHIPPED
        .tasks
        .iter()
        .find(|t| t.name == "estimator")
        .map_or(0, |t| t.budget_ns);
    let score = crate::score::score_flight(&crate::score::ScoreSetup {
        flight_dir,
        estimator_budget_ns,
        reference_filters,
    })
    .map_err(|e| format!("score: {e}"))?;
    let path = flight_dir.join("score.json");
    let text = serde_json::to_string_pretty(&score).map_err(|e| e.to_string())?;
    std::fs::write(&path, text + "\n").map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(score)
}

/// Flies with `devices` and returns the report.
fn fly_with<P: Platform>(
    platform: &P,
    mut devices: Devices<'_>,
    args: &FlightArgs,
    log: &crate::vehicle::LogConfig,
    free_space: Option<crate::platform::FreeSpaceProbe>,
) -> Result<FlightReport, String> {
    let faults = fault_plan(&SHIPPED, &args.inject_overrun)?;
    let stop = stop_flag()?;
    // A simulated airplane lost mid-flight (JSBSim's process died) stops the flight as a
    // signal would, so the tasks shut down and the logs close whole; the flight then ends
    // with the plant's error.
    let airplane_lost: Arc<Mutex<Option<String>>> = Arc::default();
    if let Devices::Sim(world) = &mut devices {
        let (lost, stop) = (Arc::clone(&airplane_lost), Arc::clone(&stop));
        world.on_failure(Box::new(move |e| {
            if let Ok(mut slot) = lost.lock() {
                *slot = Some(e.to_string());
            }
            stop.store(true, Ordering::Relaxed);
        }));
    }
    let mavlink = if matches!(devices, Devices::None) {
        if !args.mavlink.endpoints.is_empty() {
            return Err("--mavlink needs a vehicle: `skyframe sim` or `skyframe run`".into());
        }
        None
    } else {
        args.mavlink.plan(args.link.vehicle_id, &stop)?
    };
    let report = fly(
        platform,
        &SHIPPED,
        FlightPlan {
            log_dir: args.log_dir.as_deref().unwrap_or(&log.dir),
            registry: crate::tasks::REGISTRY,
            parameters: args.param.clone(),
            log: LogSettings {
                free_space,
                require_space: args.require_log_space,
                ..LogSettings::from_config(log, &args.text_log)
            },
            mission: args
                .mission
                .as_deref()
                .map(crate::mission::load)
                .transpose()?,
            link: if matches!(devices, Devices::None) {
                None
            } else {
                args.link.plan(mavlink.is_some())?
            },
            mavlink,
            devices,
            options: RunOptions {
                faults,
                realtime: args.realtime.config(),
                timer_check: TimerCheckConfig {
                    duration: Duration::from_millis(args.timer_check_ms),
                    refuse_if_over_margin: args.refuse_late_timer,
                },
                ..RunOptions::new(args.duration.map(Duration::from_secs_f64), &stop)
            },
        },
    )?;
    match airplane_lost.lock().ok().and_then(|mut lost| lost.take()) {
        Some(e) => Err(format!(
            "the simulated airplane stopped: {e} (logs in {} closed)",
            report.flight_dir.display()
        )),
        None => Ok(report),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn injection_spec_parses_and_rejects_nonsense() {
        assert_eq!(
            parse_injection("imu:12000@100..110"),
            Ok(Injection {
                task: "imu".into(),
                extra_us: 12000,
                from_frame: 100,
                to_frame: 110,
                repeat_every_frames: 0,
            })
        );
        for bad in [
            "imu",
            "imu:12@",
            "imu:x@1..2",
            "imu:5@9..3",
            ":5@1..2",
            "imu:5@1-2",
        ] {
            assert!(parse_injection(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn fault_plan_takes_a_renamed_task_by_its_old_name() {
        let old = parse_injection("logging:10@1..2").expect("parses");
        let new = parse_injection("health:10@1..2").expect("parses");
        let (old, new) = (
            fault_plan(&SHIPPED, &[old]).expect("old name"),
            fault_plan(&SHIPPED, &[new]).expect("new name"),
        );
        let health = SHIPPED.task_index("health").expect("health");
        assert_eq!(old.extra_ns(health, 1), 10_000);
        assert_eq!(new.extra_ns(health, 1), 10_000);
        let watchdog = SHIPPED.task_index("watchdog").expect("watchdog");
        assert_eq!(old.extra_ns(watchdog, 1), 0);
    }

    #[test]
    fn fault_plan_names_an_unknown_task() {
        let inj = parse_injection("camera:10@1..2").expect("parses");
        let e = fault_plan(&SHIPPED, &[inj]).expect_err("unknown");
        assert!(e.contains("no task `camera`") && e.contains("imu"), "{e}");
        let inj = parse_injection("gps:10@1..2").expect("parses");
        let plan = fault_plan(&SHIPPED, &[inj]).expect("known");
        assert_eq!(
            plan.extra_ns(SHIPPED.task_index("gps").expect("gps"), 1),
            10_000
        );
    }
}
