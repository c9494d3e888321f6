//! JSBSim as the flight model: the `jsbsim` Python package (the JSBSim library and its
//! aircraft) run as a child process in lock-step, one 9-number frame in and one fixed record
//! out over its pipes (`driver.py`, compiled into the binary).
//!
//! Why a child process and not a binding: the package is the way JSBSim is distributed (a
//! `pip install` on any machine, with the aircraft), while the Rust bindings found are
//! unmaintained or need JSBSim built from source; a frame's round trip costs about 40 µs,
//! which at 200 frames per simulated second leaves well over 50× real time
//! (`skyframe-sim-bench plant`, docs/plants.md).
//!
//! JSBSim runs in frames of [`JsbsimConfig::frame_s`] (5 ms); the world steps the plant in
//! 1 ms, so the truth is held between frames and a frame flies with the commands of the step
//! that completes it. The IMU (every 10 ms) always reads a fresh frame.
//!
//! Units: JSBSim's properties are in feet, slugs, pounds and degrees in places; every
//! conversion is here ([`FT_M`], [`LBF_N`]) and checked against physics in the tests.

pub mod airframe;

use super::math::{add, mat_vec, quat_from_euler, quat_to_euler, quat_to_rotation};
use super::model::{FlightModel, PlantError};
use super::rng::{NoiseRng, stream};
use super::sensors::GeodeticPosition;
use super::{ActuatorCommands, PlantConfig, Truth, wind};
use std::collections::VecDeque;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::PathBuf;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError, sync_channel};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The child's side of the protocol.
pub const DRIVER: &str = include_str!("driver.py");

/// One international foot in metres (exact).
pub const FT_M: f64 = 0.3048;
/// One pound-force in newtons (exact by definition of the pound and standard gravity).
pub const LBF_N: f64 = 4.448_221_615_260_5;

/// The fields of one frame, in `driver.py`'s `OUT_PROPS` order.
const FIELDS: usize = 29;
/// How long the start (which loads the aircraft and trims) may take before the child is
/// taken for hung.
const START_TIMEOUT: Duration = Duration::from_secs(60);

/// Where JSBSim starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum JsbsimStart {
    /// On the ground at home, nose towards `heading_rad`.
    OnRunway { heading_rad: f64 },
    /// Trimmed (by JSBSim) in level flight above home.
    InFlight {
        altitude_m: f64,
        airspeed_mps: f64,
        heading_rad: f64,
    },
}

/// How to run JSBSim.
#[derive(Debug, Clone, PartialEq)]
pub struct JsbsimConfig {
    /// An aircraft of the package (`c172x`, `J3Cub`, …) or of `root`.
    pub aircraft: String,
    /// A directory with `aircraft/`, `engine/` and `systems/` (JSBSim's layout); `None`: the
    /// package's own.
    pub root: Option<PathBuf>,
    /// JSBSim's integration frame (s); a whole number of milliseconds.
    pub frame_s: f64,
    /// The Python interpreter with the `jsbsim` package.
    pub python: String,
    /// On a runway start, JSBSim also trims level flight at this airspeed first, for the
    /// pilot's trim ([`JsbsimModel::trim`]); an in-flight start trims at its own speed.
    pub trim_airspeed_mps: Option<f64>,
    /// A frame unanswered this long means the child hangs: the run ends with an error.
    pub frame_timeout: Duration,
    /// An in-flight start from these commands at this angle of attack (rad) instead of
    /// JSBSim's own trim: the built-in model's trim, for the cross-check.
    pub given_trim: Option<(ActuatorCommands, f64)>,
}

impl JsbsimConfig {
    /// `aircraft` from the package, or `skyframe-uav` from the airframes shipped with
    /// platform-sim (`platform-sim/jsbsim/`), at 200 Hz, with `python3` (or `$SKYFRAME_PYTHON`).
    pub fn new(aircraft: &str) -> Self {
        let root = (aircraft == OUR_AIRFRAME)
            .then(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("jsbsim"));
        Self {
            aircraft: aircraft.to_string(),
            root,
            frame_s: 0.005,
            python: std::env::var("SKYFRAME_PYTHON").unwrap_or_else(|_| "python3".into()),
            trim_airspeed_mps: None,
            frame_timeout: Duration::from_secs(10),
            given_trim: None,
        }
    }
}

/// Our own airplane (the built-in model's Aerosonde parameters) in JSBSim's XML.
pub const OUR_AIRFRAME: &str = "skyframe-uav";

