//! `skyframe-sim --pty`: the simulated airplane's devices on pseudo-terminals, in real time,
//! so an unmodified `skyframe run --vehicle FILE` flies it as if it were hardware.
//!
//! Exit codes: 0 the scenario ran to its end (or was stopped); 2 bad usage, a scenario that
//! does not parse, ports or files that cannot be made (one line on stderr).

use clap::Parser;
use serialport::{SerialPort, TTYPort};
use skyframe_sim::scenario::Scenario;
use skyframe_sim::world::{Device, DeviceLink, SimWorld};
use std::io::{Read, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

#[derive(Parser, Debug)]
#[command(
    name = "skyframe-sim",
    version,
    about = "The simulated airplane's IMU, GPS and servo board on pseudo-terminals, in real \
             time, for `skyframe run`"
)]
struct Args {
    /// Serve the devices on pseudo-terminals (the only mode so far; in-process simulation is
    /// `skyframe sim`).
    #[arg(long)]
    pty: bool,
    /// The scenario to fly (default: the shipped take-off, circuit and landing).
    #[arg(long, value_name = "FILE")]
    scenario: Option<PathBuf>,
    /// Seed of the simulation's random processes (default: the scenario's).
    #[arg(long)]
    seed: Option<u64>,
    /// Seconds to run (default: the scenario's duration).
    #[arg(long)]
    duration: Option<f64>,
    /// Write a vehicle file naming the three ports, for `skyframe run --vehicle`.
    #[arg(long, value_name = "FILE")]
    write_vehicle: Option<PathBuf>,
    /// Benchmark a flight model instead: trimmed level flight stepped as the world steps it
    /// (1 ms, an IMU reading every 10 ms), as fast as it goes; prints JSON. Meaningful on a
    /// release build.
    #[arg(long, value_name = "builtin|jsbsim", conflicts_with = "pty")]
    bench_plant: Option<String>,
    /// With --bench-plant jsbsim: the aircraft (default c172x).
    #[arg(long, value_name = "NAME", requires = "bench_plant")]
    aircraft: Option<String>,
    /// With --bench-plant: simulated seconds to fly (default 60).
    #[arg(long, requires = "bench_plant")]
    seconds: Option<f64>,
}

/// `--bench-plant`: simulated seconds per wall-clock second of a flight model with its
/// sensors, the plant's share of a `skyframe sim --fast` run.
fn bench_plant(name: &str, aircraft: Option<&str>, seconds: f64) -> Result<(), String> {
    use skyframe_sim::plant::jsbsim::{JsbsimConfig, JsbsimModel, JsbsimStart};
    use skyframe_sim::plant::trim::trim_level_flight;
    use skyframe_sim::plant::{Plant, PlantConfig, PlantKind};
    let kind = PlantKind::from_names(name, aircraft)?;
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= 86_400.0) {
        return Err(format!("--seconds {seconds}: must be in (0, 86400]"));
    }
    let config = PlantConfig::default();
    let (mut plant, commands) = match &kind {
        PlantKind::BuiltIn => {
            let trim = trim_level_flight(&config.params, 23.0, 100.0, 0.0)
                .map_err(|e| format!("trim: {e:?}"))?;
            (
                Plant::with_config(config, trim.initial, 1).boxed(),
                trim.commands,
            )
        }
        PlantKind::Jsbsim { aircraft } => {
            let start = JsbsimStart::InFlight {
                altitude_m: 300.0,
                airspeed_mps: if aircraft == "c172x" { 40.0 } else { 23.0 },
                heading_rad: 0.0,
            };
            let model = JsbsimModel::start(JsbsimConfig::new(aircraft), &config, start, 1)
                .map_err(|e| e.to_string())?;
            let (commands, _) = model
                .trim()
                .ok_or("JSBSim gave no trim for the benchmark's level flight")?;
            (Plant::with_model(config, model, 1).boxed(), commands)
        }
    };
    let steps = (seconds * 1000.0).round() as u64;
    let started = Instant::now();
    for k in 0..steps {
        plant
            .try_step(0.001, &commands)
            .map_err(|e| e.to_string())?;
        if k % 10 == 9 {
            std::hint::black_box(plant.sample_imu());
        }
        while plant.sample_gps().is_some() {}
    }
    let wall_s = started.elapsed().as_secs_f64();
    let truth = plant.truth();
    println!(
        "{{\"plant\": \"{}\", \"aircraft\": \"{}\", \"build\": \"{}\", \"simulated_s\": {seconds}, \"wall_s\": {wall_s:.4}, \"times_real_time\": {:.1}, \"us_per_1ms_step\": {:.3}, \"final_airspeed_mps\": {:.2}}}",
        kind.plant_name(),
        kind.aircraft_name(),
        if cfg!(debug_assertions) {
            "debug"
        } else {
            "release"
        },
        seconds / wall_s,
        wall_s * 1e6 / steps as f64,
        truth.airspeed_mps,
    );
    Ok(())
}

