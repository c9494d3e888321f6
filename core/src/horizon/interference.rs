//! Periodic interference found in the working image's spectrum and removed by a notch.
//!
//! An analogue link adds a co-channel pattern across the frame: a sinusoid at any angle
//! whose crests bend as its frequency drifts down the frame (a chirp), shaken sideways row by
//! row by the line timebase. [`super::stripes`] measures a sinusoid along the crests of a
//! line the Hough stage chose, which needs straight crests next to that line; a bent,
//! jittered pattern at an angle to the horizon draws neither, scatters the horizon's edge
//! points and leaves a compromise line (`terrain` `clean` through `aerial_set.py`'s analogue
//! link at 320 px: 16–34 of 40 frames within 2°).
//!
//! In the spectrum such a pattern is a spike, where a scene's edges are ridges: a straight
//! edge's power falls with the frequency along the edge's normal, so across that line the
//! strongest bin of a band has neighbours as strong nearer the origin. The spike is found in
//! the spectrum of the windowed working image ([`find`]): the strongest bin whose power is
//! [`ISOLATION`] times that of the bins in its own direction nearer to and farther from
//! the origin. It is then removed in the image itself ([`remove`]): the image is
//! demodulated at the spike's frequency, low-passed (the pattern's slowly changing amplitude
//! and phase, drift and bend included), modulated back and subtracted. That is a Gaussian
//! notch of [`NOTCH_BINS`] bins about the spike and its mirror, without an inverse transform,
//! and without the transform's wrap-around at the borders.
//!
//! Crests within about 15° of a strong horizon put the spike on the horizon's own ridge,
//! where it does not stand out; those are [`super::stripes`]' case.

use super::edges::Working;
use super::fft::{self, LANES, Lanes};
use core::f32::consts::PI;
use microfft::Complex32;

/// Largest transform along either axis (the working image is at most 200 px wide; a taller
/// working image is left as it is).
const MAX_SIDE: usize = 256;
/// Periods a pattern may have, in working pixels: two (the working image's Nyquist) to 24
/// (`aerial`'s links draw 4–40 frame pixels: 2–20 working pixels at 320 px, 1–10 at 640).
const MIN_PERIOD: f32 = 2.0;
const MAX_PERIOD: f32 = 24.0;
/// How many times a spike's power must exceed that of the strongest bins about the same
/// direction at [`RADIAL_SHARE`] of its frequency nearer and farther (but at least
/// [`RADIAL_BINS`] bins away). On the tuning sets as rendered, frames with no pattern: at
/// most 2.6; frames with `aerial`'s analogue pattern: 3–10⁷, most over 70.
const ISOLATION: f32 = 8.0;
const RADIAL_SHARE: f32 = 0.3;
const RADIAL_BINS: f32 = 5.0;
/// The notch's Gaussian radius in bins of the working image (one bin: a cycle over its
/// width, or its height): the pattern's chirp spreads it over about two bins.
const NOTCH_BINS: f32 = 2.5;

/// A periodic pattern: its frequency in cycles per working pixel along x and y.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Pattern {
    pub fx: f32,
    pub fy: f32,
}

impl Pattern {
    pub(crate) fn period(&self) -> f32 {
        1.0 / libm::hypotf(self.fx, self.fy)
    }
}

/// The transform's size for a working image: each side padded with zeros to the power of
/// two at or over it, or `None` when that is under 16 or over [`MAX_SIDE`]. Cropping a
/// 160 × 120 working image to its middle 128 columns halved the transform's time but put
/// long periods (16 working pixels and more) within a few bins of the frame's own low
/// frequencies, where their spikes no longer stood out (`terrain` `clean` through the
/// chain's `interference` link, seed 18 at 320 px: 35 → 21 of 40 within 2°).
pub(crate) fn transform_size(width: usize, height: usize) -> Option<(usize, usize)> {
    let (nx, ny) = (
        width.checked_next_power_of_two()?,
        height.checked_next_power_of_two()?,
    );
    let fits = |n: usize| (16..=MAX_SIDE).contains(&n);
    (fits(nx) && fits(ny)).then_some((nx, ny))
}

/// Complex values the scratch buffer must hold for a working image: the half spectrum
/// (`ny` rows of `nx / 2` bins), or [`remove`]'s blocks, whichever is more.
pub fn scratch_len(width: usize, height: usize) -> usize {
    transform_size(width, height).map_or(0, |(nx, ny)| {
        (ny * nx / 2).max(width.div_ceil(BLOCK) * height.div_ceil(BLOCK))
    })
}

