//! A seam along the frame's rows. A digital link codes a frame in slices of whole block rows
//! (16 rows in JPEG's 4:2:0 and H.264, 8 in JPEG's 4:4:4); it conceals a lost slice with the
//! previous frame's, and a slice decoded out of step is torn sideways. Either way the frame is
//! spliced along a block-row boundary, and the splice is a level step drawn across the whole
//! width, which the edge stage can take for a level horizon (on the tuning sets passed through
//! `tools/horizon/camera_chain.py`, a third of the trusted answers more than 2° wrong were
//! such lines).
//!
//! Only boundaries on the 8-row grid are looked at. A splice elsewhere (`terrain`'s torn
//! bands start on any row) is not a codec's, and a noiseless test horizon can fall on any
//! row boundary as one hard step.
//!
//! What tells a splice from a horizon is how abruptly the frame changes: the rows either side
//! of a splice are each the continuation of their own picture, so neighbouring rows differ
//! little on both sides and a lot across it. A camera's optics spread even a sharp horizon
//! over more than one row. And the two pictures do not match along the splice, so the step
//! across it changes along the row; a noiseless synthetic horizon laid on a row boundary is
//! one even step.

use super::HorizonLine;
use super::camera::Camera;
use super::frame::{Frame, luma};
use super::sync_bar::LEVEL_SINE;

/// How many times more the two rows across a seam differ, on average over the width, than
/// the two rows on either side of it do. On the tuning sets (with and without the camera-and-
/// link chain) and Horizon-UAV, right level lines measured at most 2.6 (1.3 on the real
/// frames) unless the frame was spliced there; the lines on splices 3.0–152.
const SEAM_RATIO: f32 = 3.0;
/// The block-row grid a codec's slices follow (8 and 16 rows).
const BLOCK_ROWS: usize = 8;
/// Least mean difference (luma levels) counted for the rows either side.
const WITHIN_FLOOR: f32 = 0.5;
/// Least mean deviation of the step across a seam from its mean along the row (luma
/// levels): the splices measured 1.2 and more (a rolling bar's edge the least), the
/// noiseless horizons of the unit tests 0.
const UNEVEN_STEP: f32 = 1.0;

/// Whether `line` (a horizon line of the full-resolution frame) runs along the frame's rows on
/// a row boundary where the frame is spliced.
pub(crate) fn along_row_seam(frame: &Frame<'_>, camera: &Camera, line: HorizonLine) -> bool {
    near_row_seam(frame, camera, line, 0.5)
}

/// Whether a level `line`, placed to within `reach` rows (a candidate of the binned working
/// image is placed to within one of its pixels), runs along a row boundary where the frame is
/// spliced: any boundary of the grid within `reach` rows of where it crosses the principal
/// point's column. The boundary between rows r − 1 and r is at r − ½ (pixel centres at the
/// integers).
pub(crate) fn near_row_seam(
    frame: &Frame<'_>,
    camera: &Camera,
    line: HorizonLine,
    reach: f32,
) -> bool {
    let (sin_roll, cos_roll) = (
        libm::sinf(line.camera_roll_rad),
        libm::cosf(line.camera_roll_rad),
    );
    if libm::fabsf(sin_roll) > LEVEL_SINE {
        return false;
    }
    let (_, v) = camera.project(0.0, line.offset / cos_roll);
    if !v.is_finite() {
        return false;
    }
    // Rows 2 ..= height − 2 have the two rows either side a boundary is read from.
    let rows = 2.0..=frame.height() as f32 - 2.0;
    let (low, high) = (libm::ceilf(v + 0.5 - reach), libm::floorf(v + 0.5 + reach));
    let (low, high) = (low.max(*rows.start()), high.min(*rows.end()));
    if !(rows.contains(&low) && rows.contains(&high)) {
        return false;
    }
    let first = (low as usize).div_ceil(BLOCK_ROWS) * BLOCK_ROWS;
    (first..=high as usize)
        .step_by(BLOCK_ROWS)
        .any(|r| spliced_at(frame, r))
}

