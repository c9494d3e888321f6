//! The command line: the UI by default, and scriptable subcommands. Exit codes: 0 done,
//! 1 the vehicle refused the command or did not answer in time, 2 usage, key or I/O error
//! (one line on stderr).

use crate::exit::Exit;
use crate::json;
use crate::key::{self, SequenceStore};
use crate::model::{GroundModel, time_s, value_as_f64};
use crate::net::{CommandError, CommandSender, GroundLink, Incoming, Session};
use crate::values::{ack_result_name, interval_ms_for_hz, parse_value, type_name, value_text};
use clap::{Args, Parser, Subcommand, ValueEnum};
use skyframe_core::control::mode::FlightMode;
use skyframe_core::link::messages::{Command, CommandAck, Name, Value, limits};
use skyframe_core::link::senders;
use skyframe_core::logfmt::Time;
use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::{Duration, Instant};

pub const DEFAULT_LISTEN: &str = "0.0.0.0:47200";

#[derive(Parser, Debug)]
#[command(
    name = "skyframe-ground",
    version,
    about = "Ground station for skyframe vehicles: a terminal UI (the default) and scriptable link commands.",
    after_help = "Exit codes: 0 ok; 1 the vehicle refused the command or did not answer in time; \
2 usage, key or I/O error.\n\
Commands go to the address each vehicle's telemetry comes from, with its current run id."
)]
pub struct Cli {
    #[command(flatten)]
    pub common: Common,
    #[command(subcommand)]
    pub command: Option<GroundCommand>,
}

#[derive(Args, Debug, Clone)]
pub struct Common {
    /// Where to listen for telemetry (the vehicles' --telemetry address).
    #[arg(long, global = true, default_value = DEFAULT_LISTEN, value_name = "ADDR:PORT")]
    pub listen: SocketAddr,
    /// The link key: 64 hex digits or 32 bytes, mode 600. Default: $SKYFRAME_KEY, else the
    /// newest flights/*/link.key under the current directory. Without one, only monitoring works.
    #[arg(long, global = true, value_name = "FILE")]
    pub key: Option<PathBuf>,
    /// The vehicle to talk to; needed when more than one is heard.
    #[arg(long, global = true, value_name = "ID")]
    pub vehicle: Option<u16>,
    /// Seconds to wait for the vehicle and its acknowledgement.
    #[arg(long, global = true, default_value_t = 5.0, value_name = "S")]
    pub timeout: f64,
    /// This ground station's sender id in commands (1..=255; the vehicle keeps replay
    /// windows for up to 8 senders).
    #[arg(long, global = true, default_value_t = senders::GROUND_STATION, value_name = "N", value_parser = clap::value_parser!(u8).range(1..))]
    pub sender_id: u8,
    /// Where the last command sequence number per key is kept. Default:
    /// $SKYFRAME_GROUND_STATE, else $XDG_STATE_HOME/skyframe-ground, else ~/.local/state/skyframe-ground.
    #[arg(long, global = true, value_name = "DIR")]
    pub state_dir: Option<PathBuf>,
}