/// The strongest isolated spike in the working image's spectrum, if there is one.
pub(crate) fn find(grey: &[u8], geo: Working, scratch: &mut [Complex32]) -> Option<Pattern> {
    let (nx, ny) = windowed_spectrum(grey, geo, scratch)?;
    strongest_spike(scratch, nx, ny)
}

/// The search of [`find`] in a spectrum laid out by [`windowed_spectrum`].
fn strongest_spike(scratch: &[Complex32], nx: usize, ny: usize) -> Option<Pattern> {
    let half = nx / 2;
    let spectrum: &[Complex32] = scratch.get(..ny * half)?;
    // Power at bin (kx, ky), kx of either sign (the other half by symmetry), ky wrapped.
    let power = |kx: i32, ky: i32| -> f32 {
        let (kx, ky) = if kx < 0 { (-kx, -ky) } else { (kx, ky) };
        let ky = ky.rem_euclid(ny as i32);
        if kx >= half as i32 {
            return 0.0;
        }
        spectrum
            .get(ky as usize * half + kx as usize)
            .map_or(0.0, |c| c.norm_sqr())
    };
    // The band, in squared cycles per pixel.
    let (low, high) = (
        1.0 / (MAX_PERIOD * MAX_PERIOD),
        1.0 / (MIN_PERIOD * MIN_PERIOD),
    );
    let mut best: Option<(f32, i32, i32)> = None;
    for (row, bins) in spectrum.chunks_exact(half).enumerate() {
        // Row `row` holds ky = row for the upper half, row − ny for the lower.
        let ky = if row < ny / 2 {
            row as i32
        } else {
            row as i32 - ny as i32
        };
        if ky == -(ny as i32 / 2) {
            continue;
        }
        let fy = ky as f32 / ny as f32;
        let fy2 = fy * fy;
        if fy2 > high {
            continue;
        }
        // Along kx = 0 only the upper half: the lower half mirrors it.
        let first = usize::from(ky <= 0);
        for (kx, bin) in bins.iter().enumerate().skip(first) {
            let fx = kx as f32 / nx as f32;
            let f2 = fx * fx + fy2;
            if f2 < low || f2 > high {
                continue;
            }
            let p = bin.norm_sqr();
            if best.is_none_or(|(b, _, _)| p > b) {
                best = Some((p, kx as i32, ky));
            }
        }
    }
    let (peak, kx, ky) = best?;
    if peak <= 0.0 {
        return None;
    }
    let (fx, fy) = (kx as f32 / nx as f32, ky as f32 / ny as f32);
    let f = libm::hypotf(fx, fy);
    let reach = RADIAL_SHARE.max(RADIAL_BINS / (f * nx.max(ny) as f32));
    let around = |scale: f32| -> f32 {
        let (cx, cy) = (
            libm::roundf(fx * scale * nx as f32) as i32,
            libm::roundf(fy * scale * ny as f32) as i32,
        );
        let mut most = 0.0f32;
        for dy in -1..=1 {
            for dx in -1..=1 {
                most = most.max(power(cx + dx, cy + dy));
            }
        }
        most
    };
    let neighbours = around(1.0 - reach).max(around(1.0 + reach));
    // Crests along a strong edge (a horizon under stripes nearly parallel to it): the spike
    // lies on the edge's own ridge, which a notch would cut into (a horizon under crests 2°
    // off it rang into a false step 3° under it, trusted at 0.5). Those are `stripes`' case:
    // nearer the origin along the spike's direction the ridge stands out of the directions
    // either side of it.
    let turned = |turn: f32| -> f32 {
        let (s, c) = (libm::sinf(turn), libm::cosf(turn));
        let scale = 1.0 - reach;
        let (tx, ty) = (fx * c - fy * s, fx * s + fy * c);
        power(
            libm::roundf(tx * scale * nx as f32) as i32,
            libm::roundf(ty * scale * ny as f32) as i32,
        )
    };
    let along = turned(0.0);
    let aside = turned(RIDGE_TURN).max(turned(-RIDGE_TURN));
    if along > ALONG_AN_EDGE * aside {
        return None;
    }
    let isolation = if neighbours > 0.0 {
        peak / neighbours
    } else {
        f32::INFINITY
    };
    if isolation < ISOLATION {
        return None;
    }
    // The spike's centre between bins, from a Gaussian through the bin and its neighbours
    // (the Hann window's lobe is nearly one): at 160 × 120 a bin is 1/256 of a cycle a pixel
    // across and 1/128 down, and demodulating half a bin off turns the envelope through up to
    // half a cycle across the image, which the low-pass then averages away.
    let centre = |before: f32, at: f32, after: f32| -> f32 {
        let (a, b, c) = (
            libm::logf(before.max(1e-30)),
            libm::logf(at.max(1e-30)),
            libm::logf(after.max(1e-30)),
        );
        let curvature = a - 2.0 * b + c;
        if curvature < 0.0 {
            (0.5 * (a - c) / curvature).clamp(-0.5, 0.5)
        } else {
            0.0
        }
    };
    let dx = centre(power(kx - 1, ky), peak, power(kx + 1, ky));
    let dy = centre(power(kx, ky - 1), peak, power(kx, ky + 1));
    let refined = Pattern {
        fx: (kx as f32 + dx) / nx as f32,
        fy: (ky as f32 + dy) / ny as f32,
    };
    // On a working image a few rows tall a bin is a wide step of frequency, and half a bin
    // can carry a spike at the band's edge out of it (the property test of any pixels found
    // one on a 220 × 17 image); the bin's own centre, inside the band, is kept then.
    let in_band = (MIN_PERIOD..=MAX_PERIOD).contains(&refined.period());
    Some(if in_band { refined } else { Pattern { fx, fy } })
}

