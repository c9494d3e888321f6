//! `detect --send`: a fake vehicle on localhost receives the horizon commands and checks them
//! as the link protocol says (signed with the key, its run id and vehicle id, fresh sequence).

use skyframe_core::link::frame::{Envelope, Verify, decode_datagram, encode_datagram};
use skyframe_core::link::messages::{AckResult, CommandAck};
use skyframe_core::link::{Command, LinkKey, Message, Telemetry};
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::Command as Process;
use std::time::Duration;

const KEY_HEX: &str = "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f";

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "skyframe-horizon-send-{}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch");
    dir
}

fn flight(dir: &Path, frames: usize) {
    let status = Process::new(env!("CARGO_BIN_EXE_skyframe-horizon"))
        .args([
            "synth",
            "--out",
            dir.to_str().expect("utf-8"),
            "--frames",
            &frames.to_string(),
        ])
        .args(["--format", "pgm", "--seed", "4"])
        .status()
        .expect("synth");
    assert!(status.success());
    write_key(dir, format!("{KEY_HEX}\n").as_bytes(), 0o600);
}

/// The key file as the link wants it: readable by its owner only.
fn write_key(dir: &Path, contents: &[u8], mode: u32) {
    use std::os::unix::fs::PermissionsExt;
    let path = dir.join("key");
    std::fs::write(&path, contents).expect("key file");
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(mode)).expect("chmod");
}

fn key() -> LinkKey {
    LinkKey::from_hex(KEY_HEX).expect("key")
}

/// The horizon commands the vehicle socket receives, with their envelopes.
fn receive(vehicle: &UdpSocket, count: usize) -> Vec<(Envelope, f32, f32, u64)> {
    vehicle
        .set_read_timeout(Some(Duration::from_secs(20)))
        .expect("timeout");
    let mut out = Vec::new();
    let mut buffer = [0u8; 1500];
    while out.len() < count {
        let (n, _) = vehicle.recv_from(&mut buffer).expect("a command arrives");
        let (header, message) =
            decode_datagram(&buffer[..n], Verify::Required(&key())).expect("signed with the key");
        let Message::Command(Command::HorizonAttitude(h)) = message else {
            panic!("not a horizon command: {message:?}");
        };
        out.push((
            header.envelope,
            h.roll_rad.to_degrees(),
            h.pitch_rad.to_degrees(),
            h.capture_t_ns,
        ));
    }
    out
}

fn truth(dir: &Path) -> Vec<(f32, f32)> {
    std::fs::read_to_string(dir.join("truth.csv"))
        .expect("truth")
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<f32> = l.split(',').map(|v| v.parse().expect("number")).collect();
            (f[1], f[2])
        })
        .collect()
}

#[test]
fn commands_carry_the_given_run_and_vehicle() {
    let dir = scratch("given");
    flight(&dir, 3);
    let vehicle = UdpSocket::bind("127.0.0.1:0").expect("vehicle socket");
    let address = vehicle.local_addr().expect("address").to_string();
    let out = Process::new(env!("CARGO_BIN_EXE_skyframe-horizon"))
        .args(["detect", dir.to_str().expect("utf-8"), "--send", &address])
        .args(["--key", dir.join("key").to_str().expect("utf-8")])
        .args([
            "--run-id",
            "305419896",
            "--vehicle-id",
            "7",
            "--sender-id",
            "3",
        ])
        .output()
        .expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let received = receive(&vehicle, 3);
    for (i, ((envelope, roll, pitch, _), (true_roll, true_pitch))) in
        received.iter().zip(truth(&dir)).enumerate()
    {
        assert_eq!(
            (
                envelope.run_id,
                envelope.vehicle_id,
                envelope.sender_id,
                envelope.sequence
            ),
            (0x1234_5678, 7, 3, i as u32 + 1)
        );
        assert!((roll - true_roll).abs() < 1.0 && (pitch - true_pitch).abs() < 1.0);
    }
}

