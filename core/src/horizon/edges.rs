//! First half of the pipeline: the working image, the 3×3 gradient with an adaptive
//! threshold, thinned edge points as a list, and their radial distortion correction.
//!
//! The seed's detector (thesis §6.2.3) drowned in its own edge map: noise became "a filled
//! irregular shape", stripes out-voted the horizon. Here the threshold follows each frame's
//! gradient distribution, non-maximum suppression keeps one pixel across an edge (so a noise
//! blob leaves speckles, not a filled area), and each point keeps its gradient direction so
//! that the Hough stage can ignore the lines the point cannot lie on.

use super::camera::Camera;
use super::frame::{Frame, Pixels, luma};
use super::grid::UndistortedGrid;

/// One edge point in normalised undistorted coordinates, with the direction of its line's
/// normal (pointing towards the brighter side), `n = (sin a, cos a)`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EdgePoint {
    pub x: f32,
    pub y: f32,
    pub normal_angle: f32,
}

impl EdgePoint {
    pub const ZERO: EdgePoint = EdgePoint {
        x: 0.0,
        y: 0.0,
        normal_angle: 0.0,
    };
}

/// Size of the image the gradient runs on: frames wider than [`MAX_WORKING_WIDTH`] are
/// binned by an integer factor first, which averages sensor noise away and keeps the cost
/// per frame nearly constant from 320×240 to 1280×720.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Working {
    pub scale: usize,
    pub width: usize,
    pub height: usize,
}

/// Widest working image; wider frames are binned (a 320-pixel horizon already gives
/// sub-degree roll after the least-squares refinement).
pub const MAX_WORKING_WIDTH: usize = 200;
/// The binning sums at most 16×16 pixels so that a 255-valued block fits a `u16`.
const MAX_SCALE: usize = 16;

impl Working {
    pub fn for_frame(width: usize, height: usize) -> Self {
        Self::with_scale(width, height, width.div_ceil(MAX_WORKING_WIDTH))
    }

    pub fn with_scale(width: usize, height: usize, scale: usize) -> Self {
        let scale = scale.clamp(1, MAX_SCALE);
        Working {
            scale,
            width: width / scale,
            height: height / scale,
        }
    }

    /// Centre of working pixel `(wx, wy)` in the frame's pixel coordinates.
    #[inline]
    pub fn to_frame(self, wx: f32, wy: f32) -> (f32, f32) {
        let s = self.scale as f32;
        ((wx + 0.5) * s - 0.5, (wy + 0.5) * s - 0.5)
    }
}

/// Fills `grey` with the working image (luma, binned by `geo.scale`).
pub(crate) fn build_working_image(frame: &Frame<'_>, geo: Working, grey: &mut [u8]) {
    let s = geo.scale;
    let colour = frame.is_colour();
    for (wy, out_row) in grey
        .chunks_exact_mut(geo.width)
        .take(geo.height)
        .enumerate()
    {
        if s == 1 {
            let row = frame.row(wy);
            if colour {
                for (o, px) in out_row.iter_mut().zip(row.chunks_exact(3)) {
                    if let &[r, g, b] = px {
                        *o = luma(r, g, b);
                    }
                }
            } else {
                for (o, &p) in out_row.iter_mut().zip(row) {
                    *o = p;
                }
            }
            continue;
        }
        if s == 2 {
            // The common case (frames 201–400 px wide), unrolled: per-block loops cost more than
            // the arithmetic.
            bin_two_rows(frame.row(wy * 2), frame.row(wy * 2 + 1), colour, out_row);
            continue;
        }
        bin_rows(frame, wy, s, colour, out_row);
    }
}

/// Bytes of frame row summed per pass of [`bin_rows`].
const COLUMN_SUMS: usize = 768;

/// Luma of the `s`×`s` blocks of working row `wy` (`s` ≥ 3). The block's rows are summed byte
/// by byte first (a vectorised loop per row, over a run of blocks), then each block's channel
/// sums are read off those column sums: the same integers as summing block by block, where the
/// loop per block and per row cost most of the detector at 640×480.
fn bin_rows(frame: &Frame<'_>, wy: usize, s: usize, colour: bool, out_row: &mut [u8]) {
    let rows: [&[u8]; MAX_SCALE] =
        core::array::from_fn(|dy| if dy < s { frame.row(wy * s + dy) } else { &[] });
    let area = (s * s) as u32;
    let bytes_per_pixel = if colour { 3 } else { 1 };
    let bytes_per_block = bytes_per_pixel * s;
    let blocks_per_pass = (COLUMN_SUMS / bytes_per_block).max(1);
    for (pass, out) in out_row.chunks_mut(blocks_per_pass).enumerate() {
        let start = pass * blocks_per_pass * bytes_per_block;
        let len = out.len() * bytes_per_block;
        let mut column_sums = [0u16; COLUMN_SUMS];
        let Some(sums) = column_sums.get_mut(..len) else {
            continue;
        };
        // At most 16 rows of 255: a u16 holds the sum.
        for row in rows.iter().take(s) {
            if let Some(bytes) = row.get(start..start + len) {
                for (sum, &byte) in sums.iter_mut().zip(bytes) {
                    *sum += u16::from(byte);
                }
            }
        }
        for (o, block) in out.iter_mut().zip(sums.chunks_exact(bytes_per_block)) {
            *o = if colour {
                let (mut r, mut g, mut b) = (0u32, 0u32, 0u32);
                for px in block.chunks_exact(3) {
                    if let &[pr, pg, pb] = px {
                        r += u32::from(pr);
                        g += u32::from(pg);
                        b += u32::from(pb);
                    }
                }
                let weighted = 77 * r + 150 * g + 29 * b;
                ((weighted + 128 * area) / (256 * area)) as u8
            } else {
                let sum = block.iter().map(|&p| u32::from(p)).sum::<u32>();
                ((sum + area / 2) / area) as u8
            };
        }
    }
}

