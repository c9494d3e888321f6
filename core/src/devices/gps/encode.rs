//! Encoders: what the simulator sends, byte for byte what a receiver would.

use super::*;

/// The talker id an encoded sentence goes out with.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Talker {
    /// GPS only.
    #[default]
    Gp,
    /// Multi-constellation.
    Gn,
    /// GLONASS.
    Gl,
}

impl Talker {
    pub(super) fn as_str(self) -> &'static str {
        match self {
            Talker::Gp => "GP",
            Talker::Gn => "GN",
            Talker::Gl => "GL",
        }
    }
}

pub(super) type Body = String<MAX_SENTENCE_LEN>;

/// `hhmmss.ss`, or nothing.
pub(super) fn write_time(body: &mut Body, time_ms: Option<u32>) -> core::fmt::Result {
    if let Some(ms) = time_ms {
        let seconds = ms / 1000;
        write!(
            body,
            "{:02}{:02}{:02}.{:02}",
            seconds / 3600 % 24,
            seconds / 60 % 60,
            seconds % 60,
            ms % 1000 / 10
        )?;
    }
    Ok(())
}

/// `ddmm.mmmmmm,N` with integer arithmetic, so the minutes never round up to 60.
pub(super) fn write_angle(
    body: &mut Body,
    angle_deg: Option<f64>,
    degree_digits: usize,
    positive: char,
    negative: char,
) -> core::fmt::Result {
    let Some(angle) = angle_deg else {
        return body.write_str(",");
    };
    let micro_minutes = libm::round(libm::fabs(angle) * 60.0e6) as u64;
    let degrees = micro_minutes / 60_000_000;
    let minutes = micro_minutes % 60_000_000 / 1_000_000;
    let fraction = micro_minutes % 1_000_000;
    let hemisphere = if angle < 0.0 { negative } else { positive };
    write!(
        body,
        "{degrees:0degree_digits$}{minutes:02}.{fraction:06},{hemisphere}"
    )
}

pub(super) fn write_opt<T: core::fmt::Display>(
    body: &mut Body,
    value: Option<T>,
) -> core::fmt::Result {
    match value {
        Some(value) => write!(body, "{value}"),
        None => Ok(()),
    }
}

pub(super) fn write_fixed(
    body: &mut Body,
    value: Option<f64>,
    decimals: usize,
) -> core::fmt::Result {
    match value {
        Some(value) => write!(body, "{value:.decimals$}"),
        None => Ok(()),
    }
}

pub(super) fn speed_knots(fix: &GpsFix) -> Option<f64> {
    fix.ground_speed_mps
        .map(|speed| f64::from(speed) / METRES_PER_SECOND_PER_KNOT)
}

pub(super) fn course_deg(fix: &GpsFix) -> Option<f64> {
    fix.course_rad.map(|course| {
        let degrees = f64::from(course).to_degrees();
        if degrees < 0.0 {
            degrees + 360.0
        } else {
            degrees
        }
    })
}