/// One frame's values, converted to SI and our frames.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Frame {
    values: [f64; FIELDS],
}

impl Frame {
    fn get(&self, i: usize) -> f64 {
        self.values.get(i).copied().unwrap_or(f64::NAN)
    }
}

/// The child and the thread reading its output.
struct Driver {
    child: Child,
    /// `None` once closed (dropping the driver).
    stdin: Option<ChildStdin>,
    frames: Receiver<Result<Frame, String>>,
    /// The last lines the child wrote on stderr, for error messages.
    stderr_tail: Arc<Mutex<VecDeque<String>>>,
    /// Says when the child's stderr has closed (all its last words are in).
    stderr_closed: Receiver<()>,
}

impl Driver {
    fn write_all(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        let stdin = self
            .stdin
            .as_mut()
            .ok_or_else(|| std::io::Error::from(std::io::ErrorKind::BrokenPipe))?;
        stdin.write_all(bytes)?;
        stdin.flush()
    }

    /// Ends the child: closing its stdin ends the driver's loop and it cleans up after itself
    /// (its working directory); killed if it has not gone within a second.
    fn stop(&mut self) {
        drop(self.stdin.take());
        let deadline = std::time::Instant::now() + Duration::from_secs(1);
        while std::time::Instant::now() < deadline {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    /// Ends the child and waits (briefly: a grandchild may hold the pipe) for the rest of
    /// what it wrote on stderr.
    fn finish(&mut self) {
        self.stop();
        let _ = self.stderr_closed.recv_timeout(Duration::from_millis(500));
    }

    fn last_words(&self) -> String {
        self.stderr_tail
            .lock()
            .ok()
            .and_then(|t| t.back().cloned())
            .map(|l| format!(" ({l})"))
            .unwrap_or_default()
    }
}

impl Drop for Driver {
    fn drop(&mut self) {
        self.stop();
    }
}

/// JSBSim as a [`FlightModel`].
pub struct JsbsimModel {
    config: JsbsimConfig,
    child: Driver,
    home: GeodeticPosition,
    time_ns: u64,
    frame_ns: u64,
    /// Plant time of the JSBSim state held now.
    frame_time_ns: u64,
    frames_run: u64,
    wind: wind::WindModel,
    commands: ActuatorCommands,
    truth: Truth,
    /// Level-flight trim JSBSim found: commands and pitch (rad).
    trim: Option<(ActuatorCommands, f64)>,
    version: String,
}

impl std::fmt::Debug for JsbsimModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JsbsimModel")
            .field("aircraft", &self.config.aircraft)
            .field("time_ns", &self.time_ns)
            .finish_non_exhaustive()
    }
}

