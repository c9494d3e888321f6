//! The vehicle's link end to end, on real UDP sockets on 127.0.0.1: `skyframe sim` sends
//! telemetry to this test; the test sends signed commands back.

use serde_json::Value;
use skyframe_core::link::auth::LinkKey;
use skyframe_core::link::frame::{Envelope, Verify, decode_datagram, encode_datagram};
use skyframe_core::link::messages::{AckResult, Command, Message, Telemetry};
use skyframe_tests::{scratch, skyframe, to_csv};
use std::net::{SocketAddr, UdpSocket};
use std::os::unix::fs::PermissionsExt;
use std::process::Stdio;
use std::time::{Duration, Instant};

struct Ground {
    socket: UdpSocket,
    vehicle: Option<SocketAddr>,
    run_id: u32,
    sequence: u32,
}

impl Ground {
    /// The next telemetry message (and when it came), or `None` after `within`.
    fn next(&mut self, within: Duration) -> Option<(Instant, Telemetry)> {
        let deadline = Instant::now() + within;
        let mut buf = [0u8; 2048];
        while Instant::now() < deadline {
            let Ok((n, from)) = self.socket.recv_from(&mut buf) else {
                continue;
            };
            if let Ok((header, Message::Telemetry(t))) = decode_datagram(&buf[..n], Verify::No) {
                self.vehicle = Some(from);
                self.run_id = header.envelope.run_id;
                return Some((Instant::now(), t));
            }
        }
        None
    }

    fn send(&mut self, command: Command, key: &LinkKey) {
        self.sequence += 1;
        let envelope = Envelope {
            vehicle_id: 1,
            sender_id: 7,
            run_id: self.run_id,
            sequence: self.sequence,
            t_ns: 0,
        };
        let mut buf = [0u8; 1472];
        let n = encode_datagram(&envelope, &Message::Command(command), Some(key), &mut buf)
            .expect("encodes");
        self.socket
            .send_to(&buf[..n], self.vehicle.expect("heard the vehicle"))
            .expect("sends");
    }
}

fn write_key(path: &std::path::Path, byte: u8) -> LinkKey {
    std::fs::write(path, format!("{}\n", format!("{byte:02x}").repeat(32))).expect("key");
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o600)).expect("chmod");
    LinkKey::new([byte; 32])
}

/// A ground socket on loopback whose reads time out after 50 ms, and its address.
fn ground_socket() -> (UdpSocket, SocketAddr) {
    let socket = UdpSocket::bind("127.0.0.1:0").expect("ground socket");
    socket
        .set_read_timeout(Some(Duration::from_millis(50)))
        .expect("timeout");
    let address = socket.local_addr().expect("addr");
    (socket, address)
}

/// `skyframe sim` in real time, unprivileged, sending telemetry to `telemetry` and taking
/// commands on a free port, with the key `dir/link.key` and logs in `dir/flights`; `extra`
/// comes first.
fn sim_on_link(
    dir: &std::path::Path,
    telemetry: SocketAddr,
    extra: &[&str],
) -> std::process::Command {
    let mut command = skyframe();
    command
        .arg("sim")
        .args(extra)
        .args([
            "--priority",
            "0",
            "--no-mlockall",
            "--commands",
            "127.0.0.1:0",
        ])
        .arg("--telemetry")
        .arg(telemetry.to_string())
        .arg("--key")
        .arg(dir.join("link.key"))
        .arg("--log-dir")
        .arg(dir.join("flights"));
    command
}

