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
use skyframe_core::schedule::{FrameTable, SHIPPED};
use skyframe_sim::scenario::{FaultKind, Scenario};
use skyframe_sim::world::SimWorld;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
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
    /// Fly the executive with no devices (idle tasks but the watchdog and logging): the
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
    /// The GPS latency the estimator assumes, in ms (default: its configuration's).
    #[arg(long, value_name = "MS")]
    pub gps_latency_ms: Option<f64>,
}

#[derive(Args, Debug, Clone)]
pub struct RealtimeArgs {
    /// SCHED_FIFO priority of the executive thread (1-99); 0 keeps the default scheduler.
    #[arg(long, default_value_t = 80, value_parser = clap::value_parser!(u8).range(0..=99))]
    pub priority: u8,
    /// Pin the executive thread to this CPU.
    #[arg(long)]
    pub cpu: Option<usize>,
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
    #[arg(long, default_value_t = 100)]
    pub clock_period_us: u64,
}

impl RealtimeArgs {
    pub fn config(&self) -> RtConfig {
        RtConfig {
            fifo_priority: (self.priority > 0).then_some(self.priority),
            lock_memory: !self.no_mlockall,
            cpu: self.cpu,
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
    /// How long to fly, in seconds.
    #[arg(long, value_parser = parse_seconds)]
    pub duration: Option<f64>,
    /// Make a task overrun on purpose: TASK:EXTRA_US@FROM..TO (minor frames since start),
    /// e.g. imu:12000@100..110. Repeatable.
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
    /// Write this stream (`imu`, `gps`, `servo`, `health`, `executive`) as CSV text instead
    /// of binary. Repeatable.
    #[arg(long = "text-log", value_name = "STREAM")]
    pub text_log: Vec<String>,
    /// Milliseconds of timer measurement before the first frame (0 skips the check).
    #[arg(long, default_value_t = 200)]
    pub timer_check_ms: u64,
    /// Refuse to fly when the timer check finds wake-ups later than the frame margin
    /// (default: warn and fly).
    #[arg(long)]
    pub refuse_late_timer: bool,
    #[command(flatten)]
    pub link: LinkArgs,
    #[command(flatten)]
    pub realtime: RealtimeArgs,
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
    pub fn plan(&self) -> Result<Option<LinkPlan>, String> {
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
    #[arg(long)]
    pub fast: bool,
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
        /// Size of each test stream, in megabytes.
        #[arg(long, default_value_t = 5.0, value_parser = parse_seconds)]
        megabytes: f64,
    },
}

#[derive(Args, Debug)]
#[command(args_conflicts_with_subcommands = true)]
pub struct BenchArgs {
    #[command(subcommand)]
    pub what: Option<BenchWhat>,
    /// Seconds for each of the two runs (bare loop, executive).
    #[arg(long, default_value_t = 10.0, value_parser = parse_seconds)]
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
}

fn parse_seconds(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(s) if (0.0..1e9).contains(&s) => Ok(s),
        _ => Err(format!("`{text}` is not a number of seconds")),
    }
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
    };
    if injection.task.is_empty() || injection.to_frame <= injection.from_frame {
        return Err(bad());
    }
    Ok(injection)
}

/// Turns typed injections into the executive's fault plan, naming the first unknown task.
pub fn fault_plan(table: &FrameTable, injections: &[Injection]) -> Result<FaultPlan, String> {
    let mut plan = FaultPlan::new();
    for i in injections {
        let task = table.task_index(&i.task).ok_or_else(|| {
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
            let world = SimWorld::from_scenario(&scenario, args.seed);
            let mut flight = args.flight;
            flight.duration = flight.duration.or(Some(scenario.duration_s));
            flight
                .inject_overrun
                .extend(scenario_overruns(&scenario, SHIPPED.minor_frame_ns));
            let log = crate::vehicle::LogConfig::default();
            let devices = Devices::Sim(Box::new(world));
            let report = if args.fast {
                // The timer check measures the OS timer, which virtual time does not use.
                flight.timer_check_ms = 0;
                fly_with(&VirtualTime, devices, &flight, &log)?
            } else {
                fly_with(platform, devices, &flight, &log)?
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
            Ok(ExitCode::SUCCESS)
        }
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
    let report = fly_with(platform, devices, args, log)?;
    print_flight(&report, args.json)
}

fn print_flight(report: &FlightReport, json: bool) -> Result<ExitCode, String> {
    if json {
        let json = serde_json::to_string_pretty(report).map_err(|e| e.to_string())?;
        println!("{json}");
    } else {
        print!("{}", render_flight(report));
    }
    Ok(ExitCode::SUCCESS)
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
    devices: Devices<'_>,
    args: &FlightArgs,
    log: &crate::vehicle::LogConfig,
) -> Result<FlightReport, String> {
    let faults = fault_plan(&SHIPPED, &args.inject_overrun)?;
    let stop = stop_flag()?;
    fly(
        platform,
        &SHIPPED,
        FlightPlan {
            log_dir: args.log_dir.as_deref().unwrap_or(&log.dir),
            log: LogSettings::from_config(log, &args.text_log),
            mission: args
                .mission
                .as_deref()
                .map(crate::mission::load)
                .transpose()?,
            link: if matches!(devices, Devices::None) {
                None
            } else {
                args.link.plan()?
            },
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
    )
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
                to_frame: 110
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