/// Output pixels of [`bin_two_rows`] per pass of its two loops.
const BIN_RUN: usize = 16;

/// BT.601 luma weights (see `frame::luma`) for each byte of a run of RGB pixels.
const LUMA_WEIGHTS: [i16; 6 * BIN_RUN] = {
    let mut weights = [0i16; 6 * BIN_RUN];
    let mut i = 0;
    while i < weights.len() {
        weights[i] = match i % 3 {
            0 => 77,
            1 => 150,
            _ => 29,
        };
        i += 1;
    }
    weights
};

/// Luma of 2×2 blocks of two frame rows.
fn bin_two_rows(top: &[u8], bottom: &[u8], colour: bool, out: &mut [u8]) {
    if colour && top.len() == bottom.len() {
        // The two rows' sums first, byte by byte (one vectorised loop), then the channel sums
        // and the luma of each block from them: the same integers as summing the block's four
        // pixels directly, in half the scalar work.
        for ((o, a), b) in out
            .chunks_mut(BIN_RUN)
            .zip(top.chunks(6 * BIN_RUN))
            .zip(bottom.chunks(6 * BIN_RUN))
        {
            let mut sums = [0i16; 6 * BIN_RUN];
            for ((s, &t), &b) in sums.iter_mut().zip(a).zip(b) {
                *s = i16::from(t) + i16::from(b);
            }
            // Each byte's weight, then adjacent pairs of products summed: R·77 + G·150,
            // B·29 + R·77, G·150 + B·29 for each block (a multiply-add of 16-bit pairs that the
            // compiler vectorises), and a block's luma is its three pairs: the same integers as
            // weighting its channel sums.
            let mut pairs = [0i32; 3 * BIN_RUN];
            for (p, (s, w)) in pairs
                .iter_mut()
                .zip(sums.chunks_exact(2).zip(LUMA_WEIGHTS.chunks_exact(2)))
            {
                if let (&[s0, s1], &[w0, w1]) = (s, w) {
                    *p = i32::from(s0) * i32::from(w0) + i32::from(s1) * i32::from(w1);
                }
            }
            // Only whole blocks: a partial last run leaves the outputs it has no pixels for.
            let whole = a.len() / 6;
            for (o, p) in o.iter_mut().take(whole).zip(pairs.chunks_exact(3)) {
                if let &[p0, p1, p2] = p {
                    *o = ((p0 + p1 + p2 + 512) >> 10) as u8;
                }
            }
        }
    } else if colour {
        for ((o, a), b) in out
            .iter_mut()
            .zip(top.chunks_exact(6))
            .zip(bottom.chunks_exact(6))
        {
            if let (&[ar, ag, ab, cr, cg, cb], &[br, bg, bb, dr, dg, db]) = (a, b) {
                let r = u32::from(ar) + u32::from(cr) + u32::from(br) + u32::from(dr);
                let g = u32::from(ag) + u32::from(cg) + u32::from(bg) + u32::from(dg);
                let b = u32::from(ab) + u32::from(cb) + u32::from(bb) + u32::from(db);
                *o = ((77 * r + 150 * g + 29 * b + 512) >> 10) as u8;
            }
        }
    } else {
        for ((o, a), b) in out
            .iter_mut()
            .zip(top.chunks_exact(2))
            .zip(bottom.chunks_exact(2))
        {
            if let (&[a0, a1], &[b0, b1]) = (a, b) {
                let sum = u32::from(a0) + u32::from(a1) + u32::from(b0) + u32::from(b1);
                *o = ((sum + 2) >> 2) as u8;
            }
        }
    }
}

fn image_row(grey: &[u8], geo: Working, y: usize) -> &[u8] {
    grey.get(y * geo.width..(y + 1) * geo.width).unwrap_or(&[])
}

/// Gradient magnitude `|gx| + |gy|` of working row `y` (zero on the border rows/columns).
fn magnitude_row(grey: &[u8], geo: Working, y: usize, out: &mut [u16]) {
    sobel_row(grey, geo, y, out, None);
}

