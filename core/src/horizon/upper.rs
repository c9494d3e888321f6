//! The highest sky/ground step above a chosen line, found on a profile across it rather than by
//! edge points.
//!
//! A strong ground edge (a wood's border, a shore, a field edge) out-votes a hazy horizon
//! above it. Where the horizon's step is only 10–20 levels, its gradient at the working
//! resolution falls under the edge threshold (which the strong edge and the ground's texture
//! set) along most of its length, so it draws too few edge points to be a Hough candidate or
//! to pass [`super::higher_edge`]'s coverage test (measured on `synth` `ground-edge` frames:
//! 22–30 votes, 0.2 of its length). Averaged along the line, every pixel of the band counts: a
//! step of a few levels stands out of a mean over a hundred pixels.

use super::camera::Camera;
use super::edges::{MAX_WORKING_WIDTH, Working};
use super::grid::UndistortedGrid;
use super::hough::Line;

/// Profile bins, one working pixel (one rho step) each ...
const BINS: usize = 72;
/// ... of which this many lie on the ground side of the chosen line.
const BELOW: usize = 4;
/// Bins averaged either side of a step.
const SIDE: usize = 2;
/// A step must be at least this many levels ...
const MIN_STEP_LEVELS: f32 = 4.0;
/// ... and this many times its own standard error.
const MIN_STEP_SIGNIFICANCE: f32 = 6.0;
/// Columns between the points undistorted exactly on a distorted camera's rows.
const KNOT: usize = 16;
/// Knots a [`Knots`] keeps along a row: every [`KNOT`]th column of the widest working image,
/// and its last column ...
const KNOT_COLUMNS: usize = MAX_WORKING_WIDTH.div_ceil(KNOT) + 1;
/// ... on every other row of a working image up to twice this many rows tall (a 4:3 frame's
/// is at most 150; a taller one has its lower rows' knots undistorted each time).
const KNOT_ROWS: usize = 128;
/// Polarity changes of clear steps on the sky side that make it striped.
const STRIPE_ALTERNATIONS: usize = 3;
/// A step of the other polarity this strong (a share of the found one's) between the chosen
/// line and the found step rejects it.
const OPPOSITE_SHARE: f32 = 0.5;
/// Share of its rise the profile may fall back within one transition ...
const TRANSITION_FALL: f32 = 0.25;
/// ... and share of its largest step that its top step must have.
const TOP_SHARE: f32 = 0.5;
/// The first bins above the chosen line belong to its own (smoothed) transition.
const CLEAR_OF_CHOSEN: usize = 4;

#[derive(Clone, Copy, Default)]
struct Bin {
    n: f32,
    sum: f32,
    sum2: f32,
}

impl Bin {
    fn plus(self, o: Bin) -> Bin {
        Bin {
            n: self.n + o.n,
            sum: self.sum + o.sum,
            sum2: self.sum2 + o.sum2,
        }
    }

    fn mean(&self) -> f32 {
        self.sum / self.n.max(1.0)
    }

    /// Squared standard error of the mean.
    fn error2(&self) -> f32 {
        if self.n < 2.0 {
            return f32::INFINITY;
        }
        let mean = self.mean();
        let variance = (self.sum2 / self.n - mean * mean).max(0.0);
        // A floor of one level: the 8-bit quantisation of each pixel.
        (variance + 1.0) / self.n
    }
}

/// Adds pixels to the bins, holding the bin being filled in registers: along a row the
/// pixels fall in one bin for many columns, and adding each through memory made every add
/// wait for the one before. The same additions in the same order as adding in place.
struct Filling<'a> {
    bins: &'a mut [Bin; BINS],
    open: Option<(usize, Bin)>,
}

impl Filling<'_> {
    #[inline]
    fn add(&mut self, index: usize, value: u8) {
        let value = f32::from(value);
        let bin = match &mut self.open {
            Some((open, bin)) if *open == index => bin,
            _ => {
                self.close();
                let Some(&start) = self.bins.get(index) else {
                    return;
                };
                &mut self.open.insert((index, start)).1
            }
        };
        bin.n += 1.0;
        bin.sum += value;
        bin.sum2 += value * value;
    }

    /// Writes the open bin back.
    fn close(&mut self) {
        if let Some((index, bin)) = self.open.take()
            && let Some(slot) = self.bins.get_mut(index)
        {
            *slot = bin;
        }
    }
}