/// The spectrum of the working image, Hann-windowed and zero-padded to the transform's size
/// `(nx, ny)` ([`transform_size`]), which it returns: `ny` rows of the bins `kx` 0 to
/// `nx / 2 − 1` in `scratch`, row `ky` for `ky < ny / 2` and `ky − ny` from there.
fn windowed_spectrum(
    grey: &[u8],
    geo: Working,
    scratch: &mut [Complex32],
) -> Option<(usize, usize)> {
    let (w, h) = (geo.width, geo.height);
    let (nx, ny) = transform_size(w, h)?;
    let half = nx / 2;
    let spectrum = scratch.get_mut(..ny * half)?;
    let pixels = grey.get(..w * h)?;
    let mean = mean_level(pixels);
    // Hann windows along each axis: without one, the frame's borders (sky at the top,
    // ground at the bottom) are a step in the periodic transform, and its leakage a ridge.
    let mut window_x = [0.0f32; MAX_SIDE];
    let mut window_y = [0.0f32; MAX_SIDE];
    for (i, v) in window_x.iter_mut().take(w).enumerate() {
        *v = hann(i, w);
    }
    for (i, v) in window_y.iter_mut().take(h).enumerate() {
        *v = hann(i, h);
    }
    // Rows: the transform of each image row, zero-padded to `nx`, two rows at a time as the
    // real and imaginary parts of one sequence and sixteen rows in one pass of
    // `fft::transform`. Of each row's spectrum the bins 0 to `nx / 2 − 1` are kept (the rest
    // mirror them); the column of bin `nx / 2`, a period of two along x, is not searched.
    let mut lanes = [Lanes::default(); fft::MAX_POINTS];
    for (pass, out) in spectrum.chunks_mut(half * 2 * LANES).enumerate() {
        lanes.fill(Lanes::default());
        for (pair, rows) in (pass * 2 * LANES..).step_by(2).take(LANES).enumerate() {
            for (y, imaginary) in [(rows, false), (rows + 1, true)] {
                // Rows under the image are the padding: zeros.
                let (Some(src), Some(&wy)) = (pixels.get(y * w..(y + 1) * w), window_y.get(y))
                else {
                    continue;
                };
                for ((lane, &v), &wx) in lanes.iter_mut().zip(src).zip(&window_x) {
                    let part = if imaginary {
                        &mut lane.im
                    } else {
                        &mut lane.re
                    };
                    if let Some(p) = part.get_mut(pair) {
                        *p = (f32::from(v) - mean) * wx * wy;
                    }
                }
            }
        }
        if !fft::transform(&mut lanes, nx) {
            return None;
        }
        // Bin kx of row pair `pair` goes to rows 2·pair and 2·pair + 1 of the pass.
        for (kx, z) in lanes.iter().take(half).enumerate() {
            let mirror = lanes.get((nx - kx) % nx).copied().unwrap_or_default();
            let pairs = z.re.iter().zip(&z.im).zip(mirror.re.iter().zip(&mirror.im));
            for (pair, ((&zr, &zi), (&mr, &mi))) in pairs.enumerate() {
                let (a, b) = fft::split_real_pair((zr, zi), (mr, mi));
                if let Some(o) = out.get_mut(2 * pair * half + kx) {
                    *o = Complex32::new(a.0, a.1);
                }
                if let Some(o) = out.get_mut((2 * pair + 1) * half + kx) {
                    *o = Complex32::new(b.0, b.1);
                }
            }
        }
    }
    // Columns: the transform of each of the `nx / 2` columns, eight at a time.
    for x0 in (0..half).step_by(LANES) {
        for (lane, row) in lanes.iter_mut().zip(spectrum.chunks_exact(half)) {
            let bins = row.get(x0..x0 + LANES).unwrap_or(&[]);
            for ((re, im), c) in lane.re.iter_mut().zip(lane.im.iter_mut()).zip(bins) {
                *re = c.re;
                *im = c.im;
            }
        }
        if !fft::transform(&mut lanes, ny) {
            return None;
        }
        for (lane, row) in lanes.iter().zip(spectrum.chunks_exact_mut(half)) {
            let bins = row.get_mut(x0..x0 + LANES).unwrap_or(&mut []);
            for ((&re, &im), c) in lane.re.iter().zip(&lane.im).zip(bins) {
                *c = Complex32::new(re, im);
            }
        }
    }
    Some((nx, ny))
}

