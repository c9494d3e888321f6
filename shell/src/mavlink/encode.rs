//! MAVLink messages from the vehicle's live data ([`VehicleView`]), in MAVLink's units and
//! frames. skyframe's conventions (`../shared/specs/conventions.md`): SI units, radians,
//! NED, body axes forward-right-down, altitudes up. MAVLink's: degE7 for latitude and
//! longitude, mm for altitudes, cm/s for velocities, cdeg for headings, mG and mrad/s for
//! the scaled IMU, NED velocities (vx north, vy east, vz down), body rates in rad/s.

use super::mav::{
    ATTITUDE_DATA, BATTERY_STATUS_DATA, EXTENDED_SYS_STATE_DATA, GLOBAL_POSITION_INT_DATA,
    GPS_RAW_INT_DATA, GpsFixType, HEARTBEAT_DATA, MavAutopilot, MavBatteryFault,
    MavBatteryFunction, MavBatteryType, MavLandedState, MavModeFlag, MavState, MavSysStatusSensor,
    MavSysStatusSensorExtended, MavType, NAV_CONTROLLER_OUTPUT_DATA, RC_CHANNELS_DATA,
    SCALED_IMU_DATA, SERVO_OUTPUT_RAW_DATA, SYS_STATUS_DATA, VFR_HUD_DATA,
};
use super::view::VehicleView;
use skyframe_core::control::mode::FlightMode;
use skyframe_core::estimation::ekf::GRAVITY_MPS2;
use skyframe_core::estimation::geo::{GeoPoint, LocalFrame};
use skyframe_core::estimation::nalgebra::Vector3;

/// Degrees as MAVLink's degE7 integer (saturating: only an absurd input reaches the limits).
pub fn deg_e7(deg: f64) -> i32 {
    (deg * 1e7)
        .round()
        .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
}

/// Metres as millimetres.
pub fn mm(m: f64) -> i32 {
    (m * 1e3)
        .round()
        .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
}

/// m/s as cm/s in an i16.
pub fn cm_s(v: f64) -> i16 {
    (v * 100.0).round().clamp(-32768.0, 32767.0) as i16
}

/// A heading (rad, any turn) as centidegrees 0..=35999.
pub fn cdeg_heading(rad: f64) -> u16 {
    let deg = rad.to_degrees().rem_euclid(360.0);
    ((deg * 100.0).round() as u32 % 36_000) as u16
}

/// A heading (rad) as whole degrees 0..=359 (VFR_HUD).
pub fn deg_heading(rad: f64) -> i16 {
    (rad.to_degrees().rem_euclid(360.0).round() as i16) % 360
}

/// Specific force (m/s²) as milli-g.
pub fn milli_g(a: f64) -> i16 {
    (a / GRAVITY_MPS2 * 1e3).round().clamp(-32768.0, 32767.0) as i16
}

/// A normalised servo command as a pulse width: −1..1 → 1000..2000 µs; throttle 0..1 →
/// 1000..2000 µs.
pub fn pulse_us(cmd: f64, unipolar: bool) -> u16 {
    let us = if unipolar {
        1000.0 + 1000.0 * cmd.clamp(0.0, 1.0)
    } else {
        1500.0 + 500.0 * cmd.clamp(-1.0, 1.0)
    };
    us.round() as u16
}

/// MAVLink's `custom_mode` of each skyframe mode: ArduPlane's numbers for the same modes
/// (MANUAL 0, STABILIZE 2, AUTO 10), because the field's tools (pymavlink, MAVProxy) name a
/// fixed wing's custom modes by ArduPlane's table: with skyframe's own 0/1/2 they would show
/// stabilise as CIRCLE and auto as STABILIZE. docs/mavlink.md lists them.
pub const CUSTOM_MODES: [(FlightMode, u32); 3] = [
    (FlightMode::Manual, 0),
    (FlightMode::Stabilise, 2),
    (FlightMode::Auto, 10),
];

pub fn custom_mode(mode: Option<FlightMode>) -> u32 {
    mode.and_then(|m| CUSTOM_MODES.iter().find(|(f, _)| *f == m))
        .map_or(0, |(_, n)| *n)
}

/// The skyframe mode of a `custom_mode` (DO_SET_MODE's param2, SET_MODE).
pub fn flight_mode(custom: f32) -> Option<FlightMode> {
    CUSTOM_MODES
        .iter()
        .find(|(_, n)| *n as f32 == custom)
        .map(|(f, _)| *f)
}

