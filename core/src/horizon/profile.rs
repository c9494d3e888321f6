//! Full-resolution placement of the chosen line: where in the sky-to-ground transition the
//! horizon is.
//!
//! The Hough stage works on a binned image (2× at 320 px, 3× at 480 px, more on noisy
//! frames) with a 3×3 Sobel, so its edge is the gradient maximum of a picture smoothed over
//! ±4–9 full-resolution pixels. A real horizon is not a symmetric step: below it the ground
//! comes out of the haze (airlight) gradually, so the intensity is a small step at the
//! horizon followed by a ramp. Smoothing a step-plus-ramp moves its gradient maximum into
//! the ramp by about `slope · σ² / step`, quadratic in the smoothing σ: that put the line
//! ~9 px below the labelled horizon at 480 px (+1.2° of pitch) while OpenCV's 5×5 blur +
//! Canny, with a third of the σ, was off by +0.2°.
//!
//! Here the line is moved to the gradient maximum of the full-resolution frame, measured on
//! an intensity profile across the line that is averaged *along* it (hundreds of pixels a
//! bin, so noise averages out without smoothing across the edge). Every pixel near the line
//! is put in a bin by the distance of its centre (the conventions' pixel centres: pixel
//! `(u, v)` at the integer point) from the line, through the camera model, so distortion is
//! handled exactly. The left and right halves of the frame give one such profile each; the
//! line through their two positions also refines the roll.
//!
//! The halves also check the roll the Hough stage gave. On a noisy soft horizon (a Bayer
//! sensor's noise, an analogue link's jitter, a half-resolution codec) the binned image's
//! edge points scatter across the transition and its line can be a few degrees off: the two
//! halves then find the edge on either side of it, a few pixels apart. The line through
//! them is read again, and kept when its own halves agree and its edge stands out more
//! clearly than the first line's did: with the right roll the whole profile stacks the
//! step in one place. When that fails and the halves' edges lie on another roll, they
//! contradict the line ([`Halves::Contradicted`]) and the detector trusts it less.

use super::HorizonLine;
use super::camera::Camera;
use super::frame::{Frame, Pixels, luma};

/// Bins of the profile either side of the coarse line, each [`BIN_PX`] wide.
const HALF_BINS: usize = 112;
const BINS: usize = 2 * HALF_BINS + 1;
const BIN_PX: f32 = 0.5;
/// Bins either side of the coarse line the gradient noise is measured over.
const NOISE_HALF_BINS: usize = 46;
/// Least ratio of the edge's gradient to the profile's gradient noise for the position to be
/// trusted (below it the coarse line stays).
pub(crate) const MIN_SIGNIFICANCE: f32 = 4.0;
/// A local gradient maximum on the sky side of the strongest, in the same transition, is the
/// horizon's step when it has at least this share of the strongest one's gradient.
const TOP_STEP_SHARE: f32 = 0.3;
/// Beyond the search around the coarse line, the walk to the top of the transition ends where
/// the level (sky side up) falls back by this many times the profile's gradient noise.
const TRANSITION_END_NOISE: f32 = 2.0;
/// How far above the coarse line the top of a hazy transition is looked for (tan 5°): the
/// ramp's steepest part, where the coarse line lands, lies half the haze's angular depth
/// below the horizon, a few degrees at most.
const TRANSITION_TAN: f32 = 0.087;
/// Pixels past the 3 px margin of a read that the smoothing and the central difference reach
/// into: read them too, so that the short read's noise estimate is the long read's.
const SMOOTHING_PX: f32 = 2.0;
/// Largest roll change the two half-profiles may make (rad): more means the halves see
/// different edges (an occlusion, a curved shore), and only the offset is moved.
const MAX_ROLL_CHANGE: f32 = 0.03;
/// Largest turn to the halves' edges that is read again (rad, 5.7°): the Hough stage's roll on
/// a noisy soft horizon was 2–5° off; past this the halves see different things.
const MAX_TURN: f32 = 0.1;
/// Least significance of a turned line's edge: it must stand clearly out of the noise, as well
/// as more clearly than the first line's. On the tuning sets, with and without the
/// camera-and-link chain (`tools/horizon/camera_chain.py`), turns to an edge 4–6 times the
/// noise mended 14 lines (more than 2° wrong before, within 2° after) and broke 9; turns to a
/// clearer one mended 214 and broke 12 (`synth` `haze` at 640 px, among others, has a soft
/// ramp whose halves' edges lie 4–5 times the noise out of it).
const TURNED_SIGNIFICANCE: f32 = 1.5 * MIN_SIGNIFICANCE;

/// What the two halves of the frame say of the line's roll.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) enum Halves {
    /// Not checked: no clear edge in the whole profile, or in one of the halves.
    #[default]
    Unchecked,
    /// Both halves find the edge where the line has it; the roll was refined from them.
    Confirmed,
    /// The halves found the edge elsewhere; the line was turned to them and read again, and
    /// the turned line's halves agree and its edge is clearer.
    Turned,
    /// Both halves find a clear edge on the line's roll (within [`MAX_ROLL_CHANGE`]), but one
    /// of them more than 3 px from the whole profile's edge, and no clearer line through them
    /// was found: a hill or a tree line on one side, and the roll is not in question.
    Apart,
    /// Both halves find a clear edge, on a roll more than [`MAX_ROLL_CHANGE`] from the line's,
    /// and no clearer line through them was found: the roll is the binned image's guess.
    Contradicted,
}

/// What the full-resolution look at the line found.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Placement {
    /// Step across the edge (luma levels, sky minus ground, positive when the sky is
    /// brighter) measured 2 px either side of the edge.
    pub step: f32,
    /// The edge's gradient over the profile's gradient noise.
    pub significance: f32,
    /// Share of the profile's pixels at or above clipping on the sky side near the edge.
    pub clipped_sky: f32,
    /// The clipped sky ends at a sharp step onto clearly unclipped, flat-ish ground (see
    /// [`sharp_clip_end`]): the edge is the ground's own top, not a ramp crossing the clip.
    pub sharp_clip_end: bool,
    /// Pixels that went into the profiles.
    pub pixels: u32,
    /// What the frame's two halves say of the line's roll.
    pub halves: Halves,
    /// The line was read only where the sky next to it is not clipped (see
    /// [`clear_of_glare`]); the clipping measures are the whole line's.
    pub clear_of_glare: bool,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Profile {
    sum: [f32; BINS],
    count: [u32; BINS],
    clipped: [u32; BINS],
    /// Sum of the line's points (normalised undistorted) and of |∇D| over the columns.
    point: (f32, f32),
    gradient: f32,
    columns: u32,
}

impl Profile {
    const EMPTY: Profile = Profile {
        sum: [0.0; BINS],
        count: [0; BINS],
        clipped: [0; BINS],
        point: (0.0, 0.0),
        gradient: 0.0,
        columns: 0,
    };