/// An edge's ridge through the spike (see [`find`]): the power nearer the origin along the
/// spike's direction this many times that at the same frequency [`RIDGE_TURN`] either side.
const ALONG_AN_EDGE: f32 = 4.0;
const RIDGE_TURN: f32 = 20.0 * PI / 180.0;

/// Working pixels a side of the blocks the pattern's envelope is low-passed on: the
/// envelope changes over tens of pixels (the notch's Gaussian is 10 px across at 160 px).
const BLOCK: usize = 4;

/// Subtracts `pattern` from the working image: demodulated at its frequency, averaged in
/// blocks of [`BLOCK`] pixels, low-passed by three normalised box filters (a Gaussian of
/// [`NOTCH_BINS`] bins), interpolated back to the pixels and modulated back.
pub(crate) fn remove(grey: &mut [u8], geo: Working, pattern: Pattern, scratch: &mut [Complex32]) {
    let (w, h) = (geo.width, geo.height);
    if w > MAX_SIDE || h > MAX_SIDE || w == 0 || h == 0 {
        return;
    }
    let (bw, bh) = (w.div_ceil(BLOCK), h.div_ceil(BLOCK));
    let Some(blocks) = scratch.get_mut(..bw * bh) else {
        return;
    };
    let Some(pixels) = grey.get_mut(..w * h) else {
        return;
    };
    let mean = mean_level(pixels);
    // The image times the carrier e^{-i·2π(fx·x + fy·y)} (by rotation along each row from
    // its value at the row's start), summed into blocks.
    blocks.fill(Complex32::new(0.0, 0.0));
    let step = unit(-2.0 * PI * pattern.fx);
    for (y, src) in pixels.chunks_exact(w).enumerate() {
        let Some(row) = blocks.get_mut((y / BLOCK) * bw..(y / BLOCK + 1) * bw) else {
            break;
        };
        let mut carrier = unit(-2.0 * PI * pattern.fy * y as f32);
        for (chunk, block) in src.chunks(BLOCK).zip(row.iter_mut()) {
            for &v in chunk {
                *block += carrier * (f32::from(v) - mean);
                carrier *= step;
            }
        }
    }
    // Sums to means: a block on the right or bottom edge may hold fewer pixels.
    for (by, row) in blocks.chunks_exact_mut(bw).enumerate() {
        let rows = (h - by * BLOCK).min(BLOCK);
        for (bx, block) in row.iter_mut().enumerate() {
            let columns = (w - bx * BLOCK).min(BLOCK);
            *block /= (rows * columns) as f32;
        }
    }
    // A Gaussian of σ bins in frequency is one of w / (2π·σ) pixels across a row (a bin is
    // a cycle over the width) and h / (2π·σ) down a column; in blocks, a BLOCK-th of that.
    let sigma_x = w as f32 / (2.0 * PI * NOTCH_BINS * BLOCK as f32);
    let sigma_y = h as f32 / (2.0 * PI * NOTCH_BINS * BLOCK as f32);
    for (rx, ry) in box_radii(sigma_x).into_iter().zip(box_radii(sigma_y)) {
        blur_rows(blocks, bw, bh, rx);
        blur_columns(blocks, bw, bh, ry);
    }
    let blocks: &[Complex32] = blocks;
    // Each pixel's place among the blocks' centres: the block to its left (or above) and the
    // weight of the next one.
    let place = |i: usize, n: usize| -> (usize, usize, f32) {
        let t = ((i as f32 + 0.5) / BLOCK as f32 - 0.5).max(0.0);
        let first = (t as usize).min(n - 1);
        let next = (first + 1).min(n - 1);
        (first, next, t - first as f32)
    };
    let mut columns = [(0usize, 0usize, 0.0f32); MAX_SIDE];
    for (x, c) in columns.iter_mut().take(w).enumerate() {
        *c = place(x, bw);
    }
    let step = unit(2.0 * PI * pattern.fx);
    let mut line = [Complex32::new(0.0, 0.0); MAX_SIDE];
    for (y, out) in pixels.chunks_exact_mut(w).enumerate() {
        // The envelope along this row, at the blocks' columns.
        let (above, below, t) = place(y, bh);
        let (Some(a), Some(b)) = (
            blocks.get(above * bw..(above + 1) * bw),
            blocks.get(below * bw..(below + 1) * bw),
        ) else {
            break;
        };
        for ((l, &a), &b) in line.iter_mut().zip(a).zip(b) {
            *l = a + (b - a) * t;
        }
        let mut carrier = unit(2.0 * PI * pattern.fy * y as f32);
        for (o, &(left, right, s)) in out.iter_mut().zip(&columns) {
            let (Some(&l), Some(&r)) = (line.get(left), line.get(right)) else {
                break;
            };
            // The pattern's two spikes (at ±f) are the envelope's twice its real part.
            let wave = 2.0 * (carrier * (l + (r - l) * s)).re;
            // Rounded to the nearest level (the value is never negative here).
            *o = (f32::from(*o) - wave + 0.5).clamp(0.0, 255.0) as u8;
            carrier *= step;
        }
    }
}