/// One output's pixels as the zips of [`sobel_row`] give them: the left column (above, at,
/// below), the centre column (above, below) and the right column (above, at, below).
type Window<'a> = (
    (((&'a u8, &'a u8), &'a u8), (&'a u8, &'a u8)),
    ((&'a u8, &'a u8), &'a u8),
);

/// [`magnitude_row`], and when `components` is given the Sobel `gx`, `gy` of the row as well
/// (`i16` bits in `u16`, zero where the magnitude is), so that the edge pass does not compute
/// each candidate's gradient a second time.
fn sobel_row(
    grey: &[u8],
    geo: Working,
    y: usize,
    out: &mut [u16],
    components: Option<(&mut [u16], &mut [u16])>,
) {
    out.fill(0);
    let mut components = components;
    if let Some((gxs, gys)) = &mut components {
        gxs.fill(0);
        gys.fill(0);
    }
    if y == 0 || y + 1 >= geo.height {
        return;
    }
    let (above, at, below) = (
        image_row(grey, geo, y - 1),
        image_row(grey, geo, y),
        image_row(grey, geo, y + 1),
    );
    // Shifted views of the three rows: left (x−1), centre (x), right (x+1) of each output.
    // Plain zips of slices, which the compiler turns into SIMD.
    fn shifted(row: &[u8]) -> (&[u8], &[u8], &[u8]) {
        (
            row,
            row.get(1..).unwrap_or(&[]),
            row.get(2..).unwrap_or(&[]),
        )
    }
    let (a0, a1, a2) = shifted(above);
    let (m0, _, m2) = shifted(at);
    let (b0, b1, b2) = shifted(below);
    let lefts = a0.iter().zip(m0).zip(b0);
    let centres = a1.iter().zip(b1);
    let rights = a2.iter().zip(m2).zip(b2);
    let sobel = |((((&al, &ml), &bl), (&ac, &bc)), ((&ar, &mr), &br)): Window<'_>| {
        let (al, ml, bl, ac, bc, ar, mr, br) = (
            i16::from(al),
            i16::from(ml),
            i16::from(bl),
            i16::from(ac),
            i16::from(bc),
            i16::from(ar),
            i16::from(mr),
            i16::from(br),
        );
        let gx = (ar + 2 * mr + br) - (al + 2 * ml + bl);
        let gy = (bl + 2 * bc + br) - (al + 2 * ac + ar);
        (gx, gy)
    };
    match components {
        None => {
            for (o, window) in out.iter_mut().skip(1).zip(lefts.zip(centres).zip(rights)) {
                let (gx, gy) = sobel(window);
                *o = gx.unsigned_abs() + gy.unsigned_abs();
            }
        }
        Some((gxs, gys)) => {
            for (((o, ox), oy), window) in out
                .iter_mut()
                .zip(gxs.iter_mut())
                .zip(gys.iter_mut())
                .skip(1)
                .zip(lefts.zip(centres).zip(rights))
            {
                let (gx, gy) = sobel(window);
                *o = gx.unsigned_abs() + gy.unsigned_abs();
                *ox = gx as u16;
                *oy = gy as u16;
            }
        }
    }
}

/// Histogram bins of the gradient magnitude are 8 units wide (magnitudes reach 2040; a
/// clean step of 10 grey levels gives 40).
pub(crate) const HISTOGRAM_SHIFT: u32 = 3;

/// Histogram of the gradient magnitude over every other row of the working image.
pub(crate) struct GradientHistogram {
    bins: [u32; 256],
    sampled: u32,
}

impl GradientHistogram {
    pub fn measure(grey: &[u8], geo: Working, scratch: &mut [u16]) -> Self {
        // Neighbouring pixels of a smooth sky most often fall in the same bin: they are
        // counted in two copies of the histogram in turn, so that each count waits on the
        // one two pixels back, not on the one before.
        let mut copies = [[0u32; 256]; 2];
        let mut sampled = 0u32;
        let row = scratch.get_mut(..geo.width).unwrap_or(&mut []);
        let count = |copy: &mut [u32; 256], m: u16| {
            let bin = ((m >> HISTOGRAM_SHIFT) as usize).min(255);
            if let Some(h) = copy.get_mut(bin) {
                *h += 1;
            }
        };
        for y in (1..geo.height.saturating_sub(1)).step_by(2) {
            magnitude_row(grey, geo, y, row);
            // Border columns have no gradient; leave them out of the statistics.
            let inner = row.get(1..geo.width.saturating_sub(1)).unwrap_or(&[]);
            sampled += inner.len() as u32;
            let [first, second] = &mut copies;
            let pairs = inner.chunks_exact(2);
            if let &[m] = pairs.remainder() {
                count(first, m);
            }
            for pair in pairs {
                if let &[a, b] = pair {
                    count(first, a);
                    count(second, b);
                }
            }
        }
        let [first, second] = copies;
        let mut bins = first;
        for (bin, other) in bins.iter_mut().zip(second) {
            *bin += other;
        }
        GradientHistogram { bins, sampled }
    }

    /// The gradient threshold of this frame: the magnitude above which about
    /// `target_points` pixels of the working image lie, never below `floor`.
    ///
    /// A fixed threshold fails both ways on the seed's video: exposure changes make the
    /// horizon's contrast vary tenfold, and noisy frames pass a low threshold "as all-edge".
    pub fn threshold(&self, geo: Working, target_points: usize, floor: u16) -> u16 {
        let pixels = (geo.width * geo.height).max(1) as u64;
        // Pixels allowed above the threshold among those sampled.
        let allowed = (target_points as u64 * self.sampled as u64 / pixels) as u32;
        let mut above = 0u32;
        let mut threshold_bin = 256usize;
        for (bin, &count) in self.bins.iter().enumerate().rev() {
            if above + count > allowed {
                break;
            }
            above += count;
            threshold_bin = bin;
        }
        let threshold = (threshold_bin.min(255) << HISTOGRAM_SHIFT) as u16;
        threshold.max(floor)
    }

    /// The magnitude below which a share `p` of the sampled pixels lie.
    pub fn percentile(&self, p: f32) -> u16 {
        let wanted = (p * self.sampled as f32) as u32;
        let mut below = 0u32;
        for (bin, &count) in self.bins.iter().enumerate() {
            below += count;
            if below > wanted {
                return (bin << HISTOGRAM_SHIFT) as u16;
            }
        }
        (255 << HISTOGRAM_SHIFT) as u16
    }
}

/// Mean absolute response of the 3×3 mask `[1 −2 1; −2 4 −2; 1 −2 1]` over every other row
/// of the working image (Immerkær's noise estimator: about 4.8σ for white noise of σ).
///
/// Unlike the gradient, it barely answers smooth structure: a sinusoid (analog interference)
/// of period T gives `(2 − 2cos ωx)(2 − 2cos ωy)` of its amplitude, nothing for stripes along
/// an image axis, while its gradient is everywhere and made the gradient-based noise level a
/// wall no edge got over.
pub(crate) fn laplacian_mean_abs(grey: &[u8], geo: Working) -> f32 {
    let (mut sum, mut n) = (0u64, 0u64);
    for y in (1..geo.height.saturating_sub(1)).step_by(2) {
        let (above, at, below) = (
            image_row(grey, geo, y - 1),
            image_row(grey, geo, y),
            image_row(grey, geo, y + 1),
        );
        for ((a, m), b) in above.windows(3).zip(at.windows(3)).zip(below.windows(3)) {
            let (&[a0, a1, a2], &[m0, m1, m2], &[b0, b1, b2]) = (a, m, b) else {
                continue;
            };
            let [a0, a1, a2, m0, m1, m2, b0, b1, b2] =
                [a0, a1, a2, m0, m1, m2, b0, b1, b2].map(i32::from);
            let response = (a0 - 2 * a1 + a2) - 2 * (m0 - 2 * m1 + m2) + (b0 - 2 * b1 + b2);
            sum += u64::from(response.unsigned_abs());
            n += 1;
        }
    }
    if n == 0 { 0.0 } else { sum as f32 / n as f32 }
}

/// What [`collect_edges`] found.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct EdgeStats {
    pub count: usize,
    /// Edge pixels that did not fit in the list (the list is then a top-of-frame subset).
    pub dropped: usize,
}

