//! Second half: Hough voting restricted by gradient direction, local maxima as candidates,
//! least-squares refinement, and sky/ground validation of each candidate.
//!
//! Lines are `sin a · x + cos a · y = rho` in normalised undistorted coordinates with `a` over
//! the full circle: the normal points to the brighter side, so the two edges of a stripe (and
//! the light and dark borders of a road) vote in different cells from each other.

use super::edges::{EdgePoint, Sample};

/// Angle bins over the full circle (1° each).
pub const ANGLE_BINS: usize = 360;
pub(crate) const ANGLE_STEP: f32 = 2.0 * core::f32::consts::PI / ANGLE_BINS as f32;

/// Wraps an angle to (−π, π].
#[inline]
pub(crate) fn wrap_angle(a: f32) -> f32 {
    use core::f32::consts::PI;
    let shifted = a + PI;
    // `fmodf` returns an argument smaller than the divisor in magnitude as it is, which is
    // nearly every angle here (differences of two wrapped angles); the call is left for the
    // rest (and NaN).
    let mut a = if libm::fabsf(shifted) < 2.0 * PI {
        shifted
    } else {
        libm::fmodf(shifted, 2.0 * PI)
    };
    if a < 0.0 {
        a += 2.0 * PI;
    }
    a - PI
}

/// `floor(x)`, bit for bit what `libm::floorf` returns, without its call (the angle bin of
/// every edge point took one; the profile's bins need no floor at all, see `profile::place`).
#[inline]
pub(crate) fn floor(x: f32) -> f32 {
    // Below 2^23 in magnitude the truncation to i32 and back is exact; beyond it (and for NaN
    // and infinities) every f32 is already whole, which libm handles.
    let magnitude = libm::fabsf(x);
    if magnitude.is_nan() || magnitude >= 8_388_608.0 {
        return libm::floorf(x);
    }
    // Truncation, one less where it went up (negative, not whole); without branches, as the
    // signs are random (angles). The floor has the sign of `x` (−0 for −0).
    let t = x as i32 as f32;
    let floor = t - f32::from(u8::from(t > x));
    f32::from_bits((floor.to_bits() & 0x7fff_ffff) | (x.to_bits() & 0x8000_0000))
}

/// Bin of an angle in radians (any value).
#[inline]
pub(crate) fn angle_bin(a: f32) -> usize {
    let b = floor(a / ANGLE_STEP + 0.5) as i64;
    b.rem_euclid(ANGLE_BINS as i64) as usize
}

/// The sin/cos tables of the angle bins.
pub(crate) struct Tables {
    pub sin: [f32; ANGLE_BINS],
    pub cos: [f32; ANGLE_BINS],
}

impl Tables {
    pub fn new() -> Self {
        let mut sin = [0.0; ANGLE_BINS];
        let mut cos = [0.0; ANGLE_BINS];
        for (i, (s, c)) in sin.iter_mut().zip(cos.iter_mut()).enumerate() {
            let a = i as f32 * ANGLE_STEP;
            *s = libm::sinf(a);
            *c = libm::cosf(a);
        }
        Tables { sin, cos }
    }
}

/// Quantisation of `rho`: `rho_half` bins either side of zero, `step` wide (normalised units).
#[derive(Clone, Copy, Debug)]
pub(crate) struct RhoAxis {
    pub step: f32,
    pub half: usize,
}

impl RhoAxis {
    pub fn bins(&self) -> usize {
        2 * self.half + 1
    }

    #[inline]
    pub fn index(&self, rho: f32) -> Option<usize> {
        let f = rho / self.step + self.half as f32 + 0.5;
        (f >= 0.0 && f < self.bins() as f32).then_some(f as usize)
    }

    pub fn value(&self, index: usize) -> f32 {
        (index as f32 - self.half as f32) * self.step
    }
}

/// Each point votes for the lines through it whose normal is within `window` bins of its
/// gradient direction: O(N·(2w+1)) instead of the O(N·T) of a plain Hough transform, and
/// noise, whose gradient directions are random, spreads its votes thin.
pub(crate) fn vote(
    edges: &[EdgePoint],
    tables: &Tables,
    rho: RhoAxis,
    window: usize,
    accumulator: &mut [u16],
) {
    accumulator.fill(0);
    // A point votes once in each of its window's angle bins, so no cell gets more votes than
    // there are points: below 65535 points (the workspace holds 16 per working pixel of
    // perimeter) the saturating add is never needed, and the loop is compiled without it.
    if edges.len() < usize::from(u16::MAX) {
        vote_points::<false>(edges, tables, rho, window, accumulator);
    } else {
        vote_points::<true>(edges, tables, rho, window, accumulator);
    }
}

