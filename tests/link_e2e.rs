//! The vehicle's link end to end, on real UDP sockets on 127.0.0.1: `skyframe sim` sends
//! telemetry to this test; the test sends signed commands back.

use serde_json::Value;
use skyframe_core::link::auth::LinkKey;
use skyframe_core::link::frame::{Envelope, Verify, decode_datagram, encode_datagram};
use skyframe_core::link::messages::{
    AckResult, Command, LogHealth, Message, TaskData, Telemetry, Value as LinkValue,
};
use skyframe_core::schedule::SHIPPED;
use skyframe_logtable::{load_stream, time_ns};
use skyframe_tests::{finish_ok, scratch, skyframe, spawn_piped, to_csv};
use std::collections::BTreeMap;
use std::net::{SocketAddr, UdpSocket};
use std::os::unix::fs::PermissionsExt;
use std::process::Stdio;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

struct Ground {
    socket: UdpSocket,
    vehicle: Option<SocketAddr>,
    run_id: u32,
    sequence: u32,
}

impl Ground {
    /// A ground on a fresh loopback socket that has heard nothing yet, and its address.
    fn listening() -> (Self, SocketAddr) {
        let (socket, address) = ground_socket();
        let ground = Self {
            socket,
            vehicle: None,
            run_id: 0,
            sequence: 0,
        };
        (ground, address)
    }

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
    let (mut ground, telemetry) = Ground::listening();

    let child = spawn_piped(sim_on_link(
        &dir,
        telemetry,
        &["--duration", "60", "--json"],
    ));

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
    let out = finish_ok(child);
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
    // Throttled: about one status a second while 300 overruns happened, not one each (plus
    // the one that leads the IMU's column names every 1.5 s and the 1 Hz rotation's).
    let in_burst = imu.iter().filter(|(t, _)| (3.0..7.0).contains(t)).count();
    assert!((2..=10).contains(&in_burst), "{in_burst} statuses: {imu:?}");
    // The summary after the burst has them all.
    let last = imu.last().map_or(0, |(_, o)| *o);
    assert!(last >= 295, "{imu:?}");
}

/// The log stream a task writes (`docs/log-streams.md`); `None` for a task that logs nothing.
fn stream_of(task: &str) -> Option<&'static str> {
    match task {
        "imu" => Some("imu"),
        "gps" => Some("gps"),
        "servo" => Some("servo"),
        "estimator" => Some("estimator"),
        "control" => Some("control"),
        "health" => Some("health"),
        "watchdog" => Some("watchdog"),
        "telemetry" => Some("link"),
        _ => None,
    }
}

fn shipped_task(index: u8) -> &'static str {
    SHIPPED
        .tasks
        .get(usize::from(index))
        .map_or("?", |slot| slot.name)
}

/// A value on the link as the log reader gives it (`skyframe_logtable::value_f64`).
fn link_value_f64(value: &LinkValue) -> f64 {
    match *value {
        LinkValue::Bool(b) => f64::from(u8::from(b)),
        LinkValue::I32(v) => f64::from(v),
        LinkValue::U32(v) => f64::from(v),
        LinkValue::F32(v) => f64::from(v),
        LinkValue::F64(v) => v,
    }
}

fn same(a: f64, b: f64) -> bool {
    a == b || (a.is_nan() && b.is_nan())
}

/// The flight directory a `--json` run reported.
fn flight_dir(stdout: &[u8]) -> std::path::PathBuf {
    let report: Value = serde_json::from_slice(stdout).expect("JSON report");
    report["flight_dir"].as_str().expect("flight_dir").into()
}

