//! Compression blocks: how strongly a frame's luma steps on an 8-pixel grid.
//!
//! A block codec (JPEG, MPEG, a digital video link) quantises each 8×8 block of luma on its
//! own, so at low quality the luma steps at every block border and hardly inside a block. The
//! edge pass then finds edges along the borders of the blocks a horizon crosses, and on a
//! hazy horizon those draw a line degrees of roll off it; the frame's two regions still meet
//! at the horizon. This tells such a frame from a noisy one, whose edge lines are as weakly
//! drawn but whose region split is no better.

use super::edges::Working;
use super::frame::{Frame, Pixels, luma};

/// Block side of the codecs this looks for (JPEG's and MPEG's luma blocks; MPEG's 16-pixel
/// macroblocks fall on the same grid).
pub(crate) const BLOCK: usize = 8;

/// How much larger the luma steps between neighbouring pixels are on the strongest of the 8
/// grid phases than on the others, on average, across columns and across rows together.
/// About 1 for a camera's frame (any phase is as likely as another to hold an edge), 3 and
/// more for a frame coded at a video link's quality (see `CODED_IN_BLOCKS`). The phase is
/// found, not assumed: a cropped or shifted frame moves the grid.
pub(crate) fn grid_contrast(frame: &Frame<'_>) -> f32 {
    grid(frame).contrast
}

/// A frame's block grid: how strongly it shows ([`grid_contrast`]) and where its borders are
/// (a border lies between columns `x − 1` and `x` where `x % 8 == column_phase`, and between
/// rows likewise).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Grid {
    pub contrast: f32,
    /// The same figure across columns alone and across rows alone, the lower of the two: a
    /// codec's blocks step both ways, lost rows or a striped frame on the grid only one way.
    pub weaker_axis: f32,
    pub column_phase: usize,
    pub row_phase: usize,
    /// Side of the coded blocks in frame pixels: [`BLOCK`], or twice it for a frame coded
    /// at half resolution and scaled back up (see [`HALF_RESOLUTION_CONTRAST`]).
    pub tile: usize,
}

/// [`Grid`] of a frame.
pub(crate) fn grid(frame: &Frame<'_>) -> Grid {
    match frame.pixels() {
        Pixels::Grey(_) => contrast_of(frame, |row| row.iter().copied()),
        Pixels::Rgb(_) => contrast_of(frame, |row| {
            row.chunks_exact(3).map(|p| match *p {
                [r, g, b] => luma(r, g, b),
                _ => 0,
            })
        }),
    }
}

