//! The MAVLink thread: sockets, streams, parameters, missions and commands (see the
//! module's top, `super`). One thread, no locks shared with the executive: it reads the
//! vehicle's telemetry from a queue the link thread fills and hands link commands back
//! through another.

// Ground stations still send SET_MODE, MISSION_REQUEST, MISSION_ITEM and
// MISSION_SET_CURRENT (MAVProxy does): they are deprecated, not gone, and get an answer.
#![allow(deprecated)]

use super::encode;
use super::ingress::{self, Accepted, Counters, Verifier};
use super::mav::{
    AUTOPILOT_VERSION_DATA, COMMAND_ACK_DATA, COMMAND_LONG_DATA, HOME_POSITION_DATA,
    MISSION_ACK_DATA, MISSION_COUNT_DATA, MISSION_CURRENT_DATA, MISSION_ITEM_INT_DATA,
    MISSION_REQUEST_INT_DATA, MavCmd, MavMessage, MavMissionResult, MavMissionType, MavModeFlag,
    MavProtocolCapability, MavResult, MavSeverity, MissionState, PARAM_VALUE_DATA, STATUSTEXT_DATA,
};
use super::mission::{Items, items_from_mission, mission_from_items, same_mission};
use super::params::{ParamCache, decode_value, encode_value, id_from_bytes, param_type};
use super::view::{Event, VehicleView};
use super::{BridgeEnds, Endpoint, LINK_SENDER_ID, MavlinkPlan};
use mavlink::{MavHeader, SigningConfig, SigningData};
use skyframe_core::control::mission::Mission;
use skyframe_core::control::mode::FlightMode;
use skyframe_core::estimation::geo::{GeoPoint, LocalFrame};
use skyframe_core::link::auth::LinkKey;
use skyframe_core::link::frame::{Envelope, Verify, decode_datagram, encode_datagram};
use skyframe_core::link::messages::{AckResult, Command, Message as LinkMessage, Name};
use std::collections::HashMap;
use std::net::{SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// What the MAVLink thread needs from the flight.
pub struct BridgeSetup {
    pub plan: MavlinkPlan,
    pub signing_key: Option<[u8; 32]>,
    pub link_key: LinkKey,
    pub run_id: u32,
    pub vehicle_id: u16,
    pub task_names: Vec<String>,
    pub mission: Option<Mission>,
    /// Log TIME of the executive's clock zero: MAVLink's `time_boot_ms` is log TIME minus it.
    pub time_origin_ns: u64,
    pub ends: BridgeEnds,
    /// Ends the thread (the flight's I/O stop, set after the executive ended).
    pub io_stop: Arc<AtomicBool>,
}

/// Component id of the autopilot.
const COMPONENT: u8 = 1;
/// Ground stations remembered per socket; past this the one heard from longest ago goes.
const PEERS_KEPT: usize = 8;
/// Datagrams read from one socket in a row: the socket is drained in batches under a flood.
const RECEIVE_BATCH: usize = 256;
/// An answer the vehicle has not given by then is reported as failed.
const VEHICLE_ANSWER: Duration = Duration::from_secs(2);
/// A mission upload whose next item does not come within this is asked again, three times.
const MISSION_ITEM_WAIT: Duration = Duration::from_millis(1500);

/// Telemetry intervals the MAVLink side asks of the vehicle's tasks at start, so its
/// streams have fresh data (the skyframe link's default is 1 s; 50 ms is the fastest).
const TASK_INTERVALS_MS: [(&str, u32); 5] = [
    ("estimator", 100),
    ("imu", 200),
    ("control", 200),
    ("gps", 200),
    ("servo", 250),
];

/// The streams and their default rates (intervals, ms); SET_MESSAGE_INTERVAL changes them.
const STREAMS: [(u32, u64); 14] = [
    (0, 1000),   // HEARTBEAT
    (1, 1000),   // SYS_STATUS
    (245, 1000), // EXTENDED_SYS_STATE
    (30, 100),   // ATTITUDE
    (33, 200),   // GLOBAL_POSITION_INT
    (24, 500),   // GPS_RAW_INT
    (74, 250),   // VFR_HUD
    (147, 1000), // BATTERY_STATUS
    (36, 500),   // SERVO_OUTPUT_RAW
    (65, 500),   // RC_CHANNELS
    (26, 500),   // SCALED_IMU
    (62, 500),   // NAV_CONTROLLER_OUTPUT (in AUTO)
    (42, 1000),  // MISSION_CURRENT
    (242, 5000), // HOME_POSITION
];

/// The fastest a stream may be asked for: the vehicle's telemetry is at most 20 Hz.
const MIN_INTERVAL_MS: u64 = 20;

struct Socket {
    socket: UdpSocket,
    /// `udpout`'s destination (always sent to).
    fixed: Option<SocketAddr>,
    /// Who talked to us, newest last.
    peers: Vec<(SocketAddr, Instant)>,
}

enum Pending {
    ParamSet {
        index: usize,
    },
    Command {
        command: MavCmd,
        to: (u8, u8),
    },
    /// One of the link commands of the mission change under way.
    Mission,
}

/// A mission change the vehicle is asked for: its link commands, answered one by one.
enum MissionChange {
    Upload(Box<Mission>),
    Clear,
    /// Fly from this waypoint.
    SetCurrent(usize),
}

struct MissionInFlight {
    change: MissionChange,
    to: (u8, u8),
    /// Link commands not answered yet.
    outstanding: usize,
    /// One was refused, or never answered.
    failed: bool,
}

enum Upload {
    Idle,
    Receiving {
        count: u16,
        items: Vec<MISSION_ITEM_INT_DATA>,
        from: (u8, u8),
        asked: Instant,
        tries: u8,
    },
}

struct Bridge {
    sockets: Vec<Socket>,
    shares: crate::link::SourceShares,
    verifier: Verifier,
    counters: Arc<Counters>,
    signing: Option<SigningData>,
    system_id: u8,
    sequence: u8,
    link_key: LinkKey,
    run_id: u32,
    vehicle_id: u16,
    link_sequence: u32,
    ends: BridgeEnds,
    view: VehicleView,
    params: ParamCache,
    pending: HashMap<u32, (Pending, Instant)>,
    streams: HashMap<u32, (u64, Instant)>,
    home: Option<LocalFrame>,
    home_sent: bool,
    mission: Option<Mission>,
    items: Option<Items>,
    upload: Upload,
    /// The mission change the vehicle has not answered in full yet.
    changing: Option<MissionInFlight>,
    /// The control task's telemetry count when the mission last changed: its waypoint is
    /// the old mission's until two newer samples came.
    changed_at_update: Option<u64>,
    /// The active waypoint while in AUTO, and the waypoints reported reached.
    waypoint: Option<usize>,
    reached: Vec<bool>,
    stop: Arc<AtomicBool>,
    started: Instant,
    params_asked: Option<Instant>,
    /// A PARAM_REQUEST_LIST came before the vehicle had reported every parameter: answer it
    /// when the table is whole.
    list_wanted: bool,
    warned: HashMap<String, Instant>,
}

/// Opens the endpoints and starts the thread.
pub fn spawn(setup: BridgeSetup) -> Result<JoinHandle<()>, String> {
    let mut sockets = Vec::new();
    for endpoint in &setup.plan.endpoints {
        let (bind, fixed) = match endpoint {
            Endpoint::UdpIn(a) => (*a, None),
            Endpoint::UdpOut(a) => {
                let any: SocketAddr = if a.is_ipv4() {
                    ([0, 0, 0, 0], 0).into()
                } else {
                    (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
                };
                (any, Some(*a))
            }
        };
        let socket = UdpSocket::bind(bind).map_err(|e| format!("--mavlink {bind}: {e}"))?;
        socket
            .set_nonblocking(true)
            .map_err(|e| format!("--mavlink {bind}: {e}"))?;
        let _ = socket.set_broadcast(true);
        sockets.push(Socket {
            socket,
            fixed,
            peers: Vec::new(),
        });
    }
    let signing = setup
        .signing_key
        .map(|k| SigningData::from_config(SigningConfig::new(k, 0, true, false)));
    let io_stop = setup.io_stop;
    let mut bridge = Bridge {
        sockets,
        shares: crate::link::SourceShares::new(),
        verifier: Verifier::new(setup.signing_key),
        counters: Arc::clone(&setup.ends.counters),
        signing,
        system_id: setup.plan.system_id,
        sequence: 0,
        link_key: setup.link_key,
        run_id: setup.run_id,
        vehicle_id: setup.vehicle_id,
        link_sequence: 0,
        ends: setup.ends,
        view: VehicleView::new(setup.task_names, setup.time_origin_ns),
        params: ParamCache::default(),
        pending: HashMap::new(),
        streams: STREAMS
            .iter()
            .map(|(id, ms)| (*id, (*ms, Instant::now())))
            .collect(),
        home: None,
        home_sent: false,
        reached: vec![false; setup.mission.as_ref().map_or(0, |m| m.waypoints.len())],
        mission: setup.mission,
        items: None,
        upload: Upload::Idle,
        changing: None,
        changed_at_update: None,
        waypoint: None,
        stop: setup.plan.stop,
        started: Instant::now(),
        params_asked: None,
        list_wanted: false,
        warned: HashMap::new(),
    };
    std::thread::Builder::new()
        .name("mavlink".into())
        .spawn(move || bridge.run(&io_stop))
        .map_err(|e| format!("cannot start the MAVLink thread: {e}"))
}

fn statustext(severity: MavSeverity, text: &str) -> MavMessage {
    // 50 bytes; a longer text is cut (MAVLink 2's chunking would need the id/chunk pair).
    let cut: String = text.chars().filter(char::is_ascii).take(50).collect();
    MavMessage::STATUSTEXT(STATUSTEXT_DATA {
        severity,
        text: cut.as_str().into(),
        ..STATUSTEXT_DATA::default()
    })
}

fn ack(command: MavCmd, result: MavResult, to: (u8, u8)) -> MavMessage {
    MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command,
        result,
        target_system: to.0,
        target_component: to.1,
        ..COMMAND_ACK_DATA::default()
    })
}