    /// Counts a column whose crossing is at `point` with a gradient of `norm` across the line.
    fn take_column(&mut self, point: (f32, f32), norm: f32) {
        self.point = (self.point.0 + point.0, self.point.1 + point.1);
        self.gradient += norm;
        self.columns += 1;
    }

    fn merged(&self, other: &Profile) -> Profile {
        let mut m = *self;
        for i in 0..BINS {
            if let (Some(s), Some(c), Some(k)) =
                (m.sum.get_mut(i), m.count.get_mut(i), m.clipped.get_mut(i))
            {
                *s += other.sum.get(i).copied().unwrap_or(0.0);
                *c += other.count.get(i).copied().unwrap_or(0);
                *k += other.clipped.get(i).copied().unwrap_or(0);
            }
        }
        m.point = (m.point.0 + other.point.0, m.point.1 + other.point.1);
        m.gradient += other.gradient;
        m.columns += other.columns;
        m
    }

    /// Mean luma per bin, gaps filled linearly; `None` if the profile has too few bins.
    fn means(&self) -> Option<[f32; BINS]> {
        let mut m = [f32::NAN; BINS];
        let (mut filled, mut first, mut last) = (0usize, BINS, 0usize);
        for (i, ((out, &s), &c)) in m.iter_mut().zip(&self.sum).zip(&self.count).enumerate() {
            if c > 0 {
                *out = s / c as f32;
                filled += 1;
                first = first.min(i);
                last = i;
            }
        }
        // A level line fills only every other bin; fewer than that is not a profile.
        if first >= last || last - first < 8 || 3 * filled < last - first + 1 {
            return None;
        }
        // Outside what was read, the nearest filled bin's level (flat); gaps inside (a level
        // line fills only every other bin) linearly from the filled bins either side.
        let (head, tail) = (m.get(first).copied()?, m.get(last).copied()?);
        m.iter_mut().take(first).for_each(|v| *v = head);
        m.iter_mut().skip(last + 1).for_each(|v| *v = tail);
        let mut previous = (first, head);
        for i in first + 1..last {
            let v = m.get(i).copied().unwrap_or(f32::NAN);
            if !v.is_nan() {
                previous = (i, v);
                continue;
            }
            let (a, va) = previous;
            let (b, vb) = (i + 1..=last)
                .find_map(|j| m.get(j).copied().filter(|w| !w.is_nan()).map(|w| (j, w)))
                .unwrap_or((last, tail));
            if let Some(slot) = m.get_mut(i) {
                *slot = va + (vb - va) * (i - a) as f32 / (b - a) as f32;
            }
        }
        Some(m)
    }
}

/// One side's result: the edge's offset from the coarse line (px, positive towards the
/// ground), its gradient and significance.
#[derive(Clone, Copy, Debug)]
struct Edge {
    offset_px: f32,
    step: f32,
    significance: f32,
    /// The walk to the top of the transition was still going where the profile's read
    /// ended: read further to find its top.
    walk_reached_read_end: bool,
}

/// The edge in a profile within `[-sky_px, ground_px]` of the coarse line, with the
/// polarity `sky_brighter`, moved up to the top of its transition as far as `transition_px`
/// above the coarse line, or as far as the profile was read (`read_px` above it, plus the 3 px
/// the smoothing needs).
fn find_edge(
    profile: &Profile,
    sky_px: f32,
    ground_px: f32,
    transition_px: f32,
    read_px: f32,
    sky_brighter: bool,
) -> Option<Edge> {
    let m = profile.means()?;
    // A light [1 2 1] smoothing across bins (half a pixel), then a central difference over
    // one pixel: symmetric, so it moves no edge.
    let mut smooth = m;
    for i in 1..BINS - 1 {
        if let (Some(a), Some(b), Some(c), Some(out)) =
            (m.get(i - 1), m.get(i), m.get(i + 1), smooth.get_mut(i))
        {
            *out = 0.25 * a + 0.5 * b + 0.25 * c;
        }
    }
    let sign = if sky_brighter { 1.0 } else { -1.0 };
    let gradient = |i: usize| -> f32 {
        match (
            i.checked_sub(1).and_then(|j| smooth.get(j)),
            smooth.get(i + 1),
        ) {
            (Some(a), Some(b)) => sign * (a - b),
            _ => 0.0,
        }
    };
    let bin_of = |d: f32| (d / BIN_PX + HALF_BINS as f32) as isize;
    let lo = bin_of(-sky_px).clamp(2, BINS as isize - 3) as usize;
    let hi = bin_of(ground_px).clamp(2, BINS as isize - 3) as usize;
    let mut best = (lo, f32::MIN);
    for i in lo..=hi {
        let g = gradient(i);
        if g > best.1 {
            best = (i, g);
        }
    }
    let (peak, g0) = best;
    if g0 <= 0.0 {
        return None;
    }
    // Noise: the spread of the gradient away from the edge (outside ±3 px of it), within
    // [`NOISE_HALF_BINS`] of the coarse line, the bins outside what was read counting as flat
    // (they are filled flat). Pixels read beyond the search on the sky side, for the walk to
    // the top of a hazy transition, count as flat too: the thresholds on it were set when the
    // profile was read no further than 3 px past the search.
    let read_lo = if transition_px > sky_px {
        bin_of(-sky_px - 3.0)
    } else {
        0
    };
    let (mut n, mut s2) = (0.0f32, 0.0f32);
    for i in HALF_BINS - NOISE_HALF_BINS..=HALF_BINS + NOISE_HALF_BINS {
        if (i as isize - peak as isize).unsigned_abs() as f32 * BIN_PX <= 3.0 {
            continue;
        }
        n += 1.0;
        if i as isize >= read_lo {
            let g = gradient(i) - gradient(i + 1);
            s2 += g * g;
        }
    }
    let noise = if n > 0.0 {
        libm::sqrtf(s2 / n) * core::f32::consts::FRAC_1_SQRT_2
    } else {
        0.0
    };
    // The horizon is the top of the transition. Under haze the ground comes out of the
    // airlight along a ramp whose steepest part lies k/2 below the horizon (a fixed angle, so
    // more pixels and a steeper gradient per pixel at lower resolution), under a step from the
    // sky that may be smaller. The coarse line then lies on the ramp, and at 320 px several
    // degrees down it: further than the search around it reaches. Walking from the gradient
    // maximum towards the sky while the profile keeps rising (one transition: the level, sky
    // side up, does not fall back by more than [`TRANSITION_END_NOISE`] times its gradient
    // noise), as far as `transition_px`, the sky-most local maximum that is a clear edge of
    // its own is the step.
    let top = bin_of(-transition_px.min(read_px).max(sky_px)).clamp(2, BINS as isize - 3) as usize;
    let mut walk_reached_read_end = read_px < transition_px;
    let (peak, g0) = {
        let level = |i: usize| sign * smooth.get(i).copied().unwrap_or(0.0);
        let fall_back = TRANSITION_END_NOISE * (noise + 0.05);
        let mut highest = level(peak);
        let mut chosen = (peak, g0);
        let mut i = peak;
        while i > top {
            i -= 1;
            let g = gradient(i);
            let here = level(i);
            // The transition has ended where, within the search, the profile rises again by
            // more than its noise from one pixel to the next, or where, anywhere, its level has
            // fallen back from the highest so far by more than twice that (beyond the search,
            // where a long ramp's small slope is buried in the noise pixel by pixel).
            if (i >= lo && g < -(noise + 0.05)) || here < highest - fall_back {
                walk_reached_read_end = false;
                break;
            }
            highest = highest.max(here);
            if g >= gradient(i.saturating_sub(1))
                && g > gradient(i + 1)
                && g >= TOP_STEP_SHARE * g0
                && g >= MIN_SIGNIFICANCE * (noise + 0.05)
            {
                chosen = (i, g);
            }
        }
        chosen
    };
    // Sub-bin position: parabola through the peak and its neighbours.
    let (a, c) = (gradient(peak.saturating_sub(1)), gradient(peak + 1));
    let curvature = a - 2.0 * g0 + c;
    let sub = if curvature < 0.0 {
        (0.5 * (a - c) / curvature).clamp(-0.5, 0.5)
    } else {
        0.0
    };
    let offset_px = (peak as f32 + sub - HALF_BINS as f32) * BIN_PX;
    let at = |d: f32| {
        let i = bin_of(d).clamp(0, BINS as isize - 1) as usize;
        smooth.get(i).copied().unwrap_or(0.0)
    };
    Some(Edge {
        offset_px,
        step: at(offset_px - 2.0) - at(offset_px + 2.0),
        significance: g0 / (noise + 0.05),
        walk_reached_read_end,
    })
}

