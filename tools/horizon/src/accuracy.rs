//! Accuracy figures of a run against ground truth.

use crate::synth::Truth;
use serde::Serialize;

/// One frame's answer: roll and pitch in degrees (`None`: no horizon) and confidence.
#[derive(Clone, Copy, Debug)]
pub struct Answer {
    pub attitude: Option<(f32, f32)>,
    pub confidence: Option<f32>,
}

/// Errors are absolute, in degrees, over the frames with an answer; `within_2deg` is over all
/// frames (a frame without an answer is not within).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Accuracy {
    pub frames: usize,
    pub found: usize,
    pub roll_median_deg: f32,
    pub roll_p95_deg: f32,
    pub pitch_median_deg: f32,
    pub pitch_p95_deg: f32,
    /// Share of all frames with both roll and pitch within 2°.
    pub within_2deg: f32,
    /// Frames more than 5° wrong (roll or pitch) reported with confidence above 0.5.
    pub wrong_confident: usize,
    /// Frames more than 5° wrong, any confidence.
    pub wrong: usize,
    /// Share of all frames answered with confidence above 0.5 (`None` for a detector
    /// without a confidence).
    pub confident: Option<f32>,
}

/// Above this a confident answer counts as a lie (the accuracy tests assert none).
pub const CONFIDENT: f32 = 0.5;
pub const WRONG_DEG: f32 = 5.0;

pub fn roll_error_deg(measured: f32, truth: f32) -> f32 {
    let mut e = (measured - truth) % 360.0;
    if e > 180.0 {
        e -= 360.0;
    }
    if e < -180.0 {
        e += 360.0;
    }
    e.abs()
}

fn percentile(sorted: &[f32], p: f32) -> f32 {
    if sorted.is_empty() {
        return f32::NAN;
    }
    let rank = ((p * sorted.len() as f32).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}

pub fn evaluate(answers: &[Answer], truths: &[Truth]) -> Accuracy {
    let mut roll_errors = Vec::new();
    let mut pitch_errors = Vec::new();
    let mut within = 0;
    let (mut wrong, mut wrong_confident) = (0, 0);
    let mut confident = 0;
    let has_confidence = answers.iter().any(|a| a.confidence.is_some());
    for (a, t) in answers.iter().zip(truths) {
        let Some((roll, pitch)) = a.attitude else {
            continue;
        };
        if a.confidence.is_some_and(|c| c > CONFIDENT) {
            confident += 1;
        }
        let re = roll_error_deg(roll, t.roll_deg);
        let pe = (pitch - t.pitch_deg).abs();
        roll_errors.push(re);
        pitch_errors.push(pe);
        if re <= 2.0 && pe <= 2.0 {
            within += 1;
        }
        if re > WRONG_DEG || pe > WRONG_DEG {
            wrong += 1;
            if a.confidence.is_some_and(|c| c > CONFIDENT) {
                wrong_confident += 1;
            }
        }
    }
    roll_errors.sort_by(f32::total_cmp);
    pitch_errors.sort_by(f32::total_cmp);
    let frames = answers.len().min(truths.len());
    Accuracy {
        frames,
        found: roll_errors.len(),
        roll_median_deg: percentile(&roll_errors, 0.5),
        roll_p95_deg: percentile(&roll_errors, 0.95),
        pitch_median_deg: percentile(&pitch_errors, 0.5),
        pitch_p95_deg: percentile(&pitch_errors, 0.95),
        within_2deg: if frames > 0 {
            within as f32 / frames as f32
        } else {
            0.0
        },
        wrong_confident,
        wrong,
        confident: (has_confidence && frames > 0).then(|| confident as f32 / frames as f32),
    }
}