const DEFAULT_SCENARIO: &str = include_str!("../../../scenarios/takeoff-circuit.toml");
/// The world advances in steps of this much real time.
const TICK: Duration = Duration::from_millis(2);

/// The three pty masters: the devices' ends of the lines.
struct PtyLink {
    ports: [TTYPort; 3],
    /// Bytes the flight computer had no room for (it is not reading, or not there yet).
    dropped: u64,
    commands_read: u64,
}

fn slot(device: Device) -> usize {
    match device {
        Device::Imu => 0,
        Device::Gps => 1,
        Device::Servo => 2,
    }
}

impl DeviceLink for PtyLink {
    fn send_to_computer(&mut self, device: Device, bytes: &[u8]) {
        if let Some(port) = self.ports.get_mut(slot(device)) {
            // A short timeout: a device does not wait for a computer that is not listening.
            if port.write_all(bytes).is_err() {
                self.dropped += bytes.len() as u64;
            }
        }
    }

    fn receive_from_computer(&mut self, buf: &mut [u8]) -> usize {
        let Some(port) = self.ports.get_mut(2) else {
            return 0;
        };
        match port.bytes_to_read() {
            Ok(n) if n > 0 => match port.read(buf) {
                Ok(read) => {
                    self.commands_read += read as u64;
                    read
                }
                Err(_) => 0,
            },
            _ => 0,
        }
    }
}

fn pty() -> Result<(TTYPort, String), String> {
    let (mut master, slave) = TTYPort::pair().map_err(|e| format!("cannot make a pty: {e}"))?;
    master
        .set_timeout(Duration::from_millis(1))
        .map_err(|e| format!("pty timeout: {e}"))?;
    let path = slave.name().ok_or("a pty without a name")?;
    // The flight computer opens the slave by path; ours is not needed.
    drop(slave);
    Ok((master, path))
}

fn run(args: Args) -> Result<(), String> {
    if let Some(plant) = &args.bench_plant {
        return bench_plant(
            plant,
            args.aircraft.as_deref(),
            args.seconds.unwrap_or(60.0),
        );
    }
    if !args.pty {
        return Err("nothing to do: pass --pty (in-process simulation is `skyframe sim`)".into());
    }
    let scenario = match &args.scenario {
        Some(path) => Scenario::load(path),
        None => Scenario::parse(DEFAULT_SCENARIO),
    }
    .map_err(|e| e.to_string())?;
    let mut world = SimWorld::from_scenario(&scenario, args.seed).map_err(|e| e.to_string())?;
    let (imu, imu_path) = pty()?;
    let (gps, gps_path) = pty()?;
    let (servo, servo_path) = pty()?;
    println!("imu   {imu_path}\ngps   {gps_path}\nservo {servo_path}");
    if let Some(file) = &args.write_vehicle {
        let text = format!(
            "# Written by skyframe-sim --pty: the simulated airplane's devices.\n\
             [devices.imu]\nport = \"{imu_path}\"\nbaud = 57600\nstale_ms = 50\n\n\
             [devices.gps]\nport = \"{gps_path}\"\nbaud = 115200\nstale_ms = 500\n\n\
             [devices.servo]\nport = \"{servo_path}\"\nbaud = 38400\nstale_ms = 100\n"
        );
        // Written whole under another name, then renamed: a reader never sees half a file.
        let tmp = file.with_extension("tmp");
        std::fs::write(&tmp, text)
            .and_then(|()| std::fs::rename(&tmp, file))
            .map_err(|e| format!("cannot write {}: {e}", file.display()))?;
        println!("vehicle file {}", file.display());
    }
    let _ = std::io::stdout().flush();

    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, Arc::clone(&stop))
            .map_err(|e| format!("cannot install signal handlers: {e}"))?;
    }
    let mut link = PtyLink {
        ports: [imu, gps, servo],
        dropped: 0,
        commands_read: 0,
    };
    let duration = Duration::from_secs_f64(args.duration.unwrap_or(scenario.duration_s).max(0.0));
    let start = Instant::now();
    while !stop.load(Ordering::Relaxed) && start.elapsed() < duration {
        std::thread::sleep(TICK);
        let now_ns = u64::try_from(start.elapsed().as_nanos()).unwrap_or(u64::MAX);
        world.advance_to(now_ns, &mut link);
        if let Some(e) = world.failure() {
            return Err(format!("the simulated airplane stopped: {e}"));
        }
    }
    let stats = world.stats();
    let truth = world.truth();
    println!(
        "flew {:.1} s: {} IMU frames, {} GPS epochs, {} board reports sent; {} command frames \
         received ({} B), {} B refused by the computer's lines; {:.0} m from home at {:.0} m",
        start.elapsed().as_secs_f64(),
        stats.imu_frames,
        stats.gps_epochs,
        stats.board_frames,
        stats.command_frames,
        link.commands_read,
        link.dropped,
        truth.position_ned_m[0].hypot(truth.position_ned_m[1]),
        -truth.position_ned_m[2],
    );
    Ok(())
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("skyframe-sim: {message}");
            ExitCode::from(2)
        }
    }
}