/// A bin's pixel count, luma sum and sum of squares in integers (see [`Profile::measure`]).
#[derive(Clone, Copy, Default)]
struct WholeBin {
    n: u32,
    sum: u32,
    sum2: u64,
}

impl WholeBin {
    /// Whether adding the bin's whole numbers in f32 one by one never rounded: every
    /// partial sum was at most 2^24.
    fn exact_in_f32(&self) -> bool {
        const EXACT: u64 = 1 << 24;
        u64::from(self.n) <= EXACT && u64::from(self.sum) <= EXACT && self.sum2 <= EXACT
    }
}

/// The undistorted positions of [`each_pixel`]'s knots on a distorted camera, kept from frame
/// to frame (see [`UndistortedGrid`]): a frame measures a dozen profiles (a ridge is looked
/// for over 13 turns), and undistorting the knots again for each took about 7 % of the
/// detector's time at 320×240 (`perf record` over the `aerial` seeds' 320 px sets: 8 % of its
/// samples in the undistortion, four fifths of them from here).
pub(crate) struct Knots {
    grid: UndistortedGrid<{ KNOT_COLUMNS * KNOT_ROWS }>,
    /// The working image's last column, the last knot of a row.
    last_column: usize,
}

impl Knots {
    pub(crate) const fn new() -> Self {
        Knots {
            grid: UndistortedGrid::new(),
            last_column: 0,
        }
    }

    /// Undistorts the knots for `camera` and `geo`, unless they are already: every
    /// [`KNOT`]th column and the last, on every other row.
    pub(crate) fn prepare(&mut self, camera: &Camera, geo: Working) {
        let last = geo.width.saturating_sub(1);
        self.last_column = last;
        let columns = (last.div_ceil(KNOT) + 1, |i: usize| (i * KNOT).min(last));
        let rows = (geo.height.div_ceil(2), |j: usize| 2 * j);
        self.grid.prepare(camera, geo, columns, rows);
    }

    /// The knot at `(wx, wy)` if it is kept: `Some` of what [`Camera::undistort_pixel`]
    /// gives there.
    #[inline]
    fn get(&self, wx: usize, wy: usize) -> Option<Option<(f32, f32)>> {
        let index = wx.div_ceil(KNOT);
        if wy % 2 != 0 || (index * KNOT).min(self.last_column) != wx {
            return None;
        }
        self.grid.get(index, wy / 2)
    }

    /// These knots if they were undistorted for `camera` and `geo`.
    fn for_view(&self, camera: &Camera, geo: Working) -> Option<&Knots> {
        self.grid.for_view(camera, geo).map(|_| self)
    }
}