/// [`grid_contrast`] with `lumas` reading a row's bytes as luma.
fn contrast_of<'a, I: Iterator<Item = u8>>(
    frame: &Frame<'a>,
    lumas: impl Fn(&'a [u8]) -> I,
) -> Grid {
    // A frame is at least `Frame::MIN_SIDE` (two blocks) on a side.
    let (width, height) = (frame.width(), frame.height());
    // Steps across columns are binned by the column's phase (x mod 8), steps across rows by
    // the row's phase. A sample is enough, as long as every phase gets as many steps as the
    // others: for the columns, whole rows (one in 8 up to 480 rows, one in 16 from there);
    // for the rows, bands of 8 rows (one band in 2, in 4 from 480 rows) read in every 4th
    // column (every 8th from 640). About 20 000 steps at either size; on `synth` seed 1 each
    // set's lowest and highest figures were those of a sample twice as dense, to 0.1.
    let scale_down = |side: usize, base: usize| (side / base).max(1);
    let row_every = 8 * scale_down(height, 240);
    let band_every = 2 * scale_down(height, 240);
    let column_every = 4 * scale_down(width, 320);
    // Across columns by x mod 16 (two blocks), folded to x mod 8 below: the same sums, and
    // whether every other border is missing (a frame coded at half resolution).
    let mut across_two_blocks = [0u64; 2 * BLOCK];
    let mut across_rows = [0u64; BLOCK];
    for y in (BLOCK / 2..height).step_by(row_every) {
        let mut row = lumas(frame.row(y));
        let Some(mut previous) = row.next() else {
            continue;
        };
        for (x, here) in (1..width).zip(row) {
            if let Some(bin) = across_two_blocks.get_mut(x % (2 * BLOCK)) {
                *bin += u64::from(here.abs_diff(previous));
            }
            previous = here;
        }
    }
    let across_columns: [u64; BLOCK] = core::array::from_fn(|i| {
        across_two_blocks.get(i).copied().unwrap_or(0)
            + across_two_blocks.get(i + BLOCK).copied().unwrap_or(0)
    });
    for band in (1..height / BLOCK).step_by(band_every) {
        for y in band * BLOCK..(band + 1) * BLOCK {
            let above = lumas(frame.row(y - 1)).step_by(column_every);
            let row = lumas(frame.row(y)).step_by(column_every);
            let step: u64 = above.zip(row).map(|(a, b)| u64::from(a.abs_diff(b))).sum();
            if let Some(bin) = across_rows.get_mut(y % BLOCK) {
                *bin += step;
            }
        }
    }
    let contrast = |bins: &[u64; BLOCK]| -> (f32, f32, usize) {
        let (phase, strongest) = bins
            .iter()
            .copied()
            .enumerate()
            .max_by_key(|&(i, v)| (v, core::cmp::Reverse(i)))
            .unwrap_or((0, 0));
        let rest = bins.iter().sum::<u64>() - strongest;
        (strongest as f32, rest as f32 / (BLOCK - 1) as f32, phase)
    };
    let (column_grid, column_rest, column_phase) = contrast(&across_columns);
    let (row_grid, row_rest, row_phase) = contrast(&across_rows);
    // The borders of a block coded at half resolution are 16 frame pixels apart: of the two
    // columns on the strongest 8-phase, the one half a tile away steps far less. (The rows
    // are sampled in bands of 8 and cannot tell; a codec halves both sides.)
    let on_phase = |phase: usize| across_two_blocks.get(phase).copied().unwrap_or(0) as f32;
    let (near, far) = (on_phase(column_phase), on_phase(column_phase + BLOCK));
    let half_resolution = near.max(far) + 1.0 >= HALF_RESOLUTION_CONTRAST * (near.min(far) + 1.0);
    Grid {
        contrast: (column_grid + row_grid + 1.0) / (column_rest + row_rest + 1.0),
        weaker_axis: ((column_grid + 1.0) / (column_rest + 1.0))
            .min((row_grid + 1.0) / (row_rest + 1.0)),
        column_phase,
        row_phase,
        tile: if half_resolution { 2 * BLOCK } else { BLOCK },
    }
}

/// How many times more a half-resolution frame's block borders step than the columns half a
/// tile from them (see [`Grid::tile`]). Over the `synth` and `terrain` tuning sets at 320×240
/// through `camera_chain.py --jpeg-quality 4,22` (a numpy model of this measure, on the
/// frames whose grid contrast across columns reaches 2.7): at half resolution 3.6 for the 1st
/// percentile of 2627 frames, 11 the median; at full resolution 1.5 for the 99th of 3755;
/// the H.264 link's frames (16-pixel macroblocks, 4×4 and 8×8 transforms) 1.1–3.5.
const HALF_RESOLUTION_CONTRAST: f32 = 3.0;