#[derive(Subcommand, Debug)]
pub enum GroundCommand {
    /// The terminal UI (also what runs without a subcommand).
    Ui,
    /// Print every message received: one line each, or one JSON object each with --json.
    Monitor {
        #[arg(long)]
        json: bool,
        /// Stop after this many seconds (default: run until interrupted).
        #[arg(long, value_name = "N")]
        seconds: Option<f64>,
    },
    /// Print the latest logged value of task columns, e.g. `control.alt_m` (the unit suffix
    /// may be left out: `control.alt`). With --above/--below, wait until the value crosses.
    #[command(
        long_about = "Print the latest value of one or more task columns as the vehicle \
logged them (the names `skyframe-log to-csv` writes, TASK.COLUMN; the unit suffix may be left \
out). One name prints the value alone; several print `NAME VALUE UNIT` lines.\n\
With --above X or --below X (one name), wait until the value crosses X: a script can wait for \
`control.alt --above 50`. Waits at most --timeout seconds.\n\
Exit codes: 0 printed; 1 not heard, or not crossed, within --timeout; 2 a name that is not \
TASK.COLUMN, or a column the task does not log."
    )]
    Get {
        #[arg(value_name = "TASK.COLUMN", required = true)]
        names: Vec<String>,
        /// Wait until the value is above X.
        #[arg(
            long,
            value_name = "X",
            allow_negative_numbers = true,
            conflicts_with = "below"
        )]
        above: Option<f64>,
        /// Wait until the value is below X.
        #[arg(long, value_name = "X", allow_negative_numbers = true)]
        below: Option<f64>,
        /// One JSON object: name → {value, unit, time (the record's log time, s)}.
        #[arg(long)]
        json: bool,
    },
    /// List the vehicle's parameters: name, type, value, min, max.
    Params,
    /// Set a parameter; the value is read as the parameter's type. Prints the value in force.
    Set {
        /// The parameter's full name, e.g. control.roll_gain.
        #[arg(value_name = "TASK.PARAM")]
        name: String,
        value: String,
    },
    /// Send a command.
    Send {
        #[command(subcommand)]
        what: SendWhat,
    },
    /// Load test: simulated vehicles on loopback into one receive path.
    #[command(
        long_about = "Load test: N fake vehicles (threads, each its own UDP socket) send to one \
receive path (socket → decode → model) on loopback for --seconds.\n\
Each vehicle sends what the protocol's TelemetrySchedule says with every task at the link's \
fastest rate, 20 Hz: 120 TaskData/s (5 tasks with data, servo with 2 formats), a TaskStatus \
per second in rotation, ExecutiveStatus every 2 s, each task's status and TaskFormat every 1.5 s: about 125 \
datagrams/s per vehicle.\n\
Prints messages/s handled, loss (sent − handled, and the ground's own count from sequence \
gaps), and CPU: the receive thread's share of one core and the whole process's (which \
includes the fake vehicles)."
    )]
    Bench {
        #[arg(long, default_value_t = 20)]
        vehicles: u16,
        #[arg(long, default_value_t = 30.0)]
        seconds: f64,
        #[arg(long)]
        json: bool,
    },
}

#[derive(Subcommand, Debug)]
pub enum SendWhat {
    /// End the vehicle's run cleanly, before its programmed duration.
    Stop,
    /// Request a flight mode.
    Mode { mode: ModeArg },
    /// A task's telemetry rate (0 stops it; at most 20 Hz, at least one an hour).
    Rate {
        /// Task name (imu, gps, …) or frame-table index.
        task: String,
        hz: f64,
    },
    /// The watchdog's health check period.
    HealthPeriod {
        #[arg(value_name = "MS")]
        period_ms: u32,
    },
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ModeArg {
    Manual,
    Stabilise,
    Auto,
}

impl From<ModeArg> for FlightMode {
    fn from(m: ModeArg) -> Self {
        match m {
            ModeArg::Manual => FlightMode::Manual,
            ModeArg::Stabilise => FlightMode::Stabilise,
            ModeArg::Auto => FlightMode::Auto,
        }
    }
}

impl From<CommandError> for Exit {
    fn from(e: CommandError) -> Self {
        match e {
            CommandError::Nacked(ack) => Exit::refused(format!(
                "vehicle answered {}{}",
                ack_result_name(ack.result),
                ack.value_in_force
                    .map(|v| format!("; value in force {}", value_text(&v)))
                    .unwrap_or_default()
            )),
            CommandError::TimedOut(m) => Exit::refused(m),
            CommandError::Unusable(m) => Exit::usage(m),
        }
    }
}

/// What a subcommand needs of the key.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KeyNeed {
    /// Only to verify signed telemetry (monitoring).
    Verify,
    /// To command if there is one (the UI).
    CommandIfAvailable,
    /// To command: refuse to start without one.
    Command,
}

/// Opens the socket and the key as `common` says.
pub fn open_session(common: &Common, need: KeyNeed) -> Result<Session, Exit> {
    let need_key = need == KeyNeed::Command;
    let environment = std::env::var(key::KEY_ENV).ok();
    let current_dir = std::env::current_dir().map_err(|e| Exit::usage(e.to_string()))?;
    let loaded = key::find_key(common.key.as_deref(), environment.as_deref(), &current_dir)
        .map_err(Exit::usage)?;
    if need_key && loaded.is_none() {
        return Err(Exit::usage(
            "no link key: pass --key FILE or set SKYFRAME_KEY (commands must be signed)",
        ));
    }
    let sender = match (&loaded, need) {
        (Some(loaded), KeyNeed::Command | KeyNeed::CommandIfAvailable) => {
            let state_dir = common
                .state_dir
                .clone()
                .unwrap_or_else(key::default_state_dir);
            let sequences = SequenceStore::open(&state_dir, &loaded.key, common.sender_id)
                .map_err(Exit::usage)?;
            Some(CommandSender {
                key: loaded.key.clone(),
                sender_id: common.sender_id,
                sequences,
            })
        }
        _ => None,
    };
    let link = GroundLink::bind(common.listen, loaded.map(|l| l.key)).map_err(Exit::usage)?;
    Ok(Session::new(link, sender))
}