/// Thinned edge points of the working image above `threshold`, undistorted, into `edges`.
/// `rows` is scratch of at least [`EDGE_SCRATCH_ROWS`] working rows. With `ramps_removed`,
/// each point's direction is its step's, the smooth ramp it lies on taken out (see
/// [`step_gradient`]); not in a frame whose codec's blocks show, whose block borders are no
/// smooth ramp.
pub(crate) fn collect_edges(
    grey: &[u8],
    geo: Working,
    rows: &mut [u16],
    threshold: u16,
    camera: &Camera,
    edges: &mut [EdgePoint],
    ramps_removed: bool,
) -> EdgeStats {
    let w = geo.width;
    let mut stats = EdgeStats::default();
    let mut scratch = rows.chunks_exact_mut(w.max(1));
    let mut next = || scratch.next().unwrap_or(&mut []);
    // Rows y−1, y, y+1: magnitudes, and the Sobel components of each.
    let mut mags: [&mut [u16]; 3] = [next(), next(), next()];
    let mut gxs: [&mut [u16]; 3] = [next(), next(), next()];
    let mut gys: [&mut [u16]; 3] = [next(), next(), next()];
    if gys[2].len() < w {
        return stats;
    }
    for y in 0..2 {
        if let (Some(m), Some(gx), Some(gy)) = (mags.get_mut(y), gxs.get_mut(y), gys.get_mut(y)) {
            sobel_row(grey, geo, y, m, Some((gx, gy)));
        }
    }
    // A zero magnitude is never an edge (a configured threshold of 0 included).
    let threshold = threshold.max(1);
    for y in 1..geo.height.saturating_sub(1) {
        {
            let [_, _, m] = &mut mags;
            let [_, _, gx] = &mut gxs;
            let [_, _, gy] = &mut gys;
            sobel_row(grey, geo, y + 1, m, Some((gx, gy)));
        }
        let [above, at, below] = &mags;
        let [_, gx_row, _] = &gxs;
        let [_, gy_row, _] = &gys;
        let neighbour_rows: [&[u16]; 3] = [above, at, below];
        // Non-maximum suppression at pixel `x` along its gradient, quantised to 8 directions
        // (tan 22.5° ≈ 0.4142 ≈ 53/128): its magnitude, gradient, step along the gradient and
        // the magnitudes a step forward and back. The direction is written as selects rather
        // than an early-out chain: it is as unpredictable as the gradient.
        let suppression = |x: usize, m: u16| {
            let component = |row: &[u16]| row.get(x).map_or(0, |&g| i32::from(g as i16));
            let (gx, gy) = (component(gx_row), component(gy_row));
            let (ax, ay) = (gx.abs() * 128, gy.abs() * 128);
            let along_x = ay <= gx.abs() * 53;
            let along_y = !along_x && ax <= gy.abs() * 53;
            let rising = (gx > 0) == (gy > 0);
            let dx = isize::from(!along_y);
            let dy: isize = if along_x {
                0
            } else if along_y || rising {
                1
            } else {
                -1
            };
            let neighbour = |dx: isize, dy: isize| -> i32 {
                neighbour_rows
                    .get(dy.wrapping_add(1) as usize)
                    .and_then(|row| x.checked_add_signed(dx).and_then(|xx| row.get(xx)))
                    .map_or(0, |&v| i32::from(v))
            };
            Ridge {
                m: i32::from(m),
                gx,
                gy,
                dx,
                dy,
                forward: neighbour(dx, dy),
                backward: neighbour(-dx, -dy),
            }
        };
        // Most of a row is under the threshold (the budget keeps a few percent of the pixels
        // above it). A block's pixels above it are a bit mask made in one vectorised pass and
        // taken in their order, not a test per pixel whose outcome the processor cannot guess
        // (an empty mask passes the block over).
        for (block_index, block) in at.chunks(EDGE_BLOCK).enumerate() {
            let strong = block.iter().enumerate().fold(0u32, |mask, (i, &m)| {
                mask | (u32::from(m >= threshold) << i)
            });
            // First which of them are ridges (a mask again: whether a pixel survives the
            // suppression is a coin toss to the processor), then the points of those.
            let mut ridges = 0u32;
            let mut remaining = strong;
            while remaining != 0 {
                let i = remaining.trailing_zeros() as usize;
                remaining &= remaining - 1;
                let Some(&m) = block.get(i) else {
                    continue;
                };
                let r = suppression(block_index * EDGE_BLOCK + i, m);
                ridges |= u32::from(r.m >= r.forward && r.m > r.backward) << i;
            }
            while ridges != 0 {
                let i = ridges.trailing_zeros() as usize;
                ridges &= ridges - 1;
                let Some(&m) = block.get(i) else {
                    continue;
                };
                let x = block_index * EDGE_BLOCK + i;
                let Ridge {
                    m,
                    gx,
                    gy,
                    dx,
                    dy,
                    forward,
                    backward,
                } = suppression(x, m);
                // Sub-pixel position of the ridge along the gradient (parabola through the
                // three).
                let curvature = backward - 2 * m + forward;
                let offset = if curvature < 0 {
                    (0.5 * (backward - forward) as f32 / curvature as f32).clamp(-0.5, 0.5)
                } else {
                    0.0
                };
                let Some(slot) = edges.get_mut(stats.count) else {
                    stats.dropped += 1;
                    continue;
                };
                let (u, v) =
                    geo.to_frame(x as f32 + offset * dx as f32, y as f32 + offset * dy as f32);
                let (gx, gy) = if ramps_removed {
                    step_gradient(grey, geo, (x, y), (dx, dy), (gx, gy))
                } else {
                    (gx, gy)
                };
                if let Some(point) = undistort_edge(camera, u, v, gx, gy) {
                    *slot = point;
                    stats.count += 1;
                }
            }
        }
        mags.rotate_left(1);
        gxs.rotate_left(1);
        gys.rotate_left(1);
    }
    stats
}