/// Calls `add(bin, luma)` for every working pixel whose distance from `chosen` falls in the
/// profile's bins (from [`BELOW`] bins on its ground side to `reach` + [`SIDE`] on its sky
/// side, `sky_ward` and `rho_step` as in [`Profile::measure`]), row by row, in the order the
/// bins' sums are taken. With a `floor` (a line and a margin in rho steps), only pixels at
/// least that far on the sky side of the floor line count, and only every other row is read
/// (see [`Profile::measure_above`]).
fn each_pixel(
    grey: &[u8],
    geo: Working,
    (camera, knots): (&Camera, &Knots),
    (chosen, sky_ward, rho_step, reach): (Line, f32, f32, usize),
    floor: Option<(Line, f32)>,
    mut add: impl FnMut(usize, u8),
) {
    let (nx, ny) = chosen.normal();
    let inverse = sky_ward / rho_step;
    let low = -(BELOW as f32);
    let high = (reach + SIDE) as f32;
    let mut add = |s: f32, value: u8| {
        if !(low..high).contains(&s) {
            return;
        }
        // `s − low` is not negative: through i32, the cheap conversion.
        add((s - low) as i32 as usize, value);
    };
    // The floor's distance in rho steps, sky-ward positive, and the least it may be (a
    // floor at minus infinity lets every pixel through).
    let (floor_line, floor_margin) = floor.unwrap_or((chosen, f32::NEG_INFINITY));
    let (fnx, fny) = floor_line.normal();
    let row_step = if floor.is_some() { 2 } else { 1 };
    let rows = grey
        .chunks_exact(geo.width.max(1))
        .take(geo.height)
        .enumerate();
    if camera.k1 != 0.0 || camera.k2 != 0.0 {
        // Undistorting every pixel cost more than the rest of the detector (0.65 ms a
        // frame at 320×240): the bin is smooth along a row, so it is undistorted at knots
        // [`KNOT`] columns apart and interpolated, on every other row.
        let knots = knots.for_view(camera, geo);
        for (wy, row) in rows.step_by(2 * row_step) {
            let undistorted = |wx: usize| {
                knots.and_then(|k| k.get(wx, wy)).unwrap_or_else(|| {
                    let (u, v) = geo.to_frame(wx as f32, wy as f32);
                    camera.undistort_pixel(u, v)
                })
            };
            let bin_at = |wx: usize| {
                undistorted(wx).map(|(x, y)| {
                    (
                        (x * nx + y * ny - chosen.rho) * inverse,
                        (x * fnx + y * fny - floor_line.rho) * inverse,
                    )
                })
            };
            let mut a = 0usize;
            let mut at_a = bin_at(0);
            while a + 1 < row.len() {
                let b = (a + KNOT).min(row.len() - 1);
                let at_b = bin_at(b);
                // Between two knots a pixel's bin and its height over the floor lie between
                // the knots' (up to rounding, far under a bin): a stretch whose knots are both
                // out of the band on one side, or both under the floor, by more than a bin
                // holds no pixel that counts, and is passed over without testing each one.
                let counts = |(sa, fa): (f32, f32), (sb, fb): (f32, f32)| {
                    let out_of_band = sa.max(sb) < low - 1.0 || sa.min(sb) >= high + 1.0;
                    let under_floor = fa.max(fb) < floor_margin - 1.0;
                    !(out_of_band || under_floor)
                };
                if let (Some((sa, fa)), Some((sb, fb))) = (at_a, at_b)
                    && counts((sa, fa), (sb, fb))
                {
                    let slope = (sb - sa) / (b - a) as f32;
                    let floor_slope = (fb - fa) / (b - a) as f32;
                    for (i, &value) in row.get(a..b).unwrap_or(&[]).iter().enumerate() {
                        if fa + i as f32 * floor_slope >= floor_margin {
                            add(sa + i as f32 * slope, value);
                        }
                    }
                }
                a = b;
                at_a = at_b;
            }
        }
        return;
    }
    // Without distortion the bin is linear in the pixel: one add per pixel, and only
    // over the columns whose bin is in range (a band across the frame) and that are above
    // the floor; a column either side of the computed range, and the test in `add`, absorb
    // rounding (a pixel at the floor's margin may count or not).
    let along_row = nx * geo.scale as f32 / camera.fx * inverse;
    let floor_along_row = fnx * geo.scale as f32 / camera.fx * inverse;
    // The columns of a row (its first column's value `start`, `per_column` more each
    // column) whose value lies in `low..high`.
    let within = |start: f32, per_column: f32, (low, high): (f32, f32), width: usize| {
        if libm::fabsf(per_column) < 1e-6 {
            if (low..high).contains(&start) {
                0..width
            } else {
                0..0
            }
        } else {
            let (a, b) = ((low - start) / per_column, (high - start) / per_column);
            let (first, last) = (a.min(b) - 1.0, a.max(b) + 1.0);
            let w = width as f32;
            (first.clamp(0.0, w) as usize)..(last.clamp(0.0, w) as usize)
        }
    };
    for (wy, row) in rows.step_by(row_step) {
        let (u0, v) = geo.to_frame(0.0, wy as f32);
        let row_start = ((u0 - camera.cx) / camera.fx * nx + (v - camera.cy) / camera.fy * ny
            - chosen.rho)
            * inverse;
        let mut columns = within(row_start, along_row, (low, high), row.len());
        if floor.is_some() {
            let floor_start = ((u0 - camera.cx) / camera.fx * fnx
                + (v - camera.cy) / camera.fy * fny
                - floor_line.rho)
                * inverse;
            // The columns at least the margin above the floor, to the column.
            let width = row.len() as f32;
            let inside = if libm::fabsf(floor_along_row) < 1e-6 {
                if floor_start >= floor_margin {
                    0..row.len()
                } else {
                    0..0
                }
            } else {
                let edge = (floor_margin - floor_start) / floor_along_row;
                if floor_along_row > 0.0 {
                    (libm::ceilf(edge).clamp(0.0, width) as usize)..row.len()
                } else {
                    0..((libm::floorf(edge) + 1.0).clamp(0.0, width) as usize)
                }
            };
            columns = columns.start.max(inside.start)..columns.end.min(inside.end);
        }
        let start = columns.start;
        for (i, &value) in row.get(columns).unwrap_or(&[]).iter().enumerate() {
            // Through u32: the same value (a column index) without the unsigned 64-bit
            // conversion's fix-ups.
            add(row_start + (start + i) as u32 as f32 * along_row, value);
        }
    }
}

