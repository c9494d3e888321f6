//! Where a run's files go: a new directory per run under the log directory, named by the run's
//! start time (UTC), so flights sort by time and never overwrite each other.

use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// Creates `<log_dir>/<YYYY-MM-DDTHH-MM-SSZ>` (with `-2`, `-3`, … if a run started in the
/// same second) and returns it.
pub fn create(log_dir: &Path, started: SystemTime) -> std::io::Result<PathBuf> {
    std::fs::create_dir_all(log_dir)?;
    // Colons are legal on Linux but break scp, Windows and Matlab paths.
    let stamp = humantime::format_rfc3339_seconds(started)
        .to_string()
        .replace(':', "-");
    for attempt in 1u32.. {
        let name = if attempt == 1 {
            stamp.clone()
        } else {
            format!("{stamp}-{attempt}")
        };
        let dir = log_dir.join(name);
        match std::fs::create_dir(&dir) {
            Ok(()) => return Ok(dir),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
    Err(std::io::Error::other("no free flight directory name"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{Duration, UNIX_EPOCH};

    #[test]
    fn directories_are_named_by_utc_start_and_never_reused() {
        let root = std::env::temp_dir().join(format!("skyframe-flightdir-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let t = UNIX_EPOCH + Duration::from_secs(1_795_305_600); // 2026-11-22T00:00:00Z
        let a = create(&root, t).expect("first");
        let b = create(&root, t).expect("second");
        assert_eq!(a, root.join("2026-11-22T00-00-00Z"));
        assert_eq!(b, root.join("2026-11-22T00-00-00Z-2"));
        assert!(a.is_dir() && b.is_dir());
    }
}
