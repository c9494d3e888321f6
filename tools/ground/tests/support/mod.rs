//! A fake vehicle on a real loopback socket and the real binary to talk to it.
// Each test crate uses only part of this module.
#![allow(dead_code)]

use skyframe_core::link::auth::LinkKey;
use skyframe_ground::fake_vehicle::{FakeVehicle, FakeVehicleConfig, FakeVehicleReport};
use std::net::{SocketAddr, UdpSocket};
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

pub const KEY_HEX: &str = "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f";

pub fn key() -> LinkKey {
    LinkKey::from_hex(KEY_HEX).expect("hex key")
}

/// A loopback port free a moment ago, for the ground to listen on.
pub fn free_port() -> SocketAddr {
    let socket = UdpSocket::bind("127.0.0.1:0").expect("bind");
    socket.local_addr().expect("addr")
}

pub struct RunningVehicle {
    stop: Arc<AtomicBool>,
    handle: Option<JoinHandle<FakeVehicleReport>>,
}

impl RunningVehicle {
    pub fn start(vehicle_id: u16, ground: SocketAddr, data_interval_ms: u32) -> Self {
        Self::start_with(vehicle_id, ground, data_interval_ms, false)
    }

    /// A vehicle that signs its telemetry with [`KEY_HEX`].
    pub fn start_signed(vehicle_id: u16, ground: SocketAddr, data_interval_ms: u32) -> Self {
        Self::start_with(vehicle_id, ground, data_interval_ms, true)
    }

    fn start_with(
        vehicle_id: u16,
        ground: SocketAddr,
        data_interval_ms: u32,
        sign_telemetry: bool,
    ) -> Self {
        let vehicle = FakeVehicle::bind(FakeVehicleConfig {
            vehicle_id,
            run_id: 0xC0FF_EE00 + u32::from(vehicle_id),
            key: key(),
            sign_telemetry,
            telemetry_to: ground,
            data_interval_ms,
            duration: Duration::from_secs(600),
        })
        .expect("fake vehicle");
        let stop = Arc::new(AtomicBool::new(false));
        let handle = vehicle.spawn(Arc::clone(&stop), Duration::from_secs(120));
        Self {
            stop,
            handle: Some(handle),
        }
    }

    /// Stops it (if a command has not already) and says what it did.
    pub fn finish(mut self) -> FakeVehicleReport {
        self.stop.store(true, Ordering::Relaxed);
        self.handle
            .take()
            .expect("running")
            .join()
            .expect("vehicle thread")
    }
}

impl Drop for RunningVehicle {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

pub struct Ground {
    pub dir: tempfile::TempDir,
    pub listen: SocketAddr,
}

impl Ground {
    pub fn new() -> Self {
        Self {
            dir: tempfile::tempdir().expect("tempdir"),
            listen: free_port(),
        }
    }

    pub fn write_key(&self, name: &str, hex: &str, mode: u32) -> PathBuf {
        let path = self.dir.path().join(name);
        std::fs::write(&path, format!("{hex}\n")).expect("write key");
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(mode)).expect("chmod");
        path
    }

    pub fn command(&self) -> Command {
        let mut command = Command::new(env!("CARGO_BIN_EXE_skyframe-ground"));
        command
            .current_dir(self.dir.path())
            .env_remove("SKYFRAME_KEY")
            .env("SKYFRAME_GROUND_STATE", self.dir.path().join("state"))
            .arg("--listen")
            .arg(self.listen.to_string());
        command
    }

    pub fn run(&self, args: &[&str]) -> Output {
        self.command()
            .args(args)
            .output()
            .expect("run skyframe-ground")
    }

    /// Starts the ground, then (once it listens) the vehicle, so the ground hears the
    /// vehicle's first datagrams (column names, the first statuses).
    pub fn run_with_vehicle(
        &self,
        args: &[&str],
        vehicle_id: u16,
        interval_ms: u32,
    ) -> (Output, FakeVehicleReport) {
        let child = self
            .command()
            .args(args)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .expect("spawn skyframe-ground");
        std::thread::sleep(Duration::from_millis(300));
        let vehicle = RunningVehicle::start(vehicle_id, self.listen, interval_ms);
        let output = child.wait_with_output().expect("wait");
        (output, vehicle.finish())
    }

    pub fn state_dir(&self) -> PathBuf {
        self.dir.path().join("state")
    }
}

pub fn stdout(output: &Output) -> String {
    String::from_utf8_lossy(&output.stdout).into_owned()
}

pub fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

pub fn path_str(path: &Path) -> &str {
    path.to_str().expect("utf-8 path")
}