/// Every TaskData that arrived is the log record of the same task and format at the same TIME,
/// value for value, and every task that logs sent some.
#[test]
fn every_task_sends_its_logged_values_and_they_equal_the_log() {
    let dir = scratch("link-values");
    write_key(&dir.join("link.key"), 0x5d);
    let (mut socket, telemetry) = ground_socket();
    let child = spawn_piped(sim_on_link(&dir, telemetry, &["--duration", "8", "--json"]));
    let mut data: Vec<TaskData> = Vec::new();
    let mut columns: BTreeMap<(u8, u8), String> = BTreeMap::new();
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(25) {
        match receive(&mut socket) {
            Some(Telemetry::TaskData(d)) => data.push(d),
            Some(Telemetry::TaskFormat(f)) => {
                let text = String::from_utf8_lossy(&f.columns).into_owned();
                columns.insert((f.task_index, f.format_index), text);
            }
            Some(Telemetry::ExecutiveStatus(e)) if e.elapsed_ns >= 7_900_000_000 => break,
            _ => {}
        }
    }
    let out = finish_ok(child);
    let flight = flight_dir(&out.stdout);

    let mut streams = BTreeMap::new();
    for task in SHIPPED.tasks.iter().filter_map(|t| stream_of(t.name)) {
        let path = flight.join(format!("{task}.bin"));
        let stream = load_stream(&path, |p| panic!("{}: {p:?}", path.display())).expect("reads");
        streams.insert(task, stream);
    }
    let mut checked: BTreeMap<&str, usize> = BTreeMap::new();
    for d in &data {
        let task = shipped_task(d.task_index);
        let stream = &streams[stream_of(task).expect("only logging tasks send data")];
        let table = stream
            .table(d.format_index)
            .unwrap_or_else(|| panic!("{task}: no format {} in the log", d.format_index));
        // The names on the link are the log's Format Comment.
        assert_eq!(
            columns.get(&(d.task_index, d.format_index)),
            Some(&table.columns.join(",")),
            "{task} format {}",
            d.format_index
        );
        assert!(!d.values.is_empty(), "{task}: empty values");
        assert_eq!(d.values.len(), table.columns.len(), "{task}");
        let t = time_ns(d.time);
        let matches_row = |row: usize| {
            d.values
                .iter()
                .zip(&table.values)
                .all(|(v, column)| same(link_value_f64(v), column[row]))
        };
        let found = (0..table.times_ns.len())
            .filter(|&row| table.times_ns[row] == t)
            .any(matches_row);
        assert!(
            found,
            "{task} format {} at {}: {:?} is not the logged record",
            d.format_index, d.time, d.values
        );
        *checked.entry(task).or_default() += 1;
    }
    // Every task of the schedule logs, so every task sent values.
    for task in SHIPPED.tasks.iter().map(|t| t.name) {
        assert!(stream_of(task).is_some(), "{task} logs nothing");
        assert!(
            checked.get(task).copied().unwrap_or(0) >= 3,
            "{task}: {checked:?}"
        );
    }
    // Every format the logs hold was on the link, named.
    for (task_index, slot) in SHIPPED.tasks.iter().enumerate() {
        let Some(stream) = stream_of(slot.name).map(|s| &streams[s]) else {
            continue;
        };
        for index in stream.tables.keys() {
            assert!(
                columns.contains_key(&(task_index as u8, *index)),
                "{} format {index} never named",
                slot.name
            );
        }
    }
}

/// The next telemetry message within 50 ms, decoded.
fn receive(socket: &mut UdpSocket) -> Option<Telemetry> {
    let mut buf = [0u8; 2048];
    let (n, _) = socket.recv_from(&mut buf).ok()?;
    match decode_datagram(&buf[..n], Verify::No) {
        Ok((_, Message::Telemetry(t))) => Some(t),
        _ => None,
    }
}

