//! Geodetic (WGS-84 latitude, longitude, altitude) to the local NED frame (`conventions.md`)
//! around a home point: the first valid fix unless one is configured.
//!
//! A local tangent plane with the WGS-84 radii of curvature taken at home: north is
//! `Δlat · (M + h₀)`, east `Δlon · (N + h₀) · cos lat₀`, down `−Δalt`. Over the few
//! kilometres a small UAV flies the error is a few centimetres per kilometre from the radii
//! and `d²/(2R)` (≈ 8 cm at 1 km, 2 m at 5 km) of vertical curvature: well under the GPS's
//! own noise. Everything here is `f64`: a latitude in `f32` only resolves ~1 m.

use nalgebra::Vector3;

/// WGS-84 semi-major axis (m).
pub const WGS84_A_M: f64 = 6_378_137.0;
/// WGS-84 first eccentricity squared.
pub const WGS84_E2: f64 = 6.694_379_990_141_3e-3;

/// A geodetic position: degrees and metres above mean sea level.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GeoPoint {
    pub latitude_deg: f64,
    pub longitude_deg: f64,
    pub altitude_m: f64,
}

impl GeoPoint {
    pub fn is_plausible(&self) -> bool {
        self.latitude_deg.is_finite()
            && self.longitude_deg.is_finite()
            && self.altitude_m.is_finite()
            && self.latitude_deg.abs() <= 89.0
            && self.longitude_deg.abs() <= 180.0
            && self.altitude_m.abs() < 100_000.0
    }
}

/// The local tangent plane at a home point.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LocalFrame {
    home: GeoPoint,
    /// Metres per radian of latitude and of longitude at home.
    north_m_per_rad: f64,
    east_m_per_rad: f64,
}

impl LocalFrame {
    /// `None` for a home that is not a plausible position (NaN, poles, absurd altitude).
    pub fn new(home: GeoPoint) -> Option<Self> {
        if !home.is_plausible() {
            return None;
        }
        let lat = home.latitude_deg.to_radians();
        let s = libm::sin(lat);
        let w = libm::sqrt(1.0 - WGS84_E2 * s * s);
        let meridian = WGS84_A_M * (1.0 - WGS84_E2) / (w * w * w);
        let normal = WGS84_A_M / w;
        Some(Self {
            home,
            north_m_per_rad: meridian + home.altitude_m,
            east_m_per_rad: (normal + home.altitude_m) * libm::cos(lat),
        })
    }

    pub fn home(&self) -> GeoPoint {
        self.home
    }

    /// NED position (m) of a geodetic point. Longitude differences wrap at ±180°.
    pub fn to_ned(&self, point: &GeoPoint) -> Vector3<f64> {
        let dlat = (point.latitude_deg - self.home.latitude_deg).to_radians();
        let mut dlon_deg = point.longitude_deg - self.home.longitude_deg;
        if dlon_deg > 180.0 {
            dlon_deg -= 360.0;
        } else if dlon_deg < -180.0 {
            dlon_deg += 360.0;
        }
        Vector3::new(
            dlat * self.north_m_per_rad,
            dlon_deg.to_radians() * self.east_m_per_rad,
            -(point.altitude_m - self.home.altitude_m),
        )
    }

    /// The geodetic point at a NED position (the inverse of [`to_ned`](Self::to_ned)).
    pub fn to_geodetic(&self, ned: &Vector3<f64>) -> GeoPoint {
        let mut lon = self.home.longitude_deg + (ned.y / self.east_m_per_rad).to_degrees();
        if lon > 180.0 {
            lon -= 360.0;
        } else if lon < -180.0 {
            lon += 360.0;
        }
        GeoPoint {
            latitude_deg: self.home.latitude_deg + (ned.x / self.north_m_per_rad).to_degrees(),
            longitude_deg: lon,
            altitude_m: self.home.altitude_m - ned.z,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn home() -> GeoPoint {
        GeoPoint {
            latitude_deg: 46.5,
            longitude_deg: 6.6,
            altitude_m: 400.0,
        }
    }

    #[test]
    fn home_is_the_origin_and_round_trips() {
        let f = LocalFrame::new(home()).expect("plausible");
        assert!(f.to_ned(&home()).norm() < 1e-9);
        let p = Vector3::new(1234.5, -987.6, -150.0);
        let back = f.to_ned(&f.to_geodetic(&p));
        assert!((back - p).norm() < 1e-6);
    }

    #[test]
    fn one_arc_minute_of_latitude_is_about_a_nautical_mile() {
        let f = LocalFrame::new(home()).expect("plausible");
        let mut p = home();
        p.latitude_deg += 1.0 / 60.0;
        p.longitude_deg += 1.0 / 60.0;
        p.altitude_m += 10.0;
        let ned = f.to_ned(&p);
        // Meridian arc minute at 46.5° ≈ 1853 m; east shrinks with cos(lat).
        assert!((ned.x - 1853.0).abs() < 3.0, "{}", ned.x);
        assert!((ned.y - 1853.0 * libm::cos(46.5f64.to_radians())).abs() < 5.0);
        assert!((ned.z + 10.0).abs() < 1e-9);
    }

    #[test]
    fn implausible_homes_are_refused() {
        let mut p = home();
        p.latitude_deg = f64::NAN;
        assert!(LocalFrame::new(p).is_none());
        p.latitude_deg = 90.0;
        assert!(LocalFrame::new(p).is_none());
    }

    #[test]
    fn longitude_wraps_at_the_antimeridian() {
        let f = LocalFrame::new(GeoPoint {
            latitude_deg: 0.0,
            longitude_deg: 179.999,
            altitude_m: 0.0,
        })
        .expect("plausible");
        let ned = f.to_ned(&GeoPoint {
            latitude_deg: 0.0,
            longitude_deg: -179.999,
            altitude_m: 0.0,
        });
        assert!((ned.y - 222.6).abs() < 1.0, "{}", ned.y);
    }
}