fn mission_ack(result: MavMissionResult, to: (u8, u8)) -> MavMessage {
    MavMessage::MISSION_ACK(MISSION_ACK_DATA {
        target_system: to.0,
        target_component: to.1,
        mavtype: result,
        mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
        ..MISSION_ACK_DATA::default()
    })
}

/// The git commit's first 8 bytes (AUTOPILOT_VERSION.flight_custom_version, as PX4 and
/// ArduPilot fill it).
fn git_hash_bytes() -> [u8; 8] {
    let hex = env!("SKYFRAME_GIT_HASH").as_bytes();
    let mut out = [0u8; 8];
    for (slot, b) in out.iter_mut().zip(hex) {
        *slot = *b;
    }
    out
}

impl Bridge {
    fn run(&mut self, io_stop: &AtomicBool) {
        self.ask_vehicle_for_data();
        let mut received = Vec::new();
        let mut buf = vec![0u8; 2048];
        loop {
            if io_stop.load(Ordering::Acquire) {
                return;
            }
            let mut busy = false;
            for s in 0..self.sockets.len() {
                // One clock read per batch: under a flood the share check is the hot path.
                let now = Instant::now();
                for _ in 0..RECEIVE_BATCH {
                    let Some(socket) = self.sockets.get(s) else {
                        break;
                    };
                    let Ok((n, from)) = socket.socket.recv_from(&mut buf) else {
                        break;
                    };
                    busy = true;
                    self.counters.datagrams_in.fetch_add(1, Ordering::Relaxed);
                    if !self.shares.take(from, now) {
                        self.counters.rate_limited.fetch_add(1, Ordering::Relaxed);
                        continue;
                    }
                    received.clear();
                    ingress::screen(
                        buf.get(..n).unwrap_or_default(),
                        self.system_id,
                        &mut self.verifier,
                        &self.counters,
                        ingress::signing_clock(),
                        &mut received,
                    );
                    if !received.is_empty() {
                        self.learn_peer(s, from);
                    }
                    for accepted in received.drain(..) {
                        self.handle(accepted);
                    }
                }
            }
            while let Ok(datagram) = self.ends.telemetry.try_recv() {
                busy = true;
                self.take_telemetry(&datagram);
            }
            self.tick();
            if !busy {
                std::thread::sleep(Duration::from_millis(5));
            }
        }
    }