/// Working pixels from an edge pixel, along its gradient, where [`step_gradient`] reads the
/// ramp: the nearest whose Sobel window shares no pixel with the edge pixel's.
const RAMP_REACH: isize = 3;

/// The gradient of the step at edge pixel `(x, y)`, the smooth ramp it lies on taken out: its
/// Sobel gradient less the mean of the gradients [`RAMP_REACH`] pixels either side along
/// `(dx, dy)` (its gradient's direction, quantised), where those are a ramp's.
///
/// A faint horizon across a sun's glow is a step of a few levels on a ramp that brightens
/// towards the sun along the horizon: the Sobel gradient there is the step's plus the ramp's,
/// turned by 10–15° towards the sun (`aerial` `glare`, seed 157: a step of 6–10 levels, the
/// glow about one level a working pixel along it), and the point votes outside the Hough
/// window of the horizon's direction. The ramp's gradient is nearly the same three pixels
/// away and cancels; a step's own gradient there is smaller and along the same normal, so
/// its direction stays.
///
/// Only a ramp is taken out: the gradients on the two sides alike, and their sum alike again
/// twice as far out. A flat sky over textured ground is not one: taken out, the texture's
/// gradient turned a hazy horizon over noisy fields, 1.6° of pitch out (the test
/// `thick_haze_ramp_deeper_than_the_placement_search_at_320`). Nor are a link's stripes a few
/// working pixels apart, alike at one reach and not at the other: 4° of roll out under a
/// thick haze at 640 px (`stripes_parallel_to_the_horizon_are_subtracted`). On the seen sets
/// (`aerial` seeds 137–155 and the tuning sets of seed 1) the test twice as far out adds 15
/// frames within 2° to the first test alone, and trusts 15 fewer wrong answers (281 → 266).
/// Unchanged where a side is out of the image.
fn step_gradient(
    grey: &[u8],
    geo: Working,
    (x, y): (usize, usize),
    (dx, dy): (isize, isize),
    (gx, gy): (i32, i32),
) -> (i32, i32) {
    let sobel_at = |x: isize, y: isize| -> Option<(i32, i32)> {
        let (x, y) = (usize::try_from(x).ok()?, usize::try_from(y).ok()?);
        if x == 0 || y == 0 || x + 1 >= geo.width || y + 1 >= geo.height {
            return None;
        }
        let at = |x: usize, y: usize| grey.get(y * geo.width + x).map_or(0, |&v| i32::from(v));
        let column = |x: usize| at(x, y - 1) + 2 * at(x, y) + at(x, y + 1);
        let row = |y: usize| at(x - 1, y) + 2 * at(x, y) + at(x + 1, y);
        Some((column(x + 1) - column(x - 1), row(y + 1) - row(y - 1)))
    };
    let (x, y) = (x as isize, y as isize);
    // Alike: apart by at most half their mean size (L1).
    let alike = |(ax, ay): (i32, i32), (bx, by): (i32, i32)| {
        2 * ((ax - bx).abs() + (ay - by).abs()) <= ax.abs() + ay.abs() + bx.abs() + by.abs()
    };
    let sum = |(ax, ay): (i32, i32), (bx, by): (i32, i32)| (ax + bx, ay + by);
    let either_side = |reach: isize| {
        let (dx, dy) = (reach * dx, reach * dy);
        Some((sobel_at(x + dx, y + dy)?, sobel_at(x - dx, y - dy)?))
    };
    // A ramp: alike on both sides, and again twice as far (a stripe's or a texture's
    // gradients are not); the far side is read only where the near one is alike.
    let ramp = either_side(RAMP_REACH)
        .filter(|&(a, b)| alike(a, b))
        .map(|(a, b)| sum(a, b))
        .filter(|&near| either_side(2 * RAMP_REACH).is_some_and(|(a, b)| alike(near, sum(a, b))));
    match ramp {
        // Twice the step's gradient: only its direction is used.
        Some((rx, ry)) => (2 * gx - rx, 2 * gy - ry),
        None => (gx, gy),
    }
}

