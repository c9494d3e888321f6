//! One receiver epoch: what each sentence adds, merged newest-wins into one fix.

use super::*;

/// What a sentence adds to its epoch: a partial fix plus what it says about validity.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Update {
    pub(super) fix: GpsFix,
    /// `Some(false)` when the sentence says there is no fix; `Some(true)` when it vouches
    /// for one.
    pub(super) validity: Option<bool>,
    pub(super) speed_knots: Option<f64>,
    pub(super) course_deg: Option<f64>,
    pub(super) vertical_up_mps: Option<f64>,
}

/// The epoch being assembled.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Epoch {
    pub(super) update: Update,
}

macro_rules! newer_wins {
    ($into:expr, $from:expr; $($field:ident),* $(,)?) => {
        $( if $from.$field.is_some() { $into.$field = $from.$field; } )*
    };
}

impl Epoch {
    pub(super) fn is_empty(&self) -> bool {
        self.update.fix.sentences.is_empty()
    }

    pub(super) fn merge(&mut self, kind: SentenceKind, new: &Update) {
        let fix = &mut self.update.fix;
        fix.sentences = fix.sentences.with(kind);
        newer_wins!(fix, new.fix;
            utc_time_ms, utc_date, quality, dimension, satellites, latitude_deg, longitude_deg,
            altitude_msl_m, altitude_ellipsoid_m, geoid_separation_m, pdop, hdop, vdop);
        for (into, from) in fix.position_sd_m.iter_mut().zip(new.fix.position_sd_m) {
            if from.is_some() {
                *into = from;
            }
        }
        let update = &mut self.update;
        newer_wins!(update, new; speed_knots, course_deg, vertical_up_mps);
        // One "no fix" in an epoch is enough to distrust the whole epoch.
        update.validity = match (update.validity, new.validity) {
            (Some(false), _) | (_, Some(false)) => Some(false),
            (Some(true), _) | (_, Some(true)) => Some(true),
            (None, None) => None,
        };
    }

    pub(super) fn finish(&self) -> GpsFix {
        let update = &self.update;
        let mut fix = update.fix;
        let separation = fix.geoid_separation_m.map(f64::from);
        if fix.altitude_msl_m.is_none() {
            fix.altitude_msl_m = fix
                .altitude_ellipsoid_m
                .zip(separation)
                .map(|(ellipsoid, separation)| ellipsoid - separation);
        }
        if fix.altitude_ellipsoid_m.is_none() {
            fix.altitude_ellipsoid_m = fix
                .altitude_msl_m
                .zip(separation)
                .map(|(msl, separation)| msl + separation);
        }
        let speed_mps = update
            .speed_knots
            .map(|knots| knots * METRES_PER_SECOND_PER_KNOT);
        let course_rad = update.course_deg.map(f64::to_radians);
        fix.ground_speed_mps = speed_mps.map(|speed| speed as f32);
        fix.course_rad = course_rad.map(|course| course as f32);
        let horizontal = match (speed_mps, course_rad) {
            (Some(speed), Some(course)) => {
                Some((speed * libm::cos(course), speed * libm::sin(course)))
            }
            // Receivers leave the course empty when standing still.
            (Some(0.0), None) => Some((0.0, 0.0)),
            _ => None,
        };
        fix.velocity_ned_mps = [
            horizontal.map(|(north, _)| north as f32),
            horizontal.map(|(_, east)| east as f32),
            update.vertical_up_mps.map(|up| -up as f32),
        ];
        fix.valid = update.validity == Some(true)
            && fix.latitude_deg.is_some()
            && fix.longitude_deg.is_some()
            && fix.quality.is_none_or(FixQuality::is_measured_fix)
            && fix.dimension != Some(FixDimension::NoFix);
        fix
    }
}
