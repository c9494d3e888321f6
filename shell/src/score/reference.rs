//! Reference filters: the `ahrs` Python package's EKF and Madgwick filters on the flight's
//! IMU samples, scored against the same truth over the same window as our estimator.
//!
//! They run in a `python3` child (`ahrs_reference.py`, compiled into the binary); the IMU
//! samples and their output are kept in the flight's `score/` directory for anyone who wants
//! to plot them. Without python3 or ahrs the score says why and goes on.

use std::path::Path;
use std::process::Command;

use serde::Serialize;
use skyframe_logtable::Table;

use super::truth::TruthSeries;
use super::{ErrorStats, RollPitch, Window, column, seconds};
use skyframe_core::angles::wrap_pi;

const SCRIPT: &str = include_str!("ahrs_reference.py");
/// The IMU's sample rate (the filters assume a fixed one).
const IMU_RATE_HZ: f64 = 100.0;

#[derive(Debug, Serialize)]
#[serde(tag = "status", rename_all = "snake_case")]
pub enum ReferenceFilters {
    NotRun,
    /// Could not run; the reason in one line.
    Unavailable {
        reason: String,
    },
    Scored {
        ahrs_version: String,
        /// Ours over the same window, for the comparison (also in `attitude`).
        skyframe_ekf: RollPitch,
        ahrs_ekf: RollPitch,
        ahrs_madgwick: RollPitch,
    },
}

pub fn score(
    flight_dir: &Path,
    imu: &Table,
    truth: &TruthSeries,
    window: Window,
    ours: RollPitch,
) -> ReferenceFilters {
    match run(flight_dir, imu, truth, window, ours) {
        Ok(scored) => scored,
        Err(reason) => {
            eprintln!("reference filters not scored: {reason}");
            ReferenceFilters::Unavailable { reason }
        }
    }
}

fn run(
    flight_dir: &Path,
    imu: &Table,
    truth: &TruthSeries,
    window: Window,
    ours: RollPitch,
) -> Result<ReferenceFilters, String> {
    let dir = flight_dir.join("score");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let samples = dir.join("imu-samples.csv");
    std::fs::write(&samples, imu_csv(imu)?).map_err(|e| format!("{}: {e}", samples.display()))?;
    let script = dir.join("ahrs_reference.py");
    std::fs::write(&script, SCRIPT).map_err(|e| format!("{}: {e}", script.display()))?;
    let output = Command::new("python3")
        .arg(&script)
        .arg(&samples)
        .arg(IMU_RATE_HZ.to_string())
        .output()
        .map_err(|e| format!("cannot run python3: {e}"))?;
    if !output.status.success() {
        let stderr = String::from_utf8_lossy(&output.stderr);
        let last = stderr.lines().rev().find(|l| !l.trim().is_empty());
        return Err(format!(
            "python3 {} failed: {}",
            script.display(),
            last.unwrap_or("no message")
        ));
    }
    let out_path = dir.join("ahrs-estimates.csv");
    std::fs::write(&out_path, &output.stdout)
        .map_err(|e| format!("{}: {e}", out_path.display()))?;
    let text = String::from_utf8_lossy(&output.stdout);
    let mut lines = text.lines();
    let version = lines
        .next()
        .and_then(|l| l.strip_prefix("version,"))
        .ok_or("ahrs_reference.py printed no version line")?
        .to_string();
    let mut stats = [ErrorStats::default(); 4];
    for line in lines {
        let v: Vec<f64> = line
            .split(',')
            .map(|f| f.trim().parse().unwrap_or(f64::NAN))
            .collect();
        let [t_s, ekf_roll, ekf_pitch, mad_roll, mad_pitch] = v[..] else {
            return Err(format!("ahrs_reference.py printed `{line}`"));
        };
        if t_s < window.from_s || t_s > window.to_s {
            continue;
        }
        let Some(tr) = truth
            .at((t_s * 1e9).round() as i64)
            .filter(|tr| tr.pitch_rad.abs() < super::EULER_MAX_PITCH_RAD)
        else {
            continue;
        };
        let [er, ep, mr, mp] = &mut stats;
        er.push(wrap_pi(ekf_roll - tr.roll_rad));
        ep.push(wrap_pi(ekf_pitch - tr.pitch_rad));
        mr.push(wrap_pi(mad_roll - tr.roll_rad));
        mp.push(wrap_pi(mad_pitch - tr.pitch_rad));
    }
    let [er, ep, mr, mp] = stats;
    if er.n == 0 {
        return Err("no reference estimate fell inside the scored window".into());
    }
    Ok(ReferenceFilters::Scored {
        ahrs_version: version,
        skyframe_ekf: ours,
        ahrs_ekf: RollPitch::from_stats(&er, &ep),
        ahrs_madgwick: RollPitch::from_stats(&mr, &mp),
    })
}

/// One line per IMU sample (repeats of a counter dropped): `t_s,p,q,r,fx,fy,fz`.
fn imu_csv(imu: &Table) -> Result<String, String> {
    let names = [
        "counter", "p_rad_s", "q_rad_s", "r_rad_s", "fx_m_s2", "fy_m_s2", "fz_m_s2",
    ];
    let mut cols = Vec::with_capacity(names.len());
    for name in names {
        cols.push(column(imu, "imu", name)?);
    }
    let mut out = String::with_capacity(imu.times_ns.len() * 64);
    let mut last_counter = None;
    for (i, &t) in imu.times_ns.iter().enumerate() {
        let row: Vec<f64> = cols
            .iter()
            .map(|c| c.get(i).copied().unwrap_or(f64::NAN))
            .collect();
        let [counter, rest @ ..] = &row[..] else {
            continue;
        };
        if last_counter == Some(*counter) || rest.iter().any(|v| !v.is_finite()) {
            continue;
        }
        last_counter = Some(*counter);
        out += &format!("{:.6}", seconds(t));
        for v in rest {
            out += &format!(",{v}");
        }
        out.push('\n');
    }
    Ok(out)
}

pub fn render(r: &ReferenceFilters) -> String {
    match r {
        ReferenceFilters::NotRun => String::new(),
        ReferenceFilters::Unavailable { reason } => {
            format!("  reference filters not scored: {reason}\n")
        }
        ReferenceFilters::Scored {
            ahrs_version,
            skyframe_ekf,
            ahrs_ekf,
            ahrs_madgwick,
        } => {
            let line = |name: &str, rp: &RollPitch| {
                format!(
                    "    {name:<18} roll {:.2} deg RMS ({:.2} max), pitch {:.2} ({:.2})\n",
                    rp.roll_rms_deg, rp.roll_max_deg, rp.pitch_rms_deg, rp.pitch_max_deg
                )
            };
            format!("  roll/pitch against the ahrs package ({ahrs_version}), same IMU data:\n")
                + &line("skyframe EKF", skyframe_ekf)
                + &line("ahrs EKF", ahrs_ekf)
                + &line("ahrs Madgwick", ahrs_madgwick)
        }
    }
}
