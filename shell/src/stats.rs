//! Distribution summaries: timing figures, and errors against a reference (the score against
//! the simulator's truth, replay's agreement with an onboard estimate).

use serde::Serialize;
use skyframe_core::stats::{nearest_rank_index, percentile};

/// Percentiles of a sample, in the sample's unit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Distribution {
    pub count: usize,
    pub mean: f64,
    pub p50: f64,
    pub p99: f64,
    pub p999: f64,
    pub max: f64,
}

impl Distribution {
    /// Nearest-rank percentiles (the value at or below which the share of samples lies).
    pub fn of(samples: &mut [u64]) -> Self {
        if samples.is_empty() {
            return Self::default();
        }
        samples.sort_unstable();
        let rank = |num: u64, den: u64| percentile(samples, num, den).unwrap_or(0) as f64;
        let sum: u128 = samples.iter().map(|&s| u128::from(s)).sum();
        Self {
            count: samples.len(),
            mean: (sum as f64 / samples.len() as f64 * 1000.0).round() / 1000.0,
            p50: rank(50, 100),
            p99: rank(99, 100),
            p999: rank(999, 1000),
            max: samples.last().copied().unwrap_or(0) as f64,
        }
    }

    /// Percentiles of a histogram of `(value, count)` bins, with `overflows` samples above
    /// the last bin whose largest value was `max`.
    pub fn of_histogram(bins: &[(u64, u64)], overflows: u64, max: f64) -> Self {
        let total: u64 = bins.iter().map(|b| b.1).sum::<u64>() + overflows;
        if total == 0 {
            return Self::default();
        }
        let rank = |num: u64, den: u64| {
            let index = usize::try_from(total)
                .ok()
                .and_then(|n| nearest_rank_index(n, num, den));
            let wanted = index.map_or(total, |i| i as u64 + 1);
            let mut seen = 0;
            for &(value, count) in bins {
                seen += count;
                if seen >= wanted {
                    return value as f64;
                }
            }
            max
        };
        let sum: f64 =
            bins.iter().map(|&(v, c)| v as f64 * c as f64).sum::<f64>() + overflows as f64 * max;
        Self {
            count: total as usize,
            mean: (sum / total as f64 * 1000.0).round() / 1000.0,
            p50: rank(50, 100),
            p99: rank(99, 100),
            p999: rank(999, 1000),
            max,
        }
    }

    /// The same distribution in another unit (e.g. ns → µs with 1e-3), rounded to 3
    /// decimals: finer digits are below any clock's resolution here.
    pub fn scaled(self, factor: f64) -> Self {
        let s = |v: f64| (v * factor * 1000.0).round() / 1000.0;
        Self {
            mean: s(self.mean),
            p50: s(self.p50),
            p99: s(self.p99),
            p999: s(self.p999),
            max: s(self.max),
            ..self
        }
    }
}

/// `a / b`, or `None` when `b` is zero (a ratio against a zero baseline means nothing).
pub fn ratio(a: f64, b: f64) -> Option<f64> {
    (b != 0.0).then(|| a / b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentiles() {
        let mut v: Vec<u64> = (1..=1000).rev().collect();
        let d = Distribution::of(&mut v);
        assert_eq!((d.p50, d.p99, d.p999, d.max), (500.0, 990.0, 999.0, 1000.0));
        assert_eq!(d.mean, 500.5);
        let d = Distribution::of(&mut [7]);
        assert_eq!((d.p50, d.p999, d.max), (7.0, 7.0, 7.0));
        assert_eq!(Distribution::of(&mut []).count, 0);
    }
}

/// Root-mean-square and largest magnitude of a series of errors; non-finite errors are left
/// out (a missing estimate is not an error of zero).
#[derive(Clone, Copy, Debug, Default)]
pub struct ErrorStats {
    pub n: u64,
    pub sum_sq: f64,
    pub max_abs: f64,
}

impl ErrorStats {
    pub fn push(&mut self, e: f64) {
        if e.is_finite() {
            self.n += 1;
            self.sum_sq += e * e;
            self.max_abs = self.max_abs.max(e.abs());
        }
    }

    /// NaN with no samples.
    pub fn rms(&self) -> f64 {
        if self.n == 0 {
            f64::NAN
        } else {
            (self.sum_sq / self.n as f64).sqrt()
        }
    }
}
