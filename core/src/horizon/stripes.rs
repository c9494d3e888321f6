//! Analog interference as a sinusoid across the frame: measured along the crests of a line the
//! Hough stage chose, and subtracted from the working image.
//!
//! Stripes nearly parallel to the horizon draw a family of long straight edges next to it, one
//! of which explains nearly as much of the frame as the horizon and is chosen; their
//! alternating steps above the chosen line say so ([`super::upper::Profile::striped`]). Such a
//! line is a crest: the mean luma across it, averaged along it over the whole working image,
//! holds the sinusoid coherently (every pixel of a bin has the same phase) and the horizon as
//! one step. The sinusoid's period is the peak of the profile's derivative's periodogram (the
//! derivative makes the step a spike, whose spectrum is flat, and leaves the sinusoid one);
//! its amplitude and phase are a least-squares fit of that derivative away from the spike. The
//! fitted sinusoid is then subtracted from every working pixel, and the region search finds
//! the horizon among regions that no longer hold the stripes.
//!
//! Stripes at an angle to the horizon scatter its edge points instead, and the line chosen is
//! a compromise; their crests are then a family of parallel candidates, and the measurement
//! runs along one of them (see `stripe_family` in the parent module).
//!
//! The crests are straight in the image's pixels: the line's direction is taken to pixels
//! through the focal lengths only, which on a distorted camera is true near the centre.

use super::camera::Camera;
use super::edges::Working;
use super::hough::Line;
use core::f32::consts::PI;

/// Profile bins, each [`BIN`] working pixels along the crests' normal: the working image's
/// diagonal (250 px at 200 × 150, 226 at 160 × 160).
const BINS: usize = 512;
const BIN: f32 = 0.5;
/// Periods searched (working pixels): `synth` draws 5–30 px at 320 px (2.5–15 working pixels
/// at both sizes).
const MIN_PERIOD: f32 = 2.2;
const MAX_PERIOD: f32 = 24.0;
/// Coarse and fine steps of the wavenumber search (rad per working pixel).
const COARSE_DK: f32 = 0.015;
const FINE_DK: f32 = 0.002;
/// Working pixels either side of the derivative's spike (the horizon's step) left out of the
/// second fit.
const SPIKE_EXCLUSION: f32 = 4.0;
/// Columns of the subtraction's table: working images are at most 200 wide (250 for frames
/// over 3200 px, binned at most 16×; columns past the table keep their stripes).
const TABLE: usize = 256;
/// Least amplitude (levels of the working image) and share of the derivative's variance
/// the fitted sinusoid must explain to be subtracted.
const MIN_AMPLITUDE: f32 = 3.0;
const MIN_EXPLAINED: f32 = 0.5;

/// A sinusoid over the working image: `sin_part·sin(k·d) + cos_part·cos(k·d)` with
/// `d = ax·wx + ay·wy` (working pixels).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Wave {
    ax: f32,
    ay: f32,
    k: f32,
    sin_part: f32,
    cos_part: f32,
}

#[derive(Clone, Copy, Default)]
struct Bin {
    n: f32,
    sum: f32,
    d: f32,
    /// `sin(k·d)` and `cos(k·d)` at the bin's mean place, once `k` is known.
    sin: f32,
    cos: f32,
}

impl Wave {
    /// Amplitude in levels of the working image.
    pub(crate) fn amplitude(&self) -> f32 {
        libm::sqrtf(self.sin_part * self.sin_part + self.cos_part * self.cos_part)
    }