#[test]
fn telemetry_commands_rates_and_a_clean_authenticated_stop() {
    let dir = scratch("link-e2e");
    let key = write_key(&dir.join("link.key"), 0x5a);
    let wrong = LinkKey::new([0x5b; 32]);
    let (socket, telemetry) = ground_socket();
    let mut ground = Ground {
        socket,
        vehicle: None,
        run_id: 0,
        sequence: 0,
    };

    let child = sim_on_link(&dir, telemetry, &["--duration", "60", "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("skyframe sim");

    // Every task's status within 3 s of the first datagram.
    let mut statuses = std::collections::BTreeSet::new();
    let first = ground
        .next(Duration::from_secs(10))
        .expect("telemetry arrives")
        .0;
    while statuses.len() < 8 && first.elapsed() < Duration::from_secs(3) {
        if let Some((_, Telemetry::TaskStatus(s))) = ground.next(Duration::from_millis(200)) {
            statuses.insert(s.task_index);
        }
    }
    assert_eq!(
        statuses.len(),
        8,
        "every task's status within 3 s: {statuses:?}"
    );

    // IMU data (its fast format) at the default 1 Hz, then 10 Hz once the ground asks. The
    // columns' rotation (every 1.5 s) brings a latest record of its own.
    let imu_data_in = |ground: &mut Ground, seconds: u64| {
        let start = Instant::now();
        let mut count = 0;
        while start.elapsed() < Duration::from_secs(seconds) {
            if let Some((_, Telemetry::TaskData(d))) = ground.next(Duration::from_millis(100)) {
                count += u32::from(d.task_index == 0 && d.format_index == 1);
            }
        }
        count
    };
    let slow = imu_data_in(&mut ground, 2);
    ground.send(
        Command::SetTelemetryRate {
            task_index: 0,
            interval_ms: 100,
        },
        &key,
    );
    let mut acked = false;
    let start = Instant::now();
    while !acked && start.elapsed() < Duration::from_secs(2) {
        if let Some((_, Telemetry::CommandAck(a))) = ground.next(Duration::from_millis(100)) {
            acked = a.result == AckResult::Accepted;
        }
    }
    assert!(acked, "the rate change is acknowledged");
    let fast = imu_data_in(&mut ground, 2);
    assert!(
        slow <= 4 && fast >= 15,
        "imu data: {slow} in 2 s at 1 Hz, {fast} in 2 s at 10 Hz"
    );

    // A stop signed with the wrong key does nothing.
    ground.send(Command::Stop, &wrong);
    std::thread::sleep(Duration::from_millis(500));
    assert!(
        ground.next(Duration::from_millis(500)).is_some(),
        "still flying after a forged stop"
    );

    // The right key ends the run cleanly.
    ground.send(Command::Stop, &key);
    let out = child.wait_with_output().expect("exits");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: Value = serde_json::from_slice(&out.stdout).expect("JSON report");
    assert_eq!(report["stop_reason"], "requested");
    assert!(report["elapsed_s"].as_f64().unwrap_or(99.0) < 30.0);
    let link = &report["link"];
    assert_eq!(link["commands_accepted"], 2, "{link}");
    assert_eq!(link["commands_rejected"], 1, "the forged stop: {link}");
    let flight = report["flight_dir"].as_str().expect("dir");
    to_csv(&[flight], &dir.join("csv"));
}

#[test]
fn a_key_others_can_read_is_refused_in_one_line() {
    let dir = scratch("link-bad-key");
    let key = dir.join("open.key");
    write_key(&key, 1);
    std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o644)).expect("chmod");
    let out = skyframe()
        .args([
            "sim",
            "--fast",
            "--duration",
            "1",
            "--commands",
            "127.0.0.1:0",
            "--key",
        ])
        .arg(&key)
        .arg("--log-dir")
        .arg(dir.join("flights"))
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("readable by group or others"), "{err}");
}

#[test]
fn a_burst_of_overruns_reaches_the_ground_at_once_and_throttled() {
    let dir = scratch("link-overruns");
    write_key(&dir.join("link.key"), 0x5c);
    let (socket, telemetry) = ground_socket();
    // The IMU (budget 300 us, policy reset) overruns in every release of frames 300..600:
    // 300 overruns from 3 s to 6 s of the executive's clock.
    let child = sim_on_link(
        &dir,
        telemetry,
        &["--duration", "9", "--inject-overrun", "imu:1000@300..600"],
    )
    .stdout(Stdio::null())
    .stderr(Stdio::null())
    .spawn()
    .expect("skyframe sim");

    // Every IMU status, by the vehicle's clock (s), with its budget overruns.
    let mut imu = Vec::new();
    let mut buf = [0u8; 2048];
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(20) {
        let Ok((n, _)) = socket.recv_from(&mut buf) else {
            continue;
        };
        if let Ok((header, Message::Telemetry(t))) = decode_datagram(&buf[..n], Verify::No) {
            match t {
                Telemetry::TaskStatus(s) if s.task_index == 0 => {
                    imu.push((header.envelope.t_ns as f64 * 1e-9, s.overruns_budget));
                }
                Telemetry::ExecutiveStatus(e) if e.elapsed_ns >= 8_900_000_000 => break,
                _ => {}
            }
        }
    }
    let output = child.wait_with_output().expect("exits");
    assert!(output.status.success());

    // The first report after the burst began came within a second and counted overruns.
    let first = imu.iter().find(|(t, _)| *t >= 3.0).copied();
    assert!(
        first.is_some_and(|(t, overruns)| t < 4.0 && overruns > 0),
        "{imu:?}"
    );
    // Throttled: about one status a second while 300 overruns happened, not one each.
    let in_burst = imu.iter().filter(|(t, _)| (3.0..7.0).contains(t)).count();
    assert!((2..=6).contains(&in_burst), "{in_burst} statuses: {imu:?}");
    // The summary after the burst has them all.
    let last = imu.last().map_or(0, |(_, o)| *o);
    assert!(last >= 295, "{imu:?}");
}