/// Luma at or above which a profile bin counts as clipped (mean level).
const CLIP_LEVEL: f32 = 245.0;
/// The ground under a sharp clip end is at least this far below a pixel's clipping level
/// (250, luma levels).
const UNCLIPPED_MARGIN: f32 = 10.0;
/// Share of the fall from the sky to the ground 4 px down that must happen within 1.5 px of
/// the edge: a step, not a ramp.
const SHARP_SHARE: f32 = 0.8;

/// Whether the clipped sky above the edge at `offset_px` ends at a sharp step onto clearly
/// unclipped ground: clipped 1 px above the edge, well below clipping 1.5 px below it, and
/// nearly flat from there to 4 px below (the fall within 1.5 px is most of the fall to 4 px).
/// A hazy ground ramping up into the clip level instead keeps falling below the crossing.
/// The sky at the far end of the search (`sky_px` above the coarse line) must stay well above
/// that ground, at least half the step up: a thin clipped stripe (synth `white-stripes`) has
/// the same level on both sides and its lower edge is no horizon.
/// Only bins that hold pixels are read (the gap filling would fake a flat ground).
fn sharp_clip_end(profile: &Profile, offset_px: f32, sky_px: f32) -> bool {
    let Some(m) = profile.means() else {
        return false;
    };
    let at = |d: f32| -> Option<f32> {
        let i = libm::floorf(d / BIN_PX + HALF_BINS as f32 + 0.5);
        if !(0.0..BINS as f32).contains(&i) {
            return None;
        }
        let i = i as usize;
        match (m.get(i), profile.count.get(i)) {
            (Some(&v), Some(&c)) if c > 0 => Some(v),
            // A level line fills every other bin: the neighbour towards the ground.
            _ => match (m.get(i + 1), profile.count.get(i + 1)) {
                (Some(&v), Some(&c)) if c > 0 => Some(v),
                _ => None,
            },
        }
    };
    let (Some(sky), Some(near), Some(far)) = (
        at(offset_px - 1.0),
        at(offset_px + 2.0),
        at(offset_px + 5.0),
    ) else {
        return false;
    };
    let Some(top) = at(-sky_px) else {
        return false;
    };
    let fall = sky - far;
    top >= near + 0.5 * (sky - near)
        && sky >= CLIP_LEVEL
        && near <= 250.0 - UNCLIPPED_MARGIN
        && fall > 0.0
        && sky - near >= SHARP_SHARE * fall
        && libm::fabsf(near - far) <= (1.0 - SHARP_SHARE) * fall
}

/// Luma of pixel `(u, v)` of a frame (grey or RGB), 0 outside it. The pixel format and the
/// slice are taken apart once per frame rather than once per pixel, as the profile reads
/// thousands of pixels in no row order.
#[derive(Clone, Copy)]
struct LumaReader<'a> {
    data: &'a [u8],
    stride: usize,
    width: usize,
    height: usize,
    colour: bool,
}

impl<'a> LumaReader<'a> {
    fn new(frame: &Frame<'a>) -> Self {
        let (data, colour) = match frame.pixels() {
            Pixels::Grey(d) => (d, false),
            Pixels::Rgb(d) => (d, true),
        };
        LumaReader {
            data,
            stride: frame.stride(),
            width: frame.width(),
            height: frame.height(),
            colour,
        }
    }

    /// The pixels of column `a` (`along_columns`) or of row `a`: where pixel `c` along it
    /// starts in the data, and how many it has (none where `a` is outside the frame).
    fn line(&self, along_columns: bool, a: usize) -> LumaLine<'a> {
        let bytes_per_pixel = if self.colour { 3 } else { 1 };
        let (inside, base, step, len) = if along_columns {
            (
                a < self.width,
                a * bytes_per_pixel,
                self.stride,
                self.height,
            )
        } else {
            (
                a < self.height,
                a * self.stride,
                bytes_per_pixel,
                self.width,
            )
        };
        LumaLine {
            data: self.data,
            base,
            step,
            len: if inside { len } else { 0 },
            colour: self.colour,
        }
    }
}

/// One column (row) of a [`LumaReader`]'s frame: the luma of its pixel `c`, 0 outside it
/// (the same values as reading `(u, v)` one by one, without working out each pixel's place
/// from both).
#[derive(Clone, Copy)]
struct LumaLine<'a> {
    data: &'a [u8],
    base: usize,
    step: usize,
    len: usize,
    colour: bool,
}

impl LumaLine<'_> {
    #[inline]
    fn at(&self, c: usize) -> u8 {
        if c >= self.len {
            return 0;
        }
        let start = self.base + c * self.step;
        if self.colour {
            match self.data.get(start..start + 3) {
                Some(&[r, g, b]) => luma(r, g, b),
                _ => 0,
            }
        } else {
            self.data.get(start).copied().unwrap_or(0)
        }
    }
}

/// `D = s·x + c·y − offset` at a pixel (normalised undistorted units), positive on the ground.
#[inline]
fn distance(camera: &Camera, line: &HorizonLine, sc: (f32, f32), u: f32, v: f32) -> Option<f32> {
    let point = camera.undistort_pixel(u, v)?;
    Some(distance_at(line, sc, point))
}

