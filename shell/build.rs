//! Puts the git commit into the binary (`SKYFRAME_GIT_HASH`) for MAVLink's AUTOPILOT_VERSION
//! (`flight_custom_version`): a ground station then knows exactly which software flies.

use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

fn main() {
    let hash = git(&["rev-parse", "HEAD"]).unwrap_or_default();
    println!("cargo:rustc-env=SKYFRAME_GIT_HASH={hash}");
    // Build again when HEAD moves: HEAD itself, the branch it names, packed refs (a work
    // tree's HEAD and the shared refs live in different directories: ask git where).
    let mut watched = vec![git(&["rev-parse", "--git-path", "HEAD"])];
    if let Some(branch) = git(&["symbolic-ref", "-q", "HEAD"]) {
        watched.push(git(&["rev-parse", "--git-path", &branch]));
    }
    watched.push(git(&["rev-parse", "--git-path", "packed-refs"]));
    for path in watched.into_iter().flatten() {
        println!("cargo:rerun-if-changed={path}");
    }
    println!("cargo:rerun-if-changed=build.rs");
}
