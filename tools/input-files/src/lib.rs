//! Reading a file a user named, never more than a limit: `skyframe check-schedule /dev/zero`
//! must say "too large" at once instead of reading until memory runs out. Every error is one
//! line that names the file (and what it was meant to be).

use skyframe_core::link::auth::LinkKey;
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

/// A link key file: 64 hex digits (one trailing newline allowed) or 32 raw bytes, refused if
/// group or others may read it (whoever reads the key can fly the airplane). The one reader
/// of key files for the vehicle, the ground station and the horizon sender.
pub fn read_key_file(path: &Path) -> Result<LinkKey, String> {
    read_key_bytes(path).map(LinkKey::new)
}

/// [`read_key_file`]'s 32 bytes, for secrets used outside the skyframe link (MAVLink's
/// signing key, `--mavlink-key`): the same file rules.
pub fn read_key_bytes(path: &Path) -> Result<[u8; 32], String> {
    use std::os::unix::fs::PermissionsExt;
    let mode = std::fs::metadata(path)
        .map_err(|e| format!("key {}: {e}", path.display()))?
        .permissions()
        .mode();
    if mode & 0o077 != 0 {
        return Err(format!(
            "key {}: readable by group or others (mode {:o}); chmod 600 it",
            path.display(),
            mode & 0o777
        ));
    }
    let bytes = read_bytes(path, "key", KEY_LIMIT)?;
    let text = bytes
        .strip_suffix(b"\r\n")
        .or_else(|| bytes.strip_suffix(b"\n"))
        .unwrap_or(&bytes);
    if let Some(key) = hex_key(text) {
        return Ok(key);
    }
    <[u8; 32]>::try_from(bytes.as_slice())
        .map_err(|_| format!("key {}: not 64 hex digits or 32 bytes", path.display()))
}

/// Exactly 64 hex digits (either case).
fn hex_key(text: &[u8]) -> Option<[u8; 32]> {
    if text.len() != 64 {
        return None;
    }
    let digit = |c: u8| {
        char::from(c)
            .to_digit(16)
            .and_then(|d| u8::try_from(d).ok())
    };
    let mut key = [0u8; 32];
    for (byte, pair) in key.iter_mut().zip(text.chunks_exact(2)) {
        *byte = digit(*pair.first()?)? << 4 | digit(*pair.get(1)?)?;
    }
    Some(key)
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

    fn key_file(dir: &Path, name: &str, contents: &[u8], mode: u32) -> std::path::PathBuf {
        use std::os::unix::fs::PermissionsExt;
        let path = dir.join(name);
        std::fs::write(&path, contents).expect("write");
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(mode)).expect("chmod");
        path
    }

    #[test]
    fn keys_read_from_hex_or_raw_bytes_and_others_are_refused() {
        let dir = tempfile::tempdir().expect("dir");
        let hex: String = (0u8..32).map(|b| format!("{b:02x}")).collect();
        let raw: Vec<u8> = (0u8..32).collect();
        let from_hex = read_key_file(&key_file(
            dir.path(),
            "h",
            format!("{hex}\n").as_bytes(),
            0o600,
        ));
        let from_raw = read_key_file(&key_file(dir.path(), "r", &raw, 0o400));
        assert_eq!(from_hex.expect("hex"), from_raw.expect("raw"));
        let open = read_key_file(&key_file(dir.path(), "o", hex.as_bytes(), 0o640));
        assert!(
            open.expect_err("group readable")
                .ends_with("readable by group or others (mode 640); chmod 600 it")
        );
        let short = read_key_file(&key_file(dir.path(), "s", b"abcd", 0o600));
        assert!(
            short
                .expect_err("short")
                .ends_with("not 64 hex digits or 32 bytes")
        );
        let zero = read_key_file(Path::new("/dev/zero")).expect_err("endless");
        assert!(zero.contains("/dev/zero"), "{zero}");
    }

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
