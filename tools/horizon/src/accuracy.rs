//! Accuracy figures of a run against ground truth.

use crate::synth::Truth;
use serde::Serialize;

/// One frame's answer: roll and pitch in degrees (`None`: no horizon) and confidence.
#[derive(Clone, Copy, Debug)]
pub struct Answer {
    pub attitude: Option<(f32, f32)>,
    pub confidence: Option<f32>,
}

/// Errors are in degrees over the frames with a visible horizon and an answer; the shares
/// "within" are over every frame with a visible horizon (no answer = not within).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Accuracy {
    pub frames: usize,
    /// Frames whose horizon can be seen (the truth says so).
    pub visible: usize,
    /// Visible frames with an answer.
    pub found: usize,
    pub roll_median_deg: f32,
    pub roll_p95_deg: f32,
    pub pitch_median_deg: f32,
    pub pitch_p95_deg: f32,
    /// Median signed errors (measured − truth): a bias, which the absolute median hides.
    pub roll_median_signed_deg: f32,
    pub pitch_median_signed_deg: f32,
    /// Shares of the visible frames with both roll and pitch within 1°, 2°, 5° (`None` when
    /// no frame has a visible horizon).
    pub within_1deg: Option<f32>,
    pub within_2deg: Option<f32>,
    pub within_5deg: Option<f32>,
    /// Frames more than 5° wrong (roll or pitch) reported with confidence above 0.5.
    pub wrong_confident: usize,
    /// Frames more than 5° wrong, any confidence.
    pub wrong: usize,
    /// Share of all frames answered with confidence above 0.5 (`None` for a detector
    /// without a confidence).
    pub confident: Option<f32>,
    /// Share of all frames where the answer would pass the estimator's confidence gate
    /// ([`gate`]) but is wrong: more than 2° off, or a line where no horizon can be seen. A
    /// detector without a confidence claims every answer.
    pub false_confident_rate: f32,
    /// Of the frames `false_confident_rate` counts, those the truth marks without a visible
    /// horizon whose answer is nevertheless within 2° of the truth's line: a soft horizon
    /// (a haze, a coded link) whose step a few pixels either side is under the generator's
    /// threshold, found where it is. A count, to tell them from wrong lines.
    pub confident_near_hidden: usize,
    /// Share of the frames with a visible horizon whose answer is within 2° and passes the
    /// estimator's gate: what the estimator can use (a detector without a confidence: its
    /// share within 2°).
    pub usable: Option<f32>,
}

/// Above this a confident answer counts as a lie (the accuracy tests assert none).
pub const CONFIDENT: f32 = 0.5;
pub const WRONG_DEG: f32 = 5.0;
/// An answer off by more than this is wrong for the false-confidence rate.
pub const FALSE_DEG: f32 = 2.0;

/// The confidence from which the vehicle's estimator uses a horizon measurement.
pub fn gate() -> f32 {
    skyframe_core::estimation::ekf::EkfConfig::default().horizon_min_confidence as f32
}

pub fn roll_error_deg(measured: f32, truth: f32) -> f32 {
    signed_roll_error_deg(measured, truth).abs()
}

/// Roll error wrapped to [−180°, 180°).
pub fn signed_roll_error_deg(measured: f32, truth: f32) -> f32 {
    (measured - truth + 180.0).rem_euclid(360.0) - 180.0
}

/// The nearest-rank percentile `num/den` of sorted values (NaN for none): skyframe's one
/// definition (`skyframe_core::stats`).
fn percentile(sorted: &[f32], num: u64, den: u64) -> f32 {
    skyframe_core::stats::percentile(sorted, num, den).unwrap_or(f32::NAN)
}

fn median_of(mut v: Vec<f32>) -> f32 {
    v.sort_by(f32::total_cmp);
    percentile(&v, 50, 100)
}