/// A pixel's non-maximum suppression in [`collect_edges`].
struct Ridge {
    m: i32,
    gx: i32,
    gy: i32,
    dx: isize,
    dy: isize,
    forward: i32,
    backward: i32,
}

/// Working rows of scratch [`collect_edges`] needs: magnitude, `gx` and `gy` of three rows.
pub(crate) const EDGE_SCRATCH_ROWS: usize = 9;
/// Pixels tested at once for any above the threshold.
const EDGE_BLOCK: usize = 16;

/// Moves one edge pixel and its gradient direction into normalised undistorted coordinates:
/// the point itself by the inverse radial model, the direction along the edge by that
/// model's derivative there (radial distortion bends directions away from the centre).
///
/// The distortion `p ↦ p·f(|p|²)`, `f(r²) = 1 + k1·r² + k2·r⁴`, has the Jacobian
/// `f·I + g·p·pᵀ` with `g = 2·f′(r²)`; its inverse (Sherman–Morrison) takes a distorted tangent
/// `t` to `(t − p·g·(p·t) / (f + g·r²)) / f`. Only the direction is kept, and `f` is positive
/// where the point undistorted. Undistorting a second point two working pixels along the edge
/// instead, as this did before, cost a second inverse model for every edge point (3 % of the
/// detector's time at 320×240), and read a chord's direction rather than the tangent's.
fn undistort_edge(camera: &Camera, u: f32, v: f32, gx: i32, gy: i32) -> Option<EdgePoint> {
    let xd = (u - camera.cx) / camera.fx;
    let yd = (v - camera.cy) / camera.fy;
    // The intensity gradient with respect to normalised coordinates.
    let gnx = gx as f32 * camera.fx;
    let gny = gy as f32 * camera.fy;
    // The square root of a sum of squares is NaN or zero exactly when the sum is: the test
    // needs no root, and the undistorted path below no norm.
    let norm2 = gnx * gnx + gny * gny;
    if norm2.is_nan() || norm2 <= 0.0 {
        return None;
    }
    if camera.k1 == 0.0 && camera.k2 == 0.0 {
        // No distortion: the point is where it is and the normal is the gradient's direction
        // (what the general path below computes through the model and its derivative).
        return Some(EdgePoint {
            x: xd,
            y: yd,
            normal_angle: fast_atan2(gnx, gny),
        });
    }
    // The tangent along the edge: the gradient turned by +90°.
    let (tx, ty) = (-gny, gnx);
    let (x, y) = camera.undistort_normalised(xd, yd)?;
    let r2 = x * x + y * y;
    let f = 1.0 + camera.k1 * r2 + camera.k2 * r2 * r2;
    let g = 2.0 * (camera.k1 + 2.0 * camera.k2 * r2);
    // `f + g·r²` is the inverse model's Newton slope, which it keeps above zero.
    let along_p = g * (x * tx + y * ty) / (f + g * r2);
    let (tux, tuy) = (tx - along_p * x, ty - along_p * y);
    // Normal = tangent turned back by −90°, so it still points towards the brighter side.
    let normal_angle = fast_atan2(tuy, -tux);
    Some(EdgePoint { x, y, normal_angle })
}

/// `atan2(y, x)` within 2e-6 rad (0.0001°), for every edge point: libm's exact `atan2f` was a
/// tenth of the detector's time, and the angle only picks 1° Hough bins and a ±30° filter.
/// NaN in, NaN out; (0, 0) gives 0.
#[inline]
pub(crate) fn fast_atan2(y: f32, x: f32) -> f32 {
    use core::f32::consts::{FRAC_PI_2, PI};
    let (ax, ay) = (libm::fabsf(x), libm::fabsf(y));
    let (small, large) = if ay <= ax { (ay, ax) } else { (ax, ay) };
    if large == 0.0 {
        return 0.0;
    }
    // Minimax polynomial of atan on [0, 1] (odd, degree 11).
    let a = small / large;
    let s = a * a;
    let mut r = a
        * (0.999_977_2
            + s * (-0.332_622_9
                + s * (0.193_540_9 + s * (-0.116_427_84 + s * (0.052_648_87 - s * 0.011_719_74)))));
    if ay > ax {
        r = FRAC_PI_2 - r;
    }
    if x < 0.0 {
        r = PI - r;
    }
    if y < 0.0 { -r } else { r }
}

/// A sky/ground statistics sample: one point of a coarse grid over the frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sample {
    /// Normalised undistorted position.
    pub x: f32,
    pub y: f32,
    pub luma: f32,
    /// Blue minus red (0 for grey frames): the sky is bluer than the ground in daylight.
    pub chroma: f32,
    /// Local contrast: the ground is textured, the sky mostly smooth.
    pub texture: f32,
}

