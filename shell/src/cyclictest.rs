//! `cyclictest` (Debian `rt-tests`) as the machine's latency floor, run with the same period,
//! priority and CPU as the executive so the two distributions compare directly.

use crate::stats::Distribution;
use serde::Serialize;
use std::path::Path;
use std::process::Command;
use std::time::Duration;

/// Histogram range (µs); later wake-ups are counted as overflows.
const HISTOGRAM_US: u64 = 10_000;

#[derive(Debug, Serialize)]
pub struct CyclictestFigures {
    /// The command line that was run, to repeat by hand.
    pub command: String,
    pub wakeup_latency_us: Distribution,
    /// Wake-ups later than the histogram's range (their exact value is only in `max`).
    pub overflows: u64,
}

/// Runs cyclictest for `duration` with one thread at `period_ns`.
pub fn run(
    period_ns: u64,
    duration: Duration,
    fifo_priority: Option<u8>,
    cpu: Option<usize>,
    lock_memory: bool,
    scratch: &Path,
) -> Result<CyclictestFigures, String> {
    let interval_us = (period_ns / 1000).max(1);
    let loops = (duration.as_micros() as u64 / interval_us).max(1);
    let histfile = scratch.join(format!("skyframe-cyclictest-{}.hist", std::process::id()));
    let mut args = vec![
        "-t1".to_string(),
        format!("-p{}", fifo_priority.unwrap_or(0)),
        format!("-i{interval_us}"),
        format!("-l{loops}"),
        "-q".to_string(),
        format!("-h{HISTOGRAM_US}"),
        format!("--histfile={}", histfile.display()),
    ];
    if lock_memory {
        args.push("-m".into());
    }
    if let Some(cpu) = cpu {
        args.push(format!("-a{cpu}"));
    }
    let command = format!("cyclictest {}", args.join(" "));
    let output = Command::new("cyclictest")
        .args(&args)
        .output()
        .map_err(|e| {
            if e.kind() == std::io::ErrorKind::NotFound {
                "cyclictest not found: install rt-tests (apt-get install rt-tests)".to_string()
            } else {
                format!("cannot run cyclictest: {e}")
            }
        })?;
    if !output.status.success() {
        let err = String::from_utf8_lossy(&output.stderr);
        return Err(format!(
            "`{command}` failed ({}): {}",
            output.status,
            err.lines().next().unwrap_or("")
        ));
    }
    let text = std::fs::read_to_string(&histfile)
        .map_err(|e| format!("cannot read {}: {e}", histfile.display()))?;
    let _ = std::fs::remove_file(&histfile);
    let (wakeup_latency_us, overflows) = parse_histogram(&text)?;
    Ok(CyclictestFigures {
        command,
        wakeup_latency_us,
        overflows,
    })
}

/// cyclictest's histogram file: `NNNNNN COUNT` per µs bin, then `# Min/Avg/Max Latencies`
/// and `# Histogram Overflows` comment lines. Returns the distribution (µs) and the overflow
/// count.
pub fn parse_histogram(text: &str) -> Result<(Distribution, u64), String> {
    let mut bins: Vec<(u64, u64)> = Vec::new();
    let mut avg = None;
    let mut max = None;
    let mut overflows = 0;
    for line in text.lines() {
        let comment_value = |key: &str| {
            line.strip_prefix(key)
                .and_then(|v| v.split_whitespace().next())
                .and_then(|v| v.parse::<u64>().ok())
        };
        if let Some(v) = comment_value("# Avg Latencies:") {
            avg = Some(v);
        } else if let Some(v) = comment_value("# Max Latencies:") {
            max = Some(v);
        } else if let Some(v) = comment_value("# Histogram Overflows:") {
            overflows = v;
        } else if !line.starts_with('#') {
            let mut parts = line.split_whitespace();
            if let (Some(Ok(bin)), Some(Ok(count))) =
                (parts.next().map(str::parse), parts.next().map(str::parse))
            {
                bins.push((bin, count));
            }
        }
    }
    let max = max.ok_or("cyclictest histogram has no `# Max Latencies` line")?;
    let mut distribution = Distribution::of_histogram(&bins, overflows, max as f64);
    if let Some(avg) = avg {
        distribution.mean = avg as f64;
    }
    Ok((distribution, overflows))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_percentiles_and_overflows() {
        // 90 wake-ups at 20 us, 9 at 50 us, 1 overflow (max 12345 us).
        let mut text = String::from("# /dev/cpu_dma_latency set to 0us\n# Histogram\n");
        for us in 0..100u64 {
            let count = match us {
                20 => 90,
                50 => 9,
                _ => 0,
            };
            text += &format!("{us:06} {count:06}\n");
        }
        text += "# Total: 000000100\n# Min Latencies: 00020\n# Avg Latencies: 00145\n";
        text += "# Max Latencies: 12345\n# Histogram Overflows: 00001\n";
        let (d, overflows) = parse_histogram(&text).expect("parses");
        assert_eq!(overflows, 1);
        assert_eq!(d.count, 100);
        assert_eq!(
            (d.p50, d.p99, d.p999, d.max, d.mean),
            (20.0, 50.0, 12345.0, 12345.0, 145.0)
        );
        assert!(parse_histogram("000001 000001\n").is_err());
    }
}
