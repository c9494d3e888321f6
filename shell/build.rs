//! Puts the git commit into the binary (`SKYFRAME_GIT_HASH`) for MAVLink's AUTOPILOT_VERSION
//! (`flight_custom_version`): a ground station then knows exactly which software flies.

fn main() {
    let hash = std::process::Command::new("git")
        .args(["rev-parse", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .unwrap_or_default();
    println!("cargo:rustc-env=SKYFRAME_GIT_HASH={hash}");
}