impl Sample {
    pub const ZERO: Sample = Sample {
        x: 0.0,
        y: 0.0,
        luma: 0.0,
        chroma: 0.0,
        texture: 0.0,
    };
}

/// Sample grid step (working pixels) for a working image: about 64 samples across.
pub(crate) fn sample_step(geo: Working) -> usize {
    geo.width.div_ceil(64).max(1)
}

pub(crate) fn sample_count(geo: Working) -> usize {
    let (_, columns, rows) = sample_grid(geo);
    columns * rows
}

/// The sample grid: its step, columns and rows.
fn sample_grid(geo: Working) -> (usize, usize, usize) {
    let step = sample_step(geo);
    (step, geo.width / step, geo.height / step)
}

/// The working pixel (column or row) of the `i`th sample along an axis: the middle of its
/// step. [`SamplePoints`] keeps the grid [`collect_samples`] reads through this one place.
fn sample_pixel(step: usize, i: usize) -> usize {
    i * step + step / 2
}

/// Most samples whose undistorted positions [`SamplePoints`] keeps: the grid of a working
/// image 192 px wide at 4:3 (64 × 48 samples; 160 px: 53 × 40).
const KEPT_SAMPLES: usize = 64 * 48;

/// The undistorted positions of the sample grid on a distorted camera, kept from frame to
/// frame (see [`UndistortedGrid`]): a frame reads its samples once or twice, over two
/// thousand points at 320×240.
pub(crate) struct SamplePoints(UndistortedGrid<KEPT_SAMPLES>);

impl SamplePoints {
    pub(crate) const fn new() -> Self {
        SamplePoints(UndistortedGrid::new())
    }

    /// Undistorts the grid [`collect_samples`] reads for `camera` and `geo`, unless it is
    /// already.
    pub(crate) fn prepare(&mut self, camera: &Camera, geo: Working) {
        let (step, columns, rows) = sample_grid(geo);
        let at = |i: usize| sample_pixel(step, i);
        self.0.prepare(camera, geo, (columns, at), (rows, at));
    }
}