fn vote_points<const SATURATING: bool>(
    edges: &[EdgePoint],
    tables: &Tables,
    rho: RhoAxis,
    window: usize,
    accumulator: &mut [u16],
) {
    let bins = rho.bins();
    let inverse_step = 1.0 / rho.step;
    let offset = rho.half as f32 + 0.5;
    let window = window.min(ANGLE_BINS / 4);
    let limit = (bins - 1) as f32;
    for point in edges {
        let centre = angle_bin(point.normal_angle);
        let (lo, hi) = (centre + ANGLE_BINS - window, centre + ANGLE_BINS + window);
        if lo >= ANGLE_BINS && hi < 2 * ANGLE_BINS {
            // The window does not wrap (all but 2·window of the 360 bins): one contiguous run
            // of the tables, no modulo per vote (the vote loop is most of the Hough stage).
            let range = lo - ANGLE_BINS..=hi - ANGLE_BINS;
            let cells = (lo - ANGLE_BINS) * bins..(hi - ANGLE_BINS + 1) * bins;
            let (Some(sin), Some(cos), Some(rows)) = (
                tables.sin.get(range.clone()),
                tables.cos.get(range),
                accumulator.get_mut(cells),
            ) else {
                continue;
            };
            // Row by row of the window's angle bins: the cell's index is its rho bin, whose
            // bounds test is the `f < bins` of the general case (for `f` ≥ 0, the whole part
            // is below `bins` exactly when `f` is).
            for ((row, &s), &c) in rows.chunks_exact_mut(bins).zip(sin).zip(cos) {
                let f = (point.x * s + point.y * c) * inverse_step + offset;
                // NaN fails the test too.
                if f >= 0.0
                    && let Some(cell) = row.get_mut(f as i32 as usize)
                {
                    *cell = if SATURATING {
                        cell.saturating_add(1)
                    } else {
                        cell.wrapping_add(1)
                    };
                }
            }
        } else {
            let mut increment = |index: usize| {
                if let Some(cell) = accumulator.get_mut(index) {
                    *cell = if SATURATING {
                        cell.saturating_add(1)
                    } else {
                        cell.wrapping_add(1)
                    };
                }
            };
            let mut vote_at = |bin: usize, s: f32, c: f32, point: &EdgePoint| {
                let f = (point.x * s + point.y * c) * inverse_step + offset;
                // `f` in [0, bins): NaN fails the test too.
                if f >= 0.0 && f < limit + 1.0 {
                    // Through i32: the same whole part of an `f` in range, in half the instructions of
                    // the saturating conversion to a 64-bit index.
                    increment(bin * bins + f as i32 as usize);
                }
            };
            for k in lo..=hi {
                let bin = k % ANGLE_BINS;
                if let (Some(&s), Some(&c)) = (tables.sin.get(bin), tables.cos.get(bin)) {
                    vote_at(bin, s, c, point);
                }
            }
        }
    }
}

/// A Hough cell: angle bin, rho bin and its votes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Peak {
    pub angle: usize,
    pub rho: usize,
    pub votes: u16,
}

/// Largest candidate list the detector keeps.
pub const MAX_CANDIDATES: usize = 16;

/// The strongest local maxima (3×3, angle wrapping around) with at least `min_votes`,
/// strongest first, into `out`; returns how many.
pub(crate) fn find_peaks(
    accumulator: &[u16],
    rho: RhoAxis,
    min_votes: u16,
    out: &mut [Peak],
) -> usize {
    let bins = rho.bins();
    let global_max = accumulator.iter().copied().max().unwrap_or(0);
    // Peaks under a fifth of the strongest are too short to be the horizon and only cost time.
    let threshold = min_votes.max(global_max / 5).max(1);
    let mut count = 0usize;
    let cell = |a: usize, r: usize| -> u16 { accumulator.get(a * bins + r).copied().unwrap_or(0) };
    for (a, row) in accumulator.chunks_exact(bins).enumerate() {
        // Most angle rows hold nothing near the threshold: one vectorised max skips them.
        if row.iter().copied().max().unwrap_or(0) < threshold {
            continue;
        }
        for (r, &v) in row.iter().enumerate() {
            if v < threshold {
                continue;
            }
            let (prev, next) = ((a + ANGLE_BINS - 1) % ANGLE_BINS, (a + 1) % ANGLE_BINS);
            let r_lo = r.saturating_sub(1);
            let r_hi = (r + 1).min(bins - 1);
            // Strictly above cells that come before, at least equal to those after: one
            // winner per plateau.
            let mut is_peak = true;
            for (na, nr) in [
                (prev, r_lo),
                (prev, r),
                (prev, r_hi),
                (a, r_lo),
                (a, r_hi),
                (next, r_lo),
                (next, r),
                (next, r_hi),
            ] {
                if na == a && nr == r {
                    continue;
                }
                let n = cell(na, nr);
                let before = (na, nr) < (a, r);
                if n > v || (before && n == v) {
                    is_peak = false;
                    break;
                }
            }
            if !is_peak {
                continue;
            }
            insert_peak(
                out,
                &mut count,
                Peak {
                    angle: a,
                    rho: r,
                    votes: v,
                },
            );
        }
    }
    count
}