/// The profile's rise above a line's own transition ([`Profile::rise_above`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct RiseAbove {
    /// How far above the line the rise ends (normalised units).
    pub reach: f32,
    /// Levels it rises by.
    pub rise: f32,
    /// Levels the profile rose by across the line itself.
    pub across: f32,
}

impl RiseAbove {
    /// A rise of at least [`MIN_STEP_LEVELS`] that reaches `extent` above the line.
    pub(crate) fn reaches(&self, extent: f32) -> bool {
        self.rise >= MIN_STEP_LEVELS && self.reach >= extent
    }

    /// More rise above the line than across it.
    pub(crate) fn exceeds_the_step(&self) -> bool {
        self.rise >= self.across
    }
}

/// Bins either side of a ridge's top its prominence is measured at.
const RIDGE_FLANK: usize = 4;

/// The top of a ridge in a profile: the sky's glow meeting the ground's haze.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Ridge {
    pub line: Line,
    pub prominence: f32,
}

/// A step found above the chosen line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Step {
    /// The line through the step (the chosen line's direction).
    pub line: Line,
    /// Levels from the ground side to the sky side.
    pub contrast: f32,
}

/// Mean luma across a line, one bin per rho step, from [`BELOW`] bins on its ground side to
/// its reach on the sky side, on the working image.
pub(crate) struct Profile {
    bins: [Bin; BINS],
    reach: usize,
    /// +1 when the sky is on the line's normal's side, −1 otherwise.
    sky_ward: f32,
    line: Line,
    rho_step: f32,
}

impl Profile {
    /// The profile across `chosen` (normal towards the brighter side, as the Hough stage's)
    /// up to `reach_bins` rho steps on its sky side, `sky_ward` (±1) saying which side that is.
    pub(crate) fn measure(
        grey: &[u8],
        geo: Working,
        view: (&Camera, &Knots),
        chosen: Line,
        sky_ward: f32,
        rho_step: f32,
        reach_bins: usize,
    ) -> Profile {
        Self::measure_over(
            grey,
            geo,
            view,
            (chosen, sky_ward, rho_step, reach_bins),
            None,
        )
    }

    /// As [`Profile::measure`], of only the pixels at least `margin` rho steps on the sky
    /// side of `floor`, on every other row: the profile across a line turned from `floor`
    /// reads the band above `floor` without the ground below it, and a ridge, a change over
    /// several bins, is found as well on half the pixels.
    pub(crate) fn measure_above(
        grey: &[u8],
        geo: Working,
        view: (&Camera, &Knots),
        (line, sky_ward, rho_step, reach_bins): (Line, f32, f32, usize),
        (floor, margin): (Line, f32),
    ) -> Profile {
        let band = (line, sky_ward, rho_step, reach_bins);
        Self::measure_over(grey, geo, view, band, Some((floor, margin)))
    }

    fn measure_over(
        grey: &[u8],
        geo: Working,
        view: (&Camera, &Knots),
        (chosen, sky_ward, rho_step, reach_bins): (Line, f32, f32, usize),
        floor: Option<(Line, f32)>,
    ) -> Profile {
        let reach = reach_bins.min(BINS - BELOW - SIDE);
        let mut profile = Profile {
            bins: [Bin::default(); BINS],
            reach,
            sky_ward,
            line: chosen,
            rho_step,
        };
        if rho_step.is_nan() || rho_step <= 0.0 {
            return profile;
        }
        // Counts, sums and sums of squares in integers first. Adding whole numbers in f32 one
        // at a time is exact while every partial sum is at most 2^24, so where each bin's
        // totals are, they are the f32 sums to the bit, without each add waiting on the one
        // before. A bin holds about one working row's length of pixels (a sum of squares near
        // 2^24 takes 258 pixels at 255); where a total is over, the f32 sums are taken as
        // they always were.
        let mut whole = [WholeBin::default(); BINS];
        let band = (chosen, sky_ward, rho_step, reach);
        each_pixel(grey, geo, view, band, floor, |index, value| {
            if let Some(bin) = whole.get_mut(index) {
                let value = u32::from(value);
                bin.n += 1;
                bin.sum += value;
                bin.sum2 += u64::from(value * value);
            }
        });
        if whole.iter().all(WholeBin::exact_in_f32) {
            for (bin, whole) in profile.bins.iter_mut().zip(&whole) {
                *bin = Bin {
                    n: whole.n as f32,
                    sum: whole.sum as f32,
                    sum2: whole.sum2 as f32,
                };
            }
            return profile;
        }
        let mut filling = Filling {
            bins: &mut profile.bins,
            open: None,
        };
        each_pixel(grey, geo, view, band, floor, |index, value| {
            filling.add(index, value)
        });
        filling.close();
        profile
    }

