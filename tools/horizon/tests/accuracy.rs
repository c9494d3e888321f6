//! Accuracy on synthesised flights, one test per degradation of the seed's video (thesis
//! §6.2.3), 320×240. Bounds hold for the seed with margin (5, unless a test names another);
//! `cargo run --release -p skyframe-horizon -- bench --seed 5 --frames 30 --no-opencv` prints
//! the same figures.
//!
//! Two kinds of assertions:
//! - accuracy: share of frames with roll and pitch both within 2°, median and 95th-percentile
//!   errors over the frames with an answer;
//! - honesty: a frame more than 5° wrong never carries a confidence above 0.5
//!   (`accuracy::CONFIDENT`), and at most one frame in 20 passes the estimator's confidence
//!   gate more than 2° wrong (`false_confident_rate`), so a consumer that trusts only
//!   confident answers is not misled.
//!
//! These sets are the tuning generators' (`synth`, and `terrain` from the eleventh session);
//! the held-out generator (`aerial`) is only scored, by `bench --real` (docs/horizon.md).

use skyframe_horizon::accuracy::{self, Accuracy, CONFIDENT, WRONG_DEG};
use skyframe_horizon::bench;
use skyframe_horizon::synth::Degradation;
use skyframe_horizon::terrain::Class;

const SEED: u64 = 5;
const FRAMES: usize = 30;

struct Bounds {
    /// Least share of frames within 2° (roll and pitch).
    within_2deg: f32,
    /// Largest median error (roll and pitch), degrees.
    median_deg: f32,
    /// Largest 95th-percentile error (roll and pitch), degrees.
    p95_deg: f32,
}

fn measure(degradation: Degradation, seed: u64) -> Accuracy {
    let set = bench::synthesise(degradation, 320, 240, FRAMES, seed);
    let (answers, _) = bench::run_ours(&set).expect("the detector runs");
    let result = accuracy::evaluate(&answers, &set.truths);
    eprintln!("{}: {result:?}", degradation.name());
    result
}

fn check(degradation: Degradation, bounds: Bounds) {
    check_at(degradation, SEED, bounds);
}

fn check_at(degradation: Degradation, seed: u64, bounds: Bounds) {
    let a = measure(degradation, seed);
    let name = degradation.name();
    assert_eq!(
        a.wrong_confident, 0,
        "{name}: {} frames more than {WRONG_DEG}° wrong with confidence above {CONFIDENT}",
        a.wrong_confident
    );
    assert!(
        a.false_confident_rate <= 0.05,
        "{name}: {:.2} of frames pass the estimator's gate more than 2° wrong",
        a.false_confident_rate
    );
    assert!(
        a.within_2deg.unwrap_or(0.0) >= bounds.within_2deg,
        "{name}: {:?} of frames within 2°, want ≥ {:.2}",
        a.within_2deg,
        bounds.within_2deg
    );
    assert!(
        a.roll_median_deg <= bounds.median_deg && a.pitch_median_deg <= bounds.median_deg,
        "{name}: median errors roll {:.2}° pitch {:.2}°, want ≤ {:.2}°",
        a.roll_median_deg,
        a.pitch_median_deg,
        bounds.median_deg
    );
    assert!(
        a.roll_p95_deg <= bounds.p95_deg && a.pitch_p95_deg <= bounds.p95_deg,
        "{name}: p95 errors roll {:.2}° pitch {:.2}°, want ≤ {:.2}°",
        a.roll_p95_deg,
        a.pitch_p95_deg,
        bounds.p95_deg
    );
}

#[test]
fn clean() {
    let bounds = Bounds {
        within_2deg: 1.0,
        median_deg: 0.2,
        p95_deg: 0.3,
    };
    check(Degradation::Clean, bounds);
}

#[test]
fn sensor_noise() {
    let bounds = Bounds {
        within_2deg: 0.95,
        median_deg: 0.2,
        p95_deg: 0.5,
    };
    check(Degradation::SensorNoise, bounds);
}