/// Whether a block grid may show in `grey`, the working image binned by `geo.scale` (1 or 2):
/// its steps between neighbouring working pixels are at least [`GRID_HINT`] times larger on
/// one phase of the grid (a block's side in working pixels) than on the others, across
/// columns and across rows alike. A cheap test on the working image before [`grid`] reads the
/// frame itself (the steps across columns on every other row).
pub(crate) fn may_show_blocks(grey: &[u8], geo: Working) -> bool {
    let s = geo.scale.max(1);
    if BLOCK % s != 0 {
        return false;
    }
    // A power of two (1, 2, 4 or 8): the phase is a mask.
    let period = BLOCK / s;
    let phase = period - 1;
    let width = geo.width.max(1);
    let rows = || grey.chunks_exact(width).take(geo.height);
    // Steps across columns summed in eight lanes (lane i: between x = 8k + i and 8k + i + 1)
    // so that the loop vectorises; a lane's phase is (i + 1) mod period. The row's last
    // partial chunk is left out.
    let mut lanes = [0u32; BLOCK];
    for row in rows().step_by(2) {
        let next = row.get(1..).unwrap_or(&[]);
        for (here, right) in row.chunks_exact(BLOCK).zip(next.chunks_exact(BLOCK)) {
            for ((lane, &a), &b) in lanes.iter_mut().zip(here).zip(right) {
                *lane += u32::from(a.abs_diff(b));
            }
        }
    }
    let mut across_columns = [0u32; BLOCK];
    for (i, lane) in lanes.iter().enumerate() {
        if let Some(bin) = across_columns.get_mut((i + 1) & phase) {
            *bin += lane;
        }
    }
    let mut across_rows = [0u32; BLOCK];
    for (y, (above, row)) in rows().zip(rows().skip(1)).enumerate() {
        if let Some(bin) = across_rows.get_mut((y + 1) & phase) {
            *bin += above
                .iter()
                .zip(row)
                .map(|(&a, &b)| u32::from(a.abs_diff(b)))
                .sum::<u32>();
        }
    }
    let shows = |bins: &[u32]| {
        let strongest = bins.iter().copied().max().unwrap_or(0) as f32;
        let rest = (bins.iter().sum::<u32>() as f32 - strongest) / (bins.len() - 1).max(1) as f32;
        strongest + 1.0 >= GRID_HINT * (rest + 1.0)
    };
    shows(across_columns.get(..period).unwrap_or(&[]))
        && shows(across_rows.get(..period).unwrap_or(&[]))
}

/// See [`may_show_blocks`]. On `synth` seeds 1–3 and `terrain` seeds 16 and 17 at 320×240
/// (a numpy model of the test, 2×2 means of the frames' luma): the frames [`grid`] finds
/// coded, with a border between working pixels on either axis, show 1.35 and more on both;
/// 0.6 % of the others pass.
const GRID_HINT: f32 = 1.2;

/// Smooths the block borders out of a working image binned by `geo.scale` from a frame coded
/// on `grid`: either side of each border, the two working pixels are replaced by the ramp
/// between their outer neighbours (a decoder's deblocking filter, coarsely). Only where a
/// border falls between working pixels and a block is at least three of them wide; a frame
/// binned coarser keeps its blocks (a block of two working pixels has no inside to keep).
pub(crate) fn deblock(grey: &mut [u8], geo: Working, grid: Grid) {
    let s = geo.scale.max(1);
    if BLOCK % s != 0 || BLOCK / s < 3 {
        return;
    }
    let block = BLOCK / s;
    let (width, height) = (geo.width, geo.height);
    // The two pixels either side of a border, a third and two thirds of the way from their
    // outer neighbours `a` to `b`.
    let ramp = |a: u8, b: u8| -> (u8, u8) {
        let (a, b) = (u16::from(a), u16::from(b));
        (((2 * a + b + 1) / 3) as u8, ((a + 2 * b + 1) / 3) as u8)
    };
    if grid.column_phase % s == 0 {
        let first = grid.column_phase / s;
        for row in grey.chunks_exact_mut(width.max(1)).take(height) {
            let mut at = if first < 2 { first + block } else { first };
            while at + 1 < row.len() {
                if let (Some(&a), Some(&b)) = (row.get(at - 2), row.get(at + 1)) {
                    let (left, right) = ramp(a, b);
                    if let Some(p) = row.get_mut(at - 1) {
                        *p = left;
                    }
                    if let Some(p) = row.get_mut(at) {
                        *p = right;
                    }
                }
                at += block;
            }
        }
    }
    if grid.row_phase % s == 0 {
        let first = grid.row_phase / s;
        let mut at = if first < 2 { first + block } else { first };
        while at + 1 < height {
            for x in 0..width {
                let index = |y: usize| y * width + x;
                if let (Some(&a), Some(&b)) = (grey.get(index(at - 2)), grey.get(index(at + 1))) {
                    let (above, below) = ramp(a, b);
                    if let Some(p) = grey.get_mut(index(at - 1)) {
                        *p = above;
                    }
                    if let Some(p) = grey.get_mut(index(at)) {
                        *p = below;
                    }
                }
            }
            at += block;
        }
    }
}