pub fn evaluate(answers: &[Answer], truths: &[Truth]) -> Accuracy {
    let gate = gate();
    let (mut roll_errors, mut pitch_errors) = (Vec::new(), Vec::new());
    let (mut roll_signed, mut pitch_signed) = (Vec::new(), Vec::new());
    let (mut within1, mut within2, mut within5) = (0, 0, 0);
    let (mut wrong, mut wrong_confident, mut false_confident) = (0, 0, 0);
    let (mut confident, mut usable, mut near_hidden) = (0, 0, 0);
    let has_confidence = answers.iter().any(|a| a.confidence.is_some());
    for (a, t) in answers.iter().zip(truths) {
        let Some((roll, pitch)) = a.attitude else {
            continue;
        };
        if a.confidence.is_some_and(|c| c > CONFIDENT) {
            confident += 1;
        }
        let claims = a.confidence.is_none_or(|c| c >= gate);
        let rs = signed_roll_error_deg(roll, t.roll_deg);
        let ps = pitch - t.pitch_deg;
        let (re, pe) = (rs.abs(), ps.abs());
        let worst = re.max(pe);
        if !t.visible {
            false_confident += usize::from(claims);
            near_hidden += usize::from(claims && worst <= FALSE_DEG);
            continue;
        }
        roll_signed.push(rs);
        pitch_signed.push(ps);
        roll_errors.push(re);
        pitch_errors.push(pe);
        within1 += usize::from(worst <= 1.0);
        within2 += usize::from(worst <= 2.0);
        within5 += usize::from(worst <= 5.0);
        false_confident += usize::from(claims && worst > FALSE_DEG);
        usable += usize::from(claims && worst <= FALSE_DEG);
        if worst > WRONG_DEG {
            wrong += 1;
            if a.confidence.is_some_and(|c| c > CONFIDENT) {
                wrong_confident += 1;
            }
        }
    }
    roll_errors.sort_by(f32::total_cmp);
    pitch_errors.sort_by(f32::total_cmp);
    let frames = answers.len().min(truths.len());
    let visible = truths.iter().take(frames).filter(|t| t.visible).count();
    let share = |n: usize| (visible > 0).then(|| n as f32 / visible as f32);
    Accuracy {
        frames,
        visible,
        found: roll_errors.len(),
        roll_median_deg: percentile(&roll_errors, 50, 100),
        roll_p95_deg: percentile(&roll_errors, 95, 100),
        pitch_median_deg: percentile(&pitch_errors, 50, 100),
        pitch_p95_deg: percentile(&pitch_errors, 95, 100),
        roll_median_signed_deg: median_of(roll_signed),
        pitch_median_signed_deg: median_of(pitch_signed),
        within_1deg: share(within1),
        within_2deg: share(within2),
        within_5deg: share(within5),
        wrong_confident,
        wrong,
        confident: (has_confidence && frames > 0).then(|| confident as f32 / frames as f32),
        false_confident_rate: if frames > 0 {
            false_confident as f32 / frames as f32
        } else {
            0.0
        },
        confident_near_hidden: near_hidden,
        usable: share(usable),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Usable: right and through the gate, over the frames with a horizon to see.
    #[test]
    fn usable_counts_right_answers_through_the_gate() {
        let truth = |visible| Truth {
            roll_deg: 10.0,
            pitch_deg: 2.0,
            visible,
        };
        let answer = |roll: f32, confidence: f32| Answer {
            attitude: Some((roll, 2.0)),
            confidence: Some(confidence),
        };
        let answers = [
            answer(10.5, 0.9), // right, through the gate: usable
            answer(10.5, 0.1), // right, under the gate
            answer(15.0, 0.9), // wrong and confident
            answer(10.0, 0.9), // no horizon to see: a false confidence, not usable
            Answer {
                attitude: None,
                confidence: None,
            },
        ];
        let truths = [
            truth(true),
            truth(true),
            truth(true),
            truth(false),
            truth(true),
        ];
        let a = evaluate(&answers, &truths);
        assert_eq!(a.visible, 4);
        assert_eq!(a.usable, Some(0.25));
        assert_eq!(a.within_2deg, Some(0.5));
        assert!((a.false_confident_rate - 0.4).abs() < 1e-6);
        // Frame 3 has no horizon to see but is answered on the truth's line.
        assert_eq!(a.confident_near_hidden, 1);
        // Without a confidence every answer claims: usable is the share within 2°.
        let plain: Vec<Answer> = answers
            .iter()
            .map(|a| Answer {
                confidence: None,
                ..*a
            })
            .collect();
        assert_eq!(evaluate(&plain, &truths).usable, Some(0.5));
    }

    /// A confident answer on a frame without a visible horizon is near it only within 2° of
    /// roll and of pitch, and counts only past the gate.
    #[test]
    fn near_hidden_counts_confident_answers_on_the_line_only() {
        let truth = Truth {
            roll_deg: 10.0,
            pitch_deg: 2.0,
            visible: false,
        };
        let answer = |roll: f32, pitch: f32, confidence: f32| Answer {
            attitude: Some((roll, pitch)),
            confidence: Some(confidence),
        };
        let answers = [
            answer(11.5, 3.5, 0.9),
            answer(12.5, 2.0, 0.9),
            answer(10.0, 4.5, 0.9),
            answer(10.0, 2.0, 0.1),
        ];
        let a = evaluate(&answers, &[truth; 4]);
        assert_eq!(a.confident_near_hidden, 1);
        assert!((a.false_confident_rate - 0.75).abs() < 1e-6);
    }
}
