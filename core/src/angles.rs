//! Angle arithmetic shared by estimation, control, the simulator and the tools: one
//! definition of wrapping to (−π, π].

macro_rules! wrap_pi_for {
    ($name:ident, $t:ty, $fmod:path, $pi:expr) => {
        /// `a` wrapped to (−π, π]; NaN for a non-finite angle.
        pub fn $name(a: $t) -> $t {
            let two_pi: $t = 2.0 * $pi;
            let mut a = $fmod(a, two_pi);
            if a > $pi {
                a -= two_pi;
            } else if a <= -$pi {
                a += two_pi;
            }
            a
        }
    };
}

wrap_pi_for!(wrap_pi, f64, libm::fmod, core::f64::consts::PI);
wrap_pi_for!(wrap_pi_f32, f32, libm::fmodf, core::f32::consts::PI);

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::PI;

    #[test]
    fn wraps_into_the_half_open_interval() {
        for (a, wrapped) in [
            (0.0, 0.0),
            (PI, PI),
            (-PI, PI),
            (3.0 * PI, PI),
            (1.5 * PI, -0.5 * PI),
            (-1.5 * PI, 0.5 * PI),
            (7.0, 7.0 - 2.0 * PI),
        ] {
            assert!((wrap_pi(a) - wrapped).abs() < 1e-12, "{a}");
            assert!(
                (f64::from(wrap_pi_f32(a as f32)) - wrapped).abs() < 1e-5,
                "{a}"
            );
        }
        assert!(wrap_pi(f64::NAN).is_nan());
        assert!(wrap_pi(f64::INFINITY).is_nan());
    }
}