/// Where the airplane is: home plus the estimator's NED position.
pub fn position(view: &VehicleView, home: &LocalFrame) -> Option<GeoPoint> {
    let pn = view.get("estimator", "pn_m")?;
    let pe = view.get("estimator", "pe_m")?;
    let pd = view.get("estimator", "pd_m")?;
    Some(home.to_geodetic(&Vector3::new(pn, pe, pd)))
}

pub struct Armed(pub bool);

/// The flight computer is armed when its servo outputs are live (`servo.ready`): the
/// safety pilot's transmitter can hand the airplane over from then on.
pub fn armed(view: &VehicleView) -> Armed {
    Armed(view.get("servo", "ready").or(view.get("control", "ready")) == Some(1.0))
}

/// Landed when below 3 m above home and slower than 3 m/s over ground (skyframe has no
/// weight-on-wheels sensor; this is what the estimator can tell).
pub fn landed(view: &VehicleView) -> Option<bool> {
    let pd = view.get("estimator", "pd_m")?;
    let vn = view.get("estimator", "vn_m_s")?;
    let ve = view.get("estimator", "ve_m_s")?;
    Some(-pd < 3.0 && vn.hypot(ve) < 3.0)
}

pub fn heartbeat(view: &VehicleView) -> HEARTBEAT_DATA {
    let mode = view.mode();
    let mut base = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
    match mode {
        Some(FlightMode::Manual) => base |= MavModeFlag::MAV_MODE_FLAG_MANUAL_INPUT_ENABLED,
        Some(FlightMode::Stabilise) => {
            base |= MavModeFlag::MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
                | MavModeFlag::MAV_MODE_FLAG_STABILIZE_ENABLED;
        }
        Some(FlightMode::Auto) => {
            base |= MavModeFlag::MAV_MODE_FLAG_STABILIZE_ENABLED
                | MavModeFlag::MAV_MODE_FLAG_GUIDED_ENABLED
                | MavModeFlag::MAV_MODE_FLAG_AUTO_ENABLED;
        }
        None => {}
    }
    let Armed(is_armed) = armed(view);
    if is_armed {
        base |= MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
    }
    let system_status = match (view.updates("estimator") > 0, landed(view)) {
        (false, _) | (_, None) => MavState::MAV_STATE_BOOT,
        (true, Some(true)) => MavState::MAV_STATE_STANDBY,
        (true, Some(false)) => MavState::MAV_STATE_ACTIVE,
    };
    HEARTBEAT_DATA {
        custom_mode: custom_mode(mode),
        mavtype: MavType::MAV_TYPE_FIXED_WING,
        autopilot: MavAutopilot::MAV_AUTOPILOT_GENERIC,
        base_mode: base,
        system_status,
        mavlink_version: 3,
    }
}

/// A task is healthy when initialised, running, in its frame and alive (the seed's four
/// lights) and its device is not stale.
fn task_healthy(view: &VehicleView, task: &str) -> bool {
    let lights = view
        .status(task)
        .is_some_and(|s| s.initialised && s.running && s.in_frame && s.alive);
    lights && view.get(task, "stale") != Some(1.0)
}

/// SYS_STATUS: sensors from the device tasks' health, the avionics battery, and the
/// MAVLink endpoint's own drop rate and errors (`rejected` of `received`).
pub fn sys_status(view: &VehicleView, received: u64, rejected: u64) -> SYS_STATUS_DATA {
    let sensors = [
        (
            "imu",
            MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_GYRO
                | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_ACCEL,
        ),
        ("gps", MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_GPS),
        (
            "servo",
            MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
                | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_RC_RECEIVER,
        ),
        ("estimator", MavSysStatusSensor::MAV_SYS_STATUS_AHRS),
        (
            "control",
            MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
                | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
                | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_YAW_POSITION
                | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
                | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL,
        ),
    ];
    let mut present = MavSysStatusSensor::empty();
    // No geofence, so never a breach: the health bit says so (as ArduPilot sets it), or
    // MAVProxy reports "fence breach".
    let mut health = MavSysStatusSensor::MAV_SYS_STATUS_GEOFENCE;
    for (task, bits) in sensors {
        if view.status(task).is_none() && view.updates(task) == 0 {
            continue;
        }
        present |= bits;
        let estimator_ok = task != "estimator" || view.get("estimator", "healthy") == Some(1.0);
        if task_healthy(view, task) && estimator_ok {
            health |= bits;
        }
    }
    let voltage = view
        .get("servo", "batt_avionics_v")
        .map_or(u16::MAX, |v| (v * 1e3).round().clamp(0.0, 65534.0) as u16);
    // Refused per 10 000 received (c%), as MAVLink counts it; nothing received: none.
    let drop_rate = rejected
        .saturating_mul(10_000)
        .checked_div(received)
        .map_or(0, |r| r.min(10_000) as u16);
    SYS_STATUS_DATA {
        onboard_control_sensors_present: present,
        onboard_control_sensors_enabled: present,
        onboard_control_sensors_health: health,
        voltage_battery: voltage,
        current_battery: -1,
        battery_remaining: -1,
        drop_rate_comm: drop_rate,
        errors_comm: u16::try_from(rejected).unwrap_or(u16::MAX),
        // The crate's default for a bit set is its first flag, not none.
        onboard_control_sensors_present_extended: MavSysStatusSensorExtended::empty(),
        onboard_control_sensors_enabled_extended: MavSysStatusSensorExtended::empty(),
        onboard_control_sensors_health_extended: MavSysStatusSensorExtended::empty(),
        ..SYS_STATUS_DATA::default()
    }
}