impl JsbsimModel {
    /// Starts JSBSim with `config.aircraft` at `start` over `plant.gps.home`, with
    /// `plant.wind` (steady and gusts drawn from `seed`'s wind stream, as the built-in).
    pub fn start(
        config: JsbsimConfig,
        plant: &PlantConfig,
        start: JsbsimStart,
        seed: u64,
    ) -> Result<Self, PlantError> {
        let mut config = config;
        if let (
            true,
            None,
            JsbsimStart::InFlight {
                altitude_m,
                airspeed_mps,
                heading_rad,
            },
        ) = (config.aircraft == OUR_AIRFRAME, config.given_trim, start)
        {
            // JSBSim's trim cannot move our airframe's throttle (it has no JSBSim engine, only
            // the motor's tables): start from the built-in model's trim of the same airframe.
            let trim = super::trim::trim_level_flight(
                &plant.params,
                airspeed_mps,
                altitude_m,
                heading_rad,
            )
            .map_err(|e| {
                PlantError(format!(
                    "jsbsim: cannot trim {OUR_AIRFRAME} at {airspeed_mps} m/s: {e:?}"
                ))
            })?;
            config.given_trim = Some((trim.commands, trim.alpha_rad));
        }
        let frame_ns = (config.frame_s * 1e3).round().max(1.0) as u64 * 1_000_000;
        let home = plant.gps.home;
        let (kind, heading_rad, altitude_m, airspeed_mps) = match start {
            JsbsimStart::OnRunway { heading_rad } => ("runway", heading_rad, 0.0, 0.0),
            JsbsimStart::InFlight {
                altitude_m,
                airspeed_mps,
                heading_rad,
            } => ("flight", heading_rad, altitude_m, airspeed_mps),
        };
        let hello = format!(
            "{{\"aircraft\": {}, \"root\": {}, \"dt_s\": {}, \"lat_deg\": {}, \"lon_deg\": {}, \
             \"ground_msl_m\": {}, \"initial\": {{\"kind\": \"{kind}\", \"heading_deg\": {}, \
             \"altitude_m\": {altitude_m}, \"airspeed_mps\": {airspeed_mps}}}, \
             \"trim_airspeed_mps\": {}, \"given_trim\": {}}}\n",
            json_string(&config.aircraft),
            config
                .root
                .as_ref()
                .map_or("null".to_string(), |r| json_string(&r.to_string_lossy())),
            frame_ns as f64 * 1e-9,
            home.lat_deg,
            home.lon_deg,
            home.alt_msl_m,
            heading_rad.to_degrees(),
            config
                .trim_airspeed_mps
                .filter(|v| v.is_finite())
                .map_or("null".to_string(), |v| v.to_string()),
            config.given_trim.map_or("null".to_string(), |(c, alpha)| {
                let c = c.sanitized();
                format!(
                    "{{\"commands\": [{}, {}, {}, {}], \"alpha_rad\": {}}}",
                    c.aileron,
                    c.elevator,
                    c.rudder,
                    c.throttle,
                    if alpha.is_finite() { alpha } else { 0.0 }
                )
            }),
        );
        let mut child = spawn(&config)?;
        child
            .write_all(hello.as_bytes())
            .map_err(|e| PlantError(format!("jsbsim: cannot talk to {}: {e}", config.python)))?;
        let answer = match child.frames.recv_timeout(START_TIMEOUT) {
            Ok(Err(line)) => line,
            Ok(Ok(_)) => String::new(),
            Err(_) => {
                child.finish();
                return Err(PlantError(format!(
                    "jsbsim: {} did not start JSBSim{}",
                    config.python,
                    child.last_words()
                )));
            }
        };
        let (version, trim) = parse_hello(&answer).map_err(|e| {
            child.finish();
            PlantError(format!(
                "jsbsim: {e}{}",
                if e.contains("no aircraft") || e.contains("not installed") {
                    String::new()
                } else {
                    child.last_words()
                }
            ))
        })?;
        let trim = trim.map(|([aileron, elevator, rudder, throttle], pitch)| {
            (
                ActuatorCommands {
                    aileron,
                    elevator,
                    rudder,
                    throttle,
                    brake: 0.0,
                },
                pitch,
            )
        });
        let mut model = Self {
            wind: wind::WindModel::new(plant.wind, NoiseRng::new(seed, stream::WIND)),
            config,
            child,
            home,
            time_ns: 0,
            frame_ns,
            frame_time_ns: 0,
            frames_run: 0,
            commands: match (start, trim) {
                (JsbsimStart::InFlight { .. }, Some((commands, _))) => commands,
                _ => ActuatorCommands::default(),
            },
            truth: Truth::at_rest(),
            trim,
            version,
        };
        // The state JSBSim starts in, without running it.
        model.exchange(0)?;
        Ok(model)
    }

    /// The level-flight trim JSBSim found (commands, pitch in rad): for an in-flight start at
    /// its speed, else at [`JsbsimConfig::trim_airspeed_mps`].
    pub fn trim(&self) -> Option<(ActuatorCommands, f64)> {
        self.trim
    }

    /// The package's version.
    pub fn version(&self) -> &str {
        &self.version
    }

    pub fn config(&self) -> &JsbsimConfig {
        &self.config
    }

    /// JSBSim frames run so far.
    pub fn frames_run(&self) -> u64 {
        self.frames_run
    }

