//! `vehicle.toml`: what is plugged in where on this airplane, and where its data goes.
//!
//! ```toml
//! [devices.imu]
//! port = "/dev/ttyS0"
//! baud = 115200
//! stale_ms = 50          # no valid frame for this long: the device shows as stale
//!
//! [devices.gps]
//! port = "/dev/serial/by-id/usb-ashtech-if00"
//! baud = 115200
//! stale_ms = 500
//!
//! [devices.servo]
//! port = "/dev/ttyS2"
//! baud = 115200
//! stale_ms = 100
//!
//! [log]
//! dir = "flights"
//! text = ["gps"]         # streams written as CSV instead of binary
//! rotate_mb = 64
//! flush_ms = 100         # to the OS: survives kill -9
//! fsync_ms = 1000        # to the disk: survives a power cut
//! ```
//!
//! Every error is one line naming the file and the key (or line and column).

use serde::Deserialize;
use skyframe_core::schedule::file::toml_error_line;
use skyframe_input_files::{CONFIG_LIMIT, read_text};
use std::path::{Path, PathBuf};

#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct VehicleConfig {
    pub devices: Devices,
    #[serde(default)]
    pub log: LogConfig,
}

#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Devices {
    pub imu: DeviceConfig,
    pub gps: DeviceConfig,
    pub servo: DeviceConfig,
}

#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct DeviceConfig {
    pub port: PathBuf,
    pub baud: u32,
    /// No valid frame for this long makes the device stale (health, telemetry).
    pub stale_ms: u32,
}

#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields, default)]
pub struct LogConfig {
    /// Flights go into new subdirectories of this one, named by their start time.
    pub dir: PathBuf,
    /// Streams written as CSV text instead of binary (`imu`, `gps`, …).
    pub text: Vec<String>,
    /// A log file rotates when it reaches this size.
    pub rotate_mb: u64,
    /// Written data goes to the OS this often: after `kill -9` it is there.
    pub flush_ms: u64,
    /// …and to the disk this often: after a power cut it is there.
    pub fsync_ms: u64,
}

impl Default for LogConfig {
    fn default() -> Self {
        Self {
            dir: PathBuf::from("flights"),
            text: Vec::new(),
            rotate_mb: 64,
            flush_ms: 100,
            fsync_ms: 1000,
        }
    }
}

/// Baud rates a UART can be set to; anything else is a typo.
const BAUD_RATES: &[u32] = &[
    1200, 2400, 4800, 9600, 19_200, 38_400, 57_600, 115_200, 230_400, 460_800, 921_600,
];

impl VehicleConfig {
    /// Reads and checks a vehicle file; `Err` is one line naming the file and the key.
    pub fn load(path: &Path) -> Result<Self, String> {
        let text = read_text(path, "vehicle", CONFIG_LIMIT)?;
        Self::parse(&text).map_err(|e| format!("{}: {e}", path.display()))
    }

    pub fn parse(text: &str) -> Result<Self, String> {
        let config: Self = toml::from_str(text).map_err(|e| toml_error_line(&e, text))?;
        if config.log.rotate_mb == 0 || config.log.flush_ms == 0 || config.log.fsync_ms == 0 {
            return Err("log.rotate_mb, log.flush_ms and log.fsync_ms must be above 0".into());
        }
        for (name, device) in config.devices() {
            if !BAUD_RATES.contains(&device.baud) {
                return Err(format!(
                    "devices.{name}.baud = {} is not a standard baud rate",
                    device.baud
                ));
            }
            if device.stale_ms == 0 {
                return Err(format!("devices.{name}.stale_ms must be above 0"));
            }
        }
        Ok(config)
    }

    /// The devices with their table names, in a fixed order.
    pub fn devices(&self) -> [(&'static str, &DeviceConfig); 3] {
        [
            ("imu", &self.devices.imu),
            ("gps", &self.devices.gps),
            ("servo", &self.devices.servo),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
[devices.imu]
port = "/dev/ttyS0"
baud = 115200
stale_ms = 50
[devices.gps]
port = "/dev/ttyS1"
baud = 115200
stale_ms = 500
[devices.servo]
port = "/dev/ttyS2"
baud = 57600
stale_ms = 100
"#;

    #[test]
    fn a_complete_file_parses_with_defaults() {
        let c = VehicleConfig::parse(GOOD).expect("parses");
        assert_eq!(c.devices.servo.baud, 57_600);
        assert_eq!(c.log.dir, PathBuf::from("flights"));
    }

    #[test]
    fn errors_name_the_key() {
        let unknown = GOOD.replace("stale_ms = 50\n", "stale_ms = 50\nparity = \"even\"\n");
        let e = VehicleConfig::parse(&unknown).expect_err("unknown key");
        assert!(
            e.starts_with("line 6, column 1: unknown field `parity`"),
            "{e}"
        );
        assert!(!e.contains('\n'), "{e}");
        let missing = GOOD.replace(
            "[devices.servo]\nport = \"/dev/ttyS2\"\nbaud = 57600\nstale_ms = 100\n",
            "",
        );
        let e = VehicleConfig::parse(&missing).expect_err("missing servo");
        assert!(e.contains("servo"), "{e}");
        let baud = GOOD.replace("57600", "56000");
        let e = VehicleConfig::parse(&baud).expect_err("odd baud");
        assert_eq!(e, "devices.servo.baud = 56000 is not a standard baud rate");
        let e = VehicleConfig::load(Path::new("/nonexistent/vehicle.toml")).expect_err("missing");
        assert!(e.starts_with("vehicle /nonexistent/vehicle.toml: "), "{e}");
    }
}