pub(super) fn write_body(
    kind: SentenceKind,
    talker: Talker,
    fix: &GpsFix,
    body: &mut Body,
) -> core::fmt::Result {
    let t = talker.as_str();
    match kind {
        SentenceKind::Gga => {
            write!(body, "{t}GGA,")?;
            write_time(body, fix.utc_time_ms)?;
            body.write_str(",")?;
            write_angle(body, fix.latitude_deg, 2, 'N', 'S')?;
            body.write_str(",")?;
            write_angle(body, fix.longitude_deg, 3, 'E', 'W')?;
            let quality = match fix.quality {
                Some(quality) => quality,
                None if fix.valid => FixQuality::Autonomous,
                None => FixQuality::NoFix,
            };
            write!(body, ",{},", quality.gga_code())?;
            write_opt(body, fix.satellites.map(|n| n.min(99)))?;
            body.write_str(",")?;
            write_fixed(body, fix.hdop.map(f64::from), 1)?;
            body.write_str(",")?;
            write_fixed(body, fix.altitude_msl_m, 1)?;
            body.write_str(",M,")?;
            write_fixed(body, fix.geoid_separation_m.map(f64::from), 1)?;
            body.write_str(",M,,")
        }
        SentenceKind::Rmc => {
            write!(body, "{t}RMC,")?;
            write_time(body, fix.utc_time_ms)?;
            write!(body, ",{},", if fix.valid { 'A' } else { 'V' })?;
            write_angle(body, fix.latitude_deg, 2, 'N', 'S')?;
            body.write_str(",")?;
            write_angle(body, fix.longitude_deg, 3, 'E', 'W')?;
            body.write_str(",")?;
            write_fixed(body, speed_knots(fix), 3)?;
            body.write_str(",")?;
            write_fixed(body, course_deg(fix), 2)?;
            body.write_str(",")?;
            if let Some(date) = fix.utc_date {
                write!(
                    body,
                    "{:02}{:02}{:02}",
                    date.day,
                    date.month,
                    date.year % 100
                )?;
            }
            write!(body, ",,,{}", if fix.valid { 'A' } else { 'N' })
        }
        SentenceKind::Vtg => {
            write!(body, "{t}VTG,")?;
            write_fixed(body, course_deg(fix), 2)?;
            body.write_str(",T,,M,")?;
            write_fixed(body, speed_knots(fix), 3)?;
            body.write_str(",N,")?;
            write_fixed(body, fix.ground_speed_mps.map(|s| f64::from(s) * 3.6), 3)?;
            write!(body, ",K,{}", if fix.valid { 'A' } else { 'N' })
        }
        SentenceKind::Gsa => {
            let dimension = match fix.dimension {
                Some(FixDimension::ThreeD) => 3,
                Some(FixDimension::TwoD) => 2,
                Some(FixDimension::NoFix) => 1,
                None if fix.valid => 3,
                None => 1,
            };
            write!(body, "{t}GSA,A,{dimension},,,,,,,,,,,,,")?;
            write_fixed(body, fix.pdop.map(f64::from), 1)?;
            body.write_str(",")?;
            write_fixed(body, fix.hdop.map(f64::from), 1)?;
            body.write_str(",")?;
            write_fixed(body, fix.vdop.map(f64::from), 1)
        }
        SentenceKind::Gst => {
            write!(body, "{t}GST,")?;
            write_time(body, fix.utc_time_ms)?;
            body.write_str(",,,,,")?;
            for (index, sd) in fix.position_sd_m.iter().enumerate() {
                if index > 0 {
                    body.write_str(",")?;
                }
                write_fixed(body, sd.map(f64::from), 2)?;
            }
            Ok(())
        }
        SentenceKind::AshtechPos => {
            let quality = fix.quality.unwrap_or(FixQuality::Autonomous);
            body.write_str("PASHR,POS,")?;
            write!(body, "{},", quality.ashtech_code())?;
            write_opt(body, fix.satellites.map(|n| n.min(99)))?;
            body.write_str(",")?;
            write_time(body, fix.utc_time_ms)?;
            body.write_str(",")?;
            write_angle(body, fix.latitude_deg, 2, 'N', 'S')?;
            body.write_str(",")?;
            write_angle(body, fix.longitude_deg, 3, 'E', 'W')?;
            body.write_str(",")?;
            write_fixed(body, fix.altitude_ellipsoid_m, 3)?;
            body.write_str(",,")?;
            write_fixed(body, course_deg(fix), 1)?;
            body.write_str(",")?;
            write_fixed(body, speed_knots(fix), 3)?;
            body.write_str(",")?;
            let up = fix.velocity_ned_mps[2].map(|down| -f64::from(down));
            write_fixed(body, up, 3)?;
            for dop in [fix.pdop, fix.hdop, fix.vdop] {
                body.write_str(",")?;
                write_fixed(body, dop.map(f64::from), 1)?;
            }
            // TDOP and firmware version: not modelled.
            body.write_str(",,SKYF")
        }
    }
}

/// Writes one sentence (`$…*hh\r\n`) describing `fix` into `out`; returns its length, or
/// `None` when it does not fit (`out` too short, or values too large for the format).
pub fn encode_sentence(
    kind: SentenceKind,
    talker: Talker,
    fix: &GpsFix,
    out: &mut [u8],
) -> Option<usize> {
    let mut body = Body::new();
    write_body(kind, talker, fix, &mut body).ok()?;
    // The decoder's limit covers the body and `*hh`.
    if body.len() + 3 > MAX_SENTENCE_LEN {
        return None;
    }
    let checksum = nmea_checksum(body.as_bytes());
    let mut line: String<{ MAX_SENTENCE_LEN + 4 }> = String::new();
    write!(line, "${body}*{checksum:02X}\r\n").ok()?;
    let bytes = line.as_bytes();
    out.get_mut(..bytes.len())?.copy_from_slice(bytes);
    Some(bytes.len())
}