    /// Sends the commands and the wind, runs `frames` frames, reads the state back.
    fn exchange(&mut self, frames: u64) -> Result<(), PlantError> {
        let c = self.commands;
        let wind = add(
            self.wind.steady_ned_mps(),
            mat_vec(
                &quat_to_rotation(self.truth.attitude),
                self.wind.gust_body_mps(),
            ),
        );
        let mut msg = [0u8; 72];
        let values = [
            c.aileron,
            c.elevator,
            c.rudder,
            c.throttle,
            c.brake,
            wind[0],
            wind[1],
            wind[2],
            frames as f64,
        ];
        for (chunk, v) in msg.chunks_exact_mut(8).zip(values) {
            chunk.copy_from_slice(&v.to_le_bytes());
        }
        let dead = |child: &mut Driver, what: &str| {
            child.finish();
            let status = child
                .child
                .try_wait()
                .ok()
                .flatten()
                .map(|s| format!(", {s}"))
                .unwrap_or_default();
            PlantError(format!("jsbsim: {what}{status}{}", child.last_words()))
        };
        if self.child.write_all(&msg).is_err() {
            return Err(dead(&mut self.child, "the JSBSim process is gone"));
        }
        let frame = match self.child.frames.recv_timeout(self.config.frame_timeout) {
            Ok(Ok(frame)) => frame,
            Ok(Err(line)) => {
                return Err(dead(
                    &mut self.child,
                    &format!(
                        "JSBSim failed: {}",
                        parse_hello(&line).err().unwrap_or(line)
                    ),
                ));
            }
            Err(RecvTimeoutError::Timeout) => {
                return Err(dead(
                    &mut self.child,
                    &format!(
                        "no answer from JSBSim in {:.1} s",
                        self.config.frame_timeout.as_secs_f64()
                    ),
                ));
            }
            Err(RecvTimeoutError::Disconnected) => {
                return Err(dead(&mut self.child, "the JSBSim process ended"));
            }
        };
        self.frames_run += frames;
        let expected_s = self.frames_run as f64 * self.frame_ns as f64 * 1e-9;
        let sim_time = frame.get(FIELDS - 1);
        if !frame.values.iter().all(|v| v.is_finite()) || (sim_time - expected_s).abs() > 1e-6 {
            return Err(dead(
                &mut self.child,
                &format!(
                    "garbage from JSBSim (its clock says {sim_time} s, expected {expected_s} s, or a value is not finite)"
                ),
            ));
        }
        self.truth = self.to_truth(&frame);
        Ok(())
    }

    fn to_truth(&self, f: &Frame) -> Truth {
        let at = GeodeticPosition {
            lat_deg: f.get(0),
            lon_deg: f.get(1),
            alt_msl_m: self.home.alt_msl_m,
        };
        let [north, east, _] = self.home.ned_to(&at);
        let height = f.get(2) * FT_M;
        let ft3 = |i: usize| [f.get(i) * FT_M, f.get(i + 1) * FT_M, f.get(i + 2) * FT_M];
        let attitude = quat_from_euler(f.get(9), f.get(10), f.get(11));
        let [roll, pitch, yaw] = quat_to_euler(attitude);
        // Force (lbf) over mass (slug) is ft/s².
        let mass_slug = f.get(18);
        let specific_force = [
            f.get(15) / mass_slug * FT_M,
            f.get(16) / mass_slug * FT_M,
            f.get(17) / mass_slug * FT_M,
        ];
        Truth {
            t_s: self.time_ns as f64 * 1e-9,
            position_ned_m: [north, east, -height],
            velocity_ned_mps: ft3(3),
            velocity_body_mps: ft3(6),
            attitude,
            roll_rad: roll,
            pitch_rad: pitch,
            yaw_rad: yaw,
            rates_body_radps: [f.get(12), f.get(13), f.get(14)],
            specific_force_body_mps2: specific_force,
            airspeed_mps: f.get(19) * FT_M,
            alpha_rad: f.get(20),
            beta_rad: f.get(21),
            wind_ned_mps: ft3(22),
            gust_body_mps: self.wind.gust_body_mps(),
            thrust_n: f.get(25) * LBF_N,
            motor_speed_radps: f.get(26) * std::f64::consts::TAU / 60.0,
            actuators: self.commands,
            on_ground: f.get(27) > 0.5,
            // JSBSim reports no structural contact we use; the CG under the ground is a crash.
            airframe_strike: height < 0.0,
            height_above_ground_m: height,
        }
    }
}

impl FlightModel for JsbsimModel {
    fn step(&mut self, dt_s: f64, commands: &ActuatorCommands) -> Result<(), PlantError> {
        self.commands = commands.sanitized();
        let dt_ns = (dt_s.max(0.0) * 1e9).round() as u64;
        self.time_ns += dt_ns;
        let due = (self.time_ns - self.frame_time_ns) / self.frame_ns;
        if due > 0 {
            let frame_s = self.frame_ns as f64 * 1e-9;
            for _ in 0..due {
                self.wind.step(frame_s, self.truth.airspeed_mps);
            }
            self.frame_time_ns += due * self.frame_ns;
            self.exchange(due)?;
        }
        self.truth.t_s = self.time_ns as f64 * 1e-9;
        self.truth.actuators = self.commands;
        Ok(())
    }