/// Fills `samples` on a regular grid; returns how many were written.
pub(crate) fn collect_samples(
    frame: &Frame<'_>,
    grey: &[u8],
    geo: Working,
    (camera, kept): (&Camera, &SamplePoints),
    samples: &mut [Sample],
) -> usize {
    let (step, cols, rows) = sample_grid(geo);
    let kept = kept.0.for_view(camera, geo);
    let colour = matches!(frame.pixels(), Pixels::Rgb(_));
    let pixel = |x: usize, y: usize| -> f32 {
        let x = x.min(geo.width.saturating_sub(1));
        let y = y.min(geo.height.saturating_sub(1));
        grey.get(y * geo.width + x).map_or(0.0, |&p| f32::from(p))
    };
    let mut count = 0;
    for gy in 0..rows {
        for gx in 0..cols {
            let (wx, wy) = (sample_pixel(step, gx), sample_pixel(step, gy));
            let undistorted = kept.and_then(|k| k.get(gx, gy)).unwrap_or_else(|| {
                let (u, v) = geo.to_frame(wx as f32, wy as f32);
                camera.undistort_pixel(u, v)
            });
            let Some((x, y)) = undistorted else {
                continue;
            };
            let chroma = if colour {
                let (fx, fy) = (
                    wx * geo.scale + geo.scale / 2,
                    wy * geo.scale + geo.scale / 2,
                );
                let (r, _, b) = frame.rgb_at(fx, fy);
                f32::from(b) - f32::from(r)
            } else {
                0.0
            };
            let texture = libm::fabsf(pixel(wx + 1, wy) - pixel(wx.saturating_sub(1), wy))
                + libm::fabsf(pixel(wx, wy + 1) - pixel(wx, wy.saturating_sub(1)));
            let Some(slot) = samples.get_mut(count) else {
                return count;
            };
            *slot = Sample {
                x,
                y,
                luma: pixel(wx, wy),
                chroma,
                texture,
            };
            count += 1;
        }
    }
    count
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_from_kept_points_are_the_samples_undistorted_where_they_are_read() {
        let (width, height) = (320, 240);
        let rgb: std::vec::Vec<u8> = (0..width * height * 3)
            .map(|i| ((i * 2_654_435_761usize) >> 11) as u8)
            .collect();
        let frame = Frame::new(width, height, 3 * width, Pixels::Rgb(&rgb)).expect("a frame");
        let mut camera = Camera::ideal(320, 240, 75f32.to_radians());
        (camera.k1, camera.k2) = (-0.27, 0.05);
        let geo = Working::for_frame(width, height);
        let mut grey = std::vec![0u8; geo.width * geo.height];
        build_working_image(&frame, geo, &mut grey);
        let mut kept = SamplePoints::new();
        kept.prepare(&camera, geo);
        // Kept for another camera, or for none: each sample is undistorted where it is read.
        let mut stale = SamplePoints::new();
        stale.prepare(&Camera { k1: 0.1, ..camera }, geo);
        let none = SamplePoints::new();
        let count = sample_count(geo);
        let read = |points: &SamplePoints| {
            let mut samples = std::vec![Sample::default(); count];
            let n = collect_samples(&frame, &grey, geo, (&camera, points), &mut samples);
            samples.truncate(n);
            samples
        };
        let reference = read(&none);
        assert_eq!(reference.len(), count);
        assert_eq!(read(&kept), reference);
        assert_eq!(read(&stale), reference);
        // The positions are undistorted ones: the corner samples moved outwards.
        let first = reference.first().expect("samples");
        let (u, v) = geo.to_frame(1.0, 1.0);
        assert!(first.x < (u - camera.cx) / camera.fx && first.y < (v - camera.cy) / camera.fy);
    }

    /// A level step of 8 levels on a ramp brightening one level a working pixel along it: its
    /// Sobel directions are turned by 14° (the ramp's 8 against the step's 32), its step's
    /// directions are level.
    #[test]
    fn a_step_on_a_ramp_keeps_its_own_direction_with_the_ramp_taken_out() {
        let geo = Working::with_scale(320, 240, 2);
        let camera = Camera::ideal(320, 240, 60f32.to_radians());
        let step_row = geo.height / 2;
        let grey: std::vec::Vec<u8> = (0..geo.width * geo.height)
            .map(|i| {
                let (x, y) = (i % geo.width, i / geo.width);
                (40 + x + if y < step_row { 8 } else { 0 }) as u8
            })
            .collect();
        // Degrees off level of each edge point along the step, away from the image's sides.
        let off_level = |ramps_removed: bool| {
            let mut rows = std::vec![0u16; EDGE_SCRATCH_ROWS * geo.width];
            let mut edges = std::vec![EdgePoint::ZERO; 4 * geo.width];
            let stats = collect_edges(
                &grey,
                geo,
                &mut rows,
                20,
                &camera,
                &mut edges,
                ramps_removed,
            );
            let inner = (geo.to_frame(8.0, 0.0).0 - camera.cx) / camera.fx;
            let angles: std::vec::Vec<f32> = edges
                .get(..stats.count)
                .unwrap_or(&[])
                .iter()
                .filter(|p| libm::fabsf(p.x) < libm::fabsf(inner))
                .map(|p| {
                    // The brighter side is above: the normal points up, at 180°.
                    let off = (p.normal_angle.to_degrees() - 180.0 + 540.0) % 360.0 - 180.0;
                    libm::fabsf(off)
                })
                .collect();
            assert!(angles.len() > geo.width / 2, "{} points", angles.len());
            angles
        };
        for off in off_level(false) {
            assert!((10.0..20.0).contains(&off), "Sobel: {off}° off level");
        }
        for off in off_level(true) {
            assert!(off < 0.5, "the ramp taken out: {off}° off level");
        }
    }

    /// The undistorted normal read through the model's derivative, checked against the
    /// distortion itself: a short step from the undistorted point along the undistorted
    /// edge lands, once distorted, along the edge in the image (perpendicular to its
    /// gradient), and the normal still points up the gradient.
    #[test]
    fn an_edge_direction_through_the_derivative_is_the_edge_in_the_image() {
        let mut camera = Camera::ideal(320, 240, 80f32.to_radians());
        for (k1, k2) in [(-0.3f32, 0.08f32), (0.15, -0.02), (-0.05, 0.0)] {
            (camera.k1, camera.k2) = (k1, k2);
            let mut worst = 0.0f32;
            for (u, v) in [
                (3.0f32, 4.0f32),
                (160.0, 120.0),
                (300.0, 30.0),
                (40.0, 230.0),
            ] {
                for gradient_deg in (0..360).step_by(15) {
                    let a = (gradient_deg as f32).to_radians();
                    let (gx, gy) = (
                        (100.0 * libm::cosf(a)) as i32,
                        (100.0 * libm::sinf(a)) as i32,
                    );
                    let point = undistort_edge(&camera, u, v, gx, gy).expect("inside the model");
                    // The edge's direction in the undistorted plane: square to the normal
                    // `(sin, cos)` of the angle, as a Hough line's.
                    let (nx, ny) = (
                        libm::sinf(point.normal_angle),
                        libm::cosf(point.normal_angle),
                    );
                    let (ex, ey) = (ny, -nx);
                    let step = 1e-3;
                    let (ax, ay) =
                        camera.distort_normalised(point.x - step * ex, point.y - step * ey);
                    let (bx, by) =
                        camera.distort_normalised(point.x + step * ex, point.y + step * ey);
                    // In pixels: across the image gradient there is no change of level.
                    let (du, dv) = ((bx - ax) * camera.fx, (by - ay) * camera.fy);
                    let (gnx, gny) = (gx as f32, gy as f32);
                    // The angle off square to the gradient.
                    let cosine =
                        (du * gnx + dv * gny) / libm::hypotf(du, dv) / libm::hypotf(gnx, gny);
                    worst = worst.max(libm::fabsf(libm::asinf(cosine.clamp(-1.0, 1.0))));
                    // The normal is on the brighter side: turning the image gradient into the
                    // undistorted plane keeps it within 90° of the normal.
                    let up_the_gradient = camera.undistort_pixel(u + gnx * 0.01, v + gny * 0.01);
                    let (dx, dy) = up_the_gradient
                        .map(|(x, y)| (x - point.x, y - point.y))
                        .expect("inside the model");
                    assert!(
                        dx * nx + dy * ny > 0.0,
                        "normal flipped at ({u}, {v}), {gradient_deg}°"
                    );
                }
            }
            // Within a hundredth of a degree of the image's edge direction.
            assert!(worst < 2e-4, "k1 {k1}, k2 {k2}: off by {worst} rad");
        }
    }
}