fn deadline(common: &Common) -> Result<Instant, Exit> {
    if !common.timeout.is_finite() || common.timeout < 0.0 {
        return Err(Exit::usage("--timeout must be a number of seconds ≥ 0"));
    }
    Ok(Instant::now() + Duration::from_secs_f64(common.timeout.min(1e6)))
}

/// Runs the parsed command line.
pub fn run(cli: Cli) -> Result<(), Exit> {
    let common = &cli.common;
    match cli.command.unwrap_or(GroundCommand::Ui) {
        GroundCommand::Ui => {
            let session = open_session(common, KeyNeed::CommandIfAvailable)?;
            crate::ui::run_terminal(session, common.vehicle)
                .map_err(|e| Exit::usage(format!("terminal: {e}")))
        }
        GroundCommand::Monitor { json, seconds } => monitor(common, json, seconds),
        GroundCommand::Get {
            names,
            above,
            below,
            json,
        } => get(common, &names, Threshold::from_args(above, below), json),
        GroundCommand::Params => params(common),
        GroundCommand::Set { name, value } => set(common, &name, &value),
        GroundCommand::Send { what } => send(common, what),
        GroundCommand::Bench {
            vehicles,
            seconds,
            json,
        } => crate::bench::run(vehicles, seconds, json),
    }
}

fn monitor(common: &Common, as_json: bool, seconds: Option<f64>) -> Result<(), Exit> {
    let mut session = open_session(common, KeyNeed::Verify)?;
    let end = match seconds {
        Some(s) if s.is_finite() && s >= 0.0 => Some(Instant::now() + Duration::from_secs_f64(s)),
        Some(_) => return Err(Exit::usage("--seconds must be a number ≥ 0")),
        None => None,
    };
    let stdout = std::io::stdout();
    loop {
        let wait = match end {
            Some(end) => {
                let now = Instant::now();
                if now >= end {
                    return Ok(());
                }
                (end - now).min(Duration::from_millis(200))
            }
            None => Duration::from_millis(200),
        };
        let Some(received) = session.pump(wait).map_err(Exit::usage)? else {
            continue;
        };
        if let Some(wanted) = common.vehicle {
            let id = match &received.incoming {
                Incoming::Telemetry { header, .. } | Incoming::Command { header } => {
                    Some(header.envelope.vehicle_id)
                }
                Incoming::Refused(_) => None,
            };
            if id.is_some_and(|id| id != wanted) {
                continue;
            }
        }
        let line = if as_json {
            json::received_json(&received, &session.model).to_string()
        } else {
            json::received_text(&received, &session.model)
        };
        let mut out = stdout.lock();
        // A closed pipe (`| head`) ends monitoring quietly.
        if writeln!(out, "{line}").and_then(|()| out.flush()).is_err() {
            return Ok(());
        }
    }
}

/// What `get --above/--below` waits for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Threshold {
    Any,
    Above(f64),
    Below(f64),
}

impl Threshold {
    fn from_args(above: Option<f64>, below: Option<f64>) -> Self {
        match (above, below) {
            (Some(x), _) => Threshold::Above(x),
            (None, Some(x)) => Threshold::Below(x),
            (None, None) => Threshold::Any,
        }
    }

    fn met(self, value: f64) -> bool {
        match self {
            Threshold::Any => true,
            Threshold::Above(x) => value > x,
            Threshold::Below(x) => value < x,
        }
    }
}

/// A column's latest value as the ground heard it: (value, its record's log TIME, full column
/// name).
pub fn latest_column(
    model: &GroundModel,
    vehicle_id: u16,
    task: &str,
    column: &str,
) -> Result<Option<(Value, Time, String)>, String> {
    let Some((_, state)) = model.vehicle(vehicle_id).and_then(|v| v.task_by_name(task)) else {
        return Ok(None);
    };
    for format in state.formats.values() {
        if let Some(i) = format.column_index(column) {
            let found = format.latest.get(i).zip(format.latest_time);
            return Ok(found.map(|(v, t)| (*v, t, format.column_name(i))));
        }
    }
    // Every format the task sends has been named, and none has the column: a typo, not a
    // value still on its way.
    let named = !state.formats.is_empty() && state.formats.values().all(|f| !f.columns.is_empty());
    if named {
        let columns: Vec<&str> = state
            .formats
            .values()
            .flat_map(|f| f.columns.iter().map(String::as_str))
            .collect();
        return Err(format!(
            "task {task} logs no column {column:?} (it logs {})",
            columns.join(", ")
        ));
    }
    Ok(None)
}