    fn learn_peer(&mut self, socket: usize, from: SocketAddr) {
        let Some(s) = self.sockets.get_mut(socket) else {
            return;
        };
        if s.fixed == Some(from) {
            return;
        }
        let now = Instant::now();
        if let Some(p) = s.peers.iter_mut().find(|(a, _)| *a == from) {
            p.1 = now;
            return;
        }
        if s.peers.len() >= PEERS_KEPT {
            let oldest = s
                .peers
                .iter()
                .enumerate()
                .min_by_key(|(_, (_, t))| *t)
                .map(|(i, _)| i);
            if let Some(i) = oldest {
                s.peers.remove(i);
            }
        }
        s.peers.push((from, now));
    }

    fn send(&mut self, message: &MavMessage) {
        let header = MavHeader {
            system_id: self.system_id,
            component_id: COMPONENT,
            sequence: self.sequence,
        };
        self.sequence = self.sequence.wrapping_add(1);
        let bytes = ingress::frame(header, message, self.signing.as_ref());
        for s in &self.sockets {
            for to in s.fixed.iter().chain(s.peers.iter().map(|(a, _)| a)) {
                match s.socket.send_to(&bytes, to) {
                    Ok(_) => self.counters.frames_out.fetch_add(1, Ordering::Relaxed),
                    Err(_) => self.counters.send_errors.fetch_add(1, Ordering::Relaxed),
                };
            }
        }
    }

    /// Queues a skyframe link command to the vehicle; returns its sequence number.
    fn command_vehicle(&mut self, command: Command) -> Option<u32> {
        self.link_sequence = self.link_sequence.wrapping_add(1);
        let envelope = Envelope {
            vehicle_id: self.vehicle_id,
            sender_id: LINK_SENDER_ID,
            run_id: self.run_id,
            sequence: self.link_sequence,
            t_ns: u64::try_from(self.started.elapsed().as_nanos()).unwrap_or(u64::MAX),
        };
        let mut out = [0u8; 256];
        let n = encode_datagram(
            &envelope,
            &LinkMessage::Command(command),
            Some(&self.link_key),
            &mut out,
        )
        .ok()?;
        self.ends
            .commands
            .try_send(out.get(..n)?.to_vec())
            .ok()
            .map(|()| self.link_sequence)
    }

    fn ask_vehicle_for_data(&mut self) {
        for (task, ms) in TASK_INTERVALS_MS {
            if let Some(task_index) = self.view.task_index_of(task) {
                self.command_vehicle(Command::SetTelemetryRate {
                    task_index,
                    interval_ms: ms,
                });
            }
        }
        self.command_vehicle(Command::ListParams);
        self.params_asked = Some(Instant::now());
    }

    fn take_telemetry(&mut self, datagram: &[u8]) {
        // The vehicle's own datagrams, in-process: no need to check a tag.
        let Ok((_, LinkMessage::Telemetry(t))) = decode_datagram(datagram, Verify::No) else {
            return;
        };
        for event in self.view.take(t) {
            match event {
                Event::ParamValue(p) => {
                    self.params.update(&p);
                    if self.list_wanted && self.params.complete() {
                        self.list_wanted = false;
                        for i in 0..self.params.count() {
                            self.send_param(i);
                        }
                    }
                }
                Event::CommandAck(a) if a.command_sender_id == LINK_SENDER_ID => {
                    self.vehicle_answered(a);
                }
                Event::CommandAck(_) => {}
                Event::Warning(text) => self.warn(&text),
            }
        }
        self.track_home();
        self.track_mission();
    }

    /// STATUSTEXT for a warning, at most once a second for the same text's subject.
    fn warn(&mut self, text: &str) {
        let subject = text.split(':').next().unwrap_or(text).to_string();
        let now = Instant::now();
        if self
            .warned
            .get(&subject)
            .is_some_and(|t| now.duration_since(*t) < Duration::from_secs(1))
        {
            return;
        }
        self.warned.insert(subject, now);
        self.send(&statustext(MavSeverity::MAV_SEVERITY_WARNING, text));
    }

    /// Home is the first valid GPS fix seen, as the estimator's (the origin of its NED).
    fn track_home(&mut self) {
        if self.home.is_some() || self.view.get("gps", "valid") != Some(1.0) {
            return;
        }
        let (Some(lat), Some(lon), Some(alt)) = (
            self.view.get("gps", "lat_deg"),
            self.view.get("gps", "lon_deg"),
            self.view.get("gps", "alt_m"),
        ) else {
            return;
        };
        self.home = LocalFrame::new(GeoPoint {
            latitude_deg: lat,
            longitude_deg: lon,
            altitude_m: alt,
        });
        if let (Some(home), Some(mission)) = (&self.home, &self.mission) {
            self.items = Some(items_from_mission(mission, home));
        }
    }

