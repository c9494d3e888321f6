//! The conventions' camera model: pinhole intrinsics, Brown–Conrady radial distortion (k1, k2)
//! on normalised coordinates, and an optional mounting offset of the camera on the airframe.

/// Intrinsics, radial distortion and mounting angles of a forward-looking camera.
///
/// Pixel `(u, v)` and normalised undistorted `(x, y) = ((u − cx)/fx, (v − cy)/fy)` are related
/// through the distortion `(x, y) · (1 + k1·r² + k2·r⁴)` (conventions, "Camera and horizon").
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Camera {
    /// Image size the intrinsics were calibrated at (pixels).
    pub width: u32,
    pub height: u32,
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    pub k1: f32,
    pub k2: f32,
    /// Roll of the camera relative to the body (rad): camera roll = vehicle roll + this.
    pub mount_roll_rad: f32,
    /// Pitch of the camera relative to the body (rad): camera pitch = vehicle pitch + this.
    pub mount_pitch_rad: f32,
}

/// Newton steps of the inverse radial model at most; two or three reach 1e-7 (normalised) for
/// the distortions of small-UAV lenses (|k1| ≤ 0.4) within the image.
const UNDISTORT_ITERATIONS: usize = 8;

impl Camera {
    /// A distortion-free camera with the given horizontal field of view, centred principal point.
    pub fn ideal(width: u32, height: u32, horizontal_fov_rad: f32) -> Self {
        let fx = width as f32 / 2.0 / libm::tanf(horizontal_fov_rad / 2.0);
        Camera {
            width,
            height,
            fx,
            fy: fx,
            cx: (width as f32 - 1.0) / 2.0,
            cy: (height as f32 - 1.0) / 2.0,
            k1: 0.0,
            k2: 0.0,
            mount_roll_rad: 0.0,
            mount_pitch_rad: 0.0,
        }
    }

    /// The same camera for frames of another size (a video scaled down or up after
    /// calibration): focal lengths and principal point scale with the image, distortion does
    /// not (it is defined on normalised coordinates).
    pub fn scaled_to(&self, width: u32, height: u32) -> Self {
        if width == self.width && height == self.height || self.width == 0 || self.height == 0 {
            return *self;
        }
        let sx = width as f32 / self.width as f32;
        let sy = height as f32 / self.height as f32;
        Camera {
            width,
            height,
            fx: self.fx * sx,
            fy: self.fy * sy,
            // Pixel centres: u' + 0.5 = (u + 0.5)·s.
            cx: (self.cx + 0.5) * sx - 0.5,
            cy: (self.cy + 0.5) * sy - 0.5,
            ..*self
        }
    }

    /// True when the parameters can describe a camera (finite, positive focal lengths).
    pub fn is_valid(&self) -> bool {
        let all_finite = [
            self.fx,
            self.fy,
            self.cx,
            self.cy,
            self.k1,
            self.k2,
            self.mount_roll_rad,
            self.mount_pitch_rad,
        ]
        .iter()
        .all(|v| v.is_finite());
        all_finite && self.fx > 0.0 && self.fy > 0.0 && self.width > 0 && self.height > 0
    }

    /// Radial distortion factor `1 + k1·r² + k2·r⁴` at normalised radius² `r2`.
    #[inline]
    fn radial_factor(&self, r2: f32) -> f32 {
        1.0 + self.k1 * r2 + self.k2 * r2 * r2
    }

    /// Normalised undistorted coordinates of the pixel `(u, v)` of the distorted image, by
    /// fixed-point iteration of the radial model. `None` where the model folds over (the
    /// distortion factor collapses), which only happens far outside a sane field of view.
    pub fn undistort_pixel(&self, u: f32, v: f32) -> Option<(f32, f32)> {
        let xd = (u - self.cx) / self.fx;
        let yd = (v - self.cy) / self.fy;
        self.undistort_normalised(xd, yd)
    }

    /// Inverse of [`Camera::distort_normalised`].
    ///
    /// Newton's method on the radius, `r·(1 + k1·r² + k2·r⁴) = r_d`: two or three steps from
    /// `r = r_d` (the fixed-point iteration it replaces converged linearly and took 5 to 8 on
    /// a wide-angle lens; this runs for every edge point, sample and profile column of a
    /// distorted camera). `None` where the model folds over (its derivative is not positive:
    /// a larger undistorted radius would appear closer to the centre) or does not settle.
    pub fn undistort_normalised(&self, xd: f32, yd: f32) -> Option<(f32, f32)> {
        if self.k1 == 0.0 && self.k2 == 0.0 {
            return Some((xd, yd));
        }
        let rd = libm::sqrtf(xd * xd + yd * yd);
        if !rd.is_finite() {
            return None;
        }
        if rd == 0.0 {
            return Some((xd, yd));
        }
        let mut r = rd;
        for _ in 0..UNDISTORT_ITERATIONS {
            let r2 = r * r;
            let g = r * self.radial_factor(r2) - rd;
            let slope = 1.0 + 3.0 * self.k1 * r2 + 5.0 * self.k2 * r2 * r2;
            // NaN fails this test too.
            if slope.is_nan() || slope <= 0.05 {
                return None;
            }
            let step = g / slope;
            r -= step;
            // Settled (1e-7 normalised is ~1e-4 px).
            if libm::fabsf(step) < 1e-7 {
                break;
            }
        }
        let factor = self.radial_factor(r * r);
        // Reject a point where the iteration did not settle, or settled on the folded branch.
        let residual = libm::fabsf(r * factor - rd);
        if factor.is_nan()
            || factor <= 0.05
            || r.is_nan()
            || r <= 0.0
            || residual.is_nan()
            || residual >= 1e-3
        {
            return None;
        }
        let scale = r / rd;
        Some((xd * scale, yd * scale))
    }

    /// Distorted normalised coordinates of the undistorted normalised point `(x, y)`.
    #[inline]
    pub fn distort_normalised(&self, x: f32, y: f32) -> (f32, f32) {
        let factor = self.radial_factor(x * x + y * y);
        (x * factor, y * factor)
    }

    /// Pixel of the distorted image where the undistorted normalised point `(x, y)` appears.
    pub fn project(&self, x: f32, y: f32) -> (f32, f32) {
        let (xd, yd) = self.distort_normalised(x, y);
        (xd * self.fx + self.cx, yd * self.fy + self.cy)
    }
}