/// The radii of three box filters whose succession has a standard deviation nearest
/// `sigma` (a box of radius r has variance r·(r + 1) / 3), each at least 1.
fn box_radii(sigma: f32) -> [usize; 3] {
    let variance = |r: usize| (r * (r + 1)) as f32 / 3.0;
    let wanted = sigma * sigma;
    let mut radii = [1usize; 3];
    // Widen one box at a time while that brings the sum nearer.
    for _ in 0..3 * MAX_SIDE {
        let now: f32 = radii.iter().map(|&r| variance(r)).sum();
        let Some(narrowest) = radii.iter_mut().min() else {
            break;
        };
        let wider = now - variance(*narrowest) + variance(*narrowest + 1);
        if libm::fabsf(wider - wanted) >= libm::fabsf(now - wanted) {
            break;
        }
        *narrowest += 1;
    }
    radii
}

/// Each row replaced by its mean over `2·radius + 1` columns, the window clipped at the
/// row's ends (a mean over the pixels there are).
fn blur_rows(field: &mut [Complex32], width: usize, height: usize, radius: usize) {
    blur_lines(field, (height, width), (width, 1), radius);
}

/// As [`blur_rows`], down each column.
fn blur_columns(field: &mut [Complex32], width: usize, height: usize, radius: usize) {
    blur_lines(field, (width, height), (1, width), radius);
}

/// [`box_mean`] along `lines` lines of `length` values each: line `i`'s value `j` at
/// `i·between + j·along` in `field`.
fn blur_lines(
    field: &mut [Complex32],
    (lines, length): (usize, usize),
    (between, along): (usize, usize),
    radius: usize,
) {
    let mut line = [Complex32::new(0.0, 0.0); MAX_SIDE];
    let mut out = [Complex32::new(0.0, 0.0); MAX_SIDE];
    for i in 0..lines {
        for (j, l) in line.iter_mut().take(length).enumerate() {
            *l = field
                .get(i * between + j * along)
                .copied()
                .unwrap_or_default();
        }
        box_mean(
            line.get(..length).unwrap_or(&[]),
            out.get_mut(..length).unwrap_or(&mut []),
            radius,
        );
        for (j, o) in out.iter().take(length).enumerate() {
            if let Some(f) = field.get_mut(i * between + j * along) {
                *f = *o;
            }
        }
    }
}

/// `out[i]` = the mean of `input` over `i − radius ..= i + radius`, clipped to the input.
fn box_mean(input: &[Complex32], out: &mut [Complex32], radius: usize) {
    let n = input.len();
    let mut sum = Complex32::new(0.0, 0.0);
    // The window's sum is carried along: the first `radius` values are in it at the start.
    for v in input.iter().take(radius) {
        sum += *v;
    }
    for (i, o) in out.iter_mut().enumerate().take(n) {
        if let Some(v) = input.get(i + radius) {
            sum += *v;
        }
        if i > radius
            && let Some(v) = input.get(i - radius - 1)
        {
            sum -= *v;
        }
        let count = (i + radius).min(n - 1) + 1 - i.saturating_sub(radius);
        *o = sum / count as f32;
    }
}

/// The mean of the pixels (0 for none).
fn mean_level(pixels: &[u8]) -> f32 {
    pixels.iter().map(|&v| u32::from(v)).sum::<u32>() as f32 / pixels.len().max(1) as f32
}

/// The Hann window's value at sample `i` of `n`.
fn hann(i: usize, n: usize) -> f32 {
    0.5 - 0.5 * libm::cosf(2.0 * PI * (i as f32 + 0.5) / n as f32)
}

