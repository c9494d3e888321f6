//! A bar of blanked rows across the frame. An analogue link that loses vertical sync shows
//! whole rows black (thesis Fig. 6-11, `synth` `black-stripes`), a few to a few tens of pixels
//! thick, moving down the frame. The bar's edges are level steps drawn along the whole width,
//! and under a hazy horizon its top edge, a step down from the sky, can out-score the horizon
//! (`synth` `black-stripes` seeds 1–3: 4 % of the frames at 320×240 and 5 % at 640×480 passed
//! the estimator's gate on a bar's edge, 3–9° off, with confidence 0.37–0.49). No scene gives
//! rows black from edge to edge with brighter rows on both sides of them.

use super::camera::Camera;
use super::edges::Working;
use super::hough::Line;

/// Luma at or under which a working pixel counts as blanked (the bar's noise included) ...
const BLANK: u8 = 24;
/// ... and the share of a row's pixels that must be, for the row to be blanked.
const BLANK_ROW_SHARE: f32 = 0.95;
/// Thickest bar, as a share of the frame's height (`synth`'s are 4–18 of 240 rows).
const MAX_BAR_SHARE: f32 = 0.125;
/// Most a bar's edge line leans from the frame's rows (sine of half a degree): the bar is
/// rows of the frame.
pub(crate) const LEVEL_SINE: f32 = 0.0087;
/// Working rows either side of the line searched for the bar's edge (the line is placed on
/// the step between two rows, give or take the binning and the least-squares fit).
const EDGE_REACH: isize = 2;

/// Whether `line` runs along an edge of a bar of blanked rows, bounded by unblanked rows above
/// and below within the frame.
pub(crate) fn along_blank_bar(grey: &[u8], geo: Working, camera: &Camera, line: Line) -> bool {
    along_bar(grey, geo, camera, line, |p| p <= BLANK)
}

/// Whether `line` runs along an edge of a bar of saturated rows (a link's white stripe,
/// `synth` `white-stripes`), bounded as [`along_blank_bar`]'s: no scene gives rows white from
/// edge to edge with darker rows on both sides of them within an eighth of the frame.
pub(crate) fn along_saturated_bar(grey: &[u8], geo: Working, camera: &Camera, line: Line) -> bool {
    along_bar(grey, geo, camera, line, |p| p >= u8::MAX - BLANK)
}

/// Whether `line` is level with the frame's rows (within [`LEVEL_SINE`]), as a bar's edge is.
pub(crate) fn is_level(line: Line) -> bool {
    libm::fabsf(line.normal().0) <= LEVEL_SINE
}

/// Whether `line` runs along an edge of a bar of rows whose pixels are nearly all `in_bar`.
fn along_bar(
    grey: &[u8],
    geo: Working,
    camera: &Camera,
    line: Line,
    in_bar: impl Fn(u8) -> bool,
) -> bool {
    let (_, c) = line.normal();
    if !is_level(line) || libm::fabsf(c) < 0.5 {
        return false;
    }
    // The frame row the line crosses at the principal point's column, in working rows.
    let v = camera.cy + camera.fy * line.rho / c;
    let scale = geo.scale as f32;
    let wy = (v + 0.5) / scale - 0.5;
    if !wy.is_finite() {
        return false;
    }
    let centre = libm::roundf(wy) as isize;
    let blank = |row: isize| row_in_bar(grey, geo, row, &in_bar);
    let max_rows = (MAX_BAR_SHARE * geo.height as f32) as isize;
    (centre - EDGE_REACH..=centre + EDGE_REACH).any(|row| {
        // `row` is a bar's first row from above (or from below) when the row before it is
        // not blanked; the bar must end within `max_rows` on an unblanked row.
        [1isize, -1].iter().any(|&way| {
            if blank(row) != Some(true) || blank(row - way) != Some(false) {
                return false;
            }
            (1..=max_rows).find_map(|k| match blank(row + way * k) {
                Some(true) => None,
                Some(false) => Some(true),
                // The frame's edge: the bar is not bounded.
                None => Some(false),
            }) == Some(true)
        })
    })
}

