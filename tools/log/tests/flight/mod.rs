//! Small flight directories encoded with the core's encoders, per docs/log-streams.md, with
//! known values and known record times.

use std::path::Path;

use skyframe_core::logfmt::{
    LogFormat, Value, encode_begin_data, encode_data_block, encode_end_data,
};

pub const IMU_FAST: LogFormat = LogFormat::new(
    "%hhu,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%hhu",
    "counter,p_rad_s,q_rad_s,r_rad_s,fx_m_s2,fy_m_s2,fz_m_s2,status",
);
pub const IMU_SLOW: LogFormat = LogFormat::new(
    "%hu,%.2f,%.3f,%hu,%.5f,%.5f,%.5f,%.4f,%.4f,%.4f,%hu",
    "record_counter,temperature_c,supply_v,serial_number,mean_p_rad_s,mean_q_rad_s,\
     mean_r_rad_s,mean_fx_m_s2,mean_fy_m_s2,mean_fz_m_s2,built_in_test",
);
pub const GPS: LogFormat = LogFormat::new(
    "%hhu,%hhu,%hhu,%.8lf,%.8lf,%.3lf,%.3f,%.3f,%.3f,%.2f,%.2f,%.2f,%.3f,%.3f,%.3f,%u",
    "valid,quality,satellites,lat_deg,lon_deg,alt_m,vn_m_s,ve_m_s,vd_m_s,pdop,hdop,vdop,\
     sd_n_m,sd_e_m,sd_d_m,utc_ms",
);
pub const SERVO_BOARD: LogFormat = LogFormat::new(
    "%hhu,%hu,%hu,%hu,%hu,%hu,%hu,%hu,%hu,%hhu,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f",
    "counter,ch1_us,ch2_us,ch3_us,ch4_us,ch5_us,ch6_us,ch7_us,ch8_us,auto,aileron,elevator,\
     throttle,rudder,batt_avionics_v,batt_servo_v",
);
pub const SERVO_COMMAND: LogFormat = LogFormat::new(
    "%hhu,%.3f,%.3f,%.3f,%.3f",
    "ready,aileron_cmd,elevator_cmd,throttle_cmd,rudder_cmd",
);
pub const EXECUTIVE: LogFormat = LogFormat::new(
    "%llu,%llu,%u,%u,%u,%u,%u,%u,%u,%u,%u,%hhu,%u,%u",
    "frame,release_ns,start_latency_ns,work_ns,overhead_ns,missed_before,ran_mask,\
     over_budget_mask,over_frame_mask,skipped_mask,reset_mask,flags,exec_ns_imu,exec_ns_gps",
);

/// Flight start: TIME 1 700 000 000 s.
pub const START_NS: u64 = 1_700_000_000_000_000_000;
/// Flight length.
pub const SECONDS: u64 = 20;

/// The GPS record times (ns from the start): the cycle 120,140,160,100,140,130,300,30 ms —
/// eight intervals summing to 1 120 ms: a jittery 140 ms period with a 300 ms peak.
pub fn gps_times_ns() -> Vec<u64> {
    let cycle = [120u64, 140, 160, 100, 140, 130, 300, 30];
    let mut times = vec![0u64];
    let mut t = 0u64;
    'outer: loop {
        for ms in cycle {
            t += ms * 1_000_000;
            if t >= SECONDS * 1_000_000_000 {
                break 'outer;
            }
            times.push(t);
        }
    }
    times
}

/// A stream file being built.
pub struct StreamFile {
    bytes: Vec<u8>,
    buf: Vec<u8>,
}

impl StreamFile {
    pub fn new(formats: &[(u8, LogFormat)]) -> Self {
        let mut file = Self {
            bytes: Vec::new(),
            buf: vec![0; 4096],
        };
        let n = encode_begin_data(&mut file.buf, START_NS).expect("begin");
        file.bytes.extend_from_slice(&file.buf[..n]);
        for (index, format) in formats {
            let n = format
                .encode_declaration(&mut file.buf, *index)
                .expect("declaration");
            file.bytes.extend_from_slice(&file.buf[..n]);
        }
        file
    }

    pub fn record(&mut self, index: u8, format: &LogFormat, t_ns: u64, values: &[Value]) {
        let parsed = format.parse().expect("format");
        let n = encode_data_block(&mut self.buf, index, START_NS + t_ns, &parsed, values)
            .expect("record");
        self.bytes.extend_from_slice(&self.buf[..n]);
    }

    pub fn finish(mut self, path: &Path) -> Vec<u8> {
        let n = encode_end_data(&mut self.buf, START_NS + SECONDS * 1_000_000_000).expect("end");
        self.bytes.extend_from_slice(&self.buf[..n]);
        std::fs::write(path, &self.bytes).expect("write stream");
        self.bytes
    }
}

fn f(x: f64) -> Value {
    Value::F32(x as f32)
}

/// p (rad/s) at `t` s: what the IMU logs.
pub fn imu_p(t: f64) -> f64 {
    0.5 * (std::f64::consts::TAU * t / 4.0).sin()
}