    /// The sinusoid whose crests run along `crest` (a line in normalised undistorted
    /// coordinates), measured on the working image, if it is clear.
    pub(crate) fn estimate(
        grey: &[u8],
        geo: Working,
        camera: &Camera,
        crest: Line,
    ) -> Option<Wave> {
        let (nx, ny) = crest.normal();
        // The crests are straight in the image's pixels; their normal there.
        let (px, py) = (nx / camera.fx, ny / camera.fy);
        let norm = libm::sqrtf(px * px + py * py);
        if norm.is_nan() || norm <= 0.0 {
            return None;
        }
        let (ax, ay) = (px / norm, py / norm);
        // Distances of the working image's corners: the profile's origin.
        let (w, h) = (geo.width as f32 - 1.0, geo.height as f32 - 1.0);
        let low = [0.0, ax * w, ay * h, ax * w + ay * h]
            .iter()
            .fold(f32::INFINITY, |a, &b| a.min(b));
        let origin = libm::floorf(low) - 0.25;
        let mut bins = [Bin::default(); BINS];
        for (wy, row) in grey
            .chunks_exact(geo.width.max(1))
            .take(geo.height)
            .enumerate()
        {
            let start = ay * wy as f32 - origin;
            for (wx, &value) in row.iter().enumerate() {
                let d = start + ax * wx as f32;
                if let Some(bin) = bins.get_mut((d / BIN) as usize) {
                    bin.n += 1.0;
                    bin.sum += f32::from(value);
                    bin.d += d;
                }
            }
        }
        // From here on a bin's `sum` is its mean and `d` its mean place.
        let mut used = 0usize;
        for (i, b) in bins.iter_mut().enumerate() {
            if b.n > 0.0 {
                b.sum /= b.n;
                b.d /= b.n;
                used = i + 1;
            }
        }
        // The derivative over two working pixels, where both ends were filled.
        // The derivative at each bin's nominal place (0 where it is not defined).
        let mut slope = [0.0f32; BINS];
        for (j, out) in slope.iter_mut().enumerate().take(used) {
            if let Some((dv, _, _)) = derivative(&bins, j) {
                *out = dv;
            }
        }
        let slope = slope.get(..used).unwrap_or(&[]);
        // Coarse then fine search of the periodogram's peak, [`LANES`] wavenumbers a pass.
        let (coarse, _) = peak(
            slope,
            2.0 * PI / MAX_PERIOD,
            2.0 * PI / MIN_PERIOD,
            COARSE_DK,
        );
        let (k, _) = peak(slope, coarse - COARSE_DK, coarse + COARSE_DK, FINE_DK);

        // Least squares of the derivative on the sinusoid's own derivative (and a constant
        // slope), at the bins' mean places; twice, the second time without the spike.
        for b in bins.iter_mut().take(used) {
            (b.sin, b.cos) = (libm::sinf(k * b.d), libm::cosf(k * b.d));
        }
        let at = |j: usize| bins.get(j).map_or(0.0, |b| b.d);
        let basis = |j: usize| -> Option<(f32, f32, f32, f32)> {
            let (dv, a, b) = derivative(&bins, j)?;
            let (ba, bb) = (bins.get(a)?, bins.get(b)?);
            Some((bb.sin - ba.sin, bb.cos - ba.cos, bb.d - ba.d, dv))
        };
        let fit = |exclude: Option<f32>| -> Option<(f32, f32, f32)> {
            // Normal equations of [s, c, 1] (symmetric 3 × 3) and the right-hand side.
            let (mut ss, mut sc, mut s1, mut cc, mut c1, mut one) =
                (0.0f32, 0.0, 0.0, 0.0, 0.0, 0.0);
            let (mut sy, mut cy, mut y1, mut yy) = (0.0f32, 0.0, 0.0, 0.0);
            for j in 0..used {
                if exclude.is_some_and(|x| libm::fabsf(at(j) - x) < SPIKE_EXCLUSION) {
                    continue;
                }
                let Some((s, c, l, y)) = basis(j) else {
                    continue;
                };
                ss += s * s;
                sc += s * c;
                s1 += s * l;
                cc += c * c;
                c1 += c * l;
                one += l * l;
                sy += s * y;
                cy += c * y;
                y1 += l * y;
                yy += y * y;
            }
            let (alpha, beta, gamma) =
                solve3([[ss, sc, s1], [sc, cc, c1], [s1, c1, one]], [sy, cy, y1])?;
            // Share of the derivative's variance (about its mean slope) the sinusoid explains.
            let mean_slope = if one > 0.0 { y1 / one } else { 0.0 };
            let explained = alpha * sy + beta * cy + gamma * y1 - mean_slope * y1;
            let total = yy - mean_slope * y1;
            Some((alpha, beta, explained / total.max(1e-6)))
        };
        let (alpha, beta, _) = fit(None)?;
        // The spike: the largest residual of the first fit.
        let mut spike: Option<(f32, f32)> = None;
        for j in 0..used {
            if let Some((s, c, _, y)) = basis(j) {
                let r = libm::fabsf(y - alpha * s - beta * c);
                if spike.is_none_or(|(_, best)| r > best) {
                    spike = Some((at(j), r));
                }
            }
        }
        let (alpha, beta, explained) = fit(spike.map(|(x, _)| x))?;
        let wave = Wave {
            ax,
            ay,
            k,
            sin_part: alpha,
            cos_part: beta,
        };
        let origin_shift = k * origin;
        // d was measured from `origin`: move the phase to d measured from 0.
        let (so, co) = (libm::sinf(origin_shift), libm::cosf(origin_shift));
        let wave = Wave {
            sin_part: alpha * co + beta * so,
            cos_part: beta * co - alpha * so,
            ..wave
        };
        (wave.amplitude() >= MIN_AMPLITUDE && explained >= MIN_EXPLAINED && wave.k.is_finite())
            .then_some(wave)
    }