/// A ground that joins 5 s late, and one that loses the link for 3 s and forgets what it
/// knew, both have every task's name and every logged format's column names within 2 s.
#[test]
fn a_late_or_cut_off_ground_has_every_name_within_two_seconds() {
    let dir = scratch("link-late");
    write_key(&dir.join("link.key"), 0x5e);
    let (mut ground, ground_address) = ground_socket();
    // The vehicle sends to a relay that drops everything while `cut` is set.
    let relay = UdpSocket::bind("127.0.0.1:0").expect("relay");
    relay
        .set_read_timeout(Some(Duration::from_millis(50)))
        .expect("timeout");
    let relay_address = relay.local_addr().expect("addr");
    let cut = Arc::new(AtomicBool::new(true));
    let done = Arc::new(AtomicBool::new(false));
    let relay_thread = {
        let (cut, done) = (cut.clone(), done.clone());
        std::thread::spawn(move || {
            let mut buf = [0u8; 2048];
            while !done.load(Ordering::Relaxed) {
                if let Ok((n, _)) = relay.recv_from(&mut buf)
                    && !cut.load(Ordering::Relaxed)
                {
                    let _ = relay.send_to(&buf[..n], ground_address);
                }
            }
        })
    };
    let child = spawn_piped(sim_on_link(
        &dir,
        relay_address,
        &["--duration", "16", "--json"],
    ));

    // Names heard since `since`, with when they came.
    let listen = |ground: &mut UdpSocket, seconds: f64| {
        let since = Instant::now();
        // (task, format) → when its columns came; (task, 0) → when its name (status) came.
        let mut named: BTreeMap<(u8, u8), Duration> = BTreeMap::new();
        while since.elapsed().as_secs_f64() < seconds {
            match receive(ground) {
                Some(Telemetry::TaskFormat(f)) => {
                    named
                        .entry((f.task_index, f.format_index))
                        .or_insert(since.elapsed());
                }
                Some(Telemetry::TaskStatus(s)) if s.name.as_str() == shipped_task(s.task_index) => {
                    named.entry((s.task_index, 0)).or_insert(since.elapsed());
                }
                _ => {}
            }
        }
        named
    };
    // Joins once the vehicle has flown 5 s (its first datagram marks its start).
    std::thread::sleep(Duration::from_secs(5));
    cut.store(false, Ordering::Relaxed);
    let late_join = listen(&mut ground, 4.0);
    // Link lost for 3 s; the ground forgets (a restart).
    cut.store(true, Ordering::Relaxed);
    std::thread::sleep(Duration::from_secs(3));
    while receive(&mut ground).is_some() {}
    cut.store(false, Ordering::Relaxed);
    let after_loss = listen(&mut ground, 3.0);

    let out = child.wait_with_output().expect("exits");
    done.store(true, Ordering::Relaxed);
    let _ = relay_thread.join();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let flight = flight_dir(&out.stdout);
    for (task_index, slot) in SHIPPED.tasks.iter().enumerate() {
        let Some(stream) = stream_of(slot.name) else {
            continue;
        };
        let path = flight.join(format!("{stream}.bin"));
        let logged = load_stream(&path, |_| {}).expect("reads");
        // Format indices start at 1; 0 stands for the task's name (its status).
        for index in std::iter::once(&0).chain(logged.tables.keys()) {
            for (when, named) in [("late join", &late_join), ("after loss", &after_loss)] {
                let at = named.get(&(task_index as u8, *index));
                assert!(
                    at.is_some_and(|d| *d <= Duration::from_secs(2)),
                    "{when}: {} format {index} named at {at:?}",
                    slot.name
                );
            }
        }
    }
}