pub fn extended_sys_state(view: &VehicleView) -> EXTENDED_SYS_STATE_DATA {
    EXTENDED_SYS_STATE_DATA {
        landed_state: match landed(view) {
            None => MavLandedState::MAV_LANDED_STATE_UNDEFINED,
            Some(true) => MavLandedState::MAV_LANDED_STATE_ON_GROUND,
            Some(false) => MavLandedState::MAV_LANDED_STATE_IN_AIR,
        },
        ..EXTENDED_SYS_STATE_DATA::default()
    }
}

pub fn attitude(view: &VehicleView) -> Option<ATTITUDE_DATA> {
    let yaw = view.get("estimator", "yaw_rad")?;
    // MAVLink's yaw is −π..π.
    let yaw = (yaw + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
    Some(ATTITUDE_DATA {
        time_boot_ms: view.boot_ms_of("estimator", "roll_rad")?,
        roll: view.get("estimator", "roll_rad")? as f32,
        pitch: view.get("estimator", "pitch_rad")? as f32,
        yaw: yaw as f32,
        rollspeed: view.get("imu", "p_rad_s").unwrap_or(0.0) as f32,
        pitchspeed: view.get("imu", "q_rad_s").unwrap_or(0.0) as f32,
        yawspeed: view.get("imu", "r_rad_s").unwrap_or(0.0) as f32,
    })
}

pub fn global_position_int(
    view: &VehicleView,
    home: &LocalFrame,
) -> Option<GLOBAL_POSITION_INT_DATA> {
    let p = position(view, home)?;
    Some(GLOBAL_POSITION_INT_DATA {
        time_boot_ms: view.boot_ms_of("estimator", "pn_m")?,
        lat: deg_e7(p.latitude_deg),
        lon: deg_e7(p.longitude_deg),
        alt: mm(p.altitude_m),
        relative_alt: mm(-view.get("estimator", "pd_m")?),
        vx: cm_s(view.get("estimator", "vn_m_s")?),
        vy: cm_s(view.get("estimator", "ve_m_s")?),
        vz: cm_s(view.get("estimator", "vd_m_s")?),
        hdg: cdeg_heading(view.get("estimator", "yaw_rad")?),
    })
}

pub fn gps_raw_int(view: &VehicleView) -> Option<GPS_RAW_INT_DATA> {
    let valid = view.get("gps", "valid")? == 1.0;
    let vn = view.get("gps", "vn_m_s").unwrap_or(0.0);
    let ve = view.get("gps", "ve_m_s").unwrap_or(0.0);
    let dop = |c: &str| {
        view.get("gps", c)
            .filter(|d| d.is_finite() && *d > 0.0)
            .map_or(u16::MAX, |d| (d * 100.0).round().min(65534.0) as u16)
    };
    let sd = |c: &str| view.get("gps", c).filter(|d| d.is_finite());
    let h_acc = match (sd("sd_n_m"), sd("sd_e_m")) {
        (Some(n), Some(e)) => (n.hypot(e) * 1e3).round().min(f64::from(u32::MAX - 1)) as u32,
        _ => 0,
    };
    Some(GPS_RAW_INT_DATA {
        time_usec: u64::from(view.time_boot_ms()) * 1000,
        lat: if valid {
            deg_e7(view.get("gps", "lat_deg")?)
        } else {
            0
        },
        lon: if valid {
            deg_e7(view.get("gps", "lon_deg")?)
        } else {
            0
        },
        alt: if valid {
            mm(view.get("gps", "alt_m")?)
        } else {
            0
        },
        eph: dop("hdop"),
        epv: dop("vdop"),
        vel: (vn.hypot(ve) * 100.0).round().min(65534.0) as u16,
        cog: if valid {
            cdeg_heading(ve.atan2(vn))
        } else {
            u16::MAX
        },
        fix_type: if valid {
            GpsFixType::GPS_FIX_TYPE_3D_FIX
        } else {
            GpsFixType::GPS_FIX_TYPE_NO_FIX
        },
        satellites_visible: view
            .get("gps", "satellites")
            .map_or(u8::MAX, |s| s.clamp(0.0, 254.0) as u8),
        h_acc,
        v_acc: sd("sd_d_m").map_or(0, |d| (d * 1e3).round().min(f64::from(u32::MAX - 1)) as u32),
        ..GPS_RAW_INT_DATA::default()
    })
}

pub fn vfr_hud(view: &VehicleView, home: &LocalFrame) -> Option<VFR_HUD_DATA> {
    let vn = view.get("estimator", "vn_m_s")?;
    let ve = view.get("estimator", "ve_m_s")?;
    let p = position(view, home)?;
    Some(VFR_HUD_DATA {
        airspeed: view.get("control", "speed_m_s").unwrap_or(0.0) as f32,
        groundspeed: vn.hypot(ve) as f32,
        alt: p.altitude_m as f32,
        climb: -view.get("estimator", "vd_m_s")? as f32,
        heading: deg_heading(view.get("estimator", "yaw_rad")?),
        throttle: (view
            .get("control", "throttle")
            .unwrap_or(0.0)
            .clamp(0.0, 1.0)
            * 100.0)
            .round() as u16,
    })
}

pub fn battery_status(view: &VehicleView) -> Option<BATTERY_STATUS_DATA> {
    let avionics = view.get("servo", "batt_avionics_v")?;
    let mut voltages = [u16::MAX; 10];
    voltages[0] = (avionics * 1e3).round().clamp(0.0, 65534.0) as u16;
    Some(BATTERY_STATUS_DATA {
        id: 0,
        battery_function: MavBatteryFunction::MAV_BATTERY_FUNCTION_AVIONICS,
        mavtype: MavBatteryType::MAV_BATTERY_TYPE_UNKNOWN,
        temperature: i16::MAX,
        voltages,
        current_battery: -1,
        current_consumed: -1,
        energy_consumed: -1,
        battery_remaining: -1,
        // The crate's default for a bit set is its first flag (deep discharge!), not none.
        fault_bitmask: MavBatteryFault::empty(),
        ..BATTERY_STATUS_DATA::default()
    })
}

/// SERVO_OUTPUT_RAW: what drives the servos — the flight computer's commands when it has
/// the airplane (`servo.auto`), else the pilot's channels; channels 1–4 are aileron,
/// elevator, throttle, rudder.
pub fn servo_output_raw(view: &VehicleView) -> Option<SERVO_OUTPUT_RAW_DATA> {
    let auto = view.get("servo", "auto")? == 1.0;
    let out = |cmd: &str, ch: &str, unipolar: bool| {
        if auto {
            view.get("servo", cmd).map_or(0, |c| pulse_us(c, unipolar))
        } else {
            view.get("servo", ch)
                .map_or(0, |us| us.clamp(0.0, 65535.0) as u16)
        }
    };
    Some(SERVO_OUTPUT_RAW_DATA {
        time_usec: view.time_boot_ms().wrapping_mul(1000),
        servo1_raw: out("aileron_cmd", "ch1_us", false),
        servo2_raw: out("elevator_cmd", "ch2_us", false),
        servo3_raw: out("throttle_cmd", "ch3_us", true),
        servo4_raw: out("rudder_cmd", "ch4_us", false),
        ..SERVO_OUTPUT_RAW_DATA::default()
    })
}

/// RC_CHANNELS: the pilot's eight receiver channels as the servo board measured them.
pub fn rc_channels(view: &VehicleView) -> Option<RC_CHANNELS_DATA> {
    let ch = |i: usize| {
        view.get("servo", &format!("ch{i}_us"))
            .map_or(u16::MAX, |us| us.clamp(0.0, 65534.0) as u16)
    };
    view.get("servo", "ch1_us")?;
    Some(RC_CHANNELS_DATA {
        time_boot_ms: view.time_boot_ms(),
        chancount: 8,
        chan1_raw: ch(1),
        chan2_raw: ch(2),
        chan3_raw: ch(3),
        chan4_raw: ch(4),
        chan5_raw: ch(5),
        chan6_raw: ch(6),
        chan7_raw: ch(7),
        chan8_raw: ch(8),
        chan9_raw: u16::MAX,
        chan10_raw: u16::MAX,
        chan11_raw: u16::MAX,
        chan12_raw: u16::MAX,
        chan13_raw: u16::MAX,
        chan14_raw: u16::MAX,
        chan15_raw: u16::MAX,
        chan16_raw: u16::MAX,
        chan17_raw: u16::MAX,
        chan18_raw: u16::MAX,
        rssi: u8::MAX,
    })
}

/// SCALED_IMU: specific force in mG and body rates in mrad/s (body axes forward-right-down,
/// as MAVLink's); no magnetometer.
pub fn scaled_imu(view: &VehicleView) -> Option<SCALED_IMU_DATA> {
    let mrad = |c: &str| {
        view.get("imu", c)
            .map_or(0, |r| (r * 1e3).round().clamp(-32768.0, 32767.0) as i16)
    };
    Some(SCALED_IMU_DATA {
        time_boot_ms: view.time_boot_ms(),
        xacc: milli_g(view.get("imu", "fx_m_s2")?),
        yacc: milli_g(view.get("imu", "fy_m_s2")?),
        zacc: milli_g(view.get("imu", "fz_m_s2")?),
        xgyro: mrad("p_rad_s"),
        ygyro: mrad("q_rad_s"),
        zgyro: mrad("r_rad_s"),
        temperature: view
            .get("imu", "temperature_c")
            .map_or(0, |t| (t * 100.0).round().clamp(-32767.0, 32767.0) as i16),
        ..SCALED_IMU_DATA::default()
    })
}

/// NAV_CONTROLLER_OUTPUT (in AUTO): the autopilot's commands and errors, and the distance
/// and bearing to the active waypoint (`target`: its north/east, m).
pub fn nav_controller_output(
    view: &VehicleView,
    target: Option<(f64, f64)>,
) -> Option<NAV_CONTROLLER_OUTPUT_DATA> {
    let pn = view.get("estimator", "pn_m")?;
    let pe = view.get("estimator", "pe_m")?;
    let (dist, bearing) = target.map_or((0.0, 0.0), |(n, e)| {
        ((n - pn).hypot(e - pe), (e - pe).atan2(n - pn))
    });
    let deg = |rad: f64| {
        let d = rad.to_degrees();
        (((d + 180.0).rem_euclid(360.0)) - 180.0).round() as i16
    };
    Some(NAV_CONTROLLER_OUTPUT_DATA {
        nav_roll: view.get("control", "roll_c_rad")?.to_degrees() as f32,
        nav_pitch: view.get("control", "pitch_c_rad")?.to_degrees() as f32,
        nav_bearing: deg(view.get("control", "course_c_rad")?),
        target_bearing: deg(bearing),
        wp_dist: dist.round().clamp(0.0, 65535.0) as u16,
        alt_error: (view.get("control", "alt_c_m")? - view.get("control", "alt_m")?) as f32,
        aspd_error: (view.get("control", "speed_c_m_s")? - view.get("control", "speed_m_s")?)
            as f32,
        xtrack_error: 0.0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_are_mavlinks() {
        assert_eq!(deg_e7(47.397_742_1), 473_977_421);
        assert_eq!(deg_e7(-122.0), -1_220_000_000);
        assert_eq!(mm(488.123_4), 488_123);
        assert_eq!(cm_s(-1.234), -123);
        assert_eq!(cm_s(1e9), i16::MAX);
        assert_eq!(cdeg_heading(-std::f64::consts::FRAC_PI_2), 27_000);
        assert_eq!(cdeg_heading(std::f64::consts::TAU), 0);
        assert_eq!(cdeg_heading(359.994_f64.to_radians()), 35_999);
        assert_eq!(
            cdeg_heading(359.996_f64.to_radians()),
            0,
            "rounds to 360°: 0"
        );
        assert_eq!(deg_heading(-0.1_f64.to_radians()), 0);
        assert_eq!(deg_heading(3.0_f64.to_radians()), 3);
        assert_eq!(milli_g(-9.80665), -1000);
        assert_eq!(pulse_us(-1.0, false), 1000);
        assert_eq!(pulse_us(0.0, false), 1500);
        assert_eq!(pulse_us(0.25, true), 1250);
        assert_eq!(custom_mode(Some(FlightMode::Auto)), 10);
        assert_eq!(custom_mode(Some(FlightMode::Stabilise)), 2);
        assert_eq!(custom_mode(Some(FlightMode::Manual)), 0);
        assert_eq!(flight_mode(10.0), Some(FlightMode::Auto));
        assert_eq!(flight_mode(1.0), None);
        assert_eq!(flight_mode(f32::NAN), None);
    }
}
