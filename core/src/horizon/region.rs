//! The horizon as the line that best splits the frame into two regions, found without edges:
//! the fallback when the gradient is not to be trusted.
//!
//! Analog interference (a sinusoid across the frame) adds its own gradient to the horizon's at
//! every pixel: the sum points in neither direction, non-maximum suppression breaks the
//! horizon's ridge, and its edge points vote for no line (measured: 2 votes in the horizon's
//! cells against 50 for each of the stripes). The stripes themselves form a family of lines
//! that each explain nothing. The means of the two sides of a line are not fooled: a region
//! holds many periods of the pattern, which average out. This is Otsu's criterion over lines:
//! for each direction the samples are binned by their distance along the normal, and prefix
//! sums give the between-class variance of every split in one pass.

use super::edges::Sample;
use super::hough::{Line, SATURATED};
use core::f32::consts::PI;

/// Directions of the coarse search over the half circle (3° apart).
const COARSE_DIRECTIONS: usize = 60;
/// Distance bins across the frame in the coarse search.
const COARSE_BINS: usize = 64;
/// Fine search: this many half-degree steps either side of the coarse direction ...
const FINE_STEPS: i32 = 6;
const FINE_STEP: f32 = 0.5 * PI / 180.0;
/// ... and bins of this many per coarse bin, within `FINE_REACH` coarse bins of its split.
const FINE_PER_COARSE: usize = 4;
const FINE_REACH: usize = 3;
const FINE_BINS: usize = 2 * FINE_REACH * FINE_PER_COARSE;
/// Neither side may hold less than this share of the samples.
const MIN_SIDE: f32 = 0.05;

#[derive(Clone, Copy, Default)]
struct Bin {
    n: f32,
    luma: f32,
    chroma: f32,
}

impl Bin {
    fn add(&mut self, s: &Sample) {
        self.n += 1.0;
        self.luma += s.luma;
        self.chroma += s.chroma;
    }

    fn plus(self, o: Bin) -> Bin {
        Bin {
            n: self.n + o.n,
            luma: self.luma + o.luma,
            chroma: self.chroma + o.chroma,
        }
    }
}

/// Between-class variance (times the sample count) of a split with `low` on one side of
/// `total`, or `None` when a side is too small.
fn between(low: Bin, total: Bin) -> Option<f32> {
    let high_n = total.n - low.n;
    if low.n < MIN_SIDE * total.n || high_n < MIN_SIDE * total.n || low.n <= 0.0 {
        return None;
    }
    let dl = low.luma / low.n - (total.luma - low.luma) / high_n;
    let dc = low.chroma / low.n - (total.chroma - low.chroma) / high_n;
    Some(low.n * high_n / total.n * (dl * dl + dc * dc))
}

/// The unsaturated samples taken (every `stride`-th), summed: the same for every split.
fn sum_of(samples: &[Sample], stride: usize) -> Bin {
    let mut total = Bin::default();
    for sample in samples.iter().step_by(stride.max(1)) {
        if sample.luma < SATURATED {
            total.add(sample);
        }
    }
    total
}

/// The best split along direction `angle` of the samples whose distance lies in
/// `[start, start + bins.len()·width)` (those below count as the low side); `total` is
/// [`sum_of`] the same samples. Returns the split's distance, its criterion, and the luma
/// difference (high side minus low side).
fn best_split<const N: usize>(
    samples: &[Sample],
    stride: usize,
    total: Bin,
    angle: f32,
    start: f32,
    width: f32,
) -> Option<(f32, f32, f32)> {
    let (s, c) = (libm::sinf(angle), libm::cosf(angle));
    let mut bins = [Bin::default(); N];
    let mut below = Bin::default();
    let inverse = 1.0 / width;
    for sample in samples.iter().step_by(stride.max(1)) {
        if sample.luma >= SATURATED {
            continue;
        }
        let d = sample.x * s + sample.y * c;
        let f = (d - start) * inverse;
        if f < 0.0 {
            below.add(sample);
        } else if f < N as f32
            // Through i32: `f` is in [0, N), and the 64-bit saturating conversion costs twice
            // the instructions.
            && let Some(b) = bins.get_mut(f as i32 as usize)
        {
            b.add(sample);
        }
    }
    let mut low = below;
    let mut best: Option<(f32, f32, f32)> = None;
    for (k, b) in bins.iter().enumerate() {
        low = low.plus(*b);
        let Some(value) = between(low, total) else {
            continue;
        };
        if best.is_none_or(|(_, v, _)| value > v) {
            let high_n = total.n - low.n;
            let contrast = (total.luma - low.luma) / high_n - low.luma / low.n;
            best = Some((start + (k + 1) as f32 * width, value, contrast));
        }
    }
    best
}

/// The line (normal towards the brighter side, as the Hough stage's) that best splits the
/// samples into two regions; `extent` bounds the samples' distance from the centre.
pub(crate) fn search(samples: &[Sample], extent: f32) -> Option<Line> {
    search_with(samples, extent, 1)
}

/// [`search`] with the coarse directions twice as far apart (the fine search's ±3° still
/// covers the gap) and every other sample: under a third of the cost, for frames whose
/// regions are clear (stripes subtracted, see `stripes`).
pub(crate) fn quick_search(samples: &[Sample], extent: f32) -> Option<Line> {
    search_with(samples, extent, 2)
}

fn search_with(samples: &[Sample], extent: f32, thin: usize) -> Option<Line> {
    if !extent.is_finite() || extent <= 0.0 {
        return None;
    }
    let width = 2.0 * extent / COARSE_BINS as f32;
    let mut coarse: Option<(f32, f32, f32)> = None;
    let mut coarse_angle = 0.0;
    let directions = COARSE_DIRECTIONS / thin.max(1);
    let coarse_stride = thin * thin;
    let coarse_total = sum_of(samples, coarse_stride);
    let total = sum_of(samples, thin);
    for i in 0..directions {
        let angle = i as f32 * PI / directions as f32;
        if let Some(split) =
            best_split::<COARSE_BINS>(samples, coarse_stride, coarse_total, angle, -extent, width)
            && coarse.is_none_or(|(_, v, _)| split.1 > v)
        {
            coarse = Some(split);
            coarse_angle = angle;
        }
    }
    let (coarse_d, _, _) = coarse?;
    let fine_width = width / FINE_PER_COARSE as f32;
    let mut fine = coarse.map(|c| (coarse_angle, c))?;
    for j in -FINE_STEPS..=FINE_STEPS {
        let angle = coarse_angle + j as f32 * FINE_STEP;
        let start = coarse_d - FINE_REACH as f32 * width;
        if let Some(split) = best_split::<FINE_BINS>(samples, thin, total, angle, start, fine_width)
            && split.1 > fine.1.1
        {
            fine = (angle, split);
        }
    }
    let (angle, (d, _, contrast)) = fine;
    Some(if contrast >= 0.0 {
        Line { angle, rho: d }
    } else {
        Line {
            angle: angle + PI,
            rho: -d,
        }
    })
}