fn get(common: &Common, names: &[String], threshold: Threshold, as_json: bool) -> Result<(), Exit> {
    let wanted: Vec<(&str, &str)> = names
        .iter()
        .map(|n| {
            n.split_once('.')
                .filter(|(t, c)| !t.is_empty() && !c.is_empty())
                .ok_or_else(|| {
                    Exit::usage(format!("{n:?} is not TASK.COLUMN (e.g. control.alt_m)"))
                })
        })
        .collect::<Result<_, _>>()?;
    if threshold != Threshold::Any && wanted.len() != 1 {
        return Err(Exit::usage("--above/--below take one TASK.COLUMN"));
    }
    if let Threshold::Above(x) | Threshold::Below(x) = threshold
        && !x.is_finite()
    {
        return Err(Exit::usage("--above/--below take a finite number"));
    }
    let mut session = open_session(common, KeyNeed::Verify)?;
    let deadline = deadline(common)?;
    let vehicle_id = session.choose_vehicle(common.vehicle, deadline)?;
    let mut unknown: Option<String> = None;
    let mut found: Vec<Option<(Value, Time, String)>> = Vec::new();
    let crossed = |f: &Option<(Value, Time, String)>| {
        f.as_ref()
            .is_some_and(|(v, ..)| threshold.met(value_as_f64(v)))
    };
    let done = session
        .pump_until(deadline, |model| {
            found.clear();
            for &(task, column) in &wanted {
                match latest_column(model, vehicle_id, task, column) {
                    Ok(latest) => found.push(latest),
                    Err(e) => {
                        unknown = Some(e);
                        return true;
                    }
                }
            }
            found.iter().all(crossed)
        })
        .map_err(Exit::usage)?;
    if let Some(e) = unknown {
        return Err(Exit::usage(e));
    }
    if !done {
        let (name, latest) = wanted
            .iter()
            .zip(&found)
            .find(|(_, f)| !crossed(f))
            .map(|(&(t, c), f)| (format!("{t}.{c}"), f.clone()))
            .unwrap_or_default();
        let waited = common.timeout;
        return Err(Exit::refused(match (latest, threshold) {
            (None, _) => format!("{name}: not heard from vehicle {vehicle_id} in {waited} s"),
            (Some((v, t, _)), Threshold::Above(x)) => format!(
                "{name}: {} at {t} s, not above {x} within {waited} s",
                value_text(&v)
            ),
            (Some((v, t, _)), Threshold::Below(x)) => format!(
                "{name}: {} at {t} s, not below {x} within {waited} s",
                value_text(&v)
            ),
            (Some(_), Threshold::Any) => format!("{name}: not heard in {waited} s"),
        }));
    }
    let rows: Vec<(String, Value, Time, Option<&str>)> = wanted
        .iter()
        .zip(found.iter().flatten())
        .map(|(&(task, _), (v, t, column))| {
            let unit = crate::model::column_unit(column);
            (format!("{task}.{column}"), *v, *t, unit)
        })
        .collect();
    if as_json {
        let object: serde_json::Map<String, serde_json::Value> = rows
            .iter()
            .map(|(name, v, t, unit)| {
                // The log TIME as seconds, and exactly as the CSV's time column prints it.
                let mut entry = serde_json::json!({
                    "value": json::value_json(v),
                    "time": time_s(*t),
                    "log_time": t.to_string(),
                });
                if let Some(unit) = unit {
                    entry["unit"] = serde_json::json!(unit);
                }
                (name.clone(), entry)
            })
            .collect();
        println!("{}", serde_json::Value::Object(object));
    } else if let [(_, v, _, _)] = rows.as_slice() {
        println!("{}", value_text(v));
    } else {
        for (name, v, _, unit) in &rows {
            println!("{name} {} {}", value_text(v), unit.unwrap_or(""));
        }
    }
    Ok(())
}