/// [`distance`] at an undistorted point.
#[inline]
fn distance_at(line: &HorizonLine, sc: (f32, f32), (x, y): (f32, f32)) -> f32 {
    sc.0 * x + sc.1 * y - line.offset
}

/// Columns (rows) of a read whose crossings are kept for a longer read of the same line: a
/// 1024-pixel-wide frame read every other column. A wider one is read again in full.
const MAX_WALK: usize = 512;

/// What a read found where the line crosses one column (row) of the frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
enum Crossing {
    /// Not walked (past [`MAX_WALK`]), or no finite guess where the line crosses: nothing
    /// read, and the walk's last crossing kept as the next column's guess.
    #[default]
    NoGuess,
    /// Newton's steps failed (the camera model, not the reach): the next column's guess is
    /// the pinhole one.
    Lost,
    /// Newton's steps left the read's reach: a longer reach may have gone on.
    OutOfReach,
    /// Found at `b`, the next column's guess; `across` is what a read takes from it, `None`
    /// where the distance across the line cannot be read there (whatever the reach).
    Found { b: f32, across: Option<Across> },
}

/// The line across one column (row) where it crosses it.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Across {
    /// Pixels per unit of v (or u) across the line; positive towards the ground.
    k: f32,
    /// |∇D| and the crossing's undistorted point, which the half's sums take.
    norm: f32,
    point: (f32, f32),
}

/// The crossings of one read, column (row) by column, and the reaches it was read to: a
/// longer read of the same line finds the same crossings (its reach bounds Newton's steps
/// only more loosely) and reads only the pixels it adds to each column.
struct Walk {
    /// What was found in each column, for the first `len` columns.
    crossings: [Crossing; MAX_WALK],
    len: usize,
    /// Every column read has its crossing here.
    complete: bool,
    reaches: (f32, f32),
}

impl Walk {
    const fn new() -> Self {
        Walk {
            crossings: [Crossing::NoGuess; MAX_WALK],
            len: 0,
            complete: false,
            reaches: (0.0, 0.0),
        }
    }
}

/// The rows (columns) of a column (row) a read takes on either side of the crossing at `b`,
/// `reach_sky` pixels on its sky side and `reach_ground` on its ground side: first and last,
/// inside the frame's `minor` ones. `None` where that leaves none.
fn read_range(
    b: f32,
    k: f32,
    (reach_sky, reach_ground): (f32, f32),
    minor: usize,
) -> Option<(usize, usize)> {
    let (lo, hi) = if k > 0.0 {
        (b - reach_sky / k, b + reach_ground / k)
    } else {
        (b + reach_ground / k, b - reach_sky / k)
    };
    let first = libm::ceilf(lo).max(0.0) as usize;
    let last = libm::floorf(hi).min(minor as f32 - 1.0);
    if last < 0.0 {
        return None;
    }
    let last = last as usize;
    (first <= last).then_some((first, last))
}

/// Bins the pixels `range` of column (row) `a`, the line crossing it at `b` with `k` pixels
/// per unit across it, into `profile`; the number of pixels binned.
fn bin_pixels(
    profile: &mut Profile,
    pixels: &LumaReader<'_>,
    along_columns: bool,
    (a, b, k): (usize, f32, f32),
    range: core::ops::RangeInclusive<usize>,
) -> u32 {
    let mut binned = 0;
    let line = pixels.line(along_columns, a);
    for c in range {
        let d = (c as f32 - b) * k;
        // The bin is the floor of `f`; it lies in [0, BINS) exactly when `f` does, and
        // there the floor is the truncation.
        let f = d / BIN_PX + HALF_BINS as f32 + 0.5;
        if !(0.0..BINS as f32).contains(&f) {
            continue;
        }
        let bin = f as i32 as usize;
        let value = line.at(c);
        if let (Some(sum), Some(count), Some(clip)) = (
            profile.sum.get_mut(bin),
            profile.count.get_mut(bin),
            profile.clipped.get_mut(bin),
        ) {
            *sum += f32::from(value);
            *count += 1;
            *clip += u32::from(value >= 250);
        }
        binned += 1;
    }
    binned
}

/// The two half-profiles across `line` (left and right of the principal point), read from
/// `reach_sky` pixels on its sky side to `reach_ground` on its ground side, and the number of
/// pixels read. The crossings found are kept in `walk`.
fn read_halves(
    frame: &Frame<'_>,
    camera: &Camera,
    line: HorizonLine,
    sc: (f32, f32),
    along_columns: bool,
    ((reach_sky, reach_ground), span): ((f32, f32), Option<Span>),
    walk: &mut Walk,
) -> ([Profile; 2], u32) {
    let (w, h) = (frame.width(), frame.height());
    let (major, minor) = if along_columns { (w, h) } else { (h, w) };
    let Span { first, split, end } = span.unwrap_or(Span {
        first: 0,
        split: if along_columns { camera.cx } else { camera.cy },
        end: major,
    });
    let mut halves = [Profile::EMPTY, Profile::EMPTY];
    let mut total_pixels = 0u32;
    let step = column_step(major);
    let pixels = LumaReader::new(frame);
    walk.reaches = (reach_sky, reach_ground);
    // A read of part of the line keeps no walk a longer read could take up.
    walk.complete = span.is_none() && major.div_ceil(step) <= MAX_WALK;
    walk.len = 0;
    let columns = (first..end).step_by(step);
    walk_crossings(
        camera,
        line,
        (sc, along_columns),
        (columns, minor),
        reach_sky,
        |a, found| {
            let crossing = match found {
                Ok((b, across)) => Crossing::Found { b, across },
                Err(failed) => failed,
            };
            if let Some(slot) = walk.crossings.get_mut(walk.len) {
                *slot = crossing;
                walk.len += 1;
            }
            let Crossing::Found {
                b,
                across: Some(Across { k, norm, point }),
            } = crossing
            else {
                return;
            };
            let Some((first, last)) = read_range(b, k, (reach_sky, reach_ground), minor) else {
                return;
            };
            let half = usize::from(a as f32 >= split);
            let Some(profile) = halves.get_mut(half) else {
                return;
            };
            profile.take_column(point, norm);
            total_pixels += bin_pixels(profile, &pixels, along_columns, (a, b, k), first..=last);
        },
    );
    (halves, total_pixels)
}

/// Every other column (row) on wide frames: half the reads, and the line's slope still
/// spreads the pixel centres over the bins.
fn column_step(major: usize) -> usize {
    if major > 200 { 2 } else { 1 }
}

/// The line's direction (`sin`, `cos` of its roll) and whether a read walks along the
/// columns (the image axis the line is closer to: columns for a flat line).
fn walk_axis(camera: &Camera, line: HorizonLine) -> ((f32, f32), bool) {
    let sc = (
        libm::sinf(line.camera_roll_rad),
        libm::cosf(line.camera_roll_rad),
    );
    (
        sc,
        libm::fabsf(sc.1 * camera.fx) >= libm::fabsf(sc.0 * camera.fy),
    )
}