    /// The step at bin boundary `k`: its contrast (positive for the sky's polarity) and
    /// that contrast over its standard error.
    fn step_at(&self, k: usize) -> Option<(f32, f32)> {
        let polarity = if self.sky_ward > 0.0 { 1.0 } else { -1.0 };
        let side = |from: usize| {
            self.bins
                .get(from..from + SIDE)
                .map(|b| b.iter().fold(Bin::default(), |a, &x| a.plus(x)))
        };
        let (ground, sky) = (side(k.checked_sub(SIDE)?)?, side(k)?);
        if ground.n < 8.0 || sky.n < 8.0 {
            return None;
        }
        let contrast = polarity * (sky.mean() - ground.mean());
        let error = libm::sqrtf(ground.error2() + sky.error2());
        Some((contrast, contrast / error))
    }

    /// The brightest bin of the sky's polarity above the chosen line (from
    /// [`CLEAR_OF_CHOSEN`] bins over it), with its prominence: how far the profile falls from
    /// it within [`RIDGE_FLANK`] bins either way (the lesser of the two falls).
    pub(crate) fn ridge(&self) -> Option<Ridge> {
        let first = BELOW + CLEAR_OF_CHOSEN;
        let last = BELOW + self.reach;
        let (peak, top) = (first..=last)
            .filter_map(|i| Some((i, self.level(i)?)))
            .max_by(|a, b| a.1.total_cmp(&b.1))?;
        let flank = |i: Option<usize>| i.and_then(|i| self.level(i));
        let below = flank(peak.checked_sub(RIDGE_FLANK))?;
        let above = flank(Some(peak + RIDGE_FLANK))?;
        Some(Ridge {
            line: self.line_at(peak),
            prominence: (top - below).min(top - above),
        })
    }

    /// The line of the profile's direction through bin boundary `bin`.
    fn line_at(&self, bin: usize) -> Line {
        let offset = (bin as f32 - BELOW as f32) * self.rho_step;
        Line {
            angle: self.line.angle,
            rho: self.line.rho + self.sky_ward * offset,
        }
    }

    /// Bin `i`'s mean, sky's polarity up (brighter towards a brighter sky); `None` for a bin
    /// with too few pixels to say.
    fn level(&self, i: usize) -> Option<f32> {
        let polarity = if self.sky_ward > 0.0 { 1.0 } else { -1.0 };
        self.bins
            .get(i)
            .filter(|b| b.n >= 8.0)
            .map(|b| polarity * b.mean())
    }

    /// Walking sky-ward from bin `start` while the profile (sky side up) does not fall back
    /// by [`TRANSITION_FALL`] of what it rose: the last bin of that transition, and how far
    /// it rose.
    fn transition_from(&self, start: usize) -> Option<(usize, f32)> {
        let first = self.level(start)?;
        let mut high = first;
        let mut end = start;
        while end < BELOW + self.reach {
            let Some(v) = self.level(end + 1) else {
                break;
            };
            high = high.max(v);
            if v < high - (TRANSITION_FALL * (high - first)).max(MIN_STEP_LEVELS) {
                break;
            }
            end += 1;
        }
        Some((end, high - first))
    }

    /// Whether the profile keeps rising above the chosen line's own transition (past its
    /// first [`CLEAR_OF_CHOSEN`]` / 2` bins) by a step's worth ([`MIN_STEP_LEVELS`]): the line
    /// lies on a ramp, and the horizon may be at its top. Above a horizon's step the sky is
    /// level or darkens away from its glow.
    pub(crate) fn rises_above(&self) -> bool {
        self.transition_from(BELOW + CLEAR_OF_CHOSEN / 2)
            .is_some_and(|(_, rise)| rise >= MIN_STEP_LEVELS)
    }