    fn home_position(&self) -> Option<MavMessage> {
        let home = self.home.as_ref()?.home();
        Some(MavMessage::HOME_POSITION(HOME_POSITION_DATA {
            latitude: encode::deg_e7(home.latitude_deg),
            longitude: encode::deg_e7(home.longitude_deg),
            altitude: encode::mm(home.altitude_m),
            q: [1.0, 0.0, 0.0, 0.0],
            ..HOME_POSITION_DATA::default()
        }))
    }

    fn in_auto(&self) -> bool {
        self.view.mode() == Some(FlightMode::Auto)
    }

    /// MISSION_ITEM_REACHED as the autopilot passes each waypoint: the control task's
    /// active waypoint moves on, or, for the last, the airplane is within the switch radius.
    fn track_mission(&mut self) {
        let (Some(mission), Some(items)) = (&self.mission, &self.items) else {
            return;
        };
        if !self.in_auto() {
            return;
        }
        if let Some(at) = self.changed_at_update {
            if self.view.updates("control") < at.saturating_add(2) {
                return;
            }
            self.changed_at_update = None;
        }
        let Some(active) = self.view.get("control", "waypoint") else {
            return;
        };
        let active = (active.max(0.0) as usize).min(mission.waypoints.len().saturating_sub(1));
        let mut reached = Vec::new();
        for i in 0..active {
            if self.reached.get(i) == Some(&false) {
                reached.push(i);
            }
        }
        let last = mission.waypoints.len().saturating_sub(1);
        if active == last
            && let (Some(w), Some(pn), Some(pe)) = (
                mission.waypoints.get(last),
                self.view.get("estimator", "pn_m"),
                self.view.get("estimator", "pe_m"),
            )
            && (f64::from(w.north_m) - pn).hypot(f64::from(w.east_m) - pe)
                < f64::from(mission.switch_radius_m)
            && self.reached.get(last) == Some(&false)
        {
            reached.push(last);
        }
        let seqs: Vec<u16> = reached
            .iter()
            .filter_map(|i| items.waypoint_seq.get(*i).copied())
            .collect();
        for i in reached {
            if let Some(r) = self.reached.get_mut(i) {
                *r = true;
            }
        }
        let changed = self.waypoint != Some(active);
        self.waypoint = Some(active);
        for seq in seqs {
            self.send(&MavMessage::MISSION_ITEM_REACHED(
                super::mav::MISSION_ITEM_REACHED_DATA { seq },
            ));
        }
        if changed && let Some(m) = self.mission_current() {
            self.send(&m);
        }
    }