fn params(common: &Common) -> Result<(), Exit> {
    let mut session = open_session(common, KeyNeed::Command)?;
    let deadline = deadline(common)?;
    let vehicle_id = session.choose_vehicle(common.vehicle, deadline)?;
    session.command(vehicle_id, &Command::ListParams, deadline)?;
    // The values come before the acknowledgement; allow stragglers reordered behind it.
    let complete = |m: &crate::model::GroundModel| {
        m.vehicle(vehicle_id).is_some_and(|v| {
            v.params
                .values()
                .next()
                .is_some_and(|p| v.params.len() >= usize::from(p.count))
        })
    };
    let settle = (Instant::now() + Duration::from_millis(500)).min(deadline);
    session.pump_until(settle, complete).map_err(Exit::usage)?;
    let vehicle = session
        .model
        .vehicle(vehicle_id)
        .ok_or_else(|| Exit::refused("vehicle lost"))?;
    let width = vehicle
        .params
        .values()
        .map(|p| p.name.as_str().len())
        .max()
        .unwrap_or(4)
        .max(4);
    println!(
        "{:width$}  type  {:>12}  {:>12}  {:>12}",
        "name", "value", "min", "max"
    );
    for p in vehicle.params.values() {
        println!(
            "{:width$}  {:4}  {:>12}  {:>12}  {:>12}",
            p.name.as_str(),
            type_name(p.value.value_type()),
            value_text(&p.value),
            value_text(&p.min),
            value_text(&p.max)
        );
    }
    if !complete(&session.model) {
        return Err(Exit::refused("parameter list incomplete (datagrams lost)"));
    }
    Ok(())
}

fn set(common: &Common, name_text: &str, value_text_in: &str) -> Result<(), Exit> {
    let name = Name::new(name_text)
        .filter(|n| !n.is_empty())
        .ok_or_else(|| Exit::usage(format!("bad parameter name {name_text:?}")))?;
    let mut session = open_session(common, KeyNeed::Command)?;
    let deadline = deadline(common)?;
    let vehicle_id = session.choose_vehicle(common.vehicle, deadline)?;
    let known_type = |s: &Session| {
        s.model
            .vehicle(vehicle_id)
            .and_then(|v| v.param_by_name(name_text))
            .map(|p| p.value.value_type())
    };
    let value_type = match known_type(&session) {
        Some(t) => t,
        None => {
            // The answer to GetParam carries the value, whose tag is the type.
            let ack = session.command(vehicle_id, &Command::GetParam { name }, deadline)?;
            match ack
                .value_in_force
                .map(|v| v.value_type())
                .or(known_type(&session))
            {
                Some(t) => t,
                None => return Err(Exit::refused(format!("{name_text}: type unknown"))),
            }
        }
    };
    let value = parse_value(value_text_in, value_type).ok_or_else(|| {
        Exit::usage(format!(
            "{name_text} is {}; {value_text_in:?} is not one",
            type_name(value_type)
        ))
    })?;
    match session.command(vehicle_id, &Command::SetParam { name, value }, deadline) {
        Ok(ack) => {
            print_ack(name_text, &ack);
            Ok(())
        }
        Err(CommandError::Nacked(ack)) => {
            print_ack(name_text, &ack);
            Err(Exit::refused(format!(
                "{name_text}: {}",
                ack_result_name(ack.result)
            )))
        }
        Err(e) => Err(e.into()),
    }
}

fn print_ack(name: &str, ack: &CommandAck) {
    let value = ack
        .value_in_force
        .map(|v| value_text(&v))
        .unwrap_or_else(|| "?".to_string());
    println!("{name} = {value} ({})", ack_result_name(ack.result));
}