pub fn write_imu(dir: &Path) {
    let mut file = StreamFile::new(&[(1, IMU_FAST), (2, IMU_SLOW)]);
    for n in 0..SECONDS * 100 {
        let t_ns = n * 10_000_000;
        let t = t_ns as f64 * 1e-9;
        file.record(
            1,
            &IMU_FAST,
            t_ns,
            &[
                Value::U8((n % 256) as u8),
                f(imu_p(t)),
                f(0.1),
                f(-0.05),
                f(0.0),
                f(0.0),
                f(-9.80665),
                Value::U8(0),
            ],
        );
        if n % 100 == 99 {
            file.record(
                2,
                &IMU_SLOW,
                t_ns,
                &[
                    Value::U16((n / 100) as u16),
                    f(30.0),
                    f(5.0),
                    Value::U16(77),
                    f(0.0),
                    f(0.1),
                    f(-0.05),
                    f(0.0),
                    f(0.0),
                    f(-9.80665),
                    Value::U16(0),
                ],
            );
        }
    }
    file.finish(&dir.join("imu.bin"));
}

/// The first three epochs have no fix (valid 0, NaN position); the vehicle then flies north
/// at 10 m/s from (45°, 7°).
pub fn write_gps(dir: &Path) {
    let mut file = StreamFile::new(&[(1, GPS)]);
    for (i, t_ns) in gps_times_ns().into_iter().enumerate() {
        let t = t_ns as f64 * 1e-9;
        let valid = i >= 3;
        let lat = if valid {
            45.0 + (t * 10.0) / 111_131.0
        } else {
            f64::NAN
        };
        let lon = if valid { 7.0 } else { f64::NAN };
        file.record(
            1,
            &GPS,
            t_ns,
            &[
                Value::U8(u8::from(valid)),
                Value::U8(u8::from(valid)),
                Value::U8(if valid { 9 } else { 2 }),
                Value::F64(lat),
                Value::F64(lon),
                Value::F64(if valid { 250.0 } else { f64::NAN }),
                f(10.0),
                f(0.0),
                f(0.0),
                f(1.8),
                f(0.9),
                f(1.5),
                f(1.2),
                f(1.1),
                f(2.5),
                Value::U32(43_200_000 + (t_ns / 1_000_000) as u32),
            ],
        );
    }
    file.finish(&dir.join("gps.bin"));
}

pub fn write_servo(dir: &Path) {
    let mut file = StreamFile::new(&[(1, SERVO_BOARD), (2, SERVO_COMMAND)]);
    for n in 0..SECONDS * 50 {
        let t_ns = n * 20_000_000;
        let t = t_ns as f64 * 1e-9;
        let aileron = 0.8 * (std::f64::consts::TAU * t / 4.0).sin();
        let mut values = vec![Value::U8((n % 256) as u8)];
        values.extend((0..8).map(|_| Value::U16(1500)));
        values.extend([
            Value::U8(0),
            f(aileron),
            f(0.0),
            f(0.5),
            f(0.0),
            f(12.4 - t * 0.01),
            f(7.9 - t * 0.02),
        ]);
        file.record(1, &SERVO_BOARD, t_ns, &values);
        file.record(
            2,
            &SERVO_COMMAND,
            t_ns + 1_000_000,
            &[Value::U8(1), f(aileron), f(0.0), f(0.5), f(0.0)],
        );
    }
    file.finish(&dir.join("servo.bin"));
}

pub fn write_executive(dir: &Path) {
    let mut file = StreamFile::new(&[(1, EXECUTIVE)]);
    for n in 0..SECONDS * 100 {
        let t_ns = n * 10_000_000;
        let mut values = vec![Value::U64(n), Value::U64(t_ns)];
        values.extend((0..9).map(|i| Value::U32(if i == 1 { 2_000_000 } else { 0 })));
        values.extend([Value::U8(0), Value::U32(300_000), Value::U32(150_000)]);
        file.record(1, &EXECUTIVE, t_ns, &values);
    }
    file.finish(&dir.join("executive.bin"));
}

/// A whole flight: executive, imu, gps and servo streams.
pub fn write_flight(dir: &Path) {
    write_executive(dir);
    write_imu(dir);
    write_gps(dir);
    write_servo(dir);
}