/// Inserts into a list sorted by votes (descending), dropping the weakest when full.
pub(crate) fn insert_peak(out: &mut [Peak], count: &mut usize, peak: Peak) {
    let capacity = out.len();
    if capacity == 0 {
        return;
    }
    let mut position = *count;
    while position > 0 && out.get(position - 1).is_some_and(|p| p.votes < peak.votes) {
        position -= 1;
    }
    if position >= capacity {
        return;
    }
    let end = (*count).min(capacity - 1);
    if let Some(tail) = out.get_mut(position..=end) {
        tail.rotate_right(1);
    }
    if let Some(slot) = out.get_mut(position) {
        *slot = peak;
    }
    *count = (*count + 1).min(capacity);
}

/// The strongest cell within `angle_window` bins and `rho_window` bins of a line.
pub(crate) fn peak_near(
    accumulator: &[u16],
    rho: RhoAxis,
    angle: usize,
    rho_index: usize,
    angle_window: usize,
    rho_window: usize,
) -> Option<Peak> {
    let bins = rho.bins();
    let mut best: Option<Peak> = None;
    let angle_window = angle_window.min(ANGLE_BINS / 4);
    for k in 0..=2 * angle_window {
        let a = (angle % ANGLE_BINS + ANGLE_BINS + k - angle_window) % ANGLE_BINS;
        let lo = rho_index.saturating_sub(rho_window);
        let hi = rho_index.saturating_add(rho_window).min(bins - 1);
        let Some(row) = accumulator.get(a * bins + lo..=a * bins + hi) else {
            continue;
        };
        for (i, &v) in row.iter().enumerate() {
            if best.is_none_or(|b| v > b.votes) {
                best = Some(Peak {
                    angle: a,
                    rho: lo + i,
                    votes: v,
                });
            }
        }
    }
    best
}

/// A line `sin(angle)·x + cos(angle)·y = rho`, normal towards the brighter side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Line {
    pub angle: f32,
    pub rho: f32,
}

impl Line {
    pub fn normal(&self) -> (f32, f32) {
        (libm::sinf(self.angle), libm::cosf(self.angle))
    }
}

/// Edge points whose distances [`refine`] tests at once.
const REFINE_BLOCK: usize = 16;

/// Refines a Hough line by total least squares on the edge points near it whose direction
/// agrees, tightening the band each pass. Returns the line and its inlier count, or `None`
/// when too few points support it to fit.
pub(crate) fn refine(
    edges: &[EdgePoint],
    start: Line,
    bands: &[f32],
    max_angle_difference: f32,
) -> Option<(Line, usize)> {
    let mut line = start;
    let mut inliers = 0usize;
    for &band in bands {
        let (nx, ny) = line.normal();
        // Sums relative to the foot of the normal, so f32 keeps its precision.
        let (ox, oy) = (nx * line.rho, ny * line.rho);
        let (mut n, mut sx, mut sy, mut sxx, mut sxy, mut syy) = (0usize, 0.0, 0.0, 0.0, 0.0, 0.0);
        // The points within the band, taken in order from a bit mask per block: the
        // distances of a block in one vectorised pass, and no per-point test the processor
        // mispredicts. A point is outside only when `|distance| > band` holds: a NaN
        // distance is within, and a NaN band holds every point.
        let band = if band.is_nan() { f32::INFINITY } else { band };
        for block in edges.chunks(REFINE_BLOCK) {
            let mut near = block.iter().enumerate().fold(0u32, |mask, (i, p)| {
                let distance = p.x * nx + p.y * ny - line.rho;
                let kept = libm::fabsf(distance) <= band || distance.is_nan();
                mask | (u32::from(kept) << i)
            });
            while near != 0 {
                let i = near.trailing_zeros() as usize;
                near &= near - 1;
                let Some(p) = block.get(i) else {
                    continue;
                };
                if libm::fabsf(wrap_angle(p.normal_angle - line.angle)) > max_angle_difference {
                    continue;
                }
                let (dx, dy) = (p.x - ox, p.y - oy);
                n += 1;
                sx += dx;
                sy += dy;
                sxx += dx * dx;
                sxy += dx * dy;
                syy += dy * dy;
            }
        }
        if n < 8 {
            return None;
        }
        let count = n as f32;
        let (mx, my) = (sx / count, sy / count);
        let cxx = sxx / count - mx * mx;
        let cxy = sxy / count - mx * my;
        let cyy = syy / count - my * my;
        // Direction of largest spread; the normal is perpendicular, kept on the bright side.
        let direction = 0.5 * libm::atan2f(2.0 * cxy, cxx - cyy);
        let (mut fnx, mut fny) = (-libm::sinf(direction), libm::cosf(direction));
        if fnx * nx + fny * ny < 0.0 {
            fnx = -fnx;
            fny = -fny;
        }
        let angle = libm::atan2f(fnx, fny);
        let rho = fnx * (mx + ox) + fny * (my + oy);
        line = Line { angle, rho };
        inliers = n;
    }
    Some((line, inliers))
}