/// Most taps either side of the centre in [`smooth_tiles`]: a 16-pixel tile at scale 1.
const MAX_HALF_TAPS: usize = 8;

/// Smooths a working image binned by `geo.scale` over tiles `tile` frame pixels wide, rows
/// then columns, with a kernel as wide as a tile (ends at half weight when it is an even
/// number of working pixels, so that the kernel is centred). A frame coded at half
/// resolution and a low quality is tiles of nearly flat luma, and a tilted horizon through
/// them is a staircase whose treads are level edges: they vote for level lines only, and
/// the Hough stage finds the level borders of a row of tiles rather than the horizon. A
/// kernel one tread wide turns a staircase into a ramp along the horizon's own direction.
pub(crate) fn smooth_tiles(grey: &mut [u8], geo: Working, tile: usize) {
    let scale = geo.scale.max(1);
    let taps = (tile + scale / 2) / scale;
    if taps < 2 || taps / 2 > MAX_HALF_TAPS {
        return;
    }
    let (width, height) = (geo.width, geo.height);
    for y in 0..height {
        smooth_line(grey, (y * width, 1, width), taps);
    }
    for x in 0..width {
        smooth_line(grey, (x, width, height), taps);
    }
}

/// [`smooth_tiles`] along one line of `grey`: `len` pixels from `start`, `step` apart, each
/// replaced by its kernel's weighted mean (the line's end pixels repeated beyond it).
///
/// A running sum: the kernel's inside (weight 2) moves by one pixel in, one out, and its two
/// ends (weight 1 or 2) are read from a ring of the originals about the pixel, which is
/// written over as it goes. The sums are whole numbers, so the means are those of the
/// kernel summed pixel by pixel (`tests::smooth_line_pixel_by_pixel`). Summing each kernel
/// took a third of the detector's instructions on `aerial` seed 140's `transmission` frames at
/// 320 px; the running sum takes a third of what that did (141 M → 44 M over 40 frames).
fn smooth_line(grey: &mut [u8], (start, step, len): (usize, usize, usize), taps: usize) {
    let half = taps / 2;
    if half == 0 || half > MAX_HALF_TAPS {
        return;
    }
    // Weights doubled: 2 inside, 1 at the ends of an even kernel; they sum to 2·taps.
    let end_weight = if taps % 2 == 0 { 1 } else { 2 };
    let total = 2 * taps as u32;
    let index = |i: usize| start + i * step;
    let Some(&first) = grey.get(start) else {
        return;
    };
    let last = grey
        .get(index(len.saturating_sub(1)))
        .copied()
        .unwrap_or(first);
    // The original of the line's pixel `j`, the last one repeated past the end (the first one
    // is repeated before the start by the ring's initial values). Pixels ahead of the one
    // being written still hold their originals; past the end, `index(j)` would be in the
    // next line, so the last pixel is read once, here.
    let ahead = |grey: &[u8], j: usize| {
        if j + 1 >= len {
            last
        } else {
            grey.get(index(j)).copied().unwrap_or(first)
        }
    };
    // Originals from `i − half` to `i + half + 1`, at `j` modulo the ring (`j` offset by
    // `RING` so that those before the line's start index it too).
    let mut ring = [first; RING];
    let slot = |j: usize| (j + RING) % RING;
    for j in 0..=half {
        if let Some(cell) = ring.get_mut(slot(j)) {
            *cell = ahead(grey, j);
        }
    }
    let at = |ring: &[u8; RING], j: usize| u32::from(ring.get(slot(j)).copied().unwrap_or(first));
    // The inside, `i − half + 1 ..= i + half − 1`, for `i` = 0.
    let mut inside: u32 = (RING + 1 - half..=RING + half - 1)
        .map(|j| at(&ring, j))
        .sum();
    for i in 0..len {
        let (behind, front) = (at(&ring, RING + i - half), at(&ring, i + half));
        let sum = 2 * inside + end_weight * (behind + front);
        if let Some(cell) = ring.get_mut(slot(i + half + 1)) {
            *cell = ahead(grey, i + half + 1);
        }
        if let Some(p) = grey.get_mut(index(i)) {
            *p = ((sum + total / 2) / total) as u8;
        }
        inside = inside + front - at(&ring, RING + i + 1 - half);
    }
}

