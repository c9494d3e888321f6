//! The link's sockets: one UDP socket, bound to the command address, receives the ground's
//! commands and sends telemetry to every configured destination (so the ground learns where
//! to send commands from where telemetry comes from). Its thread moves datagrams between the
//! socket and two rings; the telemetry task (core) never touches a socket.

use skyframe_core::link::auth::{LinkKey, screen_command};
use skyframe_core::link::ingress::IngressCounters;
use skyframe_core::tasks::telemetry::DatagramPort;
use std::io::Read;
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Where the link listens and sends when nothing else is said; `skyframe-ground` listens on
/// the telemetry port by default.
pub const DEFAULT_COMMANDS: &str = "0.0.0.0:47201";
pub const DEFAULT_TELEMETRY: &str = "127.0.0.1:47200";

const RING_BYTES: usize = 256 * 1024;
const MAX_DATAGRAM: usize = 1472;

/// Reads a 32-byte key: 64 hex digits (a newline may follow) or 32 raw bytes. A key others
/// could read is refused: whoever reads it can fly the airplane.
pub fn load_key(path: &Path) -> Result<LinkKey, String> {
    skyframe_input_files::read_key_file(path)
}

fn random_bytes<const N: usize>() -> Result<[u8; N], String> {
    let mut out = [0u8; N];
    std::fs::File::open("/dev/urandom")
        .and_then(|mut f| f.read_exact(&mut out))
        .map_err(|e| format!("no randomness from /dev/urandom: {e}"))?;
    Ok(out)
}

/// Writes a fresh random key (hex, mode 600) as `dir/link.key`.
pub fn write_new_key(dir: &Path) -> Result<(PathBuf, LinkKey), String> {
    use std::io::Write;
    use std::os::unix::fs::OpenOptionsExt;
    let bytes = random_bytes::<32>()?;
    let path = dir.join("link.key");
    let hex: String = bytes.iter().map(|b| format!("{b:02x}")).collect();
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(&path)
        .and_then(|mut f| f.write_all(format!("{hex}\n").as_bytes()))
        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    Ok((path, LinkKey::new(bytes)))
}

/// A run id never used before under the same key: random, so restarts do not repeat.
pub fn new_run_id() -> Result<u32, String> {
    random_bytes::<4>().map(u32::from_le_bytes)
}

/// Counters of the socket thread.
#[derive(Debug, Default)]
pub struct LinkIo {
    /// The address commands are received on (the port chosen when asked for port 0).
    pub local: Option<SocketAddr>,
    pub datagrams_in: AtomicU64,
    pub datagrams_out: AtomicU64,
    /// Sends the OS refused (no route: the link is down; normal when flying away).
    pub send_errors: AtomicU64,
    /// Datagrams a full ring had no room for.
    pub dropped: AtomicU64,
}

/// The telemetry task's side of the rings.
pub struct RingDatagrams {
    rx: rtrb::Consumer<u8>,
    tx: rtrb::Producer<u8>,
}

impl DatagramPort for RingDatagrams {
    fn receive(&mut self, buf: &mut [u8]) -> Option<usize> {
        // The length first, without consuming it: the datagram may not be whole yet.
        let len = {
            let header = self.rx.read_chunk(2).ok()?;
            let (a, b) = header.as_slices();
            let mut len = [0u8; 2];
            for (slot, byte) in len.iter_mut().zip(a.iter().chain(b)) {
                *slot = *byte;
            }
            usize::from(u16::from_le_bytes(len))
        };
        let chunk = self.rx.read_chunk(2 + len).ok()?;
        let (a, b) = chunk.as_slices();
        let n = len.min(buf.len());
        for (slot, byte) in buf.iter_mut().zip(a.iter().chain(b).skip(2)) {
            *slot = *byte;
        }
        chunk.commit_all();
        Some(n)
    }

    fn send(&mut self, datagram: &[u8], reply: bool) -> bool {
        let Ok(len) = u16::try_from(datagram.len()) else {
            return false;
        };
        if self.tx.slots() < 3 + datagram.len() {
            return false;
        }
        let Ok(chunk) = self.tx.write_chunk_uninit(3 + datagram.len()) else {
            return false;
        };
        let head = len.to_le_bytes();
        chunk.fill_from_iter(
            head.into_iter()
                .chain([u8::from(reply)])
                .chain(datagram.iter().copied()),
        );
        true
    }
}