    fn truth(&self) -> Truth {
        self.truth
    }

    fn time_ns(&self) -> u64 {
        self.time_ns
    }

    fn motor_current_a(&self) -> f64 {
        // JSBSim's engines (piston, or electric at a fixed voltage) do not draw from our
        // propulsion pack model: it reads as idle.
        0.0
    }
}

fn json_string(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 => out.push_str(&format!("\\u{:04x}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// The driver's first line: `{"ok": true, "version": …, "trim": [a, e, r, t],
/// "trim_pitch_rad": …}` (trim when asked for) or
/// `{"error": …}`.
type TrimValues = ([f64; 4], f64);

fn parse_hello(line: &str) -> Result<(String, Option<TrimValues>), String> {
    #[derive(serde::Deserialize)]
    struct Hello {
        ok: Option<bool>,
        error: Option<String>,
        version: Option<String>,
        trim: Option<[f64; 4]>,
        trim_pitch_rad: Option<f64>,
    }
    let hello: Hello = serde_json::from_str(line.trim()).map_err(|_| {
        let shown: String = line.trim().chars().take(80).collect();
        format!("garbage from JSBSim's driver instead of its greeting: {shown:?}")
    })?;
    if let Some(e) = hello.error {
        return Err(e);
    }
    if hello.ok != Some(true) {
        return Err("JSBSim's driver did not say it was ready".into());
    }
    let trim = hello.trim.zip(hello.trim_pitch_rad);
    Ok((hello.version.unwrap_or_default(), trim))
}

fn spawn(config: &JsbsimConfig) -> Result<Driver, PlantError> {
    let mut child = Command::new(&config.python)
        .arg("-u")
        .arg("-c")
        .arg(DRIVER)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| PlantError(format!("jsbsim: cannot run {}: {e}", config.python)))?;
    let (Some(stdin), Some(stdout), Some(stderr)) =
        (child.stdin.take(), child.stdout.take(), child.stderr.take())
    else {
        let _ = child.kill();
        return Err(PlantError("jsbsim: the child's pipes are missing".into()));
    };
    let stderr_tail = Arc::new(Mutex::new(VecDeque::new()));
    let tail = Arc::clone(&stderr_tail);
    let (closed_tx, stderr_closed) = sync_channel(1);
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let line = line.trim().to_string();
            if line.is_empty() {
                continue;
            }
            if let Ok(mut t) = tail.lock() {
                if t.len() >= 8 {
                    t.pop_front();
                }
                t.push_back(line);
            }
        }
        let _ = closed_tx.send(());
    });
    // One frame in flight at a time: the channel needs no depth.
    let (tx, frames) = sync_channel(1);
    std::thread::spawn(move || {
        let mut reader = BufReader::new(stdout);
        let mut line = String::new();
        // The greeting (or an error) is a line of JSON; an error ends the conversation.
        match reader.read_line(&mut line) {
            Ok(n) if n > 0 => {
                let failed = !line.contains("\"ok\"");
                if tx.send(Err(line)).is_err() || failed {
                    return;
                }
            }
            _ => return,
        }
        let mut buf = [0u8; FIELDS * 8];
        loop {
            buf.fill(0);
            match reader.read_exact(&mut buf) {
                Ok(()) => {
                    let mut values = [0.0; FIELDS];
                    for (v, chunk) in values.iter_mut().zip(buf.chunks_exact(8)) {
                        let mut b = [0u8; 8];
                        b.copy_from_slice(chunk);
                        *v = f64::from_le_bytes(b);
                    }
                    if tx.send(Ok(Frame { values })).is_err() {
                        return;
                    }
                }
                Err(_) => {
                    // An error line after the greeting arrives as bytes: pass it on whole.
                    let text = String::from_utf8_lossy(&buf).into_owned();
                    let mut rest = String::new();
                    let _ = reader.read_to_string(&mut rest);
                    let all = format!("{text}{rest}")
                        .trim_matches('\0')
                        .trim()
                        .to_string();
                    if !all.is_empty() {
                        let _ = tx.send(Err(all));
                    }
                    return;
                }
            }
        }
    });
    Ok(Driver {
        child,
        stdin: Some(stdin),
        frames,
        stderr_tail,
        stderr_closed,
    })
}

#[cfg(test)]
mod tests;