#[test]
fn transmission_noise() {
    // Bursts of noise so strong that some frames are skipped (no answer) rather than guessed.
    let bounds = Bounds {
        within_2deg: 0.8,
        median_deg: 0.5,
        p95_deg: 3.0,
    };
    check(Degradation::TransmissionNoise, bounds);
}

#[test]
fn white_stripes() {
    let bounds = Bounds {
        within_2deg: 0.9,
        median_deg: 0.2,
        p95_deg: 1.0,
    };
    check(Degradation::WhiteStripes, bounds);
}

#[test]
fn black_stripes() {
    let bounds = Bounds {
        within_2deg: 0.9,
        median_deg: 0.2,
        p95_deg: 1.0,
    };
    check(Degradation::BlackStripes, bounds);
}

#[test]
fn exposure_and_colour_changes() {
    // Over-exposed frames clip sky and distant ground alike: the true horizon is not in the
    // image, and the detector says so with a low confidence (checked) instead of guessing.
    let bounds = Bounds {
        within_2deg: 0.75,
        median_deg: 0.3,
        p95_deg: 8.0,
    };
    check(Degradation::Exposure, bounds);
}

#[test]
fn glare() {
    // With the bloom over most of the horizon the answer is a ground line at confidence ~0
    // (honest, checked above): the worst frames are wrong, not trusted.
    let bounds = Bounds {
        within_2deg: 0.9,
        median_deg: 0.3,
        p95_deg: 6.0,
    };
    check(Degradation::Glare, bounds);
}

#[test]
fn roads_and_field_edges() {
    let bounds = Bounds {
        within_2deg: 0.95,
        median_deg: 0.2,
        p95_deg: 0.5,
    };
    check(Degradation::Roads, bounds);
}

#[test]
fn clouds() {
    let bounds = Bounds {
        within_2deg: 0.95,
        median_deg: 0.2,
        p95_deg: 0.5,
    };
    check(Degradation::Clouds, bounds);
}

#[test]
fn radial_distortion() {
    let bounds = Bounds {
        within_2deg: 0.95,
        median_deg: 0.3,
        p95_deg: 0.5,
    };
    check(Degradation::Distortion, bounds);
}

#[test]
fn haze() {
    // The horizon a small step above a long ramp: no bias from where the line is fitted
    // (the median). On 4 of these 30 frames the Hough line lies 5 px above the step, beyond
    // the placement's 4.5 px reach on the ground side, and the line stays ~1.1° high (0.6°
    // before the placement took the top of the transition, issue 17); one more is 3.8° off
    // below the estimator's gate.
    let bounds = Bounds {
        within_2deg: 0.95,
        median_deg: 0.1,
        p95_deg: 1.2,
    };
    check(Degradation::Haze, bounds);
}

#[test]
fn ground_edge_far_below_a_hazy_horizon() {
    // A wood's border 6–15° below a horizon eight times fainter (issue 17): the profile across
    // the border finds the horizon's step. The worst frames are those where the border lies
    // within 6° and the two lines' smoothed transitions meet (p95 1.5° measured).
    let bounds = Bounds {
        within_2deg: 0.95,
        median_deg: 0.2,
        p95_deg: 2.0,
    };
    check(Degradation::GroundEdge, bounds);
}

#[test]
fn ground_edge_out_of_parallel_below_a_hazy_horizon() {
    // The same border turned up to ±35° from square to the view (up to 6° out of parallel
    // with the horizon in the image). Before the turned searches: 0.57 within 2°, a third of
    // the frames the border itself past the gate. Of the misses left (3–7° off) one in 30
    // passes the gate.
    let bounds = Bounds {
        within_2deg: 0.8,
        median_deg: 0.2,
        p95_deg: 7.5,
    };
    check(Degradation::ObliqueGroundEdge, bounds);
}

#[test]
fn faint_hazy_horizon_over_fields_and_sea_is_the_frames_clear_split() {
    // Seed 1's coast: the sea far off or only a wedge of it, the horizon a small step over
    // hazy fields whose hedges and roads draw edge lines 2–13° of roll off it. The frame still
    // splits clearly into sky and ground there. Before the clear split: 0.29 within 2°
    // (median roll error 2.9°), 0.10 past the gate more than 2° wrong.
    let bounds = Bounds {
        within_2deg: 0.9,
        median_deg: 0.2,
        p95_deg: 1.0,
    };
    check_at(Degradation::Coast, 1, bounds);
}