    fn mission_current(&self) -> Option<MavMessage> {
        let total = self.items.as_ref().map_or(0, |i| i.items.len());
        let (seq, state) = match (&self.items, self.waypoint) {
            (None, _) => (0, MissionState::MISSION_STATE_NO_MISSION),
            (Some(_), None) => (0, MissionState::MISSION_STATE_NOT_STARTED),
            (Some(items), Some(w)) => {
                let all = !self.reached.is_empty() && self.reached.iter().all(|r| *r);
                if all {
                    (items.loiter_seq(), MissionState::MISSION_STATE_ACTIVE)
                } else {
                    (
                        items.waypoint_seq.get(w).copied().unwrap_or(0),
                        if self.in_auto() {
                            MissionState::MISSION_STATE_ACTIVE
                        } else {
                            MissionState::MISSION_STATE_PAUSED
                        },
                    )
                }
            }
        };
        Some(MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA {
            seq,
            total: u16::try_from(total).unwrap_or(u16::MAX),
            mission_state: state,
            ..MISSION_CURRENT_DATA::default()
        }))
    }

    fn stream_message(&self, id: u32) -> Option<MavMessage> {
        let v = &self.view;
        let home = self.home.as_ref();
        Some(match id {
            0 => MavMessage::HEARTBEAT(encode::heartbeat(v)),
            1 => MavMessage::SYS_STATUS(encode::sys_status(
                v,
                self.counters.datagrams_in.load(Ordering::Relaxed),
                self.counters.rejected() + self.counters.rate_limited.load(Ordering::Relaxed),
            )),
            245 => MavMessage::EXTENDED_SYS_STATE(encode::extended_sys_state(v)),
            30 => MavMessage::ATTITUDE(encode::attitude(v)?),
            33 => MavMessage::GLOBAL_POSITION_INT(encode::global_position_int(v, home?)?),
            24 => MavMessage::GPS_RAW_INT(encode::gps_raw_int(v)?),
            74 => MavMessage::VFR_HUD(encode::vfr_hud(v, home?)?),
            147 => MavMessage::BATTERY_STATUS(encode::battery_status(v)?),
            36 => MavMessage::SERVO_OUTPUT_RAW(encode::servo_output_raw(v)?),
            65 => MavMessage::RC_CHANNELS(encode::rc_channels(v)?),
            26 => MavMessage::SCALED_IMU(encode::scaled_imu(v)?),
            62 if self.in_auto() => {
                let target = self
                    .mission
                    .as_ref()
                    .zip(self.waypoint)
                    .and_then(|(m, w)| m.waypoints.get(w))
                    .map(|w| (f64::from(w.north_m), f64::from(w.east_m)));
                MavMessage::NAV_CONTROLLER_OUTPUT(encode::nav_controller_output(v, target)?)
            }
            42 => self.mission_current()?,
            242 => self.home_position()?,
            148 => self.autopilot_version(),
            _ => return None,
        })
    }

    fn autopilot_version(&self) -> MavMessage {
        MavMessage::AUTOPILOT_VERSION(AUTOPILOT_VERSION_DATA {
            capabilities: MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MAVLINK2
                | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST
                | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_INT
                | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_COMMAND_INT,
            // 0.1.0, release type "dev" (MAVLink's FIRMWARE_VERSION_TYPE_DEV = 0).
            flight_sw_version: 0x0001_0000,
            flight_custom_version: git_hash_bytes(),
            uid: u64::from(self.vehicle_id),
            ..AUTOPILOT_VERSION_DATA::default()
        })
    }

    fn tick(&mut self) {
        let now = Instant::now();
        if self.home.is_some() && !self.home_sent {
            self.home_sent = true;
            if let Some(m) = self.home_position() {
                self.send(&m);
            }
        }
        let due: Vec<u32> = self
            .streams
            .iter()
            .filter(|(_, (ms, next))| *ms > 0 && now >= *next)
            .map(|(id, _)| *id)
            .collect();
        for id in due {
            if let Some((ms, next)) = self.streams.get_mut(&id) {
                *next = now + Duration::from_millis(*ms);
            }
            if let Some(m) = self.stream_message(id) {
                self.send(&m);
            }
        }
        // The vehicle's answers that never came.
        let late: Vec<u32> = self
            .pending
            .iter()
            .filter(|(_, (_, at))| now.duration_since(*at) > VEHICLE_ANSWER)
            .map(|(s, _)| *s)
            .collect();
        for seq in late {
            if let Some((pending, _)) = self.pending.remove(&seq) {
                match pending {
                    Pending::ParamSet { index } => self.send_param(index),
                    Pending::Command { command, to } => {
                        self.send(&ack(command, MavResult::MAV_RESULT_FAILED, to));
                    }
                    Pending::Mission => self.mission_answered(false),
                }
            }
        }
        if !self.params.complete()
            && self
                .params_asked
                .is_some_and(|t| now.duration_since(t) > Duration::from_secs(2))
        {
            self.command_vehicle(Command::ListParams);
            self.params_asked = Some(now);
        }
        self.upload_timeout(now);
    }

    fn upload_timeout(&mut self, now: Instant) {
        let Upload::Receiving {
            items,
            from,
            asked,
            tries,
            ..
        } = &mut self.upload
        else {
            return;
        };
        if now.duration_since(*asked) < MISSION_ITEM_WAIT {
            return;
        }
        let from = *from;
        if *tries >= 3 {
            self.upload = Upload::Idle;
            self.send(&mission_ack(
                MavMissionResult::MAV_MISSION_OPERATION_CANCELLED,
                from,
            ));
            return;
        }
        *tries += 1;
        *asked = now;
        let seq = u16::try_from(items.len()).unwrap_or(u16::MAX);
        self.request_item(seq, from);
    }

    fn request_item(&mut self, seq: u16, to: (u8, u8)) {
        self.send(&MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq,
            target_system: to.0,
            target_component: to.1,
            mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
        }));
    }

    fn send_param(&mut self, index: usize) {
        let Some(e) = self.params.get(index) else {
            return;
        };
        let m = MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
            param_value: encode_value(e.value),
            param_count: u16::try_from(self.params.count()).unwrap_or(u16::MAX),
            param_index: u16::try_from(index).unwrap_or(u16::MAX),
            param_id: e.id.as_str().into(),
            param_type: param_type(e.value.value_type()),
        });
        self.send(&m);
    }

    fn vehicle_answered(&mut self, a: skyframe_core::link::messages::CommandAck) {
        let Some((pending, _)) = self.pending.remove(&a.command_sequence) else {
            return;
        };
        match pending {
            Pending::ParamSet { index } => {
                if let Some(v) = a.value_in_force {
                    self.params.set_value(index, v);
                }
                // The value in force: the new one, or the old one echoed when refused.
                self.send_param(index);
            }
            Pending::Command { command, to } => {
                let result = match a.result {
                    AckResult::Accepted => MavResult::MAV_RESULT_ACCEPTED,
                    AckResult::Refused => MavResult::MAV_RESULT_TEMPORARILY_REJECTED,
                    _ => MavResult::MAV_RESULT_DENIED,
                };
                self.send(&ack(command, result, to));
            }
            Pending::Mission => self.mission_answered(a.result == AckResult::Accepted),
        }
    }

    fn handle(&mut self, a: Accepted) {
        let from = (a.header.system_id, a.header.component_id);
        match a.message {
            MavMessage::PARAM_REQUEST_LIST(_) if !self.params.complete() => {
                self.list_wanted = true;
            }
            MavMessage::PARAM_REQUEST_LIST(_) => {
                for i in 0..self.params.count() {
                    self.send_param(i);
                }
            }
            MavMessage::PARAM_REQUEST_READ(r) => {
                let index = if r.param_index >= 0 {
                    Some(usize::from(r.param_index.unsigned_abs()))
                        .filter(|i| *i < self.params.count())
                } else {
                    self.params.find(&id_from_bytes(&r.param_id[..]))
                };
                if let Some(i) = index {
                    self.send_param(i);
                }
            }
            MavMessage::PARAM_SET(s) => {
                self.param_set(&id_from_bytes(&s.param_id[..]), s.param_value)
            }
            MavMessage::COMMAND_LONG(c) => self.command(&c, from),
            MavMessage::COMMAND_INT(c) => {
                let long = COMMAND_LONG_DATA {
                    param1: c.param1,
                    param2: c.param2,
                    param3: c.param3,
                    param4: c.param4,
                    param5: c.x as f32,
                    param6: c.y as f32,
                    param7: c.z,
                    command: c.command,
                    target_system: c.target_system,
                    target_component: c.target_component,
                    confirmation: 0,
                };
                self.command(&long, from);
            }
            MavMessage::SET_MODE(m) => {
                let long = COMMAND_LONG_DATA {
                    param1: m.base_mode.bits() as f32,
                    param2: m.custom_mode as f32,
                    command: MavCmd::MAV_CMD_DO_SET_MODE,
                    ..COMMAND_LONG_DATA::default()
                };
                self.command(&long, from);
            }
            MavMessage::MISSION_REQUEST_LIST(r) => self.mission_count(r.mission_type, from),
            MavMessage::MISSION_REQUEST_INT(r) => self.mission_item(r.seq, r.mission_type, from),
            MavMessage::MISSION_REQUEST(r) => self.mission_item(r.seq, r.mission_type, from),
            MavMessage::MISSION_COUNT(c) => self.upload_start(&c, from),
            MavMessage::MISSION_ITEM_INT(i) => self.upload_item(i, from),
            MavMessage::MISSION_ITEM(_) => {
                // Float positions lose ~1 m at these latitudes: only MISSION_ITEM_INT.
                self.send(&mission_ack(
                    MavMissionResult::MAV_MISSION_UNSUPPORTED,
                    from,
                ));
            }
            MavMessage::MISSION_CLEAR_ALL(c) => {
                if c.mission_type != MavMissionType::MAV_MISSION_TYPE_MISSION {
                    // No fences or rally points to clear: done.
                    self.send(&mission_ack(MavMissionResult::MAV_MISSION_ACCEPTED, from));
                } else {
                    self.change_mission(MissionChange::Clear, from);
                }
            }
            MavMessage::MISSION_SET_CURRENT(c) => self.set_current(c.seq, from),
            _ => {}
        }
    }

    fn param_set(&mut self, id: &str, value: f32) {
        let Some(index) = self.params.find(id) else {
            // No such parameter: ArduPilot stays silent; say why instead.
            self.send(&statustext(
                MavSeverity::MAV_SEVERITY_WARNING,
                &format!("param {id}: unknown"),
            ));
            return;
        };
        let Some(entry) = self.params.get(index).cloned() else {
            return;
        };
        let (Some(v), Some(name)) = (
            decode_value(value, entry.value.value_type()),
            Name::new(&entry.name),
        ) else {
            self.send_param(index);
            return;
        };
        match self.command_vehicle(Command::SetParam { name, value: v }) {
            Some(seq) => {
                self.pending
                    .insert(seq, (Pending::ParamSet { index }, Instant::now()));
            }
            None => self.send_param(index),
        }
    }

    fn command(&mut self, c: &COMMAND_LONG_DATA, from: (u8, u8)) {
        if c.target_component != 0 && c.target_component != COMPONENT {
            return;
        }
        let reply = |b: &mut Self, r| b.send(&ack(c.command, r, from));
        match c.command {
            MavCmd::MAV_CMD_DO_SET_MODE => {
                let custom = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits();
                let mode = encode::flight_mode(c.param2);
                match mode {
                    Some(mode) if (c.param1 as u32 as u8) & custom != 0 => {
                        self.vehicle_command(Command::RequestMode { mode }, c.command, from);
                    }
                    _ => reply(self, MavResult::MAV_RESULT_DENIED),
                }
            }
            MavCmd::MAV_CMD_MISSION_START => {
                if self.mission.is_none() {
                    reply(self, MavResult::MAV_RESULT_DENIED);
                } else {
                    self.vehicle_command(
                        Command::RequestMode {
                            mode: FlightMode::Auto,
                        },
                        c.command,
                        from,
                    );
                }
            }
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM => {
                let encode::Armed(armed) = encode::armed(&self.view);
                // skyframe has no software arming: its servo outputs are live once the
                // board is ready, and the safety pilot's transmitter holds the motor.
                let r = match (c.param1 == 1.0, armed) {
                    (true, true) => MavResult::MAV_RESULT_ACCEPTED,
                    (true, false) => MavResult::MAV_RESULT_TEMPORARILY_REJECTED,
                    (false, _) => MavResult::MAV_RESULT_DENIED,
                };
                reply(self, r);
            }
            MavCmd::MAV_CMD_REQUEST_MESSAGE => {
                let id = c.param1;
                let msg = (id.fract() == 0.0 && id >= 0.0)
                    .then(|| self.stream_message(id as u32))
                    .flatten();
                match msg {
                    Some(m) => {
                        reply(self, MavResult::MAV_RESULT_ACCEPTED);
                        self.send(&m);
                    }
                    None => reply(self, MavResult::MAV_RESULT_DENIED),
                }
            }
            MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES => {
                reply(self, MavResult::MAV_RESULT_ACCEPTED);
                let m = self.autopilot_version();
                self.send(&m);
            }
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => {
                let id = c.param1 as u32;
                let default = STREAMS.iter().find(|(s, _)| *s == id).map(|(_, ms)| *ms);
                let r = match (default, c.param2) {
                    (None, _) => MavResult::MAV_RESULT_DENIED,
                    (Some(_), us) if !us.is_finite() => MavResult::MAV_RESULT_DENIED,
                    (Some(ms), us) => {
                        let interval = if us < 0.0 {
                            0
                        } else if us == 0.0 {
                            ms
                        } else {
                            ((us / 1000.0) as u64).max(MIN_INTERVAL_MS)
                        };
                        self.streams.insert(id, (interval, Instant::now()));
                        MavResult::MAV_RESULT_ACCEPTED
                    }
                };
                reply(self, r);
            }
            MavCmd::MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN if c.param1 == 2.0 => {
                // Shut the autopilot down: end the run as a signal would. The run's own stop
                // flag, not a link command, so that it works while a task is stuck (the
                // shell's stop guard then closes the logs and exits 4).
                reply(self, MavResult::MAV_RESULT_ACCEPTED);
                self.send(&statustext(
                    MavSeverity::MAV_SEVERITY_NOTICE,
                    "stopping: shutdown requested",
                ));
                self.stop.store(true, Ordering::Release);
            }
            _ => reply(self, MavResult::MAV_RESULT_UNSUPPORTED),
        }
    }

    fn vehicle_command(&mut self, command: Command, mav: MavCmd, from: (u8, u8)) {
        match self.command_vehicle(command) {
            Some(seq) => {
                self.pending.insert(
                    seq,
                    (
                        Pending::Command {
                            command: mav,
                            to: from,
                        },
                        Instant::now(),
                    ),
                );
            }
            None => self.send(&ack(mav, MavResult::MAV_RESULT_TEMPORARILY_REJECTED, from)),
        }
    }

    fn mission_count(&mut self, kind: MavMissionType, to: (u8, u8)) {
        if kind != MavMissionType::MAV_MISSION_TYPE_MISSION {
            // No fences or rally points: an empty list, as ArduPilot answers for what it lacks.
            self.send(&MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                count: 0,
                target_system: to.0,
                target_component: to.1,
                mission_type: kind,
                ..MISSION_COUNT_DATA::default()
            }));
            return;
        }
        if self.mission.is_some() && self.items.is_none() {
            self.send(&statustext(
                MavSeverity::MAV_SEVERITY_WARNING,
                "mission: no home yet (waiting for GPS)",
            ));
            self.send(&mission_ack(MavMissionResult::MAV_MISSION_ERROR, to));
            return;
        }
        let count = self.items.as_ref().map_or(0, |i| i.items.len());
        self.send(&MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: u16::try_from(count).unwrap_or(u16::MAX),
            target_system: to.0,
            target_component: to.1,
            mission_type: kind,
            ..MISSION_COUNT_DATA::default()
        }));
    }

    fn mission_item(&mut self, seq: u16, kind: MavMissionType, to: (u8, u8)) {
        let item = (kind == MavMissionType::MAV_MISSION_TYPE_MISSION)
            .then_some(self.items.as_ref())
            .flatten()
            .and_then(|i| i.items.get(usize::from(seq)))
            .cloned();
        match item {
            Some(mut item) => {
                item.target_system = to.0;
                item.target_component = to.1;
                item.current = u8::from(
                    self.items
                        .as_ref()
                        .zip(self.waypoint)
                        .and_then(|(i, w)| i.waypoint_seq.get(w))
                        == Some(&seq),
                );
                self.send(&MavMessage::MISSION_ITEM_INT(item));
            }
            None => self.send(&mission_ack(
                MavMissionResult::MAV_MISSION_INVALID_SEQUENCE,
                to,
            )),
        }
    }

    fn upload_start(&mut self, c: &MISSION_COUNT_DATA, from: (u8, u8)) {
        if c.mission_type != MavMissionType::MAV_MISSION_TYPE_MISSION {
            self.send(&mission_ack(
                MavMissionResult::MAV_MISSION_UNSUPPORTED,
                from,
            ));
            return;
        }
        if c.count == 0 {
            self.send(&mission_ack(MavMissionResult::MAV_MISSION_DENIED, from));
            return;
        }
        // Speed changes and a loiter besides the waypoints: 3 items per waypoint at most.
        if usize::from(c.count) > 3 * skyframe_core::control::mission::MAX_WAYPOINTS + 1 {
            self.send(&mission_ack(MavMissionResult::MAV_MISSION_NO_SPACE, from));
            return;
        }
        self.upload = Upload::Receiving {
            count: c.count,
            items: Vec::new(),
            from,
            asked: Instant::now(),
            tries: 0,
        };
        self.request_item(0, from);
    }

    fn upload_item(&mut self, item: MISSION_ITEM_INT_DATA, from: (u8, u8)) {
        let Upload::Receiving {
            count,
            items,
            asked,
            tries,
            ..
        } = &mut self.upload
        else {
            return;
        };
        let next = u16::try_from(items.len()).unwrap_or(u16::MAX);
        if item.seq != next {
            // A resend of one we have, or one ahead: ask for the one we need.
            let ask = next;
            *asked = Instant::now();
            self.request_item(ask, from);
            return;
        }
        items.push(item);
        *tries = 0;
        *asked = Instant::now();
        if items.len() < usize::from(*count) {
            let ask = next + 1;
            self.request_item(ask, from);
            return;
        }
        let items = std::mem::take(items);
        self.upload = Upload::Idle;
        self.upload_done(&items, from);
    }

    fn upload_done(&mut self, items: &[MISSION_ITEM_INT_DATA], from: (u8, u8)) {
        let Some(home) = &self.home else {
            self.send(&statustext(
                MavSeverity::MAV_SEVERITY_WARNING,
                "mission: no home yet (waiting for GPS)",
            ));
            self.send(&mission_ack(MavMissionResult::MAV_MISSION_ERROR, from));
            return;
        };
        let cruise = self
            .params
            .find("CTL_CRUISE_MPS")
            .and_then(|i| self.params.get(i))
            .map_or(25.0, |e| encode_value(e.value));
        let uploaded = match mission_from_items(items, home, cruise) {
            Ok(m) => m,
            Err(refusal) => {
                self.send(&statustext(
                    MavSeverity::MAV_SEVERITY_WARNING,
                    &format!("mission: item {} refused", refusal.seq),
                ));
                self.send(&mission_ack(refusal.result, from));
                return;
            }
        };
        // The mission in force again (what a ground station uploads after a download, or to
        // check one): nothing to change, and the airplane flies on where it was.
        let same = self
            .mission
            .as_ref()
            .is_some_and(|m| same_mission(m, &uploaded));
        if same {
            self.send(&mission_ack(MavMissionResult::MAV_MISSION_ACCEPTED, from));
        } else {
            self.change_mission(MissionChange::Upload(Box::new(uploaded)), from);
        }
    }

    /// MISSION_SET_CURRENT: item `seq`'s waypoint (a speed change: the waypoint after it;
    /// the loiter: the last waypoint). Answered with MISSION_CURRENT once the vehicle took
    /// it; refused with a STATUSTEXT and the unchanged MISSION_CURRENT.
    fn set_current(&mut self, seq: u16, from: (u8, u8)) {
        let waypoint = self.items.as_ref().and_then(|items| {
            if usize::from(seq) >= items.items.len() {
                return None;
            }
            let at = items.waypoint_seq.iter().position(|w| *w >= seq);
            at.or_else(|| items.waypoint_seq.len().checked_sub(1))
        });
        match waypoint {
            Some(w) => self.change_mission(MissionChange::SetCurrent(w), from),
            None => {
                self.send(&statustext(
                    MavSeverity::MAV_SEVERITY_WARNING,
                    &format!("mission: no item {seq} to fly"),
                ));
                if let Some(m) = self.mission_current() {
                    self.send(&m);
                }
            }
        }
    }

    /// Sends a mission change to the vehicle as link commands; the ground station is answered
    /// when the vehicle has answered them all ([`Self::mission_answered`]).
    fn change_mission(&mut self, change: MissionChange, from: (u8, u8)) {
        if self.changing.is_some() {
            self.mission_refused(&change, from, "mission: a change is under way");
            return;
        }
        let commands: Vec<Command> = match &change {
            MissionChange::Clear => vec![Command::MissionClear],
            MissionChange::SetCurrent(w) => match u8::try_from(*w) {
                Ok(index) => vec![Command::MissionSetCurrent { index }],
                Err(_) => Vec::new(),
            },
            MissionChange::Upload(m) => match u8::try_from(m.waypoints.len()) {
                Ok(count) if count > 0 => {
                    let mut c: Vec<Command> = (0..count)
                        .zip(m.waypoints.iter())
                        .map(|(index, w)| Command::MissionItem {
                            index,
                            count,
                            waypoint: *w,
                        })
                        .collect();
                    c.push(Command::MissionCommit {
                        count,
                        switch_radius_m: m.switch_radius_m,
                        loiter_radius_m: m.loiter_radius_m,
                        loiter_clockwise: m.loiter_clockwise,
                    });
                    c
                }
                _ => Vec::new(),
            },
        };
        if commands.is_empty() {
            self.mission_refused(&change, from, "mission: nothing to fly");
            return;
        }
        let mut outstanding = 0;
        let mut failed = false;
        for command in commands {
            match self.command_vehicle(command) {
                Some(seq) => {
                    self.pending.insert(seq, (Pending::Mission, Instant::now()));
                    outstanding += 1;
                }
                None => failed = true,
            }
        }
        self.changing = Some(MissionInFlight {
            change,
            to: from,
            outstanding,
            failed,
        });
        if outstanding == 0 {
            self.mission_finished();
        }
    }

    /// One answer (or a timeout: `accepted` false) to the mission change's commands.
    fn mission_answered(&mut self, accepted: bool) {
        let Some(c) = self.changing.as_mut() else {
            return;
        };
        c.outstanding = c.outstanding.saturating_sub(1);
        c.failed |= !accepted;
        if c.outstanding == 0 {
            self.mission_finished();
        }
    }

    fn mission_refused(&mut self, change: &MissionChange, to: (u8, u8), text: &str) {
        self.send(&statustext(MavSeverity::MAV_SEVERITY_WARNING, text));
        match change {
            MissionChange::Upload(_) | MissionChange::Clear => {
                self.send(&mission_ack(MavMissionResult::MAV_MISSION_DENIED, to));
            }
            MissionChange::SetCurrent(_) => {
                if let Some(m) = self.mission_current() {
                    self.send(&m);
                }
            }
        }
    }

    /// Every command answered: what the vehicle flies now is what the ground is told.
    fn mission_finished(&mut self) {
        let Some(c) = self.changing.take() else {
            return;
        };
        if c.failed {
            self.mission_refused(&c.change, c.to, "mission: the vehicle refused the change");
            return;
        }
        self.changed_at_update = Some(self.view.updates("control"));
        match c.change {
            MissionChange::Upload(m) => {
                self.reached = vec![false; m.waypoints.len()];
                self.items = self.home.as_ref().map(|h| items_from_mission(&m, h));
                self.mission = Some(*m);
                self.waypoint = None;
                self.send(&mission_ack(MavMissionResult::MAV_MISSION_ACCEPTED, c.to));
            }
            MissionChange::Clear => {
                self.mission = None;
                self.items = None;
                self.reached.clear();
                self.waypoint = None;
                self.send(&mission_ack(MavMissionResult::MAV_MISSION_ACCEPTED, c.to));
            }
            MissionChange::SetCurrent(w) => {
                // The waypoints before it are skipped, not reached.
                for (i, r) in self.reached.iter_mut().enumerate() {
                    *r = i < w;
                }
                self.waypoint = Some(w);
                if let Some(m) = self.mission_current() {
                    self.send(&m);
                }
            }
        }
    }
}