/// A flood of forged commands — valid header and CRC, the right vehicle and run, signed with
/// another key — from several sources at once, as fast as one thread can send, while the key
/// holder asks for a parameter 50 times: every genuine command is acknowledged, and the
/// vehicle's counters account for the flood (screened out as badly signed, or rate-limited).
#[test]
fn a_flood_of_forged_commands_does_not_lock_out_the_key_holder() {
    let dir = scratch("link-flood");
    let key = write_key(&dir.join("link.key"), 0x61);
    let forger_key = LinkKey::new([0x62; 32]);
    let (mut ground, telemetry) = Ground::listening();
    let child = spawn_piped(sim_on_link(
        &dir,
        telemetry,
        &["--duration", "30", "--json"],
    ));
    ground.next(Duration::from_secs(10)).expect("telemetry");
    let (vehicle, run_id) = (ground.vehicle.expect("vehicle"), ground.run_id);

    // The flood: 8 sockets in turn, bounded to 12 s and 3 million datagrams.
    let done = Arc::new(AtomicBool::new(false));
    let flood = {
        let done = done.clone();
        std::thread::spawn(move || {
            let sockets: Vec<UdpSocket> = (0..8)
                .map(|_| UdpSocket::bind("127.0.0.1:0").expect("flood socket"))
                .collect();
            let mut buf = [0u8; 256];
            let started = Instant::now();
            let mut sent = 0u64;
            while !done.load(Ordering::Relaxed)
                && started.elapsed() < Duration::from_secs(12)
                && sent < 3_000_000
            {
                let envelope = Envelope {
                    vehicle_id: 1,
                    sender_id: 9,
                    run_id,
                    sequence: sent as u32 + 1,
                    t_ns: 0,
                };
                let command = Command::GetParam {
                    name: skyframe_core::link::messages::Name::new("control.roll_kp")
                        .expect("name"),
                };
                let n = encode_datagram(
                    &envelope,
                    &Message::Command(command),
                    Some(&forger_key),
                    &mut buf,
                )
                .expect("encodes");
                let socket = &sockets[sent as usize % sockets.len()];
                if socket.send_to(&buf[..n], vehicle).is_ok() {
                    sent += 1;
                }
            }
            (sent, started.elapsed())
        })
    };
    std::thread::sleep(Duration::from_millis(500));

    // 50 genuine requests, each resent (new sequence number) every second for up to 3 s.
    let mut acknowledged = 0;
    for _ in 0..50 {
        let mut answered = false;
        for _attempt in 0..3 {
            ground.send(
                Command::GetParam {
                    name: skyframe_core::link::messages::Name::new("control.roll_kp")
                        .expect("name"),
                },
                &key,
            );
            let asked = ground.sequence;
            let deadline = Instant::now() + Duration::from_secs(1);
            while Instant::now() < deadline {
                if let Some((_, Telemetry::CommandAck(ack))) =
                    ground.next(Duration::from_millis(100))
                    && ack.command_sender_id == 7
                    && ack.command_sequence == asked
                {
                    answered = ack.result == AckResult::Accepted;
                    break;
                }
            }
            if answered {
                break;
            }
        }
        acknowledged += usize::from(answered);
    }
    done.store(true, Ordering::Relaxed);
    let (sent, flood_time) = flood.join().expect("flood");
    let rate = sent as f64 / flood_time.as_secs_f64();

    // The vehicle's own account, in its next executive status.
    let mut counters = None;
    let deadline = Instant::now() + Duration::from_secs(5);
    while counters.is_none() && Instant::now() < deadline {
        if let Some((_, Telemetry::ExecutiveStatus(e))) = ground.next(Duration::from_millis(200)) {
            // The log's health rides along: its disk's free space was measured.
            assert_ne!(e.log.free_mib, LogHealth::UNKNOWN, "{:?}", e.log);
            assert_eq!(e.log.records_lost, 0, "{:?}", e.log);
            counters = Some(e.link);
        }
    }
    let counters = counters.expect("an executive status after the flood");
    ground.send(Command::Stop, &key);
    finish_ok(child);
    eprintln!(
        "flood: {sent} forged datagrams in {:.1} s ({rate:.0}/s); genuine acknowledged \
         {acknowledged}/50; vehicle counted bad signature {}, rate-limited {}, accepted {}",
        flood_time.as_secs_f64(),
        counters.bad_signature,
        counters.rate_limited,
        counters.accepted
    );
    assert_eq!(acknowledged, 50, "{counters:?}");
    // The flood was one (a machine this test runs on sends tens of thousands a second).
    assert!(rate > 10_000.0, "only {rate:.0} datagrams/s");
    // Every forgery that reached the vehicle was refused and counted, none accepted; what
    // the kernel dropped when the socket's buffer was full never reached it.
    let refused = u64::from(counters.bad_signature) + u64::from(counters.rate_limited);
    assert!(refused >= sent / 4, "{refused} of {sent}: {counters:?}");
    assert!(refused <= sent, "{refused} of {sent}");
    assert!(counters.accepted >= 50, "{counters:?}");
}