#[test]
fn a_calm_sea_mirroring_the_sky_is_climbed_to_its_horizon() {
    // Seed 2's calm sea: the shore, 8–25° of roll off the horizon, is the clearest step, and
    // the horizon a ridge where the sea's brightening meets the sky's darkening. Before the
    // ridge search: 0.56 within 2° at 320 px, 0.125 past the gate more than 2° wrong.
    let bounds = Bounds {
        within_2deg: 0.9,
        median_deg: 0.2,
        p95_deg: 10.0,
    };
    check_at(Degradation::CalmSea, 2, bounds);
}

#[test]
fn coast_seen_steeply_down_is_not_a_horizon() {
    // Frames 24–29 look 40–70° down at a shore: the sea is darker than the fields, but bluer
    // and smoother, so two sky cues of three take it for the sky. Seed 6: before the darker
    // sky's penalty, 5 of those 6 frames passed the gate (0.17); the horizon frames were all
    // within 2° then as now.
    let bounds = Bounds {
        within_2deg: 0.95,
        median_deg: 0.2,
        p95_deg: 1.0,
    };
    check_at(Degradation::Coast, 6, bounds);
}

#[test]
fn interference_parallel_to_the_horizon() {
    // Not solved, only honest (docs/horizon.md): a crest next to the horizon is often the line
    // found (half of the frames within 2° here), and the striped sky keeps such answers under
    // the estimator's gate; `check` asserts that none passes it more than 2° wrong beyond 1 in
    // 20, and none above 0.5 more than 5° wrong.
    let bounds = Bounds {
        within_2deg: 0.4,
        median_deg: 1.5,
        p95_deg: 8.0,
    };
    check(Degradation::ParallelInterference, bounds);
}

/// Dusk haze (`low-light`, seed 1, 320×240): the ramp under the horizon's small step is
/// steeper at the working resolution than the step, and the edge line lay on it; frames 3–6
/// were read 4.4–8.1° low with confidence 0.43–0.80 until a line with a clear step above it in
/// the same transition was moved to the top of the ridge (`region::top_step`); frames 0 and 2
/// stayed 5° low (frame 0 with confidence 0.84) while the move waited for the transition walk
/// to see a clear step there, which dim light hides.
#[test]
fn dusk_haze_is_read_at_the_top_of_its_ridge() {
    let set = bench::synthesise(Degradation::LowLight, 320, 240, 7, 1);
    let (answers, _) = bench::run_ours(&set).expect("the detector runs");
    for (frame, (answer, truth)) in answers.iter().zip(&set.truths).enumerate() {
        let (roll, pitch) = answer.attitude.expect("an answer");
        assert!(
            (roll - truth.roll_deg).abs() <= 2.0 && (pitch - truth.pitch_deg).abs() <= 2.0,
            "frame {frame}: roll {roll:.2} pitch {pitch:.2}, truth {truth:?}"
        );
    }
}

/// Each frame of `set` from `first` on: within 2° of the truth, or under the estimator's gate
/// (`accuracy::gate()`); and the median absolute pitch error of the frames whose horizon can
/// be seen at most `median_deg`. (A frame whose horizon step is under 3 levels counts as
/// without one in the bench; answered within 2°, it is right here.)
fn assert_right_or_honest_and_median_pitch_within(
    set: &bench::SynthSet,
    first: usize,
    median_deg: f32,
) {
    let (answers, _) = bench::run_ours(set).expect("the detector runs");
    let gate = accuracy::gate();
    let mut pitch_errors = Vec::new();
    for (frame, (answer, truth)) in answers.iter().zip(&set.truths).enumerate().skip(first) {
        let trusted = answer.confidence.is_some_and(|c| c >= gate);
        let Some((roll, pitch)) = answer.attitude else {
            continue;
        };
        let right = accuracy::roll_error_deg(roll, truth.roll_deg) <= 2.0
            && (pitch - truth.pitch_deg).abs() <= 2.0;
        assert!(
            right || !trusted,
            "frame {frame}: roll {roll:.2} pitch {pitch:.2} trusted ({:?}), truth {truth:?}",
            answer.confidence
        );
        if truth.visible {
            pitch_errors.push((pitch - truth.pitch_deg).abs());
        }
    }
    pitch_errors.sort_by(f32::total_cmp);
    let median = pitch_errors
        .get(pitch_errors.len() / 2)
        .copied()
        .unwrap_or(f32::NAN);
    assert!(
        median <= median_deg,
        "median pitch error {median:.2}°: {pitch_errors:?}"
    );
}

