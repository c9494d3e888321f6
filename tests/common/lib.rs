//! Helpers shared by the integration tests: where the binaries are, scratch directories.

use std::borrow::BorrowMut;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

/// The workspace root.
pub fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default()
}

/// The path of shipped scenario or mission file `scenarios/NAME.toml`, as a command-line
/// argument.
pub fn shipped(name: &str) -> String {
    workspace()
        .join("scenarios")
        .join(format!("{name}.toml"))
        .to_string_lossy()
        .into_owned()
}

/// `skyframe-log info` on these logs, which must succeed: its report.
pub fn log_info<P: AsRef<std::ffi::OsStr>>(logs: &[P]) -> String {
    let info = run_ok(
        Command::new(binary("skyframe-log", "skyframe-log"))
            .arg("info")
            .args(logs),
    );
    String::from_utf8_lossy(&info.stdout).into_owned()
}

/// Figure `group.name` of a `--score` report.
pub fn score_figure(score: &serde_json::Value, group: &str, name: &str) -> f64 {
    score[group][name]
        .as_f64()
        .unwrap_or_else(|| panic!("score.{group}.{name} in {score}"))
}

fn cargo() -> String {
    std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_string())
}

/// Path of a binary built by this workspace (same profile as the running test). Cargo does
/// not build another package's binaries for these tests, so ask it to (a no-op when fresh:
/// a stale binary would test old code).
pub fn binary(package: &str, name: &str) -> PathBuf {
    let exe = std::env::current_exe().unwrap_or_default();
    // target/<profile>/deps/<test> -> target/<profile>/<name>
    let profile_dir = exe
        .parent()
        .and_then(Path::parent)
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let path = profile_dir.join(name);
    static BUILT: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());
    let mut built = BUILT
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    if !built.iter().any(|b| b == name) {
        let release = profile_dir.file_name().is_some_and(|n| n == "release");
        let mut cmd = Command::new(cargo());
        cmd.args(["build", "-q", "-p", package, "--bin", name]);
        if release {
            cmd.arg("--release");
        }
        let status = cmd.current_dir(workspace()).status().expect("cargo runs");
        assert!(status.success(), "building {name} failed");
        built.push(name.to_string());
    }
    path
}

/// The `skyframe` flight binary.
pub fn skyframe() -> Command {
    Command::new(binary("skyframe-linux", "skyframe"))
}

/// Runs `command` to its end; it must exit 0, or the test fails showing its stderr.
pub fn run_ok(mut command: impl BorrowMut<Command>) -> Output {
    let command = command.borrow_mut();
    let out = command.output().expect("runs");
    assert!(
        out.status.success(),
        "{:?} exited {:?}: {}",
        command.get_program(),
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Starts `command` with its standard output and error piped, for
/// [`Child::wait_with_output`] or [`finish_ok`].
pub fn spawn_piped(mut command: impl BorrowMut<Command>) -> Child {
    let command = command.borrow_mut();
    command
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("{:?} does not start: {e}", command.get_program()))
}

/// Waits for `child` (started by [`spawn_piped`]); it must exit 0, or the test fails showing
/// its stderr.
pub fn finish_ok(child: Child) -> Output {
    let out = child.wait_with_output().expect("exits");
    assert!(
        out.status.success(),
        "exited {:?}: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// A run's standard output as JSON (its `--json` report).
pub fn json_of(stdout: &[u8]) -> serde_json::Value {
    serde_json::from_slice(stdout)
        .unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(stdout)))
}

/// `skyframe SUBCOMMAND --duration SECONDS --json` on the real clock, without the real-time
/// settings (the tests run beside each other: no priority, no locked memory).
pub fn on_the_clock(subcommand: &str, seconds: &str) -> Command {
    let mut command = skyframe();
    command.args([
        subcommand,
        "--duration",
        seconds,
        "--json",
        "--priority",
        "0",
        "--no-mlockall",
    ]);
    command
}

/// A fresh scratch directory for one test.
pub fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("skyframe-it-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

/// A `cargo` command for nested builds.
pub fn cargo_command() -> Command {
    Command::new(cargo())
}

/// `skyframe-log to-csv INPUTS… --out-dir OUT`, which must succeed (every log whole and
/// closed cleanly); returns `out`.
pub fn to_csv<P: AsRef<std::ffi::OsStr>>(inputs: &[P], out: &Path) -> PathBuf {
    let run = Command::new(binary("skyframe-log", "skyframe-log"))
        .arg("to-csv")
        .args(inputs)
        .arg("--out-dir")
        .arg(out)
        .output()
        .expect("skyframe-log runs");
    assert!(
        run.status.success(),
        "every log whole: {}{}",
        String::from_utf8_lossy(&run.stdout),
        String::from_utf8_lossy(&run.stderr)
    );
    out.to_path_buf()
}

/// The data rows of a converted CSV as numbers (NaN for anything else), time first.
pub fn csv_rows(csv: &Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(csv)
        .unwrap_or_else(|e| panic!("{}: {e}", csv.display()))
        .lines()
        .filter(|l| !l.starts_with('%'))
        .map(|l| {
            l.split(',')
                .map(|v| v.parse().unwrap_or(f64::NAN))
                .collect()
        })
        .collect()
}

/// The column names of a converted CSV, from its `% time,…` header line.
pub fn csv_columns(csv: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(csv).unwrap_or_else(|e| panic!("{}: {e}", csv.display()));
    let header = text
        .lines()
        .find(|l| l.starts_with("% time,"))
        .unwrap_or_else(|| panic!("{}: no column header", csv.display()));
    header
        .trim_start_matches("% ")
        .split(',')
        .map(str::to_string)
        .collect()
}

/// Column `name` of a converted CSV.
pub fn csv_column(csv: &Path, name: &str) -> Vec<f64> {
    let columns = csv_columns(csv);
    let index = columns
        .iter()
        .position(|c| c == name)
        .unwrap_or_else(|| panic!("{name} not in {columns:?}"));
    csv_rows(csv).iter().map(|r| r[index]).collect()
}

/// Pseudo-terminals standing in for serial devices.
pub mod pty {
    use serialport::{SerialPort, TTYPort};
    use std::path::{Path, PathBuf};
    use std::time::Duration;

    /// A pty whose slave end is opened by path (by the shell, or a `skyframe` child); the
    /// test holds the master, the "device", whose reads time out after `timeout`.
    pub fn device(timeout: Duration) -> (TTYPort, PathBuf) {
        let (mut master, slave) = TTYPort::pair().expect("pty pair");
        // The master must not leak into a `skyframe` child: an inherited copy would keep the
        // "device" plugged in after the test drops its own.
        {
            use std::os::fd::{AsRawFd, BorrowedFd};
            // SAFETY: the fd belongs to `master`, which outlives this borrow.
            #[allow(unsafe_code)]
            let fd = unsafe { BorrowedFd::borrow_raw(master.as_raw_fd()) };
            nix::fcntl::fcntl(
                fd,
                nix::fcntl::FcntlArg::F_SETFD(nix::fcntl::FdFlag::FD_CLOEXEC),
            )
            .expect("close-on-exec");
        }
        master.set_timeout(timeout).expect("timeout");
        let path = PathBuf::from(slave.name().expect("slave has a name"));
        drop(slave);
        (master, path)
    }

    /// Points `link` at `target`, atomically (as udev re-creates a by-id link).
    pub fn point(link: &Path, target: &Path) {
        let tmp = link.with_extension("new");
        let _ = std::fs::remove_file(&tmp);
        std::os::unix::fs::symlink(target, &tmp).expect("symlink");
        std::fs::rename(&tmp, link).expect("rename");
    }
}
