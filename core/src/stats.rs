//! Nearest-rank percentiles: the one definition of p50, p99 and p99.9 that every figure in
//! skyframe uses (the executive's timing, `skyframe bench`, the overrun report, the horizon
//! bench, the estimator scores).
//!
//! The percentile `num/den` of `n` sorted samples is the sample of rank ⌈n·num/den⌉ (1-based,
//! at least 1): the smallest value at or below which at least that share of the samples lie.
//! The share is a fraction of integers so that p99 of 1000 samples is exactly rank 990, with
//! no floating-point rounding between the two.

/// The 0-based index of the nearest-rank percentile `num/den` of `len` samples; `None` for
/// no samples or a zero denominator.
pub fn nearest_rank_index(len: usize, num: u64, den: u64) -> Option<usize> {
    let n = u64::try_from(len).ok()?;
    if n == 0 || den == 0 {
        return None;
    }
    let rank = n.saturating_mul(num).div_ceil(den).clamp(1, n);
    usize::try_from(rank - 1).ok()
}

/// The nearest-rank percentile `num/den` of `sorted` (ascending).
pub fn percentile<T: Copy>(sorted: &[T], num: u64, den: u64) -> Option<T> {
    sorted
        .get(nearest_rank_index(sorted.len(), num, den)?)
        .copied()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranks_are_exact_fractions() {
        let v: heapless::Vec<u32, 1000> = (1..=1000).collect();
        assert_eq!(percentile(&v, 50, 100), Some(500));
        assert_eq!(percentile(&v, 99, 100), Some(990));
        assert_eq!(percentile(&v, 999, 1000), Some(999));
        assert_eq!(percentile(&v, 1, 1), Some(1000));
        assert_eq!(percentile(&v, 0, 100), Some(1));
        assert_eq!(percentile(&[5u8], 999, 1000), Some(5));
        assert_eq!(percentile::<u8>(&[], 50, 100), None);
        assert_eq!(percentile(&[1.5f32, 2.5], 50, 100), Some(1.5));
        assert_eq!(nearest_rank_index(10, 1, 0), None);
    }
}
