//! Compression blocks: how strongly a frame's luma steps on an 8-pixel grid.
//!
//! A block codec (JPEG, MPEG, a digital video link) quantises each 8×8 block of luma on its
//! own, so at low quality the luma steps at every block border and hardly inside a block. The
//! edge pass then finds edges along the borders of the blocks a horizon crosses, and on a
//! hazy horizon those draw a line degrees of roll off it; the frame's two regions still meet
//! at the horizon. This tells such a frame from a noisy one, whose edge lines are as weakly
//! drawn but whose region split is no better.

use super::frame::{Frame, Pixels, luma};

/// Block side of the codecs this looks for (JPEG's and MPEG's luma blocks; MPEG's 16-pixel
/// macroblocks fall on the same grid).
const BLOCK: usize = 8;

/// How much larger the luma steps between neighbouring pixels are on the strongest of the 8
/// grid phases than on the others, on average, across columns and across rows together.
/// About 1 for a camera's frame (any phase is as likely as another to hold an edge), 3 and
/// more for a frame coded at a video link's quality (see `CODED_IN_BLOCKS`). The phase is
/// found, not assumed: a cropped or shifted frame moves the grid.
pub(crate) fn grid_contrast(frame: &Frame<'_>) -> f32 {
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
) -> f32 {
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
    let mut across_columns = [0u64; BLOCK];
    let mut across_rows = [0u64; BLOCK];
    for y in (BLOCK / 2..height).step_by(row_every) {
        let mut row = lumas(frame.row(y));
        let Some(mut previous) = row.next() else {
            continue;
        };
        for (x, here) in (1..width).zip(row) {
            if let Some(bin) = across_columns.get_mut(x % BLOCK) {
                *bin += u64::from(here.abs_diff(previous));
            }
            previous = here;
        }
    }
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
    let contrast = |bins: &[u64; BLOCK]| -> (f32, f32) {
        let strongest = bins.iter().copied().max().unwrap_or(0);
        let rest = bins.iter().sum::<u64>() - strongest;
        (strongest as f32, rest as f32 / (BLOCK - 1) as f32)
    };
    let (column_grid, column_rest) = contrast(&across_columns);
    let (row_grid, row_rest) = contrast(&across_rows);
    (column_grid + row_grid + 1.0) / (column_rest + row_rest + 1.0)
}

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

    #[test]
    fn rgb_and_grey_read_the_same_luma() {
        let grey = frame_of(64, 48, |x, y| ((x / 8 + y / 8) * 20) as u8);
        let rgb: Vec<u8> = grey.iter().flat_map(|&g| [g, g, g]).collect();
        let a = grid_contrast(&Frame::grey(64, 48, &grey).expect("fits"));
        let b = grid_contrast(&Frame::rgb(64, 48, &rgb).expect("fits"));
        assert_eq!(a, b);
        assert!(a > 3.0, "{a}");
    }
}