#[test]
fn run_id_and_clock_are_learned_from_telemetry() {
    let dir = scratch("learned");
    flight(&dir, 2);
    let vehicle = UdpSocket::bind("127.0.0.1:0").expect("vehicle socket");
    let vehicle_address = vehicle.local_addr().expect("address").to_string();
    // A free port for the tool's telemetry socket.
    let listen = UdpSocket::bind("127.0.0.1:0")
        .expect("probe")
        .local_addr()
        .expect("address");
    let mut child = Process::new(env!("CARGO_BIN_EXE_skyframe-horizon"))
        .args([
            "detect",
            dir.to_str().expect("utf-8"),
            "--send",
            &vehicle_address,
        ])
        .args(["--key", dir.join("key").to_str().expect("utf-8")])
        .args(["--listen", &listen.to_string(), "--wait", "20"])
        .spawn()
        .expect("spawns");
    // The vehicle's telemetry (a CommandAck will do), every 50 ms until commands arrive.
    let telemetry = Message::Telemetry(Telemetry::CommandAck(CommandAck {
        command_sender_id: 1,
        command_sequence: 1,
        command_type: 0x85,
        result: AckResult::Accepted,
        value_in_force: None,
    }));
    let envelope = Envelope {
        vehicle_id: 9,
        sender_id: 0,
        run_id: 0xBEEF,
        sequence: 1,
        t_ns: 5_000_000_000,
    };
    let mut datagram = [0u8; 1500];
    let n = encode_datagram(&envelope, &telemetry, None, &mut datagram).expect("encodes");
    vehicle
        .set_read_timeout(Some(Duration::from_millis(50)))
        .expect("timeout");
    let mut buffer = [0u8; 1500];
    let started = std::time::Instant::now();
    let first = loop {
        // A tool that gave up (or never started listening) ends the test, not a hang.
        if let Some(status) = child.try_wait().expect("wait") {
            panic!("skyframe-horizon exited before sending: {status}");
        }
        assert!(
            started.elapsed() < Duration::from_secs(30),
            "no command in 30 s"
        );
        vehicle
            .send_to(&datagram[..n], listen)
            .expect("telemetry sent");
        if let Ok((m, _)) = vehicle.recv_from(&mut buffer) {
            break buffer[..m].to_vec();
        }
    };
    let (header, message) = decode_datagram(&first, Verify::Required(&key())).expect("signed");
    assert!(matches!(
        message,
        Message::Command(Command::HorizonAttitude(_))
    ));
    assert_eq!(
        (header.envelope.run_id, header.envelope.vehicle_id),
        (0xBEEF, 9)
    );
    // Capture times are on the vehicle's clock: just after its 5 s telemetry.
    let Message::Command(Command::HorizonAttitude(h)) = message else {
        unreachable!()
    };
    assert!(
        (5_000_000_000..15_000_000_000).contains(&h.capture_t_ns),
        "{}",
        h.capture_t_ns
    );
    let rest = receive(&vehicle, 1);
    assert_eq!(rest[0].0.sequence, header.envelope.sequence + 1);
    assert!(child.wait_with_output().expect("exits").status.success());
}

#[test]
fn a_bad_key_file_is_refused() {
    let dir = scratch("badkey");
    flight(&dir, 1);
    write_key(&dir, b"not hex", 0o600);
    let out = Process::new(env!("CARGO_BIN_EXE_skyframe-horizon"))
        .args([
            "detect",
            dir.to_str().expect("utf-8"),
            "--send",
            "127.0.0.1:9",
        ])
        .args([
            "--key",
            dir.join("key").to_str().expect("utf-8"),
            "--run-id",
            "1",
            "--vehicle-id",
            "1",
        ])
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("64 hex digits"));
}

#[test]
fn a_key_others_can_read_is_refused() {
    let dir = scratch("openkey");
    flight(&dir, 1);
    write_key(&dir, format!("{KEY_HEX}\n").as_bytes(), 0o644);
    let out = Process::new(env!("CARGO_BIN_EXE_skyframe-horizon"))
        .args([
            "detect",
            dir.to_str().expect("utf-8"),
            "--send",
            "127.0.0.1:9",
        ])
        .args(["--key", dir.join("key").to_str().expect("utf-8")])
        .args(["--run-id", "1", "--vehicle-id", "1"])
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(2));
    let text = String::from_utf8_lossy(&out.stderr);
    assert!(
        text.contains("readable by group or others (mode 644)"),
        "{text}"
    );
}
