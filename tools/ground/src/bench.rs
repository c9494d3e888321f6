//! `bench`: many fake vehicles on loopback, each on its own thread at the link's fastest
//! telemetry, into one receive path (socket → decode → model) on this thread.
//!
//! Each vehicle sends, per second: every task's data at 20 Hz (the protocol's fastest,
//! `MIN_TELEMETRY_INTERVAL_MS` = 50; 5 tasks, servo with 2 formats: 120 TaskData/s), each
//! task's TaskFormat every 10 s, one TaskStatus per second in rotation and the
//! ExecutiveStatus every 2 s, as `TelemetrySchedule` times them: about 122 datagrams/s.

use crate::exit::Exit;
use crate::fake_vehicle::{FakeVehicle, FakeVehicleConfig};
use crate::model::GroundModel;
use crate::net::{GroundLink, apply};
use nix::sys::resource::{UsageWho, getrusage};
use serde_json::json;
use skyframe_core::link::auth::LinkKey;
use skyframe_core::link::messages::limits::MIN_TELEMETRY_INTERVAL_MS;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

fn cpu_seconds(who: UsageWho) -> f64 {
    getrusage(who).map_or(0.0, |u| {
        let t = |tv: nix::sys::time::TimeVal| tv.tv_sec() as f64 + tv.tv_usec() as f64 * 1e-6;
        t(u.user_time()) + t(u.system_time())
    })
}

#[derive(Clone, Debug, PartialEq)]
pub struct BenchResult {
    pub vehicles: u16,
    pub seconds: f64,
    pub sent: u64,
    pub handled: u64,
    pub messages_per_s: f64,
    /// Sent but not handled, per cent of sent.
    pub loss_percent: f64,
    /// Loss as the ground itself measured it from sequence gaps.
    pub ground_measured_loss_percent: f64,
    /// The receive path's thread: its share of one core.
    pub receive_cpu_percent: f64,
    /// The whole process, fake vehicles included.
    pub process_cpu_percent: f64,
    pub vehicles_seen: usize,
}

pub fn measure(vehicles: u16, seconds: f64) -> Result<BenchResult, Exit> {
    if vehicles == 0 || !seconds.is_finite() || seconds <= 0.0 {
        return Err(Exit::usage("bench needs --vehicles ≥ 1 and --seconds > 0"));
    }
    let duration = Duration::from_secs_f64(seconds.min(3600.0));
    let key = LinkKey::new([0x5a; 32]);
    let mut link =
        GroundLink::bind(([127, 0, 0, 1], 0).into(), Some(key.clone())).map_err(Exit::usage)?;
    let ground = link.local_addr().map_err(|e| Exit::usage(e.to_string()))?;
    let stop = Arc::new(AtomicBool::new(false));
    let mut senders = Vec::new();
    for id in 1..=vehicles {
        let vehicle = FakeVehicle::bind(FakeVehicleConfig {
            vehicle_id: id,
            run_id: 0x0100_0000 + u32::from(id),
            key: key.clone(),
            sign_telemetry: false,
            telemetry_to: ground,
            data_interval_ms: MIN_TELEMETRY_INTERVAL_MS,
            duration: Duration::ZERO,
        })
        .map_err(|e| Exit::usage(format!("cannot bind a fake vehicle: {e}")))?;
        senders.push(vehicle.spawn(Arc::clone(&stop), duration + Duration::from_secs(5)));
    }
    let mut model = GroundModel::default();
    let mut handled = 0u64;
    let thread_cpu_start = cpu_seconds(UsageWho::RUSAGE_THREAD);
    let process_cpu_start = cpu_seconds(UsageWho::RUSAGE_SELF);
    let start = Instant::now();
    let end = start + duration;
    while Instant::now() < end {
        match link.receive(Duration::from_millis(50)) {
            Ok(Some(received)) => {
                apply(&mut model, &received, Instant::now());
                handled += 1;
            }
            Ok(None) => {}
            Err(e) => return Err(Exit::usage(format!("receive failed: {e}"))),
        }
    }
    stop.store(true, Ordering::Relaxed);
    // What the vehicles sent up to the moment they stop is what we should have seen: drain
    // the socket for datagrams already queued before counting.
    let mut sent = 0u64;
    for handle in senders {
        sent += handle.join().map(|r| r.sent).unwrap_or(0);
    }
    while let Ok(Some(received)) = link.receive(Duration::from_millis(20)) {
        apply(&mut model, &received, Instant::now());
        handled += 1;
    }
    let elapsed = start.elapsed().as_secs_f64();
    let thread_cpu = cpu_seconds(UsageWho::RUSAGE_THREAD) - thread_cpu_start;
    let process_cpu = cpu_seconds(UsageWho::RUSAGE_SELF) - process_cpu_start;
    let (received, missed) = model.vehicles.values().fold((0u64, 0u64), |(r, m), v| {
        (r + v.link.received, m + v.link.missed)
    });
    let percent = |part: f64, whole: f64| {
        if whole > 0.0 {
            100.0 * part / whole
        } else {
            0.0
        }
    };
    Ok(BenchResult {
        vehicles,
        seconds: elapsed,
        sent,
        handled,
        messages_per_s: handled as f64 / elapsed,
        loss_percent: percent(sent.saturating_sub(handled) as f64, sent as f64),
        ground_measured_loss_percent: percent(missed as f64, (received + missed) as f64),
        receive_cpu_percent: percent(thread_cpu, elapsed),
        process_cpu_percent: percent(process_cpu, elapsed),
        vehicles_seen: model.vehicles.len(),
    })
}

pub fn run(vehicles: u16, seconds: f64, as_json: bool) -> Result<(), Exit> {
    let r = measure(vehicles, seconds)?;
    if as_json {
        println!(
            "{}",
            json!({
                "vehicles": r.vehicles,
                "seconds": r.seconds,
                "sent": r.sent,
                "handled": r.handled,
                "messages_per_s": r.messages_per_s,
                "loss_percent": r.loss_percent,
                "ground_measured_loss_percent": r.ground_measured_loss_percent,
                "receive_cpu_percent": r.receive_cpu_percent,
                "process_cpu_percent": r.process_cpu_percent,
                "vehicles_seen": r.vehicles_seen,
            })
        );
    } else {
        println!(
            "{} vehicles, {:.1} s: {} sent, {} handled ({:.0} messages/s), loss {:.2} % \
             (ground's own count {:.2} %), receive thread CPU {:.1} %, process CPU {:.1} %",
            r.vehicles,
            r.seconds,
            r.sent,
            r.handled,
            r.messages_per_s,
            r.loss_percent,
            r.ground_measured_loss_percent,
            r.receive_cpu_percent,
            r.process_cpu_percent
        );
    }
    Ok(())
}