/// Dusk haze at 640×480 (`low-light`, seed 1): from frame 26 on, the search climbed from a
/// ground edge to an edge still on the ramp under the ridge, and the answer stayed 4–7° low
/// (frame 39 with confidence 0.74) until a climbed line, too, was moved to the ridge's top step.
#[test]
fn dusk_haze_at_640_is_read_at_the_top_after_a_climb() {
    let set = bench::synthesise(Degradation::LowLight, 640, 480, 40, 1);
    assert_right_or_honest_and_median_pitch_within(&set, 16, 0.5);
}

/// Dusk haze whose horizon step is lost in the noise (`low-light`, 320×240, seeds 1 and 2):
/// the edge line lay at the foot of the ramp up to the airlight, 3–12° low, and passed the
/// estimator's gate in 8 and 16 frames of 40 (seed 2's with a step under 3 levels, scored on
/// honesty only) until a line whose profile rises more above it than across it, with no top
/// step to move to, kept a quarter of its confidence. Two frames a seed still pass: 2.2–3.1°
/// wrong, and seed 1's frame 9 with 8° of roll.
#[test]
fn dusk_haze_read_at_the_foot_of_its_ramp_is_not_trusted() {
    for seed in [1, 2] {
        let set = bench::synthesise(Degradation::LowLight, 320, 240, 40, seed);
        let (answers, _) = bench::run_ours(&set).expect("the detector runs");
        let trusted_wrong = trusted_wrong_frames(&answers, &set);
        assert!(
            trusted_wrong.len() <= 2,
            "seed {seed}: frames {trusted_wrong:?} pass the gate more than 2° wrong"
        );
    }
}

/// Lost vertical sync blanks a bar of whole rows (`black-stripes`): the bar's level top edge
/// out-scored a hazy horizon, 3–9° off, past the estimator's gate (seeds 1, 2 and 3: 1, 1 and 3
/// frames of 40 at 320×240). A line along such a bar is now no candidate while another is,
/// and keeps a quarter of its confidence when it is the only one (seed 2's frame 29).
#[test]
fn a_bar_of_blanked_rows_is_not_read_as_the_horizon() {
    for seed in [1, 2, 3] {
        let set = bench::synthesise(Degradation::BlackStripes, 320, 240, 40, seed);
        let (answers, _) = bench::run_ours(&set).expect("the detector runs");
        let trusted_wrong = trusted_wrong_frames(&answers, &set);
        assert!(
            trusted_wrong.is_empty(),
            "seed {seed}: frames {trusted_wrong:?} pass the gate more than 2° wrong"
        );
        if seed != 2 {
            let a = accuracy::evaluate(&answers, &set.truths);
            assert_eq!(a.wrong, 0, "seed {seed}: {a:?}");
        }
    }
}

/// Frames of `set` whose answer passes the estimator's confidence gate with roll or pitch more
/// than 2° wrong (frames scored as invisible included: a confident line there is wrong too).
fn trusted_wrong_frames(answers: &[accuracy::Answer], set: &bench::SynthSet) -> Vec<usize> {
    let gate = accuracy::gate();
    answers
        .iter()
        .zip(&set.truths)
        .enumerate()
        .filter(|(_, (answer, truth))| {
            answer.confidence.is_some_and(|c| c >= gate)
                && answer.attitude.is_some_and(|(roll, pitch)| {
                    accuracy::roll_error_deg(roll, truth.roll_deg) > 2.0
                        || (pitch - truth.pitch_deg).abs() > 2.0
                })
        })
        .map(|(frame, _)| frame)
        .collect()
}