/// Calls `visit(a, found)` with where `line` crosses each column (row) `a` of `columns` (see
/// [`crossing`]), each column's guess the last crossing found: a crossing that was lost or
/// left the reach leaves the next column to the pinhole guess.
fn walk_crossings(
    camera: &Camera,
    line: HorizonLine,
    (sc, along_columns): ((f32, f32), bool),
    (columns, minor): (core::iter::StepBy<core::ops::Range<usize>>, usize),
    reach_sky: f32,
    mut visit: impl FnMut(usize, Result<(f32, Option<Across>), Crossing>),
) {
    let mut previous: Option<f32> = None;
    for a in columns {
        let found = crossing(
            camera,
            line,
            sc,
            along_columns,
            (a, minor),
            reach_sky,
            previous,
        );
        match found {
            Ok((b, _)) => previous = Some(b),
            Err(Crossing::NoGuess) => {}
            Err(_) => previous = None,
        }
        visit(a, found);
    }
}

/// Where `line` crosses column (row) `a` of a frame with `minor` rows (columns): the crossing
/// `b` and what a read takes from it there (`None` where the distance across the line cannot
/// be read), or what stopped it (see [`Crossing`]). `previous`: the last column's crossing,
/// the guess Newton's steps start from on a distorted camera.
fn crossing(
    camera: &Camera,
    line: HorizonLine,
    sc: (f32, f32),
    along_columns: bool,
    (a, minor): (usize, usize),
    reach_sky: f32,
    previous: Option<f32>,
) -> Result<(f32, Option<Across>), Crossing> {
    let pixel = |a: f32, b: f32| if along_columns { (a, b) } else { (b, a) };
    let distorted = camera.k1 != 0.0 || camera.k2 != 0.0;
    let af = a as f32;
    // Where the line crosses this column (row): pinhole guess, then Newton on the
    // distorted model.
    let (x0, y0) = if along_columns {
        ((af - camera.cx) / camera.fx, 0.0)
    } else {
        (0.0, (af - camera.cy) / camera.fy)
    };
    let mut b = if along_columns {
        let y = (line.offset - sc.0 * x0) / sc.1;
        camera.cy + camera.fy * y
    } else {
        let x = (line.offset - sc.1 * y0) / sc.0;
        camera.cx + camera.fx * x
    };
    if distorted && let Some(p) = previous {
        b = p;
    }
    if !b.is_finite() {
        return Err(Crossing::NoGuess);
    }
    let mut slope = 0.0;
    // D is linear in the pixel without distortion: one step lands on the line.
    for _ in 0..if distorted { 2 } else { 1 } {
        let (p0, p1) = (pixel(af, b), pixel(af, b + 1.0));
        match (
            distance(camera, &line, sc, p0.0, p0.1),
            distance(camera, &line, sc, p1.0, p1.1),
        ) {
            (Some(d0), Some(d1)) if libm::fabsf(d1 - d0) > 1e-9 => {
                slope = d1 - d0;
                b -= d0 / slope;
            }
            _ => return Err(Crossing::Lost),
        }
        if !b.is_finite() || b < -reach_sky - 2.0 || b > minor as f32 + reach_sky + 2.0 {
            return Err(Crossing::OutOfReach);
        }
    }
    // The other component of the gradient of D, for the distance across the line.
    let p = pixel(af, b);
    let q = pixel(af + 1.0, b);
    // The crossing's own undistorted point is also what the half's mean point adds.
    let across = match (
        camera.undistort_pixel(p.0, p.1),
        distance(camera, &line, sc, q.0, q.1),
    ) {
        (Some(point), Some(d_next)) => {
            let other = d_next - distance_at(&line, sc, point);
            let norm = libm::sqrtf(slope * slope + other * other);
            // Pixels per unit of v (or u) across the line; positive towards the ground.
            let k = slope / norm;
            (!(norm.is_nan() || norm <= 0.0) && libm::fabsf(k) >= 0.3).then_some(Across {
                k,
                norm,
                point,
            })
        }
        _ => None,
    };
    Ok((b, across))
}

/// [`read_halves`] of the same line to `reaches` at least as long as those of the read
/// `walk` kept (`read`: its half-profiles and pixel count), from that read: the crossings
/// are the same where none left the shorter reach, and the profiles' sums are whole numbers
/// (exact in any order), so only the pixels the longer reach adds are read. The halves' mean
/// points and gradients are summed again in the columns' order. `None` where the walk cannot
/// tell (a crossing out of its reach, columns past [`MAX_WALK`], a shorter reach).
fn extend_halves(
    frame: &Frame<'_>,
    camera: &Camera,
    along_columns: bool,
    walk: &Walk,
    read: &([Profile; 2], u32),
    reaches: (f32, f32),
) -> Option<([Profile; 2], u32)> {
    let (short_sky, short_ground) = walk.reaches;
    if !(walk.complete && reaches.0 >= short_sky && reaches.1 >= short_ground) {
        return None;
    }
    let crossings = walk.crossings.get(..walk.len)?;
    if crossings.contains(&Crossing::OutOfReach) {
        return None;
    }
    let (w, h) = (frame.width(), frame.height());
    let (major, minor) = if along_columns { (w, h) } else { (h, w) };
    let centre = if along_columns { camera.cx } else { camera.cy };
    let step = column_step(major);
    let pixels = LumaReader::new(frame);
    let (mut halves, mut total_pixels) = (read.0, read.1);
    for profile in &mut halves {
        profile.point = (0.0, 0.0);
        profile.gradient = 0.0;
        profile.columns = 0;
    }
    for (a, &crossing) in (0..major).step_by(step).zip(crossings) {
        let Crossing::Found {
            b,
            across: Some(Across { k, norm, point }),
        } = crossing
        else {
            continue;
        };
        let Some((first, last)) = read_range(b, k, reaches, minor) else {
            continue;
        };
        let half = usize::from(a as f32 >= centre);
        let Some(profile) = halves.get_mut(half) else {
            continue;
        };
        profile.take_column(point, norm);
        let column = (a, b, k);
        total_pixels += match read_range(b, k, walk.reaches, minor) {
            // The longer reach's range holds the shorter's: the pixels either side of it.
            Some((short_first, short_last)) => {
                let before = if short_first > first {
                    bin_pixels(
                        profile,
                        &pixels,
                        along_columns,
                        column,
                        first..=short_first - 1,
                    )
                } else {
                    0
                };
                before
                    + bin_pixels(
                        profile,
                        &pixels,
                        along_columns,
                        column,
                        short_last + 1..=last,
                    )
            }
            None => bin_pixels(profile, &pixels, along_columns, column, first..=last),
        };
    }
    Some((halves, total_pixels))
}

