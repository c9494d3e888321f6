//! The sentences: GGA, RMC, VTG, GSA, GST and Ashtech POS, each field to its place in
//! the epoch's update.

use super::*;

/// Parses a checksummed body (without `$` and `*hh`). `Ok(None)`: not a sentence we use.
pub(super) fn parse_sentence(body: &[u8]) -> FieldResult<Option<(SentenceKind, Update)>> {
    let mut fields = Fields::new(body);
    let address = fields.next_field();
    let kind = match address {
        b"PASHR" => {
            if fields.next_field() != b"POS" {
                return Ok(None);
            }
            SentenceKind::AshtechPos
        }
        [b'G', b'P' | b'N' | b'L', rest @ ..] => match rest {
            b"GGA" => SentenceKind::Gga,
            b"RMC" => SentenceKind::Rmc,
            b"VTG" => SentenceKind::Vtg,
            b"GSA" => SentenceKind::Gsa,
            b"GST" => SentenceKind::Gst,
            _ => return Ok(None),
        },
        _ => return Ok(None),
    };
    let mut update = Update::default();
    match kind {
        SentenceKind::Gga => parse_gga(&mut fields, &mut update)?,
        SentenceKind::Rmc => parse_rmc(&mut fields, &mut update)?,
        SentenceKind::Vtg => parse_vtg(&mut fields, &mut update)?,
        SentenceKind::Gsa => parse_gsa(&mut fields, &mut update)?,
        SentenceKind::Gst => parse_gst(&mut fields, &mut update)?,
        SentenceKind::AshtechPos => parse_ashtech_pos(&mut fields, &mut update)?,
    }
    update.fix.sentences = SentenceSet::default().with(kind);
    Ok(Some((kind, update)))
}

/// `GGA,time,lat,N,lon,E,quality,satellites,hdop,altitude,M,separation,M,age,station`
pub(super) fn parse_gga(fields: &mut Fields<'_>, update: &mut Update) -> FieldResult<()> {
    update.fix.utc_time_ms = fields.utc_time()?;
    fields.position(update)?;
    let quality = fields.small_integer()?.map(FixQuality::from_gga);
    update.fix.quality = quality;
    update.validity = quality.map(FixQuality::is_measured_fix);
    update.fix.satellites = fields.small_integer()?;
    update.fix.hdop = to_f32(fields.number(DOP)?);
    update.fix.altitude_msl_m = fields.number(ALTITUDE_M)?;
    fields.skip(1);
    update.fix.geoid_separation_m = to_f32(fields.number(GEOID_SEPARATION_M)?);
    Ok(())
}

/// `RMC,time,status,lat,N,lon,E,speed_kn,course,date,magvar,E[,mode[,nav_status]]`
pub(super) fn parse_rmc(fields: &mut Fields<'_>, update: &mut Update) -> FieldResult<()> {
    update.fix.utc_time_ms = fields.utc_time()?;
    let status = fields.character()?;
    fields.position(update)?;
    update.speed_knots = fields.number(SPEED_KNOTS)?;
    update.course_deg = fields.number(COURSE_DEG)?;
    update.fix.utc_date = fields.utc_date()?;
    fields.skip(2);
    let mode = fields.character()?;
    update.validity = match (status, mode) {
        (Some(b'V'), _) | (_, Some(b'N')) => Some(false),
        (Some(b'A'), _) => Some(true),
        (None, _) => None,
        _ => return Err(InvalidField),
    };
    Ok(())
}

/// `VTG,course,T,course_magnetic,M,speed_kn,N,speed_kmh,K[,mode]`
pub(super) fn parse_vtg(fields: &mut Fields<'_>, update: &mut Update) -> FieldResult<()> {
    let course = fields.number(COURSE_DEG)?;
    fields.skip(3);
    let speed = fields.number(SPEED_KNOTS)?;
    fields.skip(3);
    // Mode `N` (not valid): the velocity is not worth merging.
    if fields.character()? != Some(b'N') {
        update.course_deg = course;
        update.speed_knots = speed;
    }
    Ok(())
}

/// `GSA,selection,mode,sv×12,pdop,hdop,vdop[,system]`
pub(super) fn parse_gsa(fields: &mut Fields<'_>, update: &mut Update) -> FieldResult<()> {
    fields.skip(1);
    update.fix.dimension = match fields.small_integer()? {
        None => None,
        Some(1) => Some(FixDimension::NoFix),
        Some(2) => Some(FixDimension::TwoD),
        Some(3) => Some(FixDimension::ThreeD),
        Some(_) => return Err(InvalidField),
    };
    if update.fix.dimension == Some(FixDimension::NoFix) {
        update.validity = Some(false);
    }
    fields.skip(12);
    update.fix.pdop = to_f32(fields.number(DOP)?);
    update.fix.hdop = to_f32(fields.number(DOP)?);
    update.fix.vdop = to_f32(fields.number(DOP)?);
    Ok(())
}

/// `GST,time,rms,sd_major,sd_minor,orientation,sd_lat,sd_lon,sd_alt`
pub(super) fn parse_gst(fields: &mut Fields<'_>, update: &mut Update) -> FieldResult<()> {
    update.fix.utc_time_ms = fields.utc_time()?;
    fields.skip(4);
    let north = to_f32(fields.number(SD_M)?);
    let east = to_f32(fields.number(SD_M)?);
    let down = to_f32(fields.number(SD_M)?);
    update.fix.position_sd_m = [north, east, down];
    Ok(())
}

/// `PASHR,POS,mode,satellites,time,lat,N,lon,E,height,reserved,course,speed_kn,
/// vertical_mps,pdop,hdop,vdop,tdop,firmware` (Ashtech DG14/DG16 manual, table 6.36).
/// The height is above the ellipsoid; vertical velocity is positive up.
pub(super) fn parse_ashtech_pos(fields: &mut Fields<'_>, update: &mut Update) -> FieldResult<()> {
    let mode = fields.small_integer()?;
    update.fix.satellites = fields.small_integer()?;
    update.fix.utc_time_ms = fields.utc_time()?;
    fields.position(update)?;
    update.fix.altitude_ellipsoid_m = fields.number(ALTITUDE_M)?;
    fields.skip(1);
    update.course_deg = fields.number(COURSE_DEG)?;
    update.speed_knots = fields.number(SPEED_KNOTS)?;
    update.vertical_up_mps = fields.number(VERTICAL_SPEED_MPS)?;
    update.fix.pdop = to_f32(fields.number(DOP)?);
    update.fix.hdop = to_f32(fields.number(DOP)?);
    update.fix.vdop = to_f32(fields.number(DOP)?);
    // POS has no "no fix" code: an empty position is how it says so.
    let has_position = update.fix.latitude_deg.is_some() && update.fix.longitude_deg.is_some();
    let quality = mode.map(FixQuality::from_ashtech);
    update.fix.quality = if has_position {
        quality
    } else {
        Some(FixQuality::NoFix)
    };
    update.validity = Some(has_position && quality.is_some_and(FixQuality::is_measured_fix));
    Ok(())
}
