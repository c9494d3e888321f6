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

use super::camera::Camera;
use super::edges::{Sample, Working};
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

/// What a split's two sides are told apart by.
#[derive(Clone, Copy)]
enum Criterion {
    /// Luma and colour (blue minus red) together, in levels.
    LumaAndColour,
    /// Colour alone: a sky told from the ground by its blue where a glow makes the luma split
    /// the frame along the glow (see [`search_by_colour`]).
    Colour,
}

/// Between-class variance (times the sample count) of a split with `low` on one side of
/// `total` by `criterion`, or `None` when a side is too small.
fn between(low: Bin, total: Bin, criterion: Criterion) -> Option<f32> {
    let high_n = total.n - low.n;
    if low.n < MIN_SIDE * total.n || high_n < MIN_SIDE * total.n || low.n <= 0.0 {
        return None;
    }
    let dl = match criterion {
        Criterion::LumaAndColour => low.luma / low.n - (total.luma - low.luma) / high_n,
        Criterion::Colour => 0.0,
    };
    let dc = low.chroma / low.n - (total.chroma - low.chroma) / high_n;
    Some(low.n * high_n / total.n * (dl * dl + dc * dc))
}

/// The unsaturated samples taken (every `stride`-th), summed: the same for every split.
fn sum_of(samples: &[Sample], stride: usize, keep: impl Fn(&Sample) -> bool) -> Bin {
    let mut total = Bin::default();
    for sample in samples.iter().step_by(stride.max(1)) {
        if sample.luma < SATURATED && keep(sample) {
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
    (stride, criterion, keep): (usize, Criterion, impl Fn(&Sample) -> bool),
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
        if sample.luma >= SATURATED || !keep(sample) {
            continue;
        }
        let d = sample.x * s + sample.y * c;
        add_at(&mut bins, &mut below, (d - start) * inverse, sample);
    }
    best_of_bins(&bins, (below, total), start, width, criterion)
}

/// Adds `sample` to the bin `f` (its distance from the first bin's start, in bins) falls in,
/// to `below` under the first, and nowhere past the last.
#[inline]
fn add_at<const N: usize>(bins: &mut [Bin; N], below: &mut Bin, f: f32, sample: &Sample) {
    if f < 0.0 {
        below.add(sample);
    } else if f < N as f32
        // Through i32: `f` is in [0, N), and the 64-bit saturating conversion costs twice the
        // instructions.
        && let Some(b) = bins.get_mut(f as i32 as usize)
    {
        b.add(sample);
    }
}

/// The best split of binned samples: `below` the first bin, `bins` from `start` in steps of
/// `width`, `total` all of them (see [`best_split`]).
fn best_of_bins(
    bins: &[Bin],
    (below, total): (Bin, Bin),
    start: f32,
    width: f32,
    criterion: Criterion,
) -> Option<(f32, f32, f32)> {
    let mut low = below;
    let mut best: Option<(f32, f32, f32)> = None;
    for (k, b) in bins.iter().enumerate() {
        low = low.plus(*b);
        let Some(value) = between(low, total, criterion) else {
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

/// Directions of the fine search.
const FINE_DIRECTIONS: usize = 2 * FINE_STEPS as usize + 1;
/// Margin (normalised units, 0.03 px at 320 px and 60°) that [`fine_splits`] adds to a
/// sample's swing: far above the f32 rounding of distances at the frame's scale (10^-7).
const FINE_ROUNDING: f32 = 1e-4;

/// [`best_split`] over [`FINE_BINS`] bins from `start` at each of the fine search's
/// directions around `angle` (`angle + j·FINE_STEP`, `j` from `−FINE_STEPS`), in one pass
/// over the samples instead of one per direction. Turning the direction by `δ` moves a
/// sample's distance by at most its radius times `|δ|`, so a sample farther than that from
/// the bins at `angle` lies on the same side of them in every direction: it is added once to
/// what lies below (or left out above), and only the samples near the bins are placed
/// direction by direction (about a sixth of them). The sums are of whole numbers (8-bit luma,
/// blue minus red, counts) far under 2^24, exact in f32 in any order: the splits are those
/// of a pass per direction, bit for bit.
fn fine_splits(
    samples: &[Sample],
    (stride, criterion, keep): (usize, Criterion, impl Fn(&Sample) -> bool),
    total: Bin,
    angle: f32,
    start: f32,
    width: f32,
) -> [Option<(f32, f32, f32)>; FINE_DIRECTIONS] {
    let directions: [(f32, f32); FINE_DIRECTIONS] = core::array::from_fn(|i| {
        let a = angle + (i as i32 - FINE_STEPS) as f32 * FINE_STEP;
        (libm::sinf(a), libm::cosf(a))
    });
    let (s0, c0) = (libm::sinf(angle), libm::cosf(angle));
    let end = start + FINE_BINS as f32 * width;
    // The largest turn (radians) with a tenth to spare, applied to |x| + |y| (at least the
    // radius), plus [`FINE_ROUNDING`].
    let turn = 1.1 * FINE_STEPS as f32 * FINE_STEP;
    let inverse = 1.0 / width;
    let mut below_all = Bin::default();
    let mut below = [Bin::default(); FINE_DIRECTIONS];
    let mut bins = [[Bin::default(); FINE_BINS]; FINE_DIRECTIONS];
    for sample in samples.iter().step_by(stride.max(1)) {
        if sample.luma >= SATURATED || !keep(sample) {
            continue;
        }
        let d0 = sample.x * s0 + sample.y * c0;
        let swing = turn * (libm::fabsf(sample.x) + libm::fabsf(sample.y)) + FINE_ROUNDING;
        if d0 < start - swing {
            below_all.add(sample);
            continue;
        }
        if d0 >= end + swing {
            continue;
        }
        for ((&(s, c), below), bins) in directions.iter().zip(&mut below).zip(&mut bins) {
            let f = (sample.x * s + sample.y * c - start) * inverse;
            add_at(bins, below, f, sample);
        }
    }
    core::array::from_fn(|i| {
        let (Some(bins), Some(&below)) = (bins.get(i), below.get(i)) else {
            return None;
        };
        best_of_bins(
            bins,
            (below.plus(below_all), total),
            start,
            width,
            criterion,
        )
    })
}

/// The line (normal towards the brighter side, as the Hough stage's) that best splits the
/// samples into two regions; `extent` bounds the samples' distance from the centre.
pub(crate) fn search(samples: &[Sample], extent: f32) -> Option<Line> {
    search_with(samples, extent, 1, None, Criterion::LumaAndColour)
}

/// [`search`] by colour alone (the line's normal still towards the brighter side). Where no
/// edge line splits the frame, a sun's glow over a hazy horizon makes the brightest part of
/// the frame one region and the rest the other: the luma split runs along the glow, tens of
/// degrees of roll off the horizon, while the blue sky and the grey ground still split the
/// frame's colour at the horizon (`aerial` seed 140 `glare`: 0.78–0.84 of the colour's variance
/// against 0.04–0.47 along the glow). Thinned as [`quick_search`] is: a colour split clear
/// enough to be taken is found as well on half the samples (on the seen `aerial` seeds the
/// full search gained two frames more of 56), at about a third of the cost.
pub(crate) fn search_by_colour(samples: &[Sample], extent: f32) -> Option<Line> {
    search_with(samples, extent, 2, None, Criterion::Colour)
}

/// [`search`] over the directions within [`NEAR_DIRECTIONS`] coarse steps (3° each) of
/// `line`'s, on every other sample (as [`quick_search`]): a second opinion on an edge line
/// whose roll the edges may have drawn off, at about an eighth of [`search`]'s cost.
pub(crate) fn search_near(samples: &[Sample], extent: f32, line: Line) -> Option<Line> {
    search_with(
        samples,
        extent,
        2,
        Some(line.angle),
        Criterion::LumaAndColour,
    )
}

/// [`search_near`] on every third sample: for a split that must be clear to count (it
/// must explain most of the frame), at about three fifths of [`search_near`]'s cost (on
/// `synth` `haze` at 320 px, 0.34 M instructions a frame added against 0.55 M).
pub(crate) fn clear_split_near(samples: &[Sample], extent: f32, line: Line) -> Option<Line> {
    search_with(
        samples,
        extent,
        3,
        Some(line.angle),
        Criterion::LumaAndColour,
    )
}

/// [`search`] with the coarse directions twice as far apart (the fine search's ±3° still
/// covers the gap) and every other sample: under a third of the cost, for frames whose
/// regions are clear (stripes subtracted, see `stripes`).
pub(crate) fn quick_search(samples: &[Sample], extent: f32) -> Option<Line> {
    search_with(samples, extent, 2, None, Criterion::LumaAndColour)
}

/// Coarse directions either side of a given one that [`search_near`] tries.
const NEAR_DIRECTIONS: i32 = 5;

/// The split of the samples at least `margin` from `floor` on its normal's side: the part of
/// the frame a line has for its sky, split in two (see `sea_over_shore` in the parent
/// module).
pub(crate) fn search_above(
    samples: &[Sample],
    extent: f32,
    floor: Line,
    margin: f32,
) -> Option<Line> {
    let (nx, ny) = floor.normal();
    let above = move |s: &Sample| s.x * nx + s.y * ny - floor.rho >= margin;
    search_among(samples, extent, (1, None, Criterion::LumaAndColour), above)
}

fn search_with(
    samples: &[Sample],
    extent: f32,
    thin: usize,
    near: Option<f32>,
    criterion: Criterion,
) -> Option<Line> {
    search_among(samples, extent, (thin, near, criterion), |_| true)
}

/// [`search_with`] over the samples `keep` takes.
fn search_among(
    samples: &[Sample],
    extent: f32,
    (thin, near, criterion): (usize, Option<f32>, Criterion),
    keep: impl Fn(&Sample) -> bool + Copy,
) -> Option<Line> {
    if !extent.is_finite() || extent <= 0.0 {
        return None;
    }
    let width = 2.0 * extent / COARSE_BINS as f32;
    let mut coarse: Option<(f32, f32, f32)> = None;
    let mut coarse_angle = 0.0;
    let directions = COARSE_DIRECTIONS / thin.max(1);
    let coarse_stride = thin * thin;
    let coarse_total = sum_of(samples, coarse_stride, keep);
    let total = sum_of(samples, thin, keep);
    // Near a given direction, the full search's 3° steps (`thin` then only thins the samples).
    let step = match near {
        Some(_) => PI / COARSE_DIRECTIONS as f32,
        None => PI / directions as f32,
    };
    let tried = match near {
        Some(_) => -NEAR_DIRECTIONS..NEAR_DIRECTIONS + 1,
        None => 0..directions as i32,
    };
    for i in tried {
        let angle = near.unwrap_or(0.0) + i as f32 * step;
        if let Some(split) = best_split::<COARSE_BINS>(
            samples,
            (coarse_stride, criterion, keep),
            coarse_total,
            angle,
            -extent,
            width,
        ) && coarse.is_none_or(|(_, v, _)| split.1 > v)
        {
            coarse = Some(split);
            coarse_angle = angle;
        }
    }
    let (coarse_d, _, _) = coarse?;
    let fine_width = width / FINE_PER_COARSE as f32;
    let mut fine = coarse.map(|c| (coarse_angle, c))?;
    let start = coarse_d - FINE_REACH as f32 * width;
    let splits = fine_splits(
        samples,
        (thin, criterion, keep),
        total,
        coarse_angle,
        start,
        fine_width,
    );
    for (j, split) in (-FINE_STEPS..=FINE_STEPS).zip(splits) {
        let angle = coarse_angle + j as f32 * FINE_STEP;
        if let Some(split) = split
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

/// Working pixels either side of a region line searched for the horizon's step.
const TOP_REACH: usize = 20;
const TOP_BINS: usize = 2 * TOP_REACH + 1;
/// Directions tried: this many half-degree steps either side of the region line's.
const TOP_TURNS: i32 = 6;
/// Bins the step is measured across (the lens, the binning and a motion blur spread it).
const TOP_SPAN: usize = 2;
/// The step must start within this share of the profile's range of its highest bin ...
const TOP_SHARE: f32 = 0.25;
/// ... be at least this many levels, and each of its two sides hold this many pixels.
const TOP_MIN_STEP: f32 = 2.0;
const TOP_MIN_PIXELS: f32 = 8.0;
/// The two halves of the line must find their steps within this many bins of each other
/// (their own bins, half as full: one bin is the noise of the place).
const TOP_HALVES_AGREE: usize = 1;

/// The horizon's step found near a region line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct TopStep {
    /// Through the step, its normal towards the sky (the brighter side of the step).
    pub line: Line,
    /// The two halves of the line see the step at the same place: the direction is the
    /// step's, not a compromise with something crossing it.
    pub halves_agree: bool,
    /// Working pixels from the line given to the step, towards the sky.
    pub sky_ward_px: f32,
    /// Between the step and the line given the profile only falls towards the ground (one
    /// transition: the step and the ramp below it, nothing brighter in between).
    pub one_transition: bool,
}

/// Profile bins, `(pixels, sum of luma)`: over the whole line and over each half of it (on
/// either side of the centre's foot on the line).
type Bins = [(f32, f32); TOP_BINS];

/// The mean luma of the working image across the line at `angle` and `rho` (bins of one rho
/// step, sky-ward positive, [`TOP_REACH`] either side), whole and by halves.
fn top_profile(
    grey: &[u8],
    geo: Working,
    camera: &Camera,
    (angle, rho): (f32, f32),
    rho_step: f32,
    sky_ward: f32,
) -> [Bins; 2] {
    let scale = geo.scale as f32;
    let (nx, ny) = (libm::sinf(angle), libm::cosf(angle));
    // Pixel counts and luma sums in integers: a bin holds a row or two of the working image,
    // far under 2^24 / 255 pixels, so adding them as f32 one at a time would be exact and give
    // the same values; in integers the adds do not wait on each other's rounding. A bin's
    // count and sum are one word (the count in the high half), and neighbouring pixels,
    // which most often fall in the same bin, go to two copies of the bins taken in turn:
    // each add then waits on the one two pixels back, not on the one before.
    let mut cells = [[[0u64; TOP_BINS]; 2]; 2];
    // Bin of a working pixel: its sky-ward distance in rho steps, offset by the reach and
    // rounded; linear along a row, as is the place along the line.
    let inverse = sky_ward / rho_step;
    let along_row = nx * scale / camera.fx * inverse;
    let along_line_per_column = ny * scale / camera.fx;
    for (wy, row) in grey
        .chunks_exact(geo.width.max(1))
        .take(geo.height)
        .enumerate()
    {
        let (u0, v) = geo.to_frame(0.0, wy as f32);
        let (x0, y) = ((u0 - camera.cx) / camera.fx, (v - camera.cy) / camera.fy);
        let row_start = (x0 * nx + y * ny - rho) * inverse + TOP_REACH as f32 + 0.5;
        let line_start = x0 * ny - y * nx;
        let columns = if libm::fabsf(along_row) < 1e-6 {
            if (0.0..TOP_BINS as f32).contains(&row_start) {
                0..row.len()
            } else {
                0..0
            }
        } else {
            let (a, b) = (
                -row_start / along_row,
                (TOP_BINS as f32 - row_start) / along_row,
            );
            let width = row.len() as f32;
            ((a.min(b) - 1.0).clamp(0.0, width) as usize)
                ..((a.max(b) + 1.0).clamp(0.0, width) as usize)
        };
        let first = columns.start;
        let pixels = row.get(columns).unwrap_or(&[]);
        // The half a pixel falls in changes once along the row (its place along the line is
        // monotone in the column, rounding included): the row is cut there and each part
        // binned into its half's bins without testing each pixel.
        let second_half =
            |i: usize| line_start + (first + i) as u32 as f32 * along_line_per_column >= 0.0;
        let rising = along_line_per_column >= 0.0;
        let cut_guess = -line_start / along_line_per_column - first as f32;
        let cut = first_where_from(pixels.len(), cut_guess, |i| second_half(i) == rising);
        let (before, after) = pixels.split_at(cut.min(pixels.len()));
        let halves_in_order = if rising { [0, 1] } else { [1, 0] };
        for ((part, offset), half) in [(before, 0), (after, cut)].into_iter().zip(halves_in_order) {
            let [Some(even), Some(odd)] = cells.each_mut().map(|c| c.get_mut(half)) else {
                continue;
            };
            // The pixels whose bin is inside the profile: again a run of the part, where the
            // bin (monotone in the column) is in range. The others, NaN included, are left out.
            let bin_at = |i: usize| row_start + (first + offset + i) as u32 as f32 * along_row;
            // Where the bin reaches `bin`, in the part's own columns.
            let reaches = |bin: f32| (bin - row_start) / along_row - (first + offset) as f32;
            let (top, n) = (TOP_BINS as f32, part.len());
            let (start, end) = if along_row > 0.0 {
                (
                    first_where_from(n, reaches(0.0), |i| bin_at(i) >= 0.0),
                    first_where_from(n, reaches(top), |i| bin_at(i) >= top),
                )
            } else if along_row < 0.0 {
                (
                    first_where_from(n, reaches(top), |i| bin_at(i) < top),
                    first_where_from(n, reaches(0.0), |i| bin_at(i) < 0.0),
                )
            } else if (0.0..TOP_BINS as f32).contains(&bin_at(0)) {
                (0, part.len())
            } else {
                (0, 0)
            };
            // Columns counted in f32 from the run's first: exact (far under 2^24), and the
            // same values as converting each.
            let mut column = (first + offset + start) as u32 as f32;
            let mut add = |cells: &mut [u64; TOP_BINS], value: u8| {
                let index = (row_start + column * along_row) as i32 as usize;
                column += 1.0;
                if let Some(cell) = cells.get_mut(index) {
                    *cell += PIXEL | u64::from(value);
                }
            };
            let run = part.get(start..end).unwrap_or(&[]);
            let pairs = run.chunks_exact(2);
            let last = pairs.remainder();
            for pair in pairs {
                if let &[a, b] = pair {
                    add(even, a);
                    add(odd, b);
                }
            }
            for &value in last {
                add(even, value);
            }
        }
    }
    let mut halves = [[(0.0f32, 0.0f32); TOP_BINS]; 2];
    let [even, odd] = &cells;
    for ((half, even), odd) in halves.iter_mut().zip(even).zip(odd) {
        for ((bin, &a), &b) in half.iter_mut().zip(even).zip(odd) {
            let cell = a + b;
            *bin = (
                (cell >> 32) as u32 as f32,
                (cell & 0xffff_ffff) as u32 as f32,
            );
        }
    }
    halves
}

/// One pixel in a profile's cell: counts in the high half of the word, luma in the low.
const PIXEL: u64 = 1 << 32;

/// [`first_where`] from a guess of where it is: a few steps from the guess when it is near
/// (the columns where a linear bin crosses a bound, solved in closed form, are off by a
/// rounding at most), else the bisection. The same index: the first where `holds` does.
/// A profile's rows take three each (a bisection: eight tests on a 160-pixel row).
fn first_where_from(n: usize, guess: f32, holds: impl Fn(usize) -> bool) -> usize {
    if guess.is_finite() {
        // `as` saturates: a guess under zero is 0, one over `n` is `n`.
        let mut i = (guess.max(0.0) as usize).min(n);
        for _ in 0..4 {
            if i > 0 && holds(i - 1) {
                i -= 1;
            } else if i < n && !holds(i) {
                i += 1;
            } else {
                return i;
            }
        }
    }
    first_where(n, holds)
}

/// The first `i` in `0..n` where `holds` does, for a `holds` false then true along `0..n`
/// (`n` when it never does).
fn first_where(n: usize, holds: impl Fn(usize) -> bool) -> usize {
    let (mut low, mut high) = (0, n);
    while low < high {
        let middle = low + (high - low) / 2;
        if holds(middle) {
            high = middle;
        } else {
            low = middle + 1;
        }
    }
    low
}

/// The two halves' bins added: the profile over the whole line.
fn joined([first, second]: &[Bins; 2]) -> Bins {
    let mut whole = *first;
    for (w, h) in whole.iter_mut().zip(second.iter()) {
        *w = (w.0 + h.0, w.1 + h.1);
    }
    whole
}

/// The mean luma of bin `i`, if it holds enough pixels to say.
fn bin_mean(bins: &Bins, i: usize) -> Option<f32> {
    bins.get(i)
        .filter(|b| b.0 >= TOP_MIN_PIXELS)
        .map(|b| b.1 / b.0)
}

/// The steepest fall towards the ground (bin index falling) among the bins near the
/// profile's highest (within `top_share` of its range), searched in `range`: its size and the
/// index of the bin between its two sides.
fn steepest_top_fall(
    bins: &Bins,
    range: core::ops::Range<usize>,
    top_share: f32,
) -> Option<(f32, usize)> {
    let mean = |i: usize| bin_mean(bins, i);
    let (mut high, mut low) = (f32::MIN, f32::MAX);
    for i in 0..TOP_BINS {
        if let Some(m) = mean(i) {
            high = high.max(m);
            low = low.min(m);
        }
    }
    let near_top = high - top_share * (high - low);
    let mut best: Option<(f32, usize)> = None;
    for i in range.start.max(TOP_SPAN)..range.end.min(TOP_BINS) {
        let (Some(sky), Some(ground)) = (mean(i), mean(i - TOP_SPAN)) else {
            continue;
        };
        let fall = sky - ground;
        if sky >= near_top && fall >= TOP_MIN_STEP && best.is_none_or(|(f, _)| fall > f) {
            best = Some((fall, i - TOP_SPAN / 2));
        }
    }
    best
}

/// A direction tried by [`top_step`]: its steepest top fall, where, and its profiles.
struct Candidate {
    fall: f32,
    /// Half degrees from the region line's direction.
    turn: i32,
    /// Angle and rho of the line turned.
    direction: (f32, f32),
    at: usize,
    halves: [Bins; 2],
}

/// The horizon's step near a region line: the top of the transition, where the sky's glow
/// ends and the ground begins.
///
/// A region split is the line across which the two sides differ most. Under a thick haze the
/// frame is not two regions but a ridge: the sky brightens towards the horizon (its glow),
/// the ground darkens away from it (extinction and airlight: a small step, then a long ramp),
/// so the split can fall on either flank of the ridge, degrees from its top (measured on
/// `synth` `hazy-interference`: 2–4° above or below it). The horizon is the step at the top:
/// across each direction within ±3° of the split's (whole degrees, then the half degrees
/// either side of the best), the mean luma of the working image along the line
/// (interference crossing the line averages out) in bins of one working pixel, and the
/// steepest fall towards the ground among the bins near the profile's highest; the direction
/// whose fall is steepest wins (a wrong direction smears the step over bins). Where the two
/// halves of the line see that step more than a bin apart, the direction is a compromise
/// with something crossing it (residual stripes), and the answer says so.
/// `sky_ward` (±1) says on which side of `line`'s normal the sky lies. The working image is
/// taken as undistorted (as in `stripes`), true near the centre on a distorted camera.
pub(crate) fn top_step(
    grey: &[u8],
    geo: Working,
    camera: &Camera,
    line: Line,
    rho_step: f32,
    sky_ward: f32,
) -> Option<TopStep> {
    top_step_above(grey, geo, camera, line, None, rho_step, sky_ward)
}

/// Where [`top_step_above`] looks for the fall: from `bins` on the sky side of the line (at the
/// foot of the centre's perpendicular, on each direction tried), and starting within
/// `top_share` of the profile's range of its highest bin (for [`top_step`]: anywhere, and
/// [`TOP_SHARE`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct AboveLine {
    pub bins: usize,
    pub top_share: f32,
}

/// [`top_step`], the fall looked for only where `above` says.
pub(crate) fn top_step_above(
    grey: &[u8],
    geo: Working,
    camera: &Camera,
    line: Line,
    above: Option<AboveLine>,
    rho_step: f32,
    sky_ward: f32,
) -> Option<TopStep> {
    if !(rho_step.is_finite() && rho_step > 0.0) {
        return None;
    }
    let (first, top_share) = above.map_or((0, TOP_SHARE), |a| (TOP_REACH + a.bins, a.top_share));
    let mut best: Option<Candidate> = None;
    let try_turn = |turn: i32, best: &mut Option<Candidate>| {
        let delta = turn as f32 * FINE_STEP;
        // Turned about the foot of the centre's perpendicular on the line.
        let direction = (line.angle + delta, line.rho * libm::cosf(delta));
        let halves = top_profile(grey, geo, camera, direction, rho_step, sky_ward);
        if let Some((fall, at)) = steepest_top_fall(&joined(&halves), first..TOP_BINS, top_share)
            && best.as_ref().is_none_or(|b| fall > b.fall)
        {
            *best = Some(Candidate {
                fall,
                turn,
                direction,
                at,
                halves,
            });
        }
    };
    // Whole degrees first, then the half degrees either side of the best.
    for turn in (-TOP_TURNS..=TOP_TURNS).step_by(2) {
        try_turn(turn, &mut best);
    }
    if let Some(coarse) = best.as_ref().map(|b| b.turn) {
        for turn in [coarse - 1, coarse + 1] {
            try_turn(turn, &mut best);
        }
    }
    let Candidate {
        direction: (angle, rho),
        at,
        halves,
        ..
    } = best?;
    let near = at.saturating_sub(TOP_HALVES_AGREE + 2)..at + TOP_HALVES_AGREE + 3;
    let [a, b] = halves.map(|h| steepest_top_fall(&h, near.clone(), top_share).map(|(_, i)| i));
    let halves_agree = matches!((a, b), (Some(a), Some(b)) if a.abs_diff(b) <= TOP_HALVES_AGREE);
    let whole = joined(&halves);
    let mean = |i: usize| bin_mean(&whole, i);
    let one_transition = (TOP_REACH..at.saturating_sub(1))
        .all(|j| matches!((mean(j), mean(j + 1)), (Some(g), Some(s)) if g - s <= TOP_MIN_STEP));
    let s = at as f32 - TOP_REACH as f32;
    let found = Line {
        angle,
        rho: rho + s * rho_step / sky_ward,
    };
    // Its normal towards the sky, the brighter side of the step.
    let line = if sky_ward > 0.0 {
        found
    } else {
        Line {
            angle: found.angle + PI,
            rho: -found.rho,
        }
    };
    Some(TopStep {
        line,
        halves_agree,
        sky_ward_px: s,
        one_transition,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_where_finds_where_a_rising_test_starts_to_hold() {
        for n in 0..20 {
            for threshold in 0..=n + 1 {
                for guess in [
                    f32::NAN,
                    -3.0,
                    0.0,
                    threshold as f32 - 1.6,
                    threshold as f32 + 0.4,
                    7.0,
                    1e9,
                ] {
                    let found = first_where_from(n, guess, |i| i >= threshold);
                    assert_eq!(
                        found,
                        threshold.min(n),
                        "n {n}, threshold {threshold}, guess {guess}"
                    );
                }
                let found = first_where(n, |i| i >= threshold);
                assert_eq!(found, threshold.min(n), "n {n}, threshold {threshold}");
            }
        }
    }

    /// [`top_profile`] as it was written first, pixel by pixel: the bin and the half of each
    /// pixel tested on its own.
    fn top_profile_pixel_by_pixel(
        grey: &[u8],
        geo: Working,
        camera: &Camera,
        (angle, rho): (f32, f32),
        rho_step: f32,
        sky_ward: f32,
    ) -> [Bins; 2] {
        let scale = geo.scale as f32;
        let (nx, ny) = (libm::sinf(angle), libm::cosf(angle));
        let mut counts = [[0u32; TOP_BINS + 1]; 2];
        let mut sums = [[0u32; TOP_BINS + 1]; 2];
        let inverse = sky_ward / rho_step;
        let along_row = nx * scale / camera.fx * inverse;
        let along_line_per_column = ny * scale / camera.fx;
        for (wy, row) in grey.chunks_exact(geo.width).take(geo.height).enumerate() {
            let (u0, v) = geo.to_frame(0.0, wy as f32);
            let (x0, y) = ((u0 - camera.cx) / camera.fx, (v - camera.cy) / camera.fy);
            let row_start = (x0 * nx + y * ny - rho) * inverse + TOP_REACH as f32 + 0.5;
            let line_start = x0 * ny - y * nx;
            for (column, &value) in row.iter().enumerate() {
                let column = column as u32 as f32;
                let f = row_start + column * along_row;
                let half = usize::from(line_start + column * along_line_per_column >= 0.0);
                let index = if (0.0..TOP_BINS as f32).contains(&f) {
                    (f as i32 as usize).min(TOP_BINS)
                } else {
                    TOP_BINS
                };
                counts[half][index] += 1;
                sums[half][index] += u32::from(value);
            }
        }
        let mut halves = [[(0.0f32, 0.0f32); TOP_BINS]; 2];
        for h in 0..2 {
            for i in 0..TOP_BINS {
                halves[h][i] = (counts[h][i] as f32, sums[h][i] as f32);
            }
        }
        halves
    }

    #[test]
    fn the_profile_by_runs_of_pixels_is_the_profile_pixel_by_pixel() {
        let geo = Working::with_scale(320, 240, 2);
        let camera = Camera::ideal(320, 240, 60.0_f32.to_radians());
        let grey: std::vec::Vec<u8> = (0..geo.width * geo.height)
            .map(|i| ((i * 2_654_435_761usize) >> 13) as u8)
            .collect();
        let rho_step = geo.scale as f32 / camera.fx;
        for angle_deg in [
            -179.5f32, -90.0, -45.3, -3.0, 0.0, 0.7, 12.0, 60.0, 90.0, 135.0,
        ] {
            for rho in [-0.4f32, -0.05, 0.0, 0.13, 0.5] {
                for sky_ward in [1.0, -1.0] {
                    let direction = (angle_deg.to_radians(), rho);
                    let fast = top_profile(&grey, geo, &camera, direction, rho_step, sky_ward);
                    let reference = top_profile_pixel_by_pixel(
                        &grey, geo, &camera, direction, rho_step, sky_ward,
                    );
                    assert_eq!(fast, reference, "angle {angle_deg}°, rho {rho}, {sky_ward}");
                }
            }
        }
    }
}