pub const ESTIMATOR: LogFormat = LogFormat::new(
    "%.5f,%.5f,%.5f,%.6f,%.6f,%.6f,%.6f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.6f,%.6f,%.6f,%.5f,%.5f,\
     %.5f,%hhu",
    "roll_rad,pitch_rad,yaw_rad,qw,qx,qy,qz,vn_m_s,ve_m_s,vd_m_s,pn_m,pe_m,pd_m,bgx_rad_s,\
     bgy_rad_s,bgz_rad_s,bax_m_s2,bay_m_s2,baz_m_s2,healthy",
);
pub const CONTROL: LogFormat = LogFormat::new(
    "%hhu,%hhu,%.4f,%.4f,%.4f,%.2f,%.2f,%.3f,%.3f,%.3f,%.3f,%.4f,%.4f,%.4f,%.2f,%.2f,%hhu,%hhu,\
     %.3f,%.3f,%.3f,%.3f,%hhu,%.2f,%.2f",
    "mode,reason,roll_rad,pitch_rad,course_rad,alt_m,speed_m_s,stick_aileron,stick_elevator,\
     stick_throttle,stick_rudder,roll_c_rad,pitch_c_rad,course_c_rad,alt_c_m,speed_c_m_s,zone,\
     waypoint,aileron,elevator,throttle,rudder,ready,wind_n_m_s,wind_e_m_s",
);
pub const CONTROL_GAINS: LogFormat = LogFormat::new(
    "%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,\
     %.2f,%.2f,%.2f,%.2f,%.2f",
    "roll_kp,roll_ki,roll_kd,pitch_kp,pitch_ki,pitch_kd,course_kp,course_ki,alt_kp,alt_ki,\
     alt_kd,speed_kp,speed_ki,speed_pitch_kp,speed_pitch_ki,yaw_damper,trim_elevator,\
     trim_throttle,max_bank_deg,max_pitch_deg,stab_roll_deg,stab_pitch_deg,cruise_m_s",
);

/// The control gains at start; at 10 s `roll_kp` (the first) becomes 1.5.
pub fn gains(t_s: f64) -> Vec<f64> {
    let mut g = vec![
        1.2, 0.1, 0.15, 2.0, 0.5, 0.1, 1.0, 0.05, 0.1, 0.01, 0.05, 0.2, 0.05, 0.1, 0.02, 0.3, 0.05,
        0.55, 35.0, 20.0, 30.0, 15.0, 18.0,
    ];
    if t_s >= 10.0 {
        g[0] = 1.5;
    }
    g
}

/// The flown mode at `t` s: manual (0) until 5 s, auto (2) until 15 s, then stabilise (1).
pub fn mode(t: f64) -> u8 {
    if t < 5.0 {
        0
    } else if t < 15.0 {
        2
    } else {
        1
    }
}

/// The estimate: 3-2-1 angles slowly turning, flying north at 10 m/s, 100 m above home.
pub fn write_estimator(dir: &Path) {
    let mut file = StreamFile::new(&[(1, ESTIMATOR)]);
    for n in 0..SECONDS * 100 {
        let t_ns = n * 10_000_000;
        let t = t_ns as f64 * 1e-9;
        let (roll, pitch, yaw) = (0.2 * (t / 3.0).sin(), 0.05, 0.3 + 0.01 * t);
        let (sr, cr) = (roll / 2.0).sin_cos();
        let (sp, cp) = (pitch / 2.0_f64).sin_cos();
        let (sy, cy) = (yaw / 2.0).sin_cos();
        let q = [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ];
        let mut values = vec![
            f(roll),
            f(pitch),
            f(yaw),
            f(q[0]),
            f(q[1]),
            f(q[2]),
            f(q[3]),
        ];
        values.extend([f(10.0), f(0.5), f(-0.2), f(10.0 * t), f(0.5 * t), f(-100.0)]);
        values.extend((0..6).map(|_| f(0.001)));
        values.push(Value::U8(u8::from(t >= 2.0)));
        file.record(1, &ESTIMATOR, t_ns, &values);
    }
    file.finish(&dir.join("estimator.bin"));
}

/// The control loop at 50 Hz (targets NaN in manual, as the task logs them) and its gains
/// at start and after the change at 10 s.
pub fn write_control(dir: &Path) {
    let mut file = StreamFile::new(&[(1, CONTROL), (2, CONTROL_GAINS)]);
    let gains_record = |file: &mut StreamFile, t_ns: u64| {
        let g: Vec<Value> = gains(t_ns as f64 * 1e-9).into_iter().map(f).collect();
        file.record(2, &CONTROL_GAINS, t_ns, &g);
    };
    gains_record(&mut file, 0);
    for n in 0..SECONDS * 50 {
        let t_ns = n * 20_000_000;
        let t = t_ns as f64 * 1e-9;
        if n == 500 {
            gains_record(&mut file, t_ns);
        }
        let m = mode(t);
        let target = |x: f64| if m == 0 { f(f64::NAN) } else { f(x) };
        let mut values = vec![Value::U8(m), Value::U8(0)];
        values.extend([f(0.1), f(0.05), f(0.3), f(100.0), f(17.5)]);
        values.extend([f(0.0), f(0.0), f(0.5), f(0.0)]);
        values.extend([
            target(0.25 * (t / 2.0).sin()),
            target(0.04),
            target(0.3),
            target(120.0),
            target(18.0),
        ]);
        values.extend([Value::U8(1), Value::U8(if m == 2 { 0 } else { 255 })]);
        values.extend([
            f(0.1),
            f(-0.05),
            f(0.6),
            f(0.0),
            Value::U8(u8::from(m != 0)),
        ]);
        values.extend([f(1.5), f(-0.5)]);
        file.record(1, &CONTROL, t_ns, &values);
    }
    file.finish(&dir.join("control.bin"));
}

/// A flight with the estimator's and the autopilot's streams too.
pub fn write_full_flight(dir: &Path) {
    write_flight(dir);
    write_estimator(dir);
    write_control(dir);
}