fn send(common: &Common, what: SendWhat) -> Result<(), Exit> {
    // Check the arguments before listening, so a typo fails at once.
    let early = match &what {
        SendWhat::Stop => Some(Command::Stop),
        SendWhat::Mode { mode } => Some(Command::RequestMode {
            mode: (*mode).into(),
        }),
        SendWhat::HealthPeriod { period_ms } => {
            let range = limits::MIN_HEALTH_PERIOD_MS..=limits::MAX_HEALTH_PERIOD_MS;
            if !range.contains(period_ms) {
                return Err(Exit::usage(format!(
                    "health period must be {}..={} ms",
                    range.start(),
                    range.end()
                )));
            }
            Some(Command::SetHealthPeriod {
                period_ms: *period_ms,
            })
        }
        SendWhat::Rate { .. } => None,
    };
    let mut session = open_session(common, KeyNeed::Command)?;
    let deadline = deadline(common)?;
    let vehicle_id = session.choose_vehicle(common.vehicle, deadline)?;
    let (command, what_text) = match (early, &what) {
        (Some(command), _) => (command, describe(&what)),
        (None, SendWhat::Rate { task, hz }) => {
            let interval_ms = interval_ms_for_hz(*hz)
                .ok_or_else(|| Exit::usage("rate must be 0 (stop) or between 1/3600 and 20 Hz"))?;
            let task_index = resolve_task(&mut session, vehicle_id, task, deadline)?;
            (
                Command::SetTelemetryRate {
                    task_index,
                    interval_ms,
                },
                format!("rate {task} {hz} Hz (every {interval_ms} ms)"),
            )
        }
        (None, _) => return Err(Exit::usage("nothing to send")),
    };
    let ack = session.command(vehicle_id, &command, deadline)?;
    println!(
        "vehicle {vehicle_id}: {what_text}: {}",
        ack_result_name(ack.result)
    );
    Ok(())
}

fn describe(what: &SendWhat) -> String {
    match what {
        SendWhat::Stop => "stop".to_string(),
        SendWhat::Mode { mode } => format!(
            "mode {}",
            crate::json::mode_name(Some(FlightMode::from(*mode)))
        ),
        SendWhat::Rate { task, hz } => format!("rate {task} {hz} Hz"),
        SendWhat::HealthPeriod { period_ms } => format!("health period {period_ms} ms"),
    }
}

/// A task's frame-table index from its name (learnt from its TaskStatus) or the index itself.
fn resolve_task(
    session: &mut Session,
    vehicle_id: u16,
    task: &str,
    deadline: Instant,
) -> Result<u8, Exit> {
    if let Ok(index) = task.parse::<u8>() {
        return Ok(index);
    }
    let found = |m: &crate::model::GroundModel| {
        m.vehicle(vehicle_id)
            .and_then(|v| v.task_by_name(task))
            .map(|(i, _)| i)
    };
    session
        .pump_until(deadline, |m| found(m).is_some())
        .map_err(Exit::usage)?;
    found(&session.model).ok_or_else(|| {
        Exit::refused(format!(
            "no task named {task:?} heard from vehicle {vehicle_id} (statuses rotate one task a second: pass its index or a longer --timeout)"
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use skyframe_core::link::messages::ValueType;

    #[test]
    fn values_are_read_as_the_parameters_type() {
        assert_eq!(parse_value("1.5", ValueType::F32), Some(Value::F32(1.5)));
        assert_eq!(parse_value("-3", ValueType::I32), Some(Value::I32(-3)));
        assert_eq!(parse_value("-3", ValueType::U32), None);
        assert_eq!(parse_value("on", ValueType::Bool), Some(Value::Bool(true)));
        assert_eq!(parse_value("nan", ValueType::F32), None);
        assert_eq!(parse_value("x", ValueType::F64), None);
    }

    #[test]
    fn rates_in_hz_become_intervals_within_the_protocols_limits() {
        assert_eq!(interval_ms_for_hz(0.0), Some(0));
        assert_eq!(interval_ms_for_hz(10.0), Some(100));
        assert_eq!(interval_ms_for_hz(20.0), Some(50));
        assert_eq!(interval_ms_for_hz(25.0), None);
        assert_eq!(interval_ms_for_hz(-1.0), None);
        assert_eq!(interval_ms_for_hz(f64::NAN), None);
    }

    #[test]
    fn the_command_line_parses_as_documented() {
        let cli = Cli::try_parse_from([
            "skyframe-ground",
            "set",
            "control.roll_gain",
            "1.5",
            "--key",
            "k",
            "--vehicle",
            "7",
        ])
        .expect("parses");
        assert_eq!(cli.common.vehicle, Some(7));
        assert!(matches!(cli.command, Some(GroundCommand::Set { .. })));
        let cli = Cli::try_parse_from(["skyframe-ground", "send", "mode", "auto"]).expect("parses");
        assert!(matches!(
            cli.command,
            Some(GroundCommand::Send {
                what: SendWhat::Mode {
                    mode: ModeArg::Auto
                }
            })
        ));
        assert!(Cli::try_parse_from(["skyframe-ground", "send", "mode", "loop"]).is_err());
        assert!(Cli::try_parse_from(["skyframe-ground"]).is_ok());
    }
}
