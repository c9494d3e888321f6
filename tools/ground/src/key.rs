//! Finding and reading the link key, and the command sequence numbers kept under it.
//!
//! The key comes from `--key FILE`, else `SKYFRAME_KEY` (64 hex digits), else the newest
//! `flights/*/link.key` under the current directory (where `skyframe sim` leaves a fresh
//! one), else there is none: monitoring works, commands are refused.

use skyframe_core::link::auth::{self, LinkKey};
use std::fmt;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};

pub const KEY_ENV: &str = "SKYFRAME_KEY";
pub const STATE_DIR_ENV: &str = "SKYFRAME_GROUND_STATE";

/// Where the key came from, for messages.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum KeySource {
    File(PathBuf),
    Environment,
}

impl fmt::Display for KeySource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            KeySource::File(path) => write!(f, "{}", path.display()),
            KeySource::Environment => write!(f, "${KEY_ENV}"),
        }
    }
}

#[derive(Clone, Debug)]
pub struct LoadedKey {
    pub key: LinkKey,
    pub source: KeySource,
}

/// Reads a key file: 64 hex digits (a trailing newline allowed) or 32 raw bytes. Refuses a
/// file that group or others can read: a key that leaked is no key.
pub fn read_key_file(path: &Path) -> Result<LinkKey, String> {
    skyframe_input_files::read_key_file(path)
}

/// The key as the command line, environment and current directory give it.
pub fn find_key(
    explicit: Option<&Path>,
    environment: Option<&str>,
    search_dir: &Path,
) -> Result<Option<LoadedKey>, String> {
    if let Some(path) = explicit {
        return read_key_file(path).map(|key| {
            Some(LoadedKey {
                key,
                source: KeySource::File(path.to_path_buf()),
            })
        });
    }
    if let Some(text) = environment.filter(|t| !t.is_empty()) {
        let key = LinkKey::from_hex(text.trim())
            .ok_or_else(|| format!("${KEY_ENV} is not 64 hex digits"))?;
        return Ok(Some(LoadedKey {
            key,
            source: KeySource::Environment,
        }));
    }
    match newest_flight_key(search_dir) {
        Some(path) => read_key_file(&path).map(|key| {
            Some(LoadedKey {
                key,
                source: KeySource::File(path),
            })
        }),
        None => Ok(None),
    }
}

/// The most recently modified `flights/*/link.key` under `dir`.
pub fn newest_flight_key(dir: &Path) -> Option<PathBuf> {
    let entries = fs::read_dir(dir.join("flights")).ok()?;
    entries
        .filter_map(Result::ok)
        .map(|e| e.path().join("link.key"))
        .filter_map(|p| {
            let modified = fs::metadata(&p).and_then(|m| m.modified()).ok()?;
            Some((modified, p))
        })
        .max()
        .map(|(_, p)| p)
}

/// A name for the key that does not reveal it: the state file's name.
pub fn key_fingerprint(key: &LinkKey) -> String {
    let tag = auth::sign(key, b"skyframe-ground sequence state").unwrap_or([0; 32]);
    tag.iter().take(8).map(|b| format!("{b:02x}")).collect()
}

/// The ground's command sequence numbers, kept in a file so they never go backwards across
/// ground restarts: a vehicle keeps its replay window for the whole run, so a restarted
/// ground starting again at 1 would have every command refused as a replay.
///
/// The file holds the last number handed out; each new number is written before the command
/// is sent, so a crash can skip numbers but never repeat one.
#[derive(Debug)]
pub struct SequenceStore {
    path: PathBuf,
    last: u32,
}