/// Sky/ground statistics of one line over the sample grid.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Separation {
    /// Share of the samples' variance (luma and colour) explained by the two sides, in [0, 1]
    /// (Otsu's criterion for a line instead of a threshold).
    pub explained: f32,
    /// Share of the colour's (blue minus red) variance alone explained by the two sides, over
    /// the same samples as `explained` (clipped ones and the band about the line left out, the
    /// same +1 in the variance).
    pub colour_explained: f32,
    /// Evidence, cue by cue, that the brighter side (the normal's) is the sky.
    pub cues: SkyCues,
}

impl Separation {
    /// Evidence that the brighter side (the normal's) is the sky: positive when it is
    /// brighter, bluer and smoother than the other, taken together.
    pub fn bright_is_sky(&self) -> f32 {
        self.cues.sum()
    }
}

/// Evidence that one side of a line is the sky, cue by cue, each scaled to the frame (the luma
/// and colour differences by their spread, the texture difference by the two textures' sum):
/// positive where that side is brighter, bluer, smoother than the other.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct SkyCues {
    pub brighter: f32,
    pub bluer: f32,
    pub smoother: f32,
}

impl SkyCues {
    pub fn sum(&self) -> f32 {
        self.brighter + self.bluer + self.smoother
    }

    /// The same cues for the other side.
    pub fn flipped(self) -> Self {
        SkyCues {
            brighter: -self.brighter,
            bluer: -self.bluer,
            smoother: -self.smoother,
        }
    }

    /// The cues' sum, where it does not rest on one cue alone against another: a sky is
    /// brighter, bluer and smoother, and where one cue says the side is not the sky, a second
    /// must say it is. Looking steeply down, a sunlit field is brighter than a green one beside
    /// it and clearly less blue, and no smoother: the plain sum calls its border a fair
    /// horizon. A sunset sky is as much less blue than the ground, but smoother.
    pub fn agreed(&self) -> f32 {
        let mut cues = [self.brighter, self.bluer, self.smoother];
        cues.sort_unstable_by(f32::total_cmp);
        let [against, second, _strongest] = cues;
        let backing = if against < -CUE_AGAINST {
            (second / SECOND_CUE).clamp(0.0, 1.0)
        } else {
            1.0
        };
        self.sum() * backing
    }
}

/// A cue below minus this says the side is not the sky ([`SkyCues::agreed`]).
const CUE_AGAINST: f32 = 0.3;
/// The second cue for a side at which a cue against it costs nothing; below it the evidence
/// falls in proportion. On `synth` seed 1 (all sets at 320×240, and the no-horizon sets of
/// seeds 1–3) the field borders looking down had a second cue of 0.09 at most (smoothness);
/// right answers with a cue against had 0.12–0.17 (dusk, a haze under a darker hum bar: they
/// lose half their confidence or more) and 0.28 and up (haze, a ground edge).
const SECOND_CUE: f32 = 0.3;

#[derive(Clone, Copy, Default)]
struct Moments {
    n: f32,
    luma: f32,
    luma2: f32,
    chroma: f32,
    chroma2: f32,
    texture: f32,
}