/// `e^{i·angle}`.
fn unit(angle: f32) -> Complex32 {
    Complex32::new(libm::cosf(angle), libm::sinf(angle))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec;
    use std::vec::Vec;

    /// The real transform of `row`'s first `n` values (`n` a power of two up to [`MAX_SIDE`]).
    fn real_transform(row: &mut [f32; MAX_SIDE], n: usize) -> Option<&[Complex32]> {
        Some(match n {
            16 => microfft::real::rfft_16(row.first_chunk_mut::<16>()?),
            32 => microfft::real::rfft_32(row.first_chunk_mut::<32>()?),
            64 => microfft::real::rfft_64(row.first_chunk_mut::<64>()?),
            128 => microfft::real::rfft_128(row.first_chunk_mut::<128>()?),
            256 => microfft::real::rfft_256(row),
            _ => return None,
        })
    }

    /// The complex transform of `column`'s first `n` values (`n` a power of two up to
    /// [`MAX_SIDE`]).
    fn complex_transform(column: &mut [Complex32; MAX_SIDE], n: usize) -> Option<&[Complex32]> {
        Some(match n {
            16 => microfft::complex::cfft_16(column.first_chunk_mut::<16>()?),
            32 => microfft::complex::cfft_32(column.first_chunk_mut::<32>()?),
            64 => microfft::complex::cfft_64(column.first_chunk_mut::<64>()?),
            128 => microfft::complex::cfft_128(column.first_chunk_mut::<128>()?),
            256 => microfft::complex::cfft_256(column),
            _ => return None,
        })
    }

    /// The spectrum as `find` took it before the transforms were batched: each row by
    /// `microfft`'s real transform, then each column by its complex one.
    fn microfft_spectrum(grey: &[u8], geo: Working, spectrum: &mut [Complex32]) -> (usize, usize) {
        let (w, h) = (geo.width, geo.height);
        let (nx, ny) = transform_size(w, h).expect("a transform size");
        let half = nx / 2;
        let pixels = &grey[..w * h];
        let mean = mean_level(pixels);
        let window_x: Vec<f32> = (0..w).map(|i| hann(i, w)).collect();
        for (y, out) in spectrum[..ny * half].chunks_exact_mut(half).enumerate() {
            if y >= h {
                out.fill(Complex32::new(0.0, 0.0));
                continue;
            }
            let wy = hann(y, h);
            let mut row = [0.0f32; MAX_SIDE];
            for ((r, &v), &wx) in row
                .iter_mut()
                .zip(&pixels[y * w..(y + 1) * w])
                .zip(&window_x)
            {
                *r = (f32::from(v) - mean) * wx * wy;
            }
            let bins = real_transform(&mut row, nx).expect("a size microfft has");
            out.copy_from_slice(&bins[..half]);
            out[0].im = 0.0;
        }
        for x in 0..half {
            let mut column = [Complex32::new(0.0, 0.0); MAX_SIDE];
            for y in 0..ny {
                column[y] = spectrum[y * half + x];
            }
            let bins = complex_transform(&mut column, ny).expect("a size microfft has");
            for y in 0..ny {
                spectrum[y * half + x] = bins[y];
            }
        }
        (nx, ny)
    }

    #[test]
    fn the_batched_spectrum_is_microffts_to_rounding() {
        // A textured horizon under a bent, shaken pattern, at three working sizes (160 × 120:
        // 320 × 240 frames; 100 × 75 is padded to 128 × 128; 40 × 30 to 64 × 32).
        for (w, h) in [(160, 120), (100, 75), (40, 30)] {
            let geo = Working::with_scale(w, h, 1);
            let scene = horizon(w, h, 10.0, 80.0, 2.0, 6.0);
            let wave = pattern(h, 10.0, 9.0, 30.0);
            let grey = image(w, h, |u, v| scene(u, v) + wave(u, v));
            let len = scratch_len(w, h);
            let (mut ours, mut theirs) = (
                vec![Complex32::new(0.0, 0.0); len],
                vec![Complex32::new(0.0, 0.0); len],
            );
            let sizes = windowed_spectrum(&grey, geo, &mut ours);
            assert_eq!(sizes, Some(microfft_spectrum(&grey, geo, &mut theirs)));
            let (nx, ny) = sizes.unwrap_or_default();
            let bins = ny * nx / 2;
            let largest = theirs[..bins]
                .iter()
                .map(|c| c.norm_sqr())
                .fold(0.0f32, f32::max);
            let tolerance = 1e-5 * libm::sqrtf(largest);
            for (i, (a, b)) in ours[..bins].iter().zip(&theirs[..bins]).enumerate() {
                assert!(
                    (a.re - b.re).abs() <= tolerance && (a.im - b.im).abs() <= tolerance,
                    "{w}×{h} bin {i}: {a:?} against microfft's {b:?} (largest {})",
                    libm::sqrtf(largest)
                );
            }
            // And the search's answer is the same.
            let found = strongest_spike(&ours, nx, ny);
            // (At 160 × 120 the pattern stands out; on the smaller images, whose horizon
            // spreads over more of the band, it does not, and neither path finds it.)
            assert_eq!(found.is_some(), w == 160, "{w}×{h}: {found:?}");
            assert_eq!(found, strongest_spike(&theirs, nx, ny), "{w}×{h}");
        }
    }

    const DEG: f32 = PI / 180.0;

    /// A working image of `w` × `h` from a luma function of the pixel.
    fn image(w: usize, h: usize, luma: impl Fn(f32, f32) -> f32) -> Vec<u8> {
        let mut out = vec![0u8; w * h];
        for (i, p) in out.iter_mut().enumerate() {
            let (u, v) = ((i % w) as f32, (i / w) as f32);
            *p = libm::roundf(luma(u, v)).clamp(0.0, 255.0) as u8;
        }
        out
    }

    /// A horizon through the centre at `roll_deg`, `step` levels from sky to ground, softened
    /// over `soft` pixels, the ground textured by ±`texture` levels.
    fn horizon(
        w: usize,
        h: usize,
        roll_deg: f32,
        step: f32,
        soft: f32,
        texture: f32,
    ) -> impl Fn(f32, f32) -> f32 {
        let (s, c) = (libm::sinf(roll_deg * DEG), libm::cosf(roll_deg * DEG));
        let (cx, cy) = (w as f32 / 2.0, h as f32 / 2.0);
        move |u, v| {
            let d = s * (u - cx) + c * (v - cy);
            let t = 0.5 + 0.5 * libm::tanhf(d / soft.max(0.01));
            let grain = libm::sinf(u * 12.9898 + v * 78.233) * 43_758.547;
            let grain = grain - libm::floorf(grain) - 0.5;
            180.0 - step * t + 2.0 * texture * grain * t
        }
    }

    /// An analogue link's pattern: `amplitude` levels, `period` px, crests at `angle_deg`
    /// from the columns, bent by a chirp down the frame and shaken sideways row by row.
    fn pattern(h: usize, amplitude: f32, period: f32, angle_deg: f32) -> impl Fn(f32, f32) -> f32 {
        shaken_pattern(h, amplitude, period, angle_deg, 1.0)
    }

    /// As [`pattern`], the rows shaken by up to `shake` px.
    fn shaken_pattern(
        h: usize,
        amplitude: f32,
        period: f32,
        angle_deg: f32,
        shake: f32,
    ) -> impl Fn(f32, f32) -> f32 {
        let (ca, sa) = (libm::cosf(angle_deg * DEG), libm::sinf(angle_deg * DEG));
        move |u, v| {
            let jitter = shake * (0.6 * libm::sinf(v * 0.9) + 0.4 * libm::sinf(v * 2.3 + 1.0));
            let along = (u + jitter) * ca + v * sa;
            let chirp = 0.6 * (v / h as f32) * (v / h as f32) * 2.0 * PI;
            amplitude * libm::sinf(2.0 * PI * along / period + chirp + 0.7)
        }
    }

    fn find_in(grey: &[u8], w: usize, h: usize) -> Option<Pattern> {
        let mut scratch = vec![Complex32::new(0.0, 0.0); scratch_len(w, h)];
        let geo = Working {
            scale: 1,
            width: w,
            height: h,
        };
        find(grey, geo, &mut scratch)
    }

    #[test]
    fn a_bent_shaken_pattern_over_a_horizon_is_found_at_its_frequency() {
        let (w, h) = (160, 120);
        for (roll, period, angle, amplitude) in [
            (10.0, 9.0, 30.0, 10.0),
            (-25.0, 17.0, 160.0, 10.0),
            (0.0, 3.0, 61.0, 12.0),
            (35.0, 12.0, 90.0, 8.0),
            (-5.0, 20.0, 176.0, 12.0),
        ] {
            let scene = horizon(w, h, roll, 80.0, 2.0, 6.0);
            let wave = pattern(h, amplitude, period, angle);
            let grey = image(w, h, |u, v| scene(u, v) + wave(u, v));
            let found = find_in(&grey, w, h);
            let found = found.unwrap_or_else(|| panic!("{period} px at {angle}°: not found"));
            // The chirp moves the frequency by up to 0.6 cycles over the height.
            assert!(
                libm::fabsf(found.period() / period - 1.0) < 0.08,
                "{period} px at {angle}°: found {:.2} px",
                found.period()
            );
            let direction = libm::atan2f(found.fy, found.fx) / DEG;
            let off = (direction - angle).rem_euclid(180.0);
            assert!(
                off.min(180.0 - off) < 6.0,
                "{angle}°: found at {direction:.1}°"
            );
        }
    }

    #[test]
    fn a_horizon_alone_is_not_a_pattern() {
        let (w, h) = (160, 120);
        for roll in [-40.0, -12.0, 0.0, 3.0, 25.0, 60.0] {
            for (soft, texture) in [(0.5, 0.0), (3.0, 8.0), (12.0, 15.0)] {
                let grey = image(w, h, horizon(w, h, roll, 90.0, soft, texture));
                assert_eq!(find_in(&grey, w, h), None, "roll {roll}, soft {soft}");
            }
        }
    }

    #[test]
    fn removing_a_pattern_keeps_the_horizon_and_little_of_the_pattern() {
        let (w, h) = (160, 120);
        let scene = horizon(w, h, 12.0, 80.0, 1.5, 0.0);
        let clean = image(w, h, &scene);
        // Bent only, and bent and shaken by a pixel: a row's shake turns the pattern's phase
        // by up to a third of a radian there, faster than the envelope follows.
        for (shake, most) in [(0.0, 1.2), (1.0, 3.0)] {
            let wave = shaken_pattern(h, 15.0, 11.0, 40.0, shake);
            let mut grey = image(w, h, |u, v| scene(u, v) + wave(u, v));
            let mut scratch = vec![Complex32::new(0.0, 0.0); scratch_len(w, h)];
            let geo = Working {
                scale: 1,
                width: w,
                height: h,
            };
            let found = find(&grey, geo, &mut scratch).expect("found");
            remove(&mut grey, geo, found, &mut scratch);
            // Away from the borders and from the horizon itself (the notch takes the share
            // of its step's spectrum that lies in the notch), what is left of the pattern.
            let (s, c) = (libm::sinf(12.0 * DEG), libm::cosf(12.0 * DEG));
            let mut residual2 = 0.0f32;
            let mut n = 0.0f32;
            for v in 10..h - 10 {
                for u in 10..w - 10 {
                    let d = s * (u as f32 - 80.0) + c * (v as f32 - 60.0);
                    if libm::fabsf(d) < 12.0 {
                        continue;
                    }
                    let e = f32::from(grey[v * w + u]) - f32::from(clean[v * w + u]);
                    residual2 += e * e;
                    n += 1.0;
                }
            }
            let residual = libm::sqrtf(residual2 / n);
            // The pattern's own RMS is 15/√2 = 10.6 levels.
            assert!(
                residual < most,
                "shaken {shake} px: {residual:.2} levels left"
            );
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

        /// Any pixels, any size: a pattern or none, and a notch that stays in the image.
        #[test]
        fn any_pixels_are_read_without_a_fault(
            w in 0usize..300,
            h in 0usize..300,
            seed in proptest::prelude::any::<u64>(),
            period in 1.0f32..40.0,
        ) {
            let mut state = seed | 1;
            let mut grey: Vec<u8> = (0..w * h)
                .map(|i| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    // Noise on a third, a pattern on the rest.
                    if state % 3 == 0 {
                        (state >> 8) as u8
                    } else {
                        (128.0 + 60.0 * libm::sinf(i as f32 * 2.0 * PI / period)) as u8
                    }
                })
                .collect();
            let geo = Working { scale: 1, width: w, height: h };
            let mut scratch = vec![Complex32::new(0.0, 0.0); scratch_len(w, h)];
            if let Some(p) = find(&grey, geo, &mut scratch) {
                proptest::prop_assert!(p.period() >= MIN_PERIOD * 0.95 && p.period() <= MAX_PERIOD * 1.05);
                remove(&mut grey, geo, p, &mut scratch);
            }
        }
    }

    #[test]
    fn any_size_is_read_or_refused_without_a_fault() {
        for (w, h) in [
            (0, 0),
            (1, 1),
            (15, 40),
            (16, 16),
            (17, 200),
            (200, 150),
            (257, 10),
            (100, 300),
        ] {
            let grey = image(w, h, pattern(h.max(1), 20.0, 5.0, 20.0));
            let mut scratch = vec![Complex32::new(0.0, 0.0); scratch_len(w, h)];
            let geo = Working {
                scale: 1,
                width: w,
                height: h,
            };
            if let Some(p) = find(&grey, geo, &mut scratch) {
                let mut copy = grey.clone();
                remove(&mut copy, geo, p, &mut scratch);
            }
            // A scratch buffer too small is no pattern, not a fault.
            assert_eq!(find(&grey, geo, &mut []), None);
        }
    }
}