/// Originals [`smooth_line`] keeps about its pixel: `2·half + 2` of them, a power of two
/// over that for the widest kernel.
const RING: usize = 32;
const _: () = assert!(RING >= 2 * MAX_HALF_TAPS + 2);

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    fn frame_of(width: usize, height: usize, f: impl Fn(usize, usize) -> u8) -> Vec<u8> {
        (0..width * height)
            .map(|i| f(i % width, i / width))
            .collect()
    }

    /// A smooth diagonal gradient with a little texture: no grid of its own.
    fn scene(x: usize, y: usize) -> f32 {
        let t = 40.0 + 0.4 * x as f32 + 0.3 * y as f32;
        let texture = ((x * 7919 + y * 104_729) % 13) as f32;
        t + texture
    }

    #[test]
    fn a_camera_frame_has_no_grid() {
        let grey = frame_of(320, 240, |x, y| scene(x, y) as u8);
        let frame = Frame::grey(320, 240, &grey).expect("fits");
        let c = grid_contrast(&frame);
        assert!((0.8..1.2).contains(&c), "{c}");
    }

    #[test]
    fn blocks_flattened_to_their_mean_show_the_grid_at_any_phase() {
        for phase in [0, 3, 5] {
            // Each 8×8 block (offset by `phase`) holds its mean: a coarse codec's DC only.
            let block_mean = |x: usize, y: usize| -> u8 {
                let (bx, by) = ((x + phase) / 8, (y + phase) / 8);
                let (cx, cy) = (
                    (bx * 8 + 4).saturating_sub(phase),
                    (by * 8 + 4).saturating_sub(phase),
                );
                scene(cx, cy) as u8
            };
            let grey = frame_of(320, 240, block_mean);
            let frame = Frame::grey(320, 240, &grey).expect("fits");
            let c = grid_contrast(&frame);
            assert!(c > 3.0, "phase {phase}: {c}");
        }
    }

    /// Flat tiles `tile` pixels wide of `scene`'s luma at their centres.
    fn flat_tiles(width: usize, height: usize, tile: usize) -> Vec<u8> {
        frame_of(width, height, |x, y| {
            let (cx, cy) = ((x / tile) * tile + tile / 2, (y / tile) * tile + tile / 2);
            scene(cx, cy) as u8
        })
    }

    #[test]
    fn a_frame_coded_at_half_resolution_has_tiles_of_sixteen() {
        for (tile, expected) in [(8, BLOCK), (16, 2 * BLOCK)] {
            let grey = flat_tiles(320, 240, tile);
            let g = grid(&Frame::grey(320, 240, &grey).expect("fits"));
            assert!(g.contrast > 3.0, "tiles of {tile}: {g:?}");
            assert_eq!(g.tile, expected, "tiles of {tile}: {g:?}");
        }
        // A camera's frame has no tiles either way.
        let grey = frame_of(320, 240, |x, y| scene(x, y) as u8);
        assert_eq!(
            grid(&Frame::grey(320, 240, &grey).expect("fits")).tile,
            BLOCK
        );
    }

    /// [`smooth_line`] as it was written first: each pixel's kernel summed on its own.
    fn smooth_line_pixel_by_pixel(
        grey: &mut [u8],
        (start, step, len): (usize, usize, usize),
        taps: usize,
    ) {
        let half = taps / 2;
        let end_weight = if taps % 2 == 0 { 1 } else { 2 };
        let total = 2 * taps as u32;
        let index = |i: usize| start + i * step;
        let original: Vec<u8> = (0..len).map(|i| grey[index(i)]).collect();
        for i in 0..len {
            let mut sum = 2 * u32::from(original[i]);
            for o in 1..=half {
                let weight = if o == half { end_weight } else { 2 };
                let earlier = original[i.saturating_sub(o)];
                let later = original[(i + o).min(len - 1)];
                sum += weight * (u32::from(earlier) + u32::from(later));
            }
            grey[index(i)] = ((sum + total / 2) / total) as u8;
        }
    }

    #[test]
    fn a_running_sum_smooths_a_line_as_each_kernel_summed_on_its_own() {
        let mut seed = 0x2545_f491u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        };
        for taps in 2..=2 * MAX_HALF_TAPS + 1 {
            for len in 1..40 {
                for (start, step) in [(0, 1), (3, 1), (2, 5)] {
                    let size = start + step * (len - 1) + 1 + 4;
                    let line: Vec<u8> = (0..size).map(|_| next() as u8).collect();
                    let (mut fast, mut slow) = (line.clone(), line.clone());
                    smooth_line(&mut fast, (start, step, len), taps);
                    smooth_line_pixel_by_pixel(&mut slow, (start, step, len), taps);
                    assert_eq!(
                        fast, slow,
                        "taps {taps}, len {len}, start {start}, step {step}"
                    );
                }
            }
        }
    }

    #[test]
    fn smoothing_over_a_tile_turns_a_staircase_into_a_ramp_along_the_line() {
        // A working image at scale 2 of a line rising 25° to the right, drawn in 8-pixel tiles:
        // each tile column holds the line's height at its own centre (a staircase of treads).
        let geo = Working::with_scale(320, 240, 2);
        let slope = libm::tanf(25.0f32.to_radians());
        let line = |x: f32| 60.0 - slope * (x - 80.0);
        let mut grey = frame_of(geo.width, geo.height, |x, y| {
            let tread = line(((x / 8) * 8) as f32 + 3.5);
            if (y as f32) < tread { 180 } else { 80 }
        });
        // Each column's edge by area: its sky rows counted as (value − 80) / 100 each, the
        // edge half a row above the next (pixel centres at the integers). Smoothing keeps the
        // area of a column away from the image's top and bottom; what it changes is where
        // that area comes from. The largest distance from the line, away from the sides.
        let worst = |grey: &[u8]| {
            (16..geo.width - 16)
                .map(|x| {
                    let sky_rows: f32 = (0..geo.height)
                        .map(|y| (f32::from(grey[y * geo.width + x]) - 80.0) / 100.0)
                        .sum();
                    libm::fabsf(sky_rows - 0.5 - line(x as f32))
                })
                .fold(0.0f32, f32::max)
        };
        let before = worst(&grey);
        smooth_tiles(&mut grey, geo, 16);
        let after = worst(&grey);
        assert!(
            before > 1.5,
            "the staircase is {before} px off the line at worst"
        );
        assert!(after < 0.5, "smoothed: {after} px off the line at worst");
    }

    #[test]
    fn rgb_and_grey_read_the_same_luma() {
        let grey = frame_of(64, 48, |x, y| ((x / 8 + y / 8) * 20) as u8);
        let rgb: Vec<u8> = grey.iter().flat_map(|&g| [g, g, g]).collect();
        let a = grid_contrast(&Frame::grey(64, 48, &grey).expect("fits"));
        let b = grid_contrast(&Frame::rgb(64, 48, &rgb).expect("fits"));
        assert_eq!(a, b);
        assert!(a > 3.0, "{a}");
    }

    /// A working image binned 2× from a frame coded in 8×8 blocks: 4-pixel blocks, each flat,
    /// stepping 12 levels from the block to its right and 24 from the block below.
    fn flat_blocks(width: usize, height: usize, phase: usize) -> Vec<u8> {
        frame_of(width, height, |x, y| {
            let (bx, by) = ((x + 4 - phase) / 4, (y + 4 - phase) / 4);
            (40 + 12 * bx + 24 * by) as u8
        })
    }

    /// Sides of the working image the deblocking tests use (scale 2).
    const WIDTH: usize = 24;
    const HEIGHT: usize = 12;

    /// [`flat_blocks`] (working phase 2) before and after [`deblock`] at scale 2, told the
    /// frame's grid is at `frame_phase` on both axes.
    fn deblocked(frame_phase: usize) -> (Vec<u8>, Vec<u8>, Grid) {
        let geo = Working::with_scale(2 * WIDTH, 2 * HEIGHT, 2);
        let grid = Grid {
            tile: BLOCK,
            contrast: 10.0,
            weaker_axis: 10.0,
            column_phase: frame_phase,
            row_phase: frame_phase,
        };
        let before = flat_blocks(WIDTH, HEIGHT, 2);
        let mut after = before.clone();
        deblock(&mut after, geo, grid);
        (before, after, grid)
    }

    #[test]
    fn deblocking_ramps_across_the_borders_and_keeps_each_blocks_inside() {
        // Frame phase 4: borders between working pixels 1|2, 5|6, ... at scale 2.
        let (width, height) = (WIDTH, HEIGHT);
        let (before, after, _) = deblocked(4);
        let at = |image: &[u8], x: usize, y: usize| i32::from(image[y * width + x]);
        for y in 0..height {
            for x in 1..width {
                // 12 levels a block: thirds of it across a border once it is ramped.
                let step = (at(&after, x, y) - at(&after, x - 1, y)).abs();
                assert!(step <= 4, "({x}, {y}): step {step}");
            }
        }
        for y in 1..height {
            for x in 0..width {
                let step = (at(&after, x, y) - at(&after, x, y - 1)).abs();
                assert!(step <= 8, "({x}, {y}): step {step} across rows");
            }
        }
        // The middle two pixels of each block (3, 4; 7, 8; ...) keep their values.
        let inside = |i: usize| i % 4 == 3 || i % 4 == 0;
        for y in (0..height).filter(|&y| inside(y)) {
            for x in (0..width).filter(|&x| inside(x)) {
                assert_eq!(at(&after, x, y), at(&before, x, y), "({x}, {y})");
            }
        }
    }

    #[test]
    fn a_border_inside_a_working_pixel_is_left_alone() {
        // Frame phase 3 at scale 2: each border cuts a working pixel in two.
        let (before, mut after, grid) = deblocked(3);
        assert_eq!(after, before);
        // At scale 4 a block is two working pixels: nothing inside to keep.
        let coarse = Working::with_scale(4 * WIDTH, 4 * HEIGHT, 4);
        deblock(
            &mut after,
            coarse,
            Grid {
                tile: BLOCK,
                column_phase: 0,
                row_phase: 0,
                ..grid
            },
        );
        assert_eq!(after, before);
    }

    #[test]
    fn the_grid_phase_is_where_the_blocks_step() {
        for phase in [0, 3, 5] {
            let grey = frame_of(320, 240, |x, y| {
                ((x + 8 - phase) / 8 * 5 + (y + 8 - phase) / 8 * 3) as u8
            });
            let g = grid(&Frame::grey(320, 240, &grey).expect("fits"));
            assert_eq!((g.column_phase, g.row_phase), (phase, phase), "{g:?}");
            assert!(g.weaker_axis > 3.0, "{g:?}");
        }
    }

    #[test]
    fn bars_on_the_rows_grid_are_not_blocks() {
        // A bright bar every 8 rows on a camera's scene: the combined figure says coded, the
        // weaker axis (columns) does not.
        let grey = frame_of(
            320,
            240,
            |x, y| {
                if y % 8 == 0 { 250 } else { scene(x, y) as u8 }
            },
        );
        let g = grid(&Frame::grey(320, 240, &grey).expect("fits"));
        assert!(g.contrast > 2.7, "{g:?}");
        assert!(g.weaker_axis < 1.5, "{g:?}");
    }

    #[test]
    fn the_working_images_hint_sees_blocks_both_ways_and_not_bars() {
        let (width, height) = (160, 120);
        let geo = Working::with_scale(2 * width, 2 * height, 2);
        assert!(may_show_blocks(&flat_blocks(width, height, 2), geo));
        let camera = frame_of(width, height, |x, y| scene(x, y) as u8);
        assert!(!may_show_blocks(&camera, geo));
        // Bars every four working rows step on the rows' grid only.
        let bars = frame_of(width, height, |x, y| {
            if y % 4 == 0 { 250 } else { scene(x, y) as u8 }
        });
        assert!(!may_show_blocks(&bars, geo));
    }
}