    /// Subtracts the sinusoid from the working image. Along a row it is
    /// `P·sin(k·ax·wx) + Q·cos(k·ax·wx)` with `P`, `Q` set by the row: one table of the
    /// column's sine and cosine, then two multiplies per pixel.
    pub(crate) fn subtract(&self, grey: &mut [u8], geo: Working) {
        let mut table = [(0.0f32, 0.0f32); TABLE];
        for (wx, t) in table.iter_mut().enumerate() {
            let theta = self.k * self.ax * wx as f32;
            *t = (libm::sinf(theta), libm::cosf(theta));
        }
        for (wy, row) in grey
            .chunks_exact_mut(geo.width.max(1))
            .take(geo.height)
            .enumerate()
        {
            let phase = self.k * self.ay * wy as f32;
            let (sp, cp) = (libm::sinf(phase), libm::cosf(phase));
            // sin(θ + φ) = sin θ cos φ + cos θ sin φ, cos(θ + φ) = cos θ cos φ − sin θ sin φ.
            let p = self.sin_part * cp - self.cos_part * sp;
            let q = self.sin_part * sp + self.cos_part * cp;
            for (px, &(s, c)) in row.iter_mut().zip(table.iter()) {
                let value = f32::from(*px) - p * s - q * c;
                *px = (value + 0.5).clamp(0.0, 255.0) as u8;
            }
        }
    }
}

/// The profile's difference over two working pixels about bin `j` (its mean there, both
/// bins' indices), where both ends were filled.
fn derivative(bins: &[Bin], j: usize) -> Option<(f32, usize, usize)> {
    let lag = (1.0 / BIN) as usize;
    let (a, b) = (j.checked_sub(lag)?, j + lag);
    let (ba, bb) = (bins.get(a)?, bins.get(b)?);
    if ba.n <= 0.0 || bb.n <= 0.0 {
        return None;
    }
    Some((bb.sum - ba.sum, a, b))
}

/// Wavenumbers whose periodogram one pass over the profile computes: independent
/// recurrences, so that they run side by side.
const LANES: usize = 16;

#[derive(Clone, Copy)]
struct Lane {
    k: f32,
    /// `exp(−i·k·x)` at the current bin, and its factor per bin.
    z: (f32, f32),
    step: (f32, f32),
    sum: (f32, f32),
}

/// The wavenumber in `[from, to]` (steps of `dk`) where the periodogram of `values` (one per
/// bin of [`BIN`] working pixels) is highest, and that power.
fn peak(values: &[f32], from: f32, to: f32, dk: f32) -> (f32, f32) {
    let mut best = (from, f32::MIN);
    let mut k0 = from;
    while k0 <= to {
        let mut lanes = [Lane {
            k: 0.0,
            z: (1.0, 0.0),
            step: (1.0, 0.0),
            sum: (0.0, 0.0),
        }; LANES];
        for (i, lane) in lanes.iter_mut().enumerate() {
            lane.k = k0 + i as f32 * dk;
            lane.step = (libm::cosf(lane.k * BIN), -libm::sinf(lane.k * BIN));
        }
        for &v in values {
            for lane in lanes.iter_mut() {
                let (zr, zi) = lane.z;
                lane.sum = (lane.sum.0 + v * zr, lane.sum.1 + v * zi);
                lane.z = (
                    zr * lane.step.0 - zi * lane.step.1,
                    zr * lane.step.1 + zi * lane.step.0,
                );
            }
        }
        for lane in &lanes {
            let power = lane.sum.0 * lane.sum.0 + lane.sum.1 * lane.sum.1;
            if lane.k <= to && power > best.1 {
                best = (lane.k, power);
            }
        }
        k0 += LANES as f32 * dk;
    }
    best
}

/// Solves the symmetric 3 × 3 system `m·x = r` by Cramer's rule; `None` when singular.
fn solve3(m: [[f32; 3]; 3], r: [f32; 3]) -> Option<(f32, f32, f32)> {
    let [[a, b, c], [d, e, f], [g, h, i]] = m;
    let [p, q, s] = r;
    let det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
    if !det.is_finite() || libm::fabsf(det) < 1e-12 {
        return None;
    }
    let x = (p * (e * i - f * h) - b * (q * i - f * s) + c * (q * h - e * s)) / det;
    let y = (a * (q * i - f * s) - p * (d * i - f * g) + c * (d * s - q * g)) / det;
    let z = (a * (e * s - q * h) - b * (d * s - q * g) + p * (d * h - e * g)) / det;
    Some((x, y, z))
}