/// Moves `line` to the full-resolution edge within `search_px` pixels on its sky side (and a
/// few on its ground side). `sky_brighter`: the polarity the Hough stage saw. Returns the
/// placed line (the input line when the edge is not significant) and what was measured. A
/// line whose halves find the edge elsewhere is turned to their edges and read again (see the
/// module's text). A line with clipped sky next to its edge on one side of the frame is read
/// again on the rest of its length (see [`clear_of_glare`]).
pub(crate) fn place(
    frame: &Frame<'_>,
    camera: &Camera,
    line: HorizonLine,
    search_px: f32,
    sky_brighter: bool,
) -> (HorizonLine, Placement) {
    let (placed, placement) = place_turning(frame, camera, line, search_px, sky_brighter);
    if placement.clipped_sky < GLARE_CLIPPED_SKY || placement.sharp_clip_end {
        return (placed, placement);
    }
    match clear_of_glare(frame, camera, placed, search_px, sky_brighter) {
        // What the whole line measured of the clipping stays (the detector weighs it less for
        // a line read clear, see `read_clear` in the detector), and so do a contradiction its
        // halves found and the lesser significance. A bright halo that is not clipped can
        // still draw the clear run's edge (`aerial` seed 141 `glare`, frames 0–1: the halves
        // of the run agree on a line 5° of roll out), and those lines are under the gate for
        // their halves' contradiction.
        Some((clear, clear_placement)) => (
            clear,
            Placement {
                clipped_sky: placement.clipped_sky,
                sharp_clip_end: placement.sharp_clip_end,
                clear_of_glare: true,
                halves: if placement.halves == Halves::Contradicted {
                    Halves::Contradicted
                } else {
                    clear_placement.halves
                },
                significance: clear_placement.significance.min(placement.significance),
                ..clear_placement
            },
        ),
        None => (placed, placement),
    }
}

/// [`place`] before the look clear of the glare: one read, and one turn at most.
fn place_turning(
    frame: &Frame<'_>,
    camera: &Camera,
    line: HorizonLine,
    search_px: f32,
    sky_brighter: bool,
) -> (HorizonLine, Placement) {
    let (placed, placement, turn) = place_once(frame, camera, line, search_px, sky_brighter, None);
    if let Some(turned) = turn {
        // One turn at most: the second read's own turn, if any, is not followed.
        let (again, again_placement, _) =
            place_once(frame, camera, turned, search_px, sky_brighter, None);
        if again_placement.halves == Halves::Confirmed
            && again_placement.significance > placement.significance
            && again_placement.significance >= TURNED_SIGNIFICANCE
        {
            return (
                again,
                Placement {
                    halves: Halves::Turned,
                    ..again_placement
                },
            );
        }
    }
    (placed, placement)
}

/// Least share of the sky next to a placed line's edge that is clipped for the line to be
/// read again clear of the glare ([`clear_of_glare`]).
const GLARE_CLIPPED_SKY: f32 = 0.05;
/// Least share of the columns (rows) a line crosses that the run clear of clipping must hold,
/// and least columns in it: each half of it gives one point of the line.
const GLARE_CLEAR_SHARE: f32 = 0.35;
const GLARE_CLEAR_COLUMNS: usize = 24;
/// Pixels across the line on the sky side of a crossing that a column's clipping is judged
/// by: the window the placement's `clipped_sky` counts (within 4 px of the edge).
const GLARE_LOOK_PX: [f32; 4] = [1.0, 2.0, 3.0, 4.0];
/// Reads of the clear run at most: the first, and a turn to its halves' edges (and one more).
const GLARE_READS: usize = 3;

/// The line read only where the sky next to it is clear of clipping. The sun low in the
/// frame blooms over the horizon on its side: the sky there is clipped down to where the
/// bloom fades on the ground, below the horizon, and that edge (the strongest in the frame)
/// drags the Hough line's end down with it, a few degrees of roll towards the sun (`aerial`
/// seed 141 `glare`: 17 of 40 frames 2.3–6.3° of roll out, the edge where the sky is not
/// clipped on the horizon to the pixel). The longest run of columns whose sky is not
/// clipped is read as two halves of its own; their edges must agree with the line through
/// them ([`Halves::Confirmed`]) clearly ([`TURNED_SIGNIFICANCE`]), after at most two turns to
/// them. `None` where no such run holds enough of the line or its halves do not agree.
fn clear_of_glare(
    frame: &Frame<'_>,
    camera: &Camera,
    placed: HorizonLine,
    search_px: f32,
    sky_brighter: bool,
) -> Option<(HorizonLine, Placement)> {
    let mut line = placed;
    for _ in 0..GLARE_READS {
        let span = unclipped_span(frame, camera, line, search_px)?;
        let (again, placement, turn) =
            place_once(frame, camera, line, search_px, sky_brighter, Some(span));
        if placement.halves == Halves::Confirmed {
            return (placement.significance >= TURNED_SIGNIFICANCE).then_some((again, placement));
        }
        line = turn?;
    }
    None
}

/// The longest run of the columns (rows) `line` crosses whose sky within 4 px of it
/// ([`GLARE_LOOK_PX`]) holds no clipped pixel, split in two halves of as many columns;
/// `None` where no column is clipped (the whole read is the same) or the run is short.
fn unclipped_span(
    frame: &Frame<'_>,
    camera: &Camera,
    line: HorizonLine,
    search_px: f32,
) -> Option<Span> {
    let (sc, along_columns) = walk_axis(camera, line);
    let (w, h) = (frame.width(), frame.height());
    let (major, minor) = if along_columns { (w, h) } else { (h, w) };
    let pixels = LumaReader::new(frame);
    let (mut crossed, mut clipped) = (0usize, 0usize);
    // The run going on (first and last column, columns) and the longest so far.
    let mut run: Option<(usize, usize, usize)> = None;
    let mut best: Option<(usize, usize, usize)> = None;
    let columns = (0..major).step_by(column_step(major));
    walk_crossings(
        camera,
        line,
        (sc, along_columns),
        (columns, minor),
        search_px,
        |a, found| {
            let Ok((b, Some(Across { k, .. }))) = found else {
                return;
            };
            let column = pixels.line(along_columns, a);
            // The sky's pixels next to the crossing (`d = (c − b)·k` px across the line,
            // negative on the sky side), those inside the frame.
            let (mut seen, mut is_clipped) = (false, false);
            for px in GLARE_LOOK_PX {
                let c = libm::roundf(b - px / k);
                if c >= 0.0 && c < minor as f32 {
                    seen = true;
                    is_clipped |= column.at(c as usize) >= 250;
                }
            }
            if !seen {
                return;
            }
            crossed += 1;
            if is_clipped {
                clipped += 1;
                run = None;
                return;
            }
            let now = match run {
                Some((first, _, n)) => (first, a, n + 1),
                None => (a, a, 1),
            };
            run = Some(now);
            if best.is_none_or(|(_, _, n)| now.2 > n) {
                best = Some(now);
            }
        },
    );
    let (first, last, n) = best?;
    (clipped > 0 && n >= GLARE_CLEAR_COLUMNS && n as f32 >= GLARE_CLEAR_SHARE * crossed as f32)
        .then_some(Span {
            first,
            split: 0.5 * (first + last) as f32,
            end: last + 1,
        })
}

