//! Frames of the independent generator (`aerial_set.py`, seeds seen and scored) on which a
//! change to the detector was made, kept with their camera and truth in `tests/fixtures`: each
//! is read within 2° of its truth, as a flight's frame read alone.

mod common;

use common::detect_set;
use std::path::PathBuf;

/// `(roll, pitch, confidence)` read from the fixture `name` and `(roll, pitch)` of its truth.
fn read_fixture(name: &str) -> ((f32, f32, f32), (f32, f32)) {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name);
    let second_row = |text: &str| -> Vec<f32> {
        let row = text
            .lines()
            .nth(1)
            .unwrap_or_else(|| panic!("{name}: no row"));
        row.split(',')
            .skip(1)
            .map(|v| v.parse().unwrap_or(f32::NAN))
            .collect()
    };
    let read = second_row(&detect_set(&dir));
    let truth = second_row(&std::fs::read_to_string(dir.join("truth.csv")).expect("truth"));
    ((read[0], read[1], read[2]), (truth[0], truth[1]))
}

fn assert_within_2_deg(name: &str) {
    let ((roll, pitch, confidence), (true_roll, true_pitch)) = read_fixture(name);
    assert!(
        (roll - true_roll).abs() <= 2.0 && (pitch - true_pitch).abs() <= 2.0,
        "{name}: read roll {roll} pitch {pitch} (confidence {confidence}), truth {true_roll} {true_pitch}"
    );
}

/// Seed 157 `glare` 320 px frame 14: the sun low over a uniformly hazy ground, the horizon a
/// step of a few levels on its glow. Before the ramp was taken out of the edge points'
/// directions (`edges::step_gradient`) read 1.4° of roll and 16° of pitch out, at a cloud.
#[test]
fn a_faint_horizon_across_a_sun_glow() {
    assert_within_2_deg("aerial157-glare-320-frame14");
}

/// Seed 160 `mixed` 320 px frame 26: a link's slice torn sideways across a hazy horizon, its
/// lower edge a level step along a block row. Before a level candidate on such a seam was
/// left to the link (`seam::near_row_seam`) read the slice's edge, 18° of roll out.
#[test]
fn a_horizon_across_a_torn_slice() {
    assert_within_2_deg("aerial160-mixed-320-frame26");
}

/// Seed 150 `mixed` 320 px frame 12: a sun's glow over a haze band, a link's stripes across
/// both. The band's top, the horizon, is drawn along three quarters of it (0.76) and the
/// ground's edge under the band along nearly all of it (0.96). Before a line drawn along 60 %
/// of its length was climbed to (`DRAWN_ABOVE_COVERAGE`, 0.8 before) read the ground's edge,
/// 5° of roll and 7° of pitch out, trusted.
#[test]
fn the_top_of_a_haze_band_drawn_along_most_of_it() {
    assert_within_2_deg("aerial150-mixed-320-frame12");
}

/// Seed 159 `mixed` 320 px frame 12: a haze band over a nearly level ground edge, with two
/// level seams of a link's lost slices below. The seams and the edge made a family of
/// parallel lines, taken for a link's stripes, which kept the climb from the edge to the
/// band's top (`stripe_family`); before seams were left out of families read the edge, 5° of
/// roll and 6° of pitch out, trusted.
#[test]
fn seams_make_no_family_of_stripes() {
    assert_within_2_deg("aerial159-mixed-320-frame12");
}