#[test]
fn no_horizon_in_runs_of_frames_looking_down_or_up_is_never_trusted() {
    // Seed 2 looks down on a sunlit field's border for frames 32–39 and at roads for 0–7:
    // borders that persist from frame to frame as a horizon would. Before the sky cues had to
    // agree (`hough::SkyCues::agreed`), 12 of its 40 frames passed the gate.
    let set = bench::synthesise(Degradation::NoHorizon, 320, 240, 40, 2);
    let (answers, _) = bench::run_ours(&set).expect("the detector runs");
    let result = accuracy::evaluate(&answers, &set.truths);
    assert_eq!(result.visible, 0, "{result:?}");
    assert_eq!(result.false_confident_rate, 0.0, "{result:?}");
}

/// A digital video link over a hazy horizon at 320×240 (`video-link`, seed 1): the Hough line
/// followed the haze's lower edge across the blocks, 5–13° of roll off and 3–7° low (frames
/// 22 and 26 trusted, 26 with confidence 1.0), while a region split of the same frame was
/// right and explained more of it; the region search now also checks a best edge line that
/// explains under 0.75 of the frame and is drawn along under 0.8 of its length, in a frame
/// coded in blocks (`blocks::grid_contrast`; not in a camera's own noisy frame). Since the
/// working image of such a frame is deblocked, frame 21's edge line (2.9° of roll off) is no
/// longer replaced by a split and came out at confidence 0.64: an edge line of a deblocked
/// frame keeps its confidence only where it was placed on a clear full-resolution step
/// (`CODED_SIGNIFICANCE_SPAN`).
#[test]
fn video_link_blocks_do_not_draw_the_line_off_the_horizon() {
    let set = bench::synthesise(Degradation::VideoLink, 320, 240, 31, 1);
    assert_right_or_honest_and_median_pitch_within(&set, 20, 0.5);
}

#[test]
fn video_link_haze_is_split_at_the_horizon_not_along_its_lower_edge() {
    // Seed 3, frames 30–35: the edge line runs along the hazy band's lower edge through the
    // blocks, 7–8° of roll off, explaining 0.71–0.74 of the frame, with confidence 0.60–0.77;
    // the split at the horizon explains 0.77–0.80, short of the coded frame's first bar
    // (1.15 times the edge line). Before its second bar (a clear split): 0.85 within 2°,
    // 0.07 past the gate more than 2° wrong.
    let set = bench::synthesise(Degradation::VideoLink, 320, 240, 40, 3);
    assert_within_2deg_and_false_confidence(&set, 0.9, 0.03);
}

/// At least `within_2deg` of `set`'s frames within 2° and at most `false_confident` past the
/// gate more than 2° wrong or with no horizon to see.
fn assert_within_2deg_and_false_confidence(
    set: &bench::SynthSet,
    within_2deg: f32,
    false_confident: f32,
) {
    let (answers, _) = bench::run_ours(set).expect("the detector runs");
    let a = accuracy::evaluate(&answers, &set.truths);
    eprintln!("{} {}: {a:?}", set.generator, set.name);
    assert!(
        a.within_2deg.unwrap_or(0.0) >= within_2deg,
        "{:?} within 2°",
        a.within_2deg
    );
    assert!(
        a.false_confident_rate <= false_confident,
        "{:.3} past the gate more than 2° wrong or with no horizon to see",
        a.false_confident_rate
    );
}

/// A digital video link at 320×240 (`terrain` `transmission`, seed 17): an 8×8 block is four
/// working pixels, and its borders drew the staircase of a coded horizon as separate level and
/// upright edges. The working image of a frame coded in blocks is deblocked (`blocks::deblock`):
/// within 2° 0.82 → 0.97, and false confidence 0.075 → 0.025.
#[test]
fn a_coded_horizon_at_320_is_read_through_its_blocks() {
    let set = bench::terrain_set(Class::Transmission, 320, 240, 40, 17);
    assert_within_2deg_and_false_confidence(&set, 0.9, 0.05);
}
