//! The simulator's ground truth (`truth.bin`) as a time series that can be read at any time.

use skyframe_core::angles::wrap_pi;
use skyframe_logtable::Table;

/// Truth at one instant: NED position from the simulator's origin, NED velocity, 3-2-1 Euler
/// attitude.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TruthAt {
    pub ned_m: [f64; 3],
    pub vel_ned_mps: [f64; 3],
    pub roll_rad: f64,
    pub pitch_rad: f64,
    pub yaw_rad: f64,
    pub on_ground: bool,
}

/// The truth samples, in time order.
pub struct TruthSeries {
    times_ns: Vec<i64>,
    samples: Vec<TruthAt>,
}

/// Two truth samples further apart than this are a hole (a dropped record), not something to
/// interpolate across.
const MAX_GAP_NS: i64 = 100_000_000;

impl TruthSeries {
    /// From `truth.bin` format 1; `None` names the missing column.
    pub fn from_table(table: &Table) -> Result<Self, String> {
        let col = |name: &str| {
            table
                .column(name)
                .ok_or_else(|| format!("truth.bin has no column `{name}`"))
        };
        let (n, e, d) = (col("north_m")?, col("east_m")?, col("down_m")?);
        let (vn, ve, vd) = (col("vn_m_s")?, col("ve_m_s")?, col("vd_m_s")?);
        let (roll, pitch, yaw) = (col("roll_rad")?, col("pitch_rad")?, col("yaw_rad")?);
        let ground = col("on_ground")?;
        let mut times_ns = Vec::with_capacity(table.times_ns.len());
        let mut samples = Vec::with_capacity(table.times_ns.len());
        for (i, &t) in table.times_ns.iter().enumerate() {
            let at = |c: &[f64]| c.get(i).copied().unwrap_or(f64::NAN);
            let sample = TruthAt {
                ned_m: [at(n), at(e), at(d)],
                vel_ned_mps: [at(vn), at(ve), at(vd)],
                roll_rad: at(roll),
                pitch_rad: at(pitch),
                yaw_rad: at(yaw),
                on_ground: at(ground) != 0.0,
            };
            // Out-of-order times (a damaged file read past) would break the search.
            if times_ns.last().is_none_or(|&last| t > last) {
                times_ns.push(t);
                samples.push(sample);
            }
        }
        Ok(Self { times_ns, samples })
    }

    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// Truth at `t_ns`, linearly interpolated (angles along the shorter way round); `None`
    /// outside the series or inside a hole.
    pub fn at(&self, t_ns: i64) -> Option<TruthAt> {
        let i = self.times_ns.partition_point(|&t| t < t_ns);
        let after_t = *self.times_ns.get(i)?;
        let after = self.samples.get(i)?;
        if after_t == t_ns {
            return Some(*after);
        }
        let before_t = *self.times_ns.get(i.checked_sub(1)?)?;
        let before = self.samples.get(i - 1)?;
        if after_t - before_t > MAX_GAP_NS {
            return None;
        }
        let w = (t_ns - before_t) as f64 / (after_t - before_t) as f64;
        let lerp = |a: f64, b: f64| a + (b - a) * w;
        let angle = |a: f64, b: f64| wrap_pi(a + wrap_pi(b - a) * w);
        let lerp3 =
            |a: [f64; 3], b: [f64; 3]| [lerp(a[0], b[0]), lerp(a[1], b[1]), lerp(a[2], b[2])];
        Some(TruthAt {
            ned_m: lerp3(before.ned_m, after.ned_m),
            vel_ned_mps: lerp3(before.vel_ned_mps, after.vel_ned_mps),
            roll_rad: angle(before.roll_rad, after.roll_rad),
            pitch_rad: lerp(before.pitch_rad, after.pitch_rad),
            yaw_rad: angle(before.yaw_rad, after.yaw_rad),
            on_ground: before.on_ground && after.on_ground,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series() -> TruthSeries {
        let sample = |x: f64, yaw: f64| TruthAt {
            ned_m: [x, 0.0, -x],
            vel_ned_mps: [1.0, 0.0, 0.0],
            roll_rad: 0.0,
            pitch_rad: 0.0,
            yaw_rad: yaw,
            on_ground: false,
        };
        TruthSeries {
            times_ns: vec![0, 20_000_000, 40_000_000, 400_000_000],
            samples: vec![
                sample(0.0, 3.1),
                sample(2.0, -3.1),
                sample(4.0, 0.0),
                sample(9.0, 0.0),
            ],
        }
    }

    #[test]
    fn interpolates_between_samples_and_the_short_way_round_for_angles() {
        let s = series();
        let mid = s.at(10_000_000).expect("inside");
        assert!((mid.ned_m[0] - 1.0).abs() < 1e-12);
        assert!((mid.ned_m[2] + 1.0).abs() < 1e-12);
        // From 3.1 to -3.1 rad is 0.083 rad through ±π, not 6.2 rad through zero.
        assert!(
            (mid.yaw_rad.abs() - std::f64::consts::PI).abs() < 1e-9,
            "{}",
            mid.yaw_rad
        );
        assert_eq!(s.at(20_000_000).map(|t| t.ned_m[0]), Some(2.0));
    }

    #[test]
    fn nothing_outside_the_series_or_across_a_hole() {
        let s = series();
        assert!(s.at(-1).is_none());
        assert!(s.at(400_000_001).is_none());
        // 40 ms → 400 ms is a 360 ms hole.
        assert!(s.at(200_000_000).is_none());
        assert!(s.at(400_000_000).is_some());
    }
}