    /// The rise above the line's own transition (from [`BELOW`] bins under it to
    /// [`CLEAR_OF_CHOSEN`]` / 2` above it), in a transition (see [`Profile::transition_from`]).
    pub(crate) fn rise_above(&self) -> Option<RiseAbove> {
        let own_top = BELOW + CLEAR_OF_CHOSEN / 2;
        let ((end, rise), top, foot) = (
            self.transition_from(own_top)?,
            self.level(own_top)?,
            self.level(0)?,
        );
        Some(RiseAbove {
            reach: end.saturating_sub(BELOW) as f32 * self.rho_step,
            rise,
            across: top - foot,
        })
    }

    /// Whether the line lies at the foot of a ramp rather than on a step: above the line's
    /// own transition the profile rises by more than it rose across the line, in a transition
    /// that reaches at least `extent` (normalised units) above the line (see [`RiseAbove`]).
    /// Under haze in dim light the ground's ramp up to the airlight is the steepest part of
    /// the profile at the working resolution and the horizon's small step at its top is lost
    /// in the noise. Above a real horizon the sky may go on brightening for as far, but by
    /// less than the horizon's own step.
    pub(crate) fn at_foot_of_ramp(&self, extent: f32) -> bool {
        self.rise_above()
            .is_some_and(|rise| rise.reaches(extent) && rise.exceeds_the_step())
    }

    /// Whether the sky side is striped: clear steps of alternating polarity, at least
    /// [`STRIPE_ALTERNATIONS`] changes. A periodic pattern nearly parallel to the horizon
    /// (interference) puts its crests next to the horizon, where they out-explain it and
    /// the line found is one of them; the sky above a real horizon has no such steps.
    pub(crate) fn striped(&self) -> bool {
        let mut last_sign = 0.0f32;
        let mut alternations = 0;
        let mut k = BELOW + CLEAR_OF_CHOSEN;
        while k <= BELOW + self.reach {
            match self.step_at(k) {
                Some((c, sig))
                    if libm::fabsf(c) >= MIN_STEP_LEVELS
                        && libm::fabsf(sig) >= MIN_STEP_SIGNIFICANCE =>
                {
                    let sign = if c > 0.0 { 1.0 } else { -1.0 };
                    if sign != last_sign {
                        if last_sign != 0.0 {
                            alternations += 1;
                        }
                        last_sign = sign;
                    }
                    // One step counts once: skip past its window.
                    k += SIDE;
                }
                _ => k += 1,
            }
        }
        alternations >= STRIPE_ALTERNATIONS
    }

    /// The top of the transition the line lies in (a line found by regions splits it in its
    /// middle: under haze, mid-ramp): walking sky-ward while the profile does not fall back
    /// by [`TRANSITION_FALL`] of what it rose (a plateau of airlight is crossed), the sky-most
    /// clear step of the sky's polarity with at least [`TOP_SHARE`] of the walk's largest.
    /// `None` when there is none above the line.
    pub(crate) fn top_of_transition(&self) -> Option<Line> {
        let (end, _) = self.transition_from(BELOW)?;
        let mut largest = 0.0f32;
        let clear = |k: usize| {
            self.step_at(k).filter(|&(contrast, significance)| {
                contrast >= MIN_STEP_LEVELS && significance >= MIN_STEP_SIGNIFICANCE
            })
        };
        for k in BELOW - 1..=end {
            if let Some((contrast, _)) = clear(k) {
                largest = largest.max(contrast);
            }
        }
        let top = (BELOW - 1..=end)
            .rev()
            .find(|&k| clear(k).is_some_and(|(c, _)| c >= TOP_SHARE * largest))?;
        Some(self.line_at(top))
    }