/// Whether working row `row` is nearly all `in_bar`; `None` outside the image.
fn row_in_bar(grey: &[u8], geo: Working, row: isize, in_bar: impl Fn(u8) -> bool) -> Option<bool> {
    let row = usize::try_from(row).ok().filter(|&r| r < geo.height)?;
    let pixels = grey.get(row * geo.width..(row + 1) * geo.width)?;
    let blanked = pixels.iter().filter(|&&p| in_bar(p)).count();
    Some(blanked as f32 >= BLANK_ROW_SHARE * pixels.len() as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 160×120 working image binned from 320×240, row `r` at `level(r, column)`.
    fn image(level: impl Fn(usize, usize) -> u8) -> (std::vec::Vec<u8>, Working, Camera) {
        let geo = Working {
            scale: 2,
            width: 160,
            height: 120,
        };
        let grey = (0..geo.width * geo.height)
            .map(|i| level(i / geo.width, i % geo.width))
            .collect();
        (grey, geo, Camera::ideal(320, 240, 60f32.to_radians()))
    }

    /// The level line between working rows `row − 1` and `row` (normal up).
    fn level_line_above(row: usize, camera: &Camera) -> Line {
        // Working row boundary `row − ½` is frame row `2·row − ½`.
        let v = 2.0 * row as f32 - 0.5;
        Line {
            angle: core::f32::consts::PI,
            rho: -(v - camera.cy) / camera.fy,
        }
    }

    /// Whether the level line between working rows `row − 1` and `row` of `level`'s image is
    /// along a blank bar.
    fn bar_edge_above(level: impl Fn(usize, usize) -> u8, row: usize) -> bool {
        let (grey, geo, camera) = image(level);
        along_blank_bar(&grey, geo, &camera, level_line_above(row, &camera))
    }

    /// Sky at 180 with a bar of rows `bar` at 4 (a little noise), hazy ground below row 90.
    fn sky_with_bar(bar: core::ops::Range<usize>) -> impl Fn(usize, usize) -> u8 {
        move |r, c| {
            if bar.contains(&r) {
                (4 + (r * 7 + c * 13) % 9) as u8
            } else if r < 90 {
                180
            } else {
                120
            }
        }
    }

    #[test]
    fn both_edges_of_a_black_bar_across_the_frame_are_along_it() {
        let bar = || sky_with_bar(60..68);
        assert!(bar_edge_above(bar(), 60));
        assert!(bar_edge_above(bar(), 68));
        // Two rows off either way still finds the edge; four does not.
        assert!(bar_edge_above(bar(), 62));
        assert!(!bar_edge_above(bar(), 56));
        // The horizon under the bar is not along it.
        assert!(!bar_edge_above(bar(), 90));
    }

    #[test]
    fn both_edges_of_a_white_bar_are_along_a_saturated_bar_and_a_clipped_sky_is_none() {
        let (grey, geo, camera) = image(|r, c| match r {
            60..68 => (250 + (r * 7 + c * 13) % 6) as u8,
            0..90 => 180,
            _ => 120,
        });
        let along = |row| along_saturated_bar(&grey, geo, &camera, level_line_above(row, &camera));
        assert!(along(60) && along(68));
        assert!(!along(90));
        // Not a blanked bar.
        assert!(!along_blank_bar(
            &grey,
            geo,
            &camera,
            level_line_above(60, &camera)
        ));
        // A sky clipped white from the frame's top down to the horizon is no bar.
        let (grey, geo, camera) = image(|r, _| if r < 60 { 255 } else { 120 });
        assert!(!along_saturated_bar(
            &grey,
            geo,
            &camera,
            level_line_above(60, &camera)
        ));
    }

    #[test]
    fn a_line_leaning_from_the_rows_is_not_along_a_bar() {
        let (grey, geo, camera) = image(sky_with_bar(60..68));
        let mut line = level_line_above(60, &camera);
        line.angle += 1f32.to_radians();
        assert!(!along_blank_bar(&grey, geo, &camera, line));
    }

    #[test]
    fn dark_ground_down_to_the_frame_edge_is_no_bar() {
        assert!(!bar_edge_above(sky_with_bar(60..120), 60));
    }

    #[test]
    fn a_band_thicker_than_a_bar_is_none() {
        // 16 rows: over an eighth of 120.
        assert!(!bar_edge_above(sky_with_bar(60..76), 60));
        assert!(bar_edge_above(sky_with_bar(60..75), 60));
    }

    #[test]
    fn a_dark_tree_line_or_a_bar_with_scene_through_it_is_none() {
        // A level tree line at 40 levels, and a black bar with lit fields through a tenth of it.
        let tree_line = |r: usize, _| if (60..68).contains(&r) { 40 } else { 180 };
        assert!(!bar_edge_above(tree_line, 60));
        let lit_through = |r: usize, c: usize| match r {
            60..68 if c % 10 == 0 => 150,
            60..68 => 4,
            _ => 180,
        };
        assert!(!bar_edge_above(lit_through, 60));
    }
}