/// What the socket thread checks before it queues a datagram for the telemetry task: the
/// command gate's stateless checks ([`screen_command`]) and each source's share.
pub struct Screen {
    pub key: LinkKey,
    pub vehicle_id: u16,
    /// Counts what is dropped here; the telemetry task reports them with its own.
    pub ingress: Arc<IngressCounters>,
}

/// Binds the command socket and starts its thread; ends when `stop` is set, after sending
/// what is queued.
pub fn spawn_link(
    bind: SocketAddr,
    telemetry: Vec<SocketAddr>,
    screen: Screen,
    stop: Arc<AtomicBool>,
) -> Result<(RingDatagrams, JoinHandle<()>, Arc<LinkIo>), String> {
    spawn_link_with(Some(bind), telemetry, screen, stop, None)
}

/// [`spawn_link`], with the MAVLink endpoint's hook (it sees every telemetry datagram and
/// queues its commands here), and without a socket when `bind` is `None` (`--no-link` with
/// `--mavlink`: the rings and this thread carry MAVLink's traffic only).
pub fn spawn_link_with(
    bind: Option<SocketAddr>,
    telemetry: Vec<SocketAddr>,
    screen: Screen,
    stop: Arc<AtomicBool>,
    hook: Option<crate::mavlink::LinkHook>,
) -> Result<(RingDatagrams, JoinHandle<()>, Arc<LinkIo>), String> {
    let socket = match bind {
        Some(bind) => {
            let socket = UdpSocket::bind(bind).map_err(|e| format!("--commands {bind}: {e}"))?;
            socket
                .set_read_timeout(Some(Duration::from_millis(5)))
                .map_err(|e| format!("--commands {bind}: {e}"))?;
            // Telemetry may go to a broadcast address.
            let _ = socket.set_broadcast(true);
            Some(socket)
        }
        None => None,
    };
    let (rx_in, rx_out) = rtrb::RingBuffer::new(RING_BYTES);
    let (tx_in, tx_out) = rtrb::RingBuffer::new(RING_BYTES);
    let io = Arc::new(LinkIo {
        local: socket.as_ref().and_then(|s| s.local_addr().ok()),
        ..LinkIo::default()
    });
    let thread_io = Arc::clone(&io);
    let join = std::thread::Builder::new()
        .name("link".into())
        .stack_size(256 * 1024)
        .spawn(move || {
            link_thread(
                socket.as_ref(),
                &telemetry,
                &screen,
                rx_in,
                tx_out,
                &thread_io,
                &stop,
                hook.as_ref(),
            )
        })
        .map_err(|e| format!("cannot start the link thread: {e}"))?;
    Ok((
        RingDatagrams {
            rx: rx_out,
            tx: tx_in,
        },
        join,
        io,
    ))
}

/// Datagrams received in a row before the queued telemetry is sent: under a flood the
/// socket is drained in batches and telemetry still goes out between them.
const RECEIVE_BATCH: usize = 256;