/// The columns (rows) of the frame a read takes, `first..end`, and where its halves part
/// (the left half is under `split`). `first` is a column the whole line's walk reads (a
/// multiple of [`column_step`]), so a read of the span takes the whole read's columns in it.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Span {
    first: usize,
    split: f32,
    end: usize,
}

/// [`place`] without the turn: the placed line, what was measured, and the line through the
/// halves' edges when they find the edge off the line by a turn worth reading again.
fn place_once(
    frame: &Frame<'_>,
    camera: &Camera,
    line: HorizonLine,
    search_px: f32,
    sky_brighter: bool,
    span: Option<Span>,
) -> (HorizonLine, Placement, Option<HorizonLine>) {
    let (sc, along_columns) = walk_axis(camera, line);
    let search_px = search_px.clamp(2.0, HALF_BINS as f32 * BIN_PX - 3.0);
    // A read clear of the glare looks as far on the ground side as on the sky side: the
    // bloom pulls the line's end down on the sun's side, so the line pivots and its other
    // end lies above the horizon.
    let ground_px = if span.is_some() {
        search_px
    } else {
        (0.5 * search_px).max(3.0)
    };
    // The top of a hazy transition is looked for only under a sky brighter than the ground:
    // the airlight a hazy ground comes out of is at most as bright as the sky at the horizon,
    // and the ground is darker still. The other polarity, walked out this far, climbs the
    // sky's own glow (synth `haze` at 640 px, whose hazy ground is brighter than the sky).
    let transition_px = if sky_brighter {
        (0.5 * (camera.fx + camera.fy) * TRANSITION_TAN)
            .clamp(search_px, HALF_BINS as f32 * BIN_PX - 3.0)
    } else {
        search_px
    };
    // The long read, up to `transition_px`, only when the walk to the top of the transition
    // reaches the end of the short one: most horizons are a step, and the long read costs
    // as much again as the rest of the placement. The short read takes the pixels the
    // smoothing reaches past its margin too, so that its noise estimate is the long read's.
    let edge_in = |profile: &Profile, read_px: f32| {
        find_edge(
            profile,
            search_px,
            ground_px,
            transition_px,
            read_px,
            sky_brighter,
        )
    };
    let find_in = |read: ([Profile; 2], u32), read_px: f32| {
        let (halves, pixels) = read;
        let [left, right] = &halves;
        let both = left.merged(right);
        let whole = edge_in(&both, read_px);
        (halves, pixels, both, whole, read_px)
    };
    let mut walk = Walk::new();
    let short_reaches = (search_px + 3.0 + SMOOTHING_PX, ground_px + 3.0);
    let short = read_halves(
        frame,
        camera,
        line,
        sc,
        along_columns,
        (short_reaches, span),
        &mut walk,
    );
    let mut read = find_in(short, search_px);
    if transition_px > search_px && read.3.is_some_and(|e| e.walk_reached_read_end) {
        let reaches = (transition_px + 3.0, ground_px + 3.0);
        let long = extend_halves(
            frame,
            camera,
            along_columns,
            &walk,
            &(read.0, read.1),
            reaches,
        )
        .unwrap_or_else(|| {
            read_halves(
                frame,
                camera,
                line,
                sc,
                along_columns,
                (reaches, span),
                &mut walk,
            )
        });
        read = find_in(long, transition_px);
    }
    let (halves, total_pixels, both, whole, read_px) = read;
    let [left, right] = halves;
    let mut placement = Placement {
        pixels: total_pixels,
        ..Placement::default()
    };
    let Some(whole) = whole else {
        return (line, placement, None);
    };
    placement.step = whole.step * if sky_brighter { 1.0 } else { -1.0 };
    placement.significance = whole.significance;
    // Clipping on the sky side within 4 px of the edge.
    let (mut clipped, mut counted) = (0u32, 0u32);
    for i in 0..BINS {
        let d = (i as f32 - HALF_BINS as f32) * BIN_PX;
        if d < whole.offset_px - 4.0 || d > whole.offset_px - 0.5 {
            continue;
        }
        clipped += both.clipped.get(i).copied().unwrap_or(0);
        counted += both.count.get(i).copied().unwrap_or(0);
    }
    placement.clipped_sky = if counted > 0 {
        clipped as f32 / counted as f32
    } else {
        0.0
    };
    placement.sharp_clip_end = sharp_clip_end(&both, whole.offset_px, search_px);
    if whole.significance < MIN_SIGNIFICANCE || both.columns == 0 {
        return (line, placement, None);
    }
    let gradient = both.gradient / both.columns as f32;
    let shifted = HorizonLine {
        camera_roll_rad: line.camera_roll_rad,
        offset: line.offset + whole.offset_px * gradient,
    };
    // Roll from the two halves, when both see an edge clearly.
    let sides = [&left, &right].map(|p| {
        if p.columns < 8 {
            return None;
        }
        let e = edge_in(p, read_px)?;
        if e.significance < MIN_SIGNIFICANCE {
            return None;
        }
        let n = p.columns as f32;
        let (px, py) = (p.point.0 / n, p.point.1 / n);
        let g = p.gradient / n;
        Some((
            (px + sc.0 * e.offset_px * g, py + sc.1 * e.offset_px * g),
            e,
        ))
    });
    let [Some((l, left_edge)), Some((r, right_edge))] = sides else {
        return (shifted, placement, None);
    };
    let (ex, ey) = (r.0 - l.0, r.1 - l.1);
    let length = libm::sqrtf(ex * ex + ey * ey);
    if length <= 1e-6 {
        return (shifted, placement, None);
    }
    // Normal of the line through the halves' edges, on the same side as the old one.
    let (mut nx, mut ny) = (-ey / length, ex / length);
    if nx * sc.0 + ny * sc.1 < 0.0 {
        nx = -nx;
        ny = -ny;
    }
    let roll = libm::atan2f(nx, ny);
    let change = super::hough::wrap_angle(roll - line.camera_roll_rad);
    let mid = (0.5 * (l.0 + r.0), 0.5 * (l.1 + r.1));
    let through_halves = HorizonLine {
        camera_roll_rad: roll,
        offset: nx * mid.0 + ny * mid.1,
    };
    let near_whole = |e: Edge| libm::fabsf(e.offset_px - whole.offset_px) <= 3.0;
    if near_whole(left_edge) && near_whole(right_edge) && libm::fabsf(change) <= MAX_ROLL_CHANGE {
        placement.halves = Halves::Confirmed;
        return (through_halves, placement, None);
    }
    placement.halves = if libm::fabsf(change) > MAX_ROLL_CHANGE {
        Halves::Contradicted
    } else {
        Halves::Apart
    };
    let turn = (libm::fabsf(change) <= MAX_TURN).then_some(through_halves);
    (shifted, placement, turn)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A longer read taken from a shorter one's walk is the longer read taken afresh, to the
    /// bit: on distorted and undistorted cameras, frames read every column and every other,
    /// lines crossing the frame and lines leaving it (crossings out of the shorter reach,
    /// where the walk must refuse).
    #[test]
    fn a_longer_read_from_the_shorter_ones_walk_is_the_longer_read() {
        let (mut extended, mut refused) = (0, 0);
        for (width, height) in [(200usize, 150usize), (320, 240)] {
            let data: std::vec::Vec<u8> = (0..width * height * 3)
                .map(|i| ((i * 2_654_435_761usize) >> 11) as u8)
                .collect();
            let frame = Frame::rgb(width, height, &data).expect("frame");
            for k1 in [0.0f32, -0.25] {
                let mut camera = Camera::ideal(width as u32, height as u32, 1.1);
                camera.k1 = k1;
                camera.k2 = 0.05 * k1;
                for roll_deg in [-60.0f32, -20.0, -3.0, 0.0, 0.4, 11.0, 35.0, 80.0, 150.0] {
                    for offset in [-0.5f32, -0.3, -0.05, 0.0, 0.12, 0.38, 0.6] {
                        let line = HorizonLine {
                            camera_roll_rad: roll_deg.to_radians(),
                            offset,
                        };
                        let sc = (
                            libm::sinf(line.camera_roll_rad),
                            libm::cosf(line.camera_roll_rad),
                        );
                        let along_columns =
                            libm::fabsf(sc.1 * camera.fx) >= libm::fabsf(sc.0 * camera.fy);
                        for (short, long) in [
                            ((10.0f32, 6.0f32), (27.0f32, 6.0f32)),
                            ((5.0, 3.0), (40.0, 9.0)),
                            ((12.0, 6.0), (12.0, 6.0)),
                        ] {
                            let mut walk = Walk::new();
                            let read = read_halves(
                                &frame,
                                &camera,
                                line,
                                sc,
                                along_columns,
                                (short, None),
                                &mut walk,
                            );
                            let Some(from_walk) =
                                extend_halves(&frame, &camera, along_columns, &walk, &read, long)
                            else {
                                refused += 1;
                                continue;
                            };
                            let mut fresh_walk = Walk::new();
                            let fresh = read_halves(
                                &frame,
                                &camera,
                                line,
                                sc,
                                along_columns,
                                (long, None),
                                &mut fresh_walk,
                            );
                            assert_eq!(
                                from_walk, fresh,
                                "{width}x{height}, k1 {k1}, roll {roll_deg}°, offset {offset}, {short:?} -> {long:?}"
                            );
                            assert!(fresh.1 >= read.1);
                            extended += 1;
                        }
                    }
                }
            }
        }
        // Both ways were taken: most lines from the walk, lines leaving the frame afresh.
        assert!(
            extended > 200 && refused > 10,
            "extended {extended}, refused {refused}"
        );
    }

    /// A shorter reach than the walk's, or a walk past its kept columns, is read afresh.
    #[test]
    fn a_walk_is_not_extended_to_a_shorter_reach() {
        let data = [128u8; 64 * 48];
        let frame = Frame::grey(64, 48, &data).expect("frame");
        let camera = Camera::ideal(64, 48, 1.0);
        let line = HorizonLine {
            camera_roll_rad: 0.0,
            offset: 0.0,
        };
        let mut walk = Walk::new();
        let read = read_halves(
            &frame,
            &camera,
            line,
            (0.0, 1.0),
            true,
            ((10.0, 5.0), None),
            &mut walk,
        );
        assert!(read.1 > 0);
        assert!(extend_halves(&frame, &camera, true, &walk, &read, (10.0, 5.0)).is_some());
        assert!(extend_halves(&frame, &camera, true, &walk, &read, (9.0, 5.0)).is_none());
        assert!(extend_halves(&frame, &camera, true, &walk, &read, (10.0, 4.0)).is_none());
        walk.complete = false;
        assert!(extend_halves(&frame, &camera, true, &walk, &read, (20.0, 5.0)).is_none());
    }

    /// The line through two pixels, the ground below it.
    fn through(camera: &Camera, (u0, v0): (f32, f32), (u1, v1): (f32, f32)) -> HorizonLine {
        let p = |u: f32, v: f32| ((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy);
        let (a, b) = (p(u0, v0), p(u1, v1));
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let n = libm::sqrtf(dx * dx + dy * dy);
        let (nx, ny) = (-dy / n, dx / n);
        let (nx, ny) = if ny < 0.0 { (-nx, -ny) } else { (nx, ny) };
        HorizonLine {
            camera_roll_rad: libm::atan2f(nx, ny),
            offset: nx * a.0 + ny * a.1,
        }
    }

    /// A level horizon on row 240 of a 640×480 frame, a faint step (170 over 155), with the
    /// sun's bloom clipping the frame's left third down to a slanted end under the horizon
    /// (30 px under it at the left edge, on it at column 200). The Hough line given is pulled
    /// down at the left, as the bloom's end pulls it: 1.9° of roll out. Read where the sky is
    /// clear, the line is the horizon; the same frame without the bloom reads the same.
    #[test]
    fn a_line_pulled_by_the_suns_bloom_is_read_where_the_sky_is_clear() {
        let (w, h) = (640usize, 480usize);
        let camera = Camera::ideal(w as u32, h as u32, 60f32.to_radians());
        let render = |bloom: bool| -> std::vec::Vec<u8> {
            (0..w * h)
                .map(|i| {
                    let (u, v) = ((i % w) as f32, (i / w) as f32);
                    let clip_end = 240.0 + 30.0 * (200.0 - u) / 200.0;
                    if bloom && u < 200.0 && v < clip_end {
                        255
                    } else if v < 240.0 {
                        170
                    } else {
                        155
                    }
                })
                .collect()
        };
        let pulled = through(&camera, (0.0, 261.0), (639.0, 240.0 - 0.034 * 439.0));
        let truth = through(&camera, (0.0, 239.5), (639.0, 239.5));
        let search_px = 15.0;
        for bloom in [true, false] {
            let data = render(bloom);
            let frame = Frame::grey(w, h, &data).expect("frame");
            let (placed, placement) = place(&frame, &camera, pulled, search_px, true);
            let roll_error = (placed.camera_roll_rad - truth.camera_roll_rad).to_degrees();
            let offset_error_px = (placed.offset - truth.offset) * camera.fy;
            assert!(
                roll_error.abs() < 0.2 && offset_error_px.abs() < 1.0,
                "bloom {bloom}: roll {roll_error:.2}° and {offset_error_px:.2} px out ({placement:?})"
            );
            assert_eq!(placement.clear_of_glare, bloom, "{placement:?}");
            if bloom {
                // The bloom's clipping stays in what was measured, for the confidence.
                assert!(placement.clipped_sky >= GLARE_CLIPPED_SKY, "{placement:?}");
            }
        }
    }
}