impl Moments {
    fn add(&mut self, s: &Sample) {
        self.n += 1.0;
        self.luma += s.luma;
        self.luma2 += s.luma * s.luma;
        self.chroma += s.chroma;
        self.chroma2 += s.chroma * s.chroma;
        self.texture += s.texture;
    }
}

/// Luma at and above which a sample counts as clipped.
pub(crate) const SATURATED: f32 = 248.0;

/// Splits the samples by the line (leaving out a band `band` wide around it, where pixels mix
/// both sides) and measures how well the two sides separate.
pub(crate) fn separation(samples: &[Sample], line: Line, band: f32) -> Separation {
    separation_of(samples, line, band, |_| true)
}

/// [`separation`] over the samples `keep` accepts.
pub(crate) fn separation_of(
    samples: &[Sample],
    line: Line,
    band: f32,
    keep: impl Fn(&Sample) -> bool,
) -> Separation {
    let (nx, ny) = line.normal();
    let mut bright = Moments::default();
    let mut dark = Moments::default();
    for s in samples.iter().filter(|s| keep(s)) {
        // Clipped pixels (glare, over-exposure) say nothing about sky or ground, and a
        // saturated blob would otherwise dominate the variance.
        if s.luma >= SATURATED {
            continue;
        }
        let d = s.x * nx + s.y * ny - line.rho;
        if d > band {
            bright.add(s);
        } else if d < -band {
            dark.add(s);
        }
    }
    let total = bright.n + dark.n;
    if bright.n < 1.0 || dark.n < 1.0 {
        return Separation::default();
    }
    let (wb, wd) = (bright.n / total, dark.n / total);
    let mean = |sum: f32, m: &Moments| sum / m.n;
    let (lb, ld) = (mean(bright.luma, &bright), mean(dark.luma, &dark));
    let (cb, cd) = (mean(bright.chroma, &bright), mean(dark.chroma, &dark));
    let (tb, td) = (mean(bright.texture, &bright), mean(dark.texture, &dark));
    let luma_mean = (bright.luma + dark.luma) / total;
    let chroma_mean = (bright.chroma + dark.chroma) / total;
    let luma_var = ((bright.luma2 + dark.luma2) / total - luma_mean * luma_mean).max(0.0);
    let chroma_var = ((bright.chroma2 + dark.chroma2) / total - chroma_mean * chroma_mean).max(0.0);
    let between_luma = wb * wd * (lb - ld) * (lb - ld);
    let between_chroma = wb * wd * (cb - cd) * (cb - cd);
    // The +1 keeps a flat frame (no variance at all) from looking perfectly separated.
    let explained =
        ((between_luma + between_chroma) / (luma_var + chroma_var + 1.0)).clamp(0.0, 1.0);
    Separation {
        explained,
        colour_explained: (between_chroma / (chroma_var + 1.0)).clamp(0.0, 1.0),
        cues: SkyCues {
            brighter: (lb - ld) / (libm::sqrtf(luma_var) + 1.0),
            bluer: (cb - cd) / (libm::sqrtf(chroma_var) + 4.0),
            smoother: (td - tb) / (td + tb + 1.0),
        },
    }
}

/// Mean texture of the samples between two parallel lines and beyond the second one.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct BandTextures {
    pub between: f32,
    pub between_count: u32,
    pub above: f32,
    pub above_count: u32,
}

/// Texture between `lower` and `upper` and beyond `upper`, "beyond" being the direction
/// `sky_ward` (±1) along the lines' normals; `margin` leaves out the pixels on the edges.
pub(crate) fn band_textures(
    samples: &[Sample],
    lower: Line,
    upper: Line,
    sky_ward: f32,
    margin: f32,
) -> BandTextures {
    let (lx, ly) = lower.normal();
    let (ux, uy) = upper.normal();
    let (mut between, mut above) = ((0.0f32, 0u32), (0.0f32, 0u32));
    for s in samples {
        if s.luma >= SATURATED {
            continue;
        }
        let from_lower = sky_ward * (s.x * lx + s.y * ly - lower.rho);
        let from_upper = sky_ward * (s.x * ux + s.y * uy - upper.rho);
        if from_upper > margin {
            above = (above.0 + s.texture, above.1 + 1);
        } else if from_lower > margin && from_upper < -margin {
            between = (between.0 + s.texture, between.1 + 1);
        }
    }
    let mean = |(sum, n): (f32, u32)| if n > 0 { sum / n as f32 } else { 0.0 };
    BandTextures {
        between: mean(between),
        between_count: between.1,
        above: mean(above),
        above_count: above.1,
    }
}