impl SequenceStore {
    /// `state_dir/seq-<key fingerprint>-<sender id>`.
    pub fn open(state_dir: &Path, key: &LinkKey, sender_id: u8) -> Result<Self, String> {
        fs::create_dir_all(state_dir)
            .map_err(|e| format!("cannot create state dir {}: {e}", state_dir.display()))?;
        let path = state_dir.join(format!("seq-{}-{sender_id}", key_fingerprint(key)));
        let last = match fs::read_to_string(&path) {
            Ok(text) => text
                .trim()
                .parse::<u32>()
                .map_err(|_| format!("sequence state {} is not a number", path.display()))?,
            Err(e) if e.kind() == io::ErrorKind::NotFound => 0,
            Err(e) => return Err(format!("cannot read {}: {e}", path.display())),
        };
        Ok(Self { path, last })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The next sequence number, persisted before it is returned.
    pub fn take_next(&mut self) -> Result<u32, String> {
        let next = self
            .last
            .checked_add(1)
            .ok_or_else(|| format!("sequence numbers exhausted in {}", self.path.display()))?;
        let temporary = self.path.with_extension("tmp");
        fs::write(&temporary, format!("{next}\n"))
            .and_then(|()| fs::rename(&temporary, &self.path))
            .map_err(|e| format!("cannot write {}: {e}", self.path.display()))?;
        self.last = next;
        Ok(next)
    }
}

/// `$SKYFRAME_GROUND_STATE`, else `$XDG_STATE_HOME/skyframe-ground`, else
/// `~/.local/state/skyframe-ground`, else `.skyframe-ground` in the current directory.
pub fn default_state_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os(STATE_DIR_ENV).filter(|d| !d.is_empty()) {
        return PathBuf::from(dir);
    }
    if let Some(dir) = std::env::var_os("XDG_STATE_HOME").filter(|d| !d.is_empty()) {
        return PathBuf::from(dir).join("skyframe-ground");
    }
    match std::env::var_os("HOME").filter(|d| !d.is_empty()) {
        Some(home) => PathBuf::from(home).join(".local/state/skyframe-ground"),
        None => PathBuf::from(".skyframe-ground"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt;

    fn write_key(dir: &Path, name: &str, contents: &[u8], mode: u32) -> PathBuf {
        let path = dir.join(name);
        fs::write(&path, contents).expect("write");
        fs::set_permissions(&path, fs::Permissions::from_mode(mode)).expect("chmod");
        path
    }

    const HEX: &str = "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f";

    #[test]
    fn hex_with_newline_and_raw_bytes_both_read() {
        let dir = tempfile::tempdir().expect("tempdir");
        let hex = write_key(dir.path(), "a", format!("{HEX}\n").as_bytes(), 0o600);
        let raw: Vec<u8> = (0u8..32).collect();
        let raw = write_key(dir.path(), "b", &raw, 0o400);
        assert_eq!(read_key_file(&hex), read_key_file(&raw));
        assert!(read_key_file(&hex).is_ok());
    }

    #[test]
    fn group_readable_and_malformed_keys_are_refused() {
        let dir = tempfile::tempdir().expect("tempdir");
        let open = write_key(dir.path(), "a", HEX.as_bytes(), 0o640);
        let error = read_key_file(&open).expect_err("refused");
        assert!(error.contains("readable by group or others"), "{error}");
        let short = write_key(dir.path(), "b", b"abcd", 0o600);
        assert!(read_key_file(&short).is_err());
    }

    #[test]
    fn explicit_then_environment_then_newest_flight_key() {
        let dir = tempfile::tempdir().expect("tempdir");
        assert!(find_key(None, None, dir.path()).expect("ok").is_none());
        for flight in ["2026-01-01T00-00-00Z", "2026-01-02T00-00-00Z"] {
            fs::create_dir_all(dir.path().join("flights").join(flight)).expect("mkdir");
        }
        let older = dir.path().join("flights/2026-01-01T00-00-00Z");
        write_key(&older, "link.key", HEX.as_bytes(), 0o600);
        std::thread::sleep(std::time::Duration::from_millis(20));
        let newer = dir.path().join("flights/2026-01-02T00-00-00Z");
        write_key(&newer, "link.key", "ff".repeat(32).as_bytes(), 0o600);
        let found = find_key(None, None, dir.path()).expect("ok").expect("key");
        assert_eq!(found.source, KeySource::File(newer.join("link.key")));
        let from_env = find_key(None, Some(HEX), dir.path())
            .expect("ok")
            .expect("key");
        assert_eq!(from_env.source, KeySource::Environment);
        let explicit = older.join("link.key");
        let found = find_key(Some(&explicit), Some(HEX), dir.path())
            .expect("ok")
            .expect("key");
        assert_eq!(found.source, KeySource::File(explicit));
    }

    #[test]
    fn sequence_numbers_survive_a_restart() {
        let dir = tempfile::tempdir().expect("tempdir");
        let key = LinkKey::new([7; 32]);
        let mut store = SequenceStore::open(dir.path(), &key, 1).expect("open");
        assert_eq!(store.take_next(), Ok(1));
        assert_eq!(store.take_next(), Ok(2));
        let mut reopened = SequenceStore::open(dir.path(), &key, 1).expect("open");
        assert_eq!(reopened.take_next(), Ok(3));
        let mut other_sender = SequenceStore::open(dir.path(), &key, 2).expect("open");
        assert_eq!(other_sender.take_next(), Ok(1));
        let name = reopened.path().file_name().and_then(|n| n.to_str());
        assert!(name.is_some_and(|n| !n.contains("0707")), "{name:?}");
    }
}
