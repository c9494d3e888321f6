//! Reading a file a user named, never more than a limit: `skyframe check-schedule /dev/zero`
//! must say "too large" at once instead of reading until memory runs out. Every error is one
//! line that names the file (and what it was meant to be).

use std::fs::File;
use std::io::Read;
use std::path::Path;

/// Configuration files (schedule, scenario, mission, vehicle, camera): the shipped ones are
/// a few kB; a megabyte is a generous hand-written file and still nothing to hold in memory.
pub const CONFIG_LIMIT: u64 = 1024 * 1024;
/// Key files: 64 hex digits and a newline, or 32 raw bytes.
pub const KEY_LIMIT: u64 = 1024;

/// The file's bytes, or why not: unreadable, or larger than `limit` bytes.
pub fn read_bytes(path: &Path, what: &str, limit: u64) -> Result<Vec<u8>, String> {
    let file = File::open(path).map_err(|e| format!("{what} {}: {e}", path.display()))?;
    let mut bytes = Vec::new();
    // One byte past the limit tells "exactly at the limit" from "larger".
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| format!("{what} {}: {e}", path.display()))?;
    if bytes.len() as u64 > limit {
        return Err(format!(
            "{what} {}: larger than {} (not a {what} file?)",
            path.display(),
            size_text(limit)
        ));
    }
    Ok(bytes)
}

/// The file as UTF-8 text, or why not (unreadable, too large, not UTF-8 — with the offset of
/// the first bad byte).
pub fn read_text(path: &Path, what: &str, limit: u64) -> Result<String, String> {
    let bytes = read_bytes(path, what, limit)?;
    String::from_utf8(bytes).map_err(|e| {
        format!(
            "{what} {}: not UTF-8 text (byte offset {})",
            path.display(),
            e.utf8_error().valid_up_to()
        )
    })
}

fn size_text(bytes: u64) -> String {
    if bytes >= 1024 * 1024 && bytes % (1024 * 1024) == 0 {
        format!("{} MiB", bytes / (1024 * 1024))
    } else if bytes >= 1024 && bytes % 1024 == 0 {
        format!("{} KiB", bytes / 1024)
    } else {
        format!("{bytes} bytes")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_endless_file_is_refused_after_the_limit_not_read_to_the_end() {
        let err = read_text(Path::new("/dev/zero"), "schedule", CONFIG_LIMIT).expect_err("big");
        assert_eq!(
            err,
            "schedule /dev/zero: larger than 1 MiB (not a schedule file?)"
        );
    }

    #[test]
    fn a_file_at_the_limit_is_read_and_one_byte_more_is_not() {
        let dir = tempfile::tempdir().expect("dir");
        let path = dir.path().join("k");
        std::fs::write(&path, [b'a'; 1024]).expect("write");
        assert_eq!(
            read_text(&path, "key", KEY_LIMIT).expect("fits").len(),
            1024
        );
        std::fs::write(&path, [b'a'; 1025]).expect("write");
        let err = read_text(&path, "key", KEY_LIMIT).expect_err("too large");
        assert!(
            err.ends_with("larger than 1 KiB (not a key file?)"),
            "{err}"
        );
    }

    #[test]
    fn errors_name_the_file_and_the_first_bad_byte() {
        let dir = tempfile::tempdir().expect("dir");
        let path = dir.path().join("m.toml");
        std::fs::write(&path, b"ok = 1\n\xff").expect("write");
        let err = read_text(&path, "mission", CONFIG_LIMIT).expect_err("not utf-8");
        assert!(err.ends_with("not UTF-8 text (byte offset 7)"), "{err}");
        let err = read_text(&dir.path().join("none"), "mission", CONFIG_LIMIT).expect_err("none");
        assert!(err.starts_with("mission ") && err.contains("none"), "{err}");
        assert_eq!(err.lines().count(), 1);
    }
}
