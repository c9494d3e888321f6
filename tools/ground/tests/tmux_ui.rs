//! The real binary's UI in a real terminal (tmux, 120×40) against a fake vehicle: it shows
//! the Executive tab, switches tabs, and stops the vehicle after a y/n confirmation.
//! Without tmux this test is skipped locally and fails under CI=true (`.ci/run` installs it).

mod support;

use std::process::Command;
use std::time::{Duration, Instant};
use support::{Ground, KEY_HEX, RunningVehicle, path_str};

/// A tmux server of our own (`-L`), killed when the test ends however it ends.
struct Tmux {
    socket: String,
}

impl Tmux {
    fn command(&self) -> Command {
        let mut command = Command::new("tmux");
        command.arg("-L").arg(&self.socket);
        command
    }

    fn run(&self, args: &[&str]) -> String {
        let output = self.command().args(args).output().expect("run tmux");
        String::from_utf8_lossy(&output.stdout).into_owned()
    }

    fn screen(&self) -> String {
        self.run(&["capture-pane", "-p", "-t", "ui"])
    }

    /// Polls the screen until `done` holds; panics with the last screen if it never does.
    fn wait_for(&self, what: &str, done: impl Fn(&str) -> bool) -> String {
        let deadline = Instant::now() + Duration::from_secs(15);
        loop {
            let screen = self.screen();
            if done(&screen) {
                return screen;
            }
            if Instant::now() > deadline {
                panic!("waited for {what}; the screen is:\n{screen}");
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

impl Drop for Tmux {
    fn drop(&mut self) {
        let _ = self.command().arg("kill-server").output();
    }
}

fn tmux_available() -> bool {
    Command::new("tmux")
        .arg("-V")
        .output()
        .is_ok_and(|o| o.status.success())
}

#[test]
fn the_ui_runs_in_a_terminal_and_stops_a_vehicle_after_confirmation() {
    if !tmux_available() {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "tmux is missing under CI: .ci/run must install it"
        );
        eprintln!("tmux not installed: skipping the terminal test");
        return;
    }
    let ground = Ground::new();
    let key = ground.write_key("link.key", KEY_HEX, 0o600);
    let tmux = Tmux {
        socket: format!("skyframe-ground-test-{}", std::process::id()),
    };
    let command = format!(
        "env SKYFRAME_GROUND_STATE={} {} --listen {} --key {}",
        path_str(&ground.state_dir()),
        env!("CARGO_BIN_EXE_skyframe-ground"),
        ground.listen,
        path_str(&key)
    );
    let started = tmux
        .command()
        .args(["new-session", "-d", "-x", "120", "-y", "40", "-s", "ui"])
        .arg("-c")
        .arg(ground.dir.path())
        .arg(&command)
        .status()
        .expect("tmux new-session");
    assert!(started.success());
    tmux.wait_for("the UI listening", |s| s.contains("no vehicle heard yet"));
    let vehicle = RunningVehicle::start(9, ground.listen, 200);

    // Statuses rotate one task a second: all eight tasks' lights within ~8 s.
    let executive = tmux.wait_for("the Executive tab with every task's lights", |s| {
        s.contains("vehicle 9") && s.contains("│health     ● ● ● ●")
    });
    println!("Executive tab:\n{executive}");
    assert!(executive.contains("1 Executive"));
    assert!(executive.contains("imu        ● ● ● ●"), "{executive}");

    tmux.run(&["send-keys", "-t", "ui", "3"]);
    let gps = tmux.wait_for("the GPS tab", |s| s.contains("track, local metres"));
    assert!(gps.contains("satellites 9"), "{gps}");

    // Back to the Executive tab; `p` asks for the parameter list, signed with the key.
    tmux.run(&["send-keys", "-t", "ui", "1"]);
    tmux.run(&["send-keys", "-t", "ui", "p"]);
    let params = tmux.wait_for("the parameter list and its acknowledgement", |s| {
        s.contains("control.roll_gain") && s.contains("list parameters of vehicle 9: accepted")
    });
    println!("Executive tab after p:\n{params}");

    tmux.run(&["send-keys", "-t", "ui", "s"]);
    tmux.wait_for("the stop confirmation", |s| s.contains("STOP vehicle 9?"));
    tmux.run(&["send-keys", "-t", "ui", "y"]);
    let stopped = tmux.wait_for("the stop's acknowledgement", |s| {
        s.contains("stop vehicle 9: accepted")
    });
    assert!(stopped.contains("stop vehicle 9: accepted"));
    assert!(vehicle.finish().stopped_by_command);

    // The vehicle is gone; the UI says so and keeps running until q.
    tmux.wait_for("link lost", |s| s.contains("LINK LOST"));
    tmux.run(&["send-keys", "-t", "ui", "q"]);
    let deadline = Instant::now() + Duration::from_secs(5);
    while tmux
        .command()
        .args(["has-session", "-t", "ui"])
        .output()
        .is_ok_and(|o| o.status.success())
    {
        assert!(Instant::now() < deadline, "q did not quit the UI");
        std::thread::sleep(Duration::from_millis(100));
    }
}