/// Whether the frame is spliced at the boundary between rows `r − 1` and `r`.
fn spliced_at(frame: &Frame<'_>, r: usize) -> bool {
    let (w, h) = (frame.width(), frame.height());
    if w == 0 || r < 2 || r + 1 >= h || r % BLOCK_ROWS != 0 {
        return false;
    }
    let luma_at = |u: usize, v: usize| {
        let (red, green, blue) = frame.rgb_at(u, v);
        f32::from(luma(red, green, blue))
    };
    let (mut across, mut step, mut above, mut below) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
    for u in 0..w {
        let [a, b, c, d] = [r - 2, r - 1, r, r + 1].map(|v| luma_at(u, v));
        above += libm::fabsf(a - b);
        across += libm::fabsf(b - c);
        step += b - c;
        below += libm::fabsf(c - d);
    }
    let width = w as f32;
    if across < SEAM_RATIO * above.max(below).max(WITHIN_FLOOR * width) {
        return false;
    }
    let mean_step = step / width;
    let uneven: f32 = (0..w)
        .map(|u| libm::fabsf(luma_at(u, r - 1) - luma_at(u, r) - mean_step))
        .sum();
    uneven >= UNEVEN_STEP * width
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    const W: usize = 64;
    const H: usize = 48;

    fn camera() -> Camera {
        Camera::ideal(W as u32, H as u32, 60.0 * core::f32::consts::PI / 180.0)
    }

    /// A textured frame: a slow gradient down the rows and a pattern across the columns.
    fn texture(u: usize, v: usize, shift: usize) -> u8 {
        let x = (u + shift) as f32;
        (100.0 + 30.0 * libm::sinf(0.7 * x) + 2.0 * v as f32) as u8
    }

    /// A W×H grey frame of `pixel(u, v)`.
    fn grey(pixel: impl Fn(usize, usize) -> u8) -> Vec<u8> {
        (0..H)
            .flat_map(|v| (0..W).map(move |u| (u, v)))
            .map(|(u, v)| pixel(u, v))
            .collect()
    }

    /// [`along_row_seam`] of `line` on the grey frame `pixels`.
    fn seam_at(pixels: &[u8], line: HorizonLine) -> bool {
        let frame = Frame::grey(W, H, pixels).expect("fits");
        along_row_seam(&frame, &camera(), line)
    }

    /// The level line through the row boundary between rows `r − 1` and `r`.
    fn level_at(r: usize) -> HorizonLine {
        let camera = camera();
        HorizonLine::from_attitude(0.0, libm::atanf((r as f32 - 0.5 - camera.cy) / camera.fy))
    }

    #[test]
    fn a_band_torn_sideways_leaves_a_seam_at_its_top() {
        let frame = grey(|u, v| texture(u, v, if v >= 24 { 5 } else { 0 }));
        assert!(seam_at(&frame, level_at(24)));
        // A block row higher, the rows across the line are the same picture's.
        assert!(!seam_at(&frame, level_at(16)));
        // Tilted by a degree, the line is not along the rows.
        let tilted = HorizonLine {
            camera_roll_rad: 1.0f32.to_radians(),
            ..level_at(24)
        };
        assert!(!seam_at(&frame, tilted));
    }

    #[test]
    fn a_splice_off_the_block_rows_is_not_a_codecs() {
        let frame = grey(|u, v| texture(u, v, if v >= 28 { 5 } else { 0 }));
        assert!(!seam_at(&frame, level_at(28)));
    }

    #[test]
    fn a_horizon_spread_over_two_rows_is_not_a_seam() {
        // Textured ground under a smooth sky, the step shared by two rows as a lens shares it.
        let frame = grey(|u, v| match v {
            0..=23 => 200,
            24 => 150,
            _ => texture(u, v, 0) / 2,
        });
        assert!(!seam_at(&frame, level_at(24)));
    }

    #[test]
    fn an_even_step_on_a_row_boundary_is_not_a_seam() {
        // A noiseless two-tone horizon laid exactly on a row boundary: no texture to show the
        // two sides are different pictures.
        let frame = grey(|_, v| if v < 24 { 200 } else { 90 });
        assert!(!seam_at(&frame, level_at(24)));
    }

    #[test]
    fn a_candidate_placed_within_reach_of_a_seam_is_on_it() {
        let pixels = grey(|u, v| texture(u, v, if v >= 24 { 5 } else { 0 }));
        let frame = Frame::grey(W, H, &pixels).expect("fits");
        let camera = camera();
        // Two rows below the boundary (a working pixel of a frame binned 2× is two rows).
        let off = HorizonLine::from_attitude(0.0, libm::atanf((25.5 - camera.cy) / camera.fy));
        assert!(!along_row_seam(&frame, &camera, off));
        assert!(near_row_seam(&frame, &camera, off, 2.0));
        assert!(!near_row_seam(&frame, &camera, off, 1.0));
    }

    #[test]
    fn lines_near_the_frames_top_and_bottom_are_read_safely() {
        let frame = grey(|_, _| 128);
        for r in [0usize, 1, 2, H - 2, H - 1, H, H + 40] {
            assert!(!seam_at(&frame, level_at(r)));
        }
        assert!(!seam_at(&frame, HorizonLine::from_attitude(0.0, 1.5)));
        // Any reach, any offset: only the frame's own boundaries are read.
        let frame = Frame::grey(W, H, &frame).expect("fits");
        for offset in [f32::NAN, f32::INFINITY, -1e30, 1e30, 0.0] {
            for reach in [0.5, 4.0, 1e9, f32::INFINITY] {
                let line = HorizonLine {
                    camera_roll_rad: 0.0,
                    offset,
                };
                assert!(!near_row_seam(&frame, &camera(), line, reach));
            }
        }
    }
}