    /// The sky-most step of the sky's polarity within the reach above the line.
    pub(crate) fn highest_step(&self) -> Option<Step> {
        let first = BELOW + CLEAR_OF_CHOSEN;
        let mut k = BELOW + self.reach;
        while k >= first {
            if let Some((contrast, significance)) = self.step_at(k)
                && contrast >= MIN_STEP_LEVELS
                && significance >= MIN_STEP_SIGNIFICANCE
            {
                // The sharpest boundary of this step, within a bin or two.
                let mut best = (k, contrast);
                for j in k.saturating_sub(2)..=k + 2 {
                    if let Some((c, _)) = self.step_at(j)
                        && c > best.1
                    {
                        best = (j, c);
                    }
                }
                // One transition from ground to sky: a band with a step of the other
                // polarity as strong as half of this one is not ground under the sky but a
                // stripe, a cloud or a bar (a dark band in the sky has a step of the sky's
                // polarity at its top). Only below the step: the sky itself darkens away
                // from the horizon.
                let opposite = (first..=best.0.saturating_sub(SIDE)).any(|j| {
                    self.step_at(j).is_some_and(|(c, sig)| {
                        -c >= MIN_STEP_LEVELS.max(OPPOSITE_SHARE * best.1)
                            && -sig >= MIN_STEP_SIGNIFICANCE
                    })
                });
                if opposite {
                    return None;
                }
                return Some(Step {
                    line: self.line_at(best.0),
                    contrast: best.1,
                });
            }
            k -= 1;
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A level line (normal up, so the sky is on its normal's side) between working rows 59
    /// and 60 of a 160×120 working image binned from 320×240, and the profile across it of
    /// an image with ground at 100 under the line and the level `above(k)` in the `k`th row
    /// above it (`k` = 0 for row 59).
    fn profile_over_ground(above: impl Fn(usize) -> f32) -> Profile {
        let geo = Working {
            scale: 2,
            width: 160,
            height: 120,
        };
        let camera = Camera::ideal(320, 240, 60f32.to_radians());
        let grey: std::vec::Vec<u8> = (0..geo.width * geo.height)
            .map(|i| {
                let r = i / geo.width;
                let level = if r >= 60 { 100.0 } else { above(59 - r) };
                level.round() as u8
            })
            .collect();
        let line = Line {
            angle: core::f32::consts::PI,
            rho: 0.0,
        };
        let rho_step = geo.scale as f32 / camera.fy;
        Profile::measure(
            &grey,
            geo,
            (&camera, &Knots::new()),
            line,
            1.0,
            rho_step,
            37,
        )
    }

    /// The distorted camera's profile as it was read before knots were kept and stretches
    /// passed over: every knot undistorted where it is needed, every pixel tested. Counts,
    /// sums and sums of squares of each bin.
    fn distorted_profile_pixel_by_pixel(
        grey: &[u8],
        geo: Working,
        camera: &Camera,
        (chosen, sky_ward, rho_step, reach): (Line, f32, f32, usize),
        floor: Option<(Line, f32)>,
    ) -> [(u64, u64, u64); BINS] {
        let mut bins = [(0u64, 0u64, 0u64); BINS];
        let (nx, ny) = chosen.normal();
        let inverse = sky_ward / rho_step;
        let (low, high) = (-(BELOW as f32), (reach + SIDE) as f32);
        let (floor_line, margin) = floor.unwrap_or((chosen, f32::NEG_INFINITY));
        let (fnx, fny) = floor_line.normal();
        let row_step = if floor.is_some() { 4 } else { 2 };
        for wy in (0..geo.height).step_by(row_step) {
            let at = |wx: usize| {
                let (u, v) = geo.to_frame(wx as f32, wy as f32);
                camera.undistort_pixel(u, v).map(|(x, y)| {
                    (
                        (x * nx + y * ny - chosen.rho) * inverse,
                        (x * fnx + y * fny - floor_line.rho) * inverse,
                    )
                })
            };
            let mut a = 0;
            while a + 1 < geo.width {
                let b = (a + KNOT).min(geo.width - 1);
                if let (Some((sa, fa)), Some((sb, fb))) = (at(a), at(b)) {
                    let slope = (sb - sa) / (b - a) as f32;
                    let floor_slope = (fb - fa) / (b - a) as f32;
                    for i in 0..b - a {
                        let s = sa + i as f32 * slope;
                        if fa + i as f32 * floor_slope >= margin && (low..high).contains(&s) {
                            let v = u64::from(grey[wy * geo.width + a + i]);
                            let bin = &mut bins[(s - low) as i32 as usize];
                            *bin = (bin.0 + 1, bin.1 + v, bin.2 + v * v);
                        }
                    }
                }
                a = b;
            }
        }
        bins
    }

    #[test]
    fn a_distorted_profile_from_kept_knots_is_the_profile_pixel_by_pixel() {
        let mut camera = Camera::ideal(320, 240, 70f32.to_radians());
        (camera.k1, camera.k2) = (-0.28, 0.06);
        let other_camera = Camera { k1: 0.12, ..camera };
        let geo = Working::for_frame(320, 240);
        let grey: std::vec::Vec<u8> = (0..geo.width * geo.height)
            .map(|i| ((i * 2_654_435_761usize) >> 13) as u8)
            .collect();
        let rho_step = geo.scale as f32 / camera.fy;
        let mut kept = Knots::new();
        kept.prepare(&camera, geo);
        // Kept for another camera: not used for this one.
        let mut stale = Knots::new();
        stale.prepare(&other_camera, geo);
        assert!(stale.for_view(&camera, geo).is_none());
        assert!(kept.for_view(&camera, geo).is_some());
        let none = Knots::new();
        let mut compared = 0;
        for angle_deg in [-179.0f32, -150.0, -95.0, 3.0, 25.0, 90.0, 178.5] {
            for rho in [-0.3f32, -0.02, 0.0, 0.17, 0.4] {
                for sky_ward in [1.0, -1.0] {
                    let line = Line {
                        angle: angle_deg.to_radians(),
                        rho,
                    };
                    let band = (line, sky_ward, rho_step, 45);
                    let floor = (
                        Line {
                            angle: line.angle + 0.1,
                            rho: rho - 0.05,
                        },
                        3.0,
                    );
                    for floor in [None, Some(floor)] {
                        let reference =
                            distorted_profile_pixel_by_pixel(&grey, geo, &camera, band, floor);
                        let views = [&kept, &none, &stale].map(|k| (&camera, k));
                        for view in views {
                            let profile = Profile::measure_over(&grey, geo, view, band, floor);
                            for (bin, &(n, sum, sum2)) in profile.bins.iter().zip(&reference) {
                                assert_eq!(
                                    (bin.n, bin.sum, bin.sum2),
                                    (n as f32, sum as f32, sum2 as f32),
                                    "{angle_deg}°, rho {rho}, sky-ward {sky_ward}, {floor:?}"
                                );
                            }
                            compared += reference.iter().filter(|b| b.0 > 0).count();
                        }
                    }
                }
            }
        }
        assert!(compared > 1000, "{compared} bins with pixels compared");
    }

    #[test]
    fn a_line_under_a_long_ramp_is_at_its_foot() {
        // Ground at 100, then 30 rows rising to an airlight of 150.
        let ramp = profile_over_ground(|k| 100.0 + 50.0 * (k + 1).min(30) as f32 / 30.0);
        assert!(ramp.at_foot_of_ramp(0.1));
    }

    #[test]
    fn a_horizon_step_under_a_sky_brightening_upwards_is_not() {
        // A step of 60 levels, then a sky half a level brighter each row up (as far as the
        // reach: 18 levels, less than the step).
        let step = profile_over_ground(|k| 160.0 + 0.5 * k as f32);
        assert!(step.rises_above());
        assert!(!step.at_foot_of_ramp(0.1));
    }

    #[test]
    fn a_band_of_hazy_ground_over_a_sharp_edge_rises_far_but_less_than_the_edge_steps() {
        // A sharp edge from the ground's 100 to 150, then a band of hazy far ground rising
        // 1.2 levels a row for 24 rows (about 10° at 320 px) up to 179, then a sky darkening
        // away from its glow: the rise above the line reaches the ramp's extent, but by less
        // than the edge stepped, so the line is not at the foot of a ramp by its levels alone
        // (`aerial` seed 140 `mixed`: the band's colour tells it, see `mod.rs`).
        let band = profile_over_ground(|k| {
            if k < 2 {
                150.0
            } else if k < 26 {
                150.0 + 1.2 * (k - 1) as f32
            } else {
                (179.0 - 3.0 * (k - 25) as f32).max(0.0)
            }
        });
        let rise = band.rise_above().expect("a rise above the edge");
        assert!(rise.reaches(0.1), "{rise:?}");
        assert!(!rise.exceeds_the_step(), "{rise:?}");
        assert!(!band.at_foot_of_ramp(0.1));
    }

    #[test]
    fn a_short_ramp_under_a_glowing_sky_is_not() {
        // Eight rows up to 180, then a sky darkening away from its glow, 4 levels a row: more
        // of the rise is above the line than across it, but the transition ends (falls back
        // by a quarter of its rise) about 4° above the line, short of the extent asked.
        let hazy_step = profile_over_ground(|k| {
            if k < 8 {
                100.0 + 80.0 * (k + 1) as f32 / 8.0
            } else {
                (180.0 - 4.0 * (k - 7) as f32).max(0.0)
            }
        });
        assert!(hazy_step.rises_above());
        assert!(!hazy_step.at_foot_of_ramp(0.1));
        assert!(hazy_step.at_foot_of_ramp(0.02));
    }
}