#[allow(clippy::too_many_arguments)]
fn link_thread(
    socket: Option<&UdpSocket>,
    telemetry: &[SocketAddr],
    screen: &Screen,
    mut rx: rtrb::Producer<u8>,
    mut tx: rtrb::Consumer<u8>,
    io: &LinkIo,
    stop: &AtomicBool,
    hook: Option<&crate::mavlink::LinkHook>,
) {
    let mut buf = [0u8; MAX_DATAGRAM + 1];
    let mut last_sender: Option<SocketAddr> = None;
    let mut shares = SourceShares::new();
    loop {
        let stopping = stop.load(Ordering::Acquire);
        // MAVLink's commands: made and signed in this process, queued as they are.
        while let Some(datagram) = hook.and_then(|h| h.commands.try_recv().ok()) {
            match (
                u16::try_from(datagram.len()),
                rx.write_chunk_uninit(2 + datagram.len()),
            ) {
                (Ok(len), Ok(chunk)) => {
                    chunk.fill_from_iter(len.to_le_bytes().into_iter().chain(datagram));
                }
                _ => {
                    io.dropped.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
        if socket.is_none() {
            // No socket to wait on: pace the loop as the socket's read timeout would.
            std::thread::sleep(Duration::from_millis(5));
        }
        for _ in 0..RECEIVE_BATCH {
            let Some(Ok((n, from))) = socket.map(|s| s.recv_from(&mut buf)) else {
                break;
            };
            io.datagrams_in.fetch_add(1, Ordering::Relaxed);
            // Cheapest first: a source over its share costs no HMAC.
            if !shares.take(from, Instant::now()) {
                screen.ingress.rate_limited();
                continue;
            }
            let datagram = buf.get(..n).unwrap_or_default();
            if let Err(reason) = screen_command(datagram, &screen.key, screen.vehicle_id) {
                screen.ingress.screened_out(reason);
                continue;
            }
            // Only an authentic command decides where replies go.
            last_sender = Some(from);
            match (u16::try_from(n), rx.write_chunk_uninit(2 + n)) {
                (Ok(len), Ok(chunk)) => {
                    chunk.fill_from_iter(
                        len.to_le_bytes()
                            .into_iter()
                            .chain(datagram.iter().copied()),
                    );
                }
                _ => {
                    io.dropped.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
        while tx.slots() >= 3 {
            let Ok(head) = tx.read_chunk(3) else { break };
            let (a, b) = head.as_slices();
            let mut h = [0u8; 3];
            for (slot, byte) in h.iter_mut().zip(a.iter().chain(b)) {
                *slot = *byte;
            }
            let len = usize::from(u16::from_le_bytes([h[0], h[1]]));
            let reply = h[2] != 0;
            head.commit_all();
            let Ok(body) = tx.read_chunk(len) else { break };
            let (a, b) = body.as_slices();
            let mut datagram = Vec::with_capacity(len);
            datagram.extend_from_slice(a);
            datagram.extend_from_slice(b);
            body.commit_all();
            if let Some(hook) = hook {
                hook.offer(&datagram);
            }
            let Some(socket) = socket else { continue };
            let replies = last_sender.filter(|s| reply && !telemetry.contains(s));
            for to in telemetry.iter().chain(replies.iter()) {
                match socket.send_to(&datagram, to) {
                    Ok(_) => io.datagrams_out.fetch_add(1, Ordering::Relaxed),
                    Err(_) => io.send_errors.fetch_add(1, Ordering::Relaxed),
                };
            }
        }
        if stopping {
            return;
        }
    }
}

/// Datagrams a source may send per second before the rest are dropped unread, and the
/// burst it may send at once: far above a ground station's few commands a second (and its
/// resends), far below a flood.
const SHARE_PER_S: f64 = 100.0;
const SHARE_BURST: f64 = 100.0;
/// Sources remembered; past this the longest silent one is forgotten.
const SOURCES_KEPT: usize = 256;

/// A token bucket per source address, so one sender cannot starve the others. (A forger
/// who spoofs the ground's own address and port shares its bucket: UDP cannot tell them
/// apart; the HMAC still refuses every forgery.)
pub(crate) struct SourceShares {
    buckets: std::collections::HashMap<SocketAddr, (f64, Instant)>,
}

impl SourceShares {
    pub(crate) fn new() -> Self {
        Self {
            buckets: std::collections::HashMap::new(),
        }
    }

    /// Whether `from` may have one more datagram read now.
    pub(crate) fn take(&mut self, from: SocketAddr, now: Instant) -> bool {
        if !self.buckets.contains_key(&from) && self.buckets.len() >= SOURCES_KEPT {
            let oldest = self
                .buckets
                .iter()
                .min_by_key(|(_, (_, last))| *last)
                .map(|(a, _)| *a);
            if let Some(oldest) = oldest {
                self.buckets.remove(&oldest);
            }
        }
        let (tokens, last) = self.buckets.entry(from).or_insert((SHARE_BURST, now));
        let refill = now.saturating_duration_since(*last).as_secs_f64() * SHARE_PER_S;
        *tokens = (*tokens + refill).min(SHARE_BURST);
        *last = now;
        if *tokens >= 1.0 {
            *tokens -= 1.0;
            true
        } else {
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skyframe_core::link::counters::LinkCounters;
    use skyframe_core::link::frame::{Envelope, encode_datagram};
    use skyframe_core::link::messages::{Command, Message};
    use std::os::unix::fs::PermissionsExt;

    #[test]
    fn each_source_gets_its_share_and_a_flood_does_not_take_anothers() {
        let start = Instant::now();
        let mut shares = SourceShares::new();
        let flood: SocketAddr = "127.0.0.1:9".parse().expect("addr");
        let ground: SocketAddr = "127.0.0.1:47200".parse().expect("addr");
        // 10 000 datagrams in the same instant: the burst passes, the rest do not.
        let passed = (0..10_000).filter(|_| shares.take(flood, start)).count();
        assert_eq!(passed, SHARE_BURST as usize);
        // Another source is untouched by the flood.
        assert!(shares.take(ground, start));
        // A second later the flood has a second's share again, no more.
        let later = start + Duration::from_secs(1);
        let passed = (0..10_000).filter(|_| shares.take(flood, later)).count();
        assert_eq!(passed, SHARE_PER_S as usize);
    }

    #[test]
    fn forgotten_sources_make_room_for_new_ones() {
        let start = Instant::now();
        let mut shares = SourceShares::new();
        for port in 0..(SOURCES_KEPT as u16 + 10) {
            let at = start + Duration::from_millis(u64::from(port));
            assert!(shares.take(SocketAddr::from(([127, 0, 0, 1], port)), at));
        }
        assert_eq!(shares.buckets.len(), SOURCES_KEPT);
    }

    #[test]
    fn keys_load_from_hex_or_raw_and_readable_ones_are_refused() {
        let dir = std::env::temp_dir().join(format!("skyframe-key-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("dir");
        let (path, key) = write_new_key(&dir).expect("written");
        let mode = std::fs::metadata(&path).expect("meta").permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
        let loaded = load_key(&path).expect("loads");
        assert_eq!(format!("{loaded:?}"), format!("{key:?}"));
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o640)).expect("chmod");
        let e = load_key(&path).expect_err("group readable");
        assert!(e.contains("readable by group or others (mode 640)"), "{e}");
        let raw = dir.join("raw.key");
        std::fs::write(&raw, [7u8; 32]).expect("write");
        std::fs::set_permissions(&raw, std::fs::Permissions::from_mode(0o600)).expect("chmod");
        assert!(load_key(&raw).is_ok());
        std::fs::write(&raw, b"not a key\n").expect("write");
        assert!(
            load_key(&raw)
                .expect_err("junk")
                .contains("not 64 hex digits")
        );
    }

    #[test]
    fn datagrams_cross_the_rings_whole_and_in_order() {
        let stop = Arc::new(AtomicBool::new(false));
        let ground = UdpSocket::bind("127.0.0.1:0").expect("ground socket");
        ground
            .set_read_timeout(Some(Duration::from_secs(2)))
            .expect("timeout");
        let key = LinkKey::new([3; 32]);
        let ingress = Arc::new(IngressCounters::new());
        let screen = Screen {
            key: key.clone(),
            vehicle_id: 7,
            ingress: Arc::clone(&ingress),
        };
        let (mut port, join, io) = spawn_link(
            "127.0.0.1:0".parse().expect("addr"),
            vec![ground.local_addr().expect("addr")],
            screen,
            Arc::clone(&stop),
        )
        .expect("link");
        for i in 0..20u8 {
            assert!(port.send(&[i; 100], false));
        }
        let mut buf = [0u8; 2048];
        let mut from = None;
        for i in 0..20u8 {
            let (n, addr) = ground.recv_from(&mut buf).expect("telemetry");
            assert_eq!(&buf[..n], &[i; 100][..]);
            from = Some(addr);
        }
        // The ground answers to where telemetry came from: the command socket. A forgery
        // (another key) and junk are screened out and counted; the signed command arrives.
        let command = |key: &LinkKey, sequence: u32| {
            let envelope = Envelope {
                vehicle_id: 7,
                sender_id: 1,
                run_id: 1,
                sequence,
                t_ns: 0,
            };
            let mut out = [0u8; 256];
            let n = encode_datagram(
                &envelope,
                &Message::Command(Command::Stop),
                Some(key),
                &mut out,
            )
            .expect("encodes");
            out[..n].to_vec()
        };
        let vehicle = from.expect("vehicle");
        ground
            .send_to(&command(&LinkKey::new([4; 32]), 1), vehicle)
            .expect("send");
        ground.send_to(b"junk", vehicle).expect("send");
        let genuine = command(&key, 2);
        ground.send_to(&genuine, vehicle).expect("send");
        let start = std::time::Instant::now();
        let mut got = [0u8; 256];
        let n = loop {
            if let Some(n) = port.receive(&mut got) {
                break n;
            }
            assert!(
                start.elapsed() < Duration::from_secs(2),
                "command never arrived"
            );
            std::thread::sleep(Duration::from_millis(2));
        };
        assert_eq!(&got[..n], &genuine[..]);
        assert!(
            port.receive(&mut got).is_none(),
            "only the genuine one is queued"
        );
        stop.store(true, Ordering::Release);
        join.join().expect("thread");
        assert_eq!(io.datagrams_out.load(Ordering::Relaxed), 20);
        assert_eq!(io.datagrams_in.load(Ordering::Relaxed), 3);
        let counted = ingress.added_to(&LinkCounters::default());
        assert_eq!(counted.bad_signature, 1);
        assert_eq!(counted.malformed, 1);
        assert_eq!(counted.received, 2);
    }
}
