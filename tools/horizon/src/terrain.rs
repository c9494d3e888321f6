//! The second generator ("terrain"): a different construction from [`crate::synth`], held
//! out (only scored) until the eleventh session and tuned on since, when `aerial_set.py`
//! became the held-out one (docs/horizon.md). Nothing here is shared
//! with `synth` but the camera model and the image type.
//!
//! | | `synth` | `terrain` |
//! |---|---|---|
//! | world | value-noise fields on an 80 m grid, constant haze colour | Voronoi fields, gradient (Perlin) noise, ridge shading, coast and sea, roads at random angles |
//! | light | 8-bit sRGB-like values mixed directly | linear radiance; sky glow towards the horizon; haze as extinction + airlight, so the horizon is a small step and a ramp, as in real haze |
//! | camera | 2×2 samples, [1 2 1] blur | 4 rook samples at 4 instants (motion blur and rolling shutter), vignetting, principal point off centre, exposure then Poisson–Gaussian sensor noise in electrons, clipping, sRGB gamma |
//! | artefacts | grain, torn lines, bright/black bars | 8×8 DCT quantisation (JPEG-like) with lost and repeated macroblocks, sinusoidal interference, sun bloom/starburst/ghosts in linear light, over/under exposure |
//!
//! Truth: pixel `(u, v)` covers `[u − ½, u + ½] × [v − ½, v + ½]`, its centre is the integer
//! point, and `(u − cx)/fx` is measured from that centre (the convention of `Camera::ideal`,
//! whose `cx = (width − 1)/2`, and of OpenCV). The four samples of a pixel average to its
//! centre. The truth is the attitude at the capture instant of the principal point's row (the
//! middle of the exposure), and the horizon is the conventions' level line: the flat world
//! has no Earth curvature, so no dip below it.

use crate::image_io::Image;
use crate::synth::{Rng, Truth};
use clap::ValueEnum;
use skyframe_core::horizon::Camera;
use std::f32::consts::PI;

/// Classes of the `terrain` sets (and of `aerial_set.py`'s).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, ValueEnum)]
pub enum Class {
    /// Haze, clouds, fields; nothing added.
    Clean,
    /// Dim light and high gain: shot noise, read noise, row noise, chroma noise.
    SensorNoise,
    /// A digital video link: coarse JPEG-like blocks, lost and repeated macroblocks, tears.
    Transmission,
    /// Analogue interference: sinusoidal bands at an angle, rolling bars.
    Interference,
    /// Over- and under-exposure with clipping.
    Exposure,
    /// The sun in or near the view, low: bloom, starburst, ghosts, veil.
    Glare,
    /// Coastlines, roads and high-contrast field edges below the horizon.
    GroundEdges,
    /// A bit of everything.
    Mixed,
    /// No horizon to see: pitched far out of the frame, or fog/cloud over it. Scored only on
    /// honesty (an answer here must not be confident).
    NoHorizon,
}

impl Class {
    pub const ALL: [Class; 9] = [
        Class::Clean,
        Class::SensorNoise,
        Class::Transmission,
        Class::Interference,
        Class::Exposure,
        Class::Glare,
        Class::GroundEdges,
        Class::Mixed,
        Class::NoHorizon,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Class::Clean => "clean",
            Class::SensorNoise => "sensor-noise",
            Class::Transmission => "transmission",
            Class::Interference => "interference",
            Class::Exposure => "exposure",
            Class::Glare => "glare",
            Class::GroundEdges => "ground-edges",
            Class::Mixed => "mixed",
            Class::NoHorizon => "no-horizon",
        }
    }
}

/// Hash of three integers to [0, 1) (a different mixer from `synth`'s lattice).
fn hash3(seed: u64, a: i64, b: i64) -> f32 {
    let mut h = seed.wrapping_mul(0xD6E8_FEB8_6659_FD93)
        ^ (a as u64).wrapping_mul(0xA076_1D64_78BD_642F)
        ^ (b as u64).wrapping_mul(0xE703_7ED1_A0B4_28DB);
    h ^= h >> 32;
    h = h.wrapping_mul(0xD6E8_FEB8_6659_FD93);
    h ^= h >> 29;
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// 2-D gradient noise (Perlin), about [−0.7, 0.7].
fn perlin(seed: u64, x: f32, y: f32) -> f32 {
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (xi, yi) = (x0 as i64, y0 as i64);
    let grad = |i: i64, j: i64, dx: f32, dy: f32| {
        let a = hash3(seed, i, j) * 2.0 * PI;
        a.cos() * dx + a.sin() * dy
    };
    let fade = |t: f32| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let (u, v) = (fade(fx), fade(fy));
    let n00 = grad(xi, yi, fx, fy);
    let n10 = grad(xi + 1, yi, fx - 1.0, fy);
    let n01 = grad(xi, yi + 1, fx, fy - 1.0);
    let n11 = grad(xi + 1, yi + 1, fx - 1.0, fy - 1.0);
    let a = n00 + (n10 - n00) * u;
    let b = n01 + (n11 - n01) * u;
    a + (b - a) * v
}

fn turbulence(seed: u64, x: f32, y: f32, octaves: u32) -> f32 {
    let mut sum = 0.0;
    let mut amp = 1.0;
    let mut f = 1.0;
    for o in 0..octaves {
        sum += amp * perlin(seed.wrapping_add(u64::from(o) * 7919), x * f, y * f);
        amp *= 0.5;
        f *= 2.03;
    }
    sum
}

/// Nearest Voronoi cell of a point (cells about `size` apart): its id.
fn voronoi(seed: u64, x: f32, y: f32, size: f32) -> (i64, i64, f32) {
    let (gx, gy) = ((x / size).floor() as i64, (y / size).floor() as i64);
    let mut best = (0, 0, f32::INFINITY);
    let mut second = f32::INFINITY;
    for j in -1..=1 {
        for i in -1..=1 {
            let (cx, cy) = (gx + i, gy + j);
            let px = (cx as f32 + hash3(seed, cx, cy)) * size;
            let py = (cy as f32 + hash3(seed ^ 0x55, cx, cy)) * size;
            let d = ((px - x).powi(2) + (py - y).powi(2)).sqrt();
            if d < best.2 {
                second = best.2;
                best = (cx, cy, d);
            } else if d < second {
                second = d;
            }
        }
    }
    // Third value: distance to the cell border (half the gap to the second nearest centre).
    (best.0, best.1, 0.5 * (second - best.2))
}

/// What one sequence looks like: drawn once per sequence from the seed.
#[derive(Clone, Debug)]
struct Scene {
    seed: u64,
    altitude_m: f32,
    /// Extinction length of the haze (m): visibility / 3.9.
    haze_m: f32,
    sun_azimuth: f32,
    sun_elevation: f32,
    /// Sky brightness relative to the sun-lit ground.
    sky_gain: f32,
    cloud_cover: f32,
    coast: bool,
    roads: bool,
    contrast_fields: bool,
    fog: bool,
}

/// Renders one class.
pub struct TerrainRenderer {
    pub class: Class,
    pub camera: Camera,
    pub width: usize,
    pub height: usize,
    seed: u64,
}

/// Per-frame camera effects.
#[derive(Clone, Copy, Debug)]
struct Exposure {
    gain: f32,
    /// Electrons at a linear value of 1 (full well): fewer means more shot noise.
    full_well: f32,
    read_noise: f32,
}

impl TerrainRenderer {
    pub fn new(class: Class, width: usize, height: usize, seed: u64) -> Self {
        let mut rng = Rng::new(seed ^ 0x7E44_A1B0 ^ ((class as u64) << 40));
        let fov = rng.range(55.0, 70.0).to_radians();
        let mut camera = Camera::ideal(width as u32, height as u32, fov);
        // A principal point off centre, as calibrations give, and a mild lens on some classes.
        camera.cx += rng.range(-0.02, 0.02) * width as f32;
        camera.cy += rng.range(-0.02, 0.02) * height as f32;
        camera.fy = camera.fx * rng.range(0.995, 1.005);
        if matches!(class, Class::Mixed | Class::Glare | Class::GroundEdges) {
            camera.k1 = rng.range(-0.18, -0.05);
            camera.k2 = rng.range(0.0, 0.04);
        }
        TerrainRenderer {
            class,
            camera,
            width,
            height,
            seed: seed.wrapping_mul(0x2545_F491_4F6C_DD1D) ^ (class as u64 + 1),
        }
    }

    fn scene(&self, rng: &mut Rng) -> Scene {
        let c = self.class;
        let mixed = c == Class::Mixed;
        Scene {
            seed: rng.next_u64(),
            altitude_m: rng.range(60.0, 700.0),
            haze_m: rng.range(2500.0, 12000.0),
            sun_azimuth: rng.range(-PI, PI),
            sun_elevation: rng.range(15.0, 60.0).to_radians(),
            sky_gain: rng.range(1.1, 1.8),
            cloud_cover: if mixed || c == Class::Clean {
                rng.range(0.0, 0.5)
            } else {
                rng.range(0.0, 0.25)
            },
            coast: c == Class::GroundEdges || (mixed && rng.uniform() < 0.5),
            roads: c == Class::GroundEdges || (mixed && rng.uniform() < 0.5),
            contrast_fields: c == Class::GroundEdges || mixed,
            fog: false,
        }
    }

    /// Frame `index` of the sequence and its truth.
    pub fn render(&self, index: usize) -> (Image, Truth) {
        let mut seq = Rng::new(self.seed);
        let mut scene = self.scene(&mut seq);
        let mut rng = Rng::new(self.seed ^ (index as u64 + 1).wrapping_mul(0x9FB2_1C65_1E98_DF25));
        // Attitude: an integrated random walk of rates (different each sequence), sampled 5
        // frames a second; heading drifts.
        let attitude_at = |t: f32| -> (f32, f32, f32) {
            let mut r = Rng::new(self.seed ^ 0xA771);
            let (a1, a2, f1, f2, p1, p2) = (
                r.range(15.0, 40.0),
                r.range(3.0, 12.0),
                r.range(0.05, 0.15),
                r.range(0.3, 0.8),
                r.range(0.0, 2.0 * PI),
                r.range(0.0, 2.0 * PI),
            );
            let (b1, b2, g1, g2, q1, q2) = (
                r.range(3.0, 9.0),
                r.range(1.0, 4.0),
                r.range(0.07, 0.2),
                r.range(0.4, 1.1),
                r.range(0.0, 2.0 * PI),
                r.range(0.0, 2.0 * PI),
            );
            let bias = r.range(-3.0, 4.0);
            let roll = a1 * (2.0 * PI * f1 * t + p1).sin() + a2 * (2.0 * PI * f2 * t + p2).sin();
            let pitch =
                bias + b1 * (2.0 * PI * g1 * t + q1).sin() + b2 * (2.0 * PI * g2 * t + q2).sin();
            let heading = r.range(-PI, PI) + 0.2 * t;
            (roll.to_radians(), pitch.to_radians(), heading)
        };
        let t0 = index as f32 * 0.2;
        let (mut roll0, mut pitch0, heading0) = attitude_at(t0);
        // The flight's rates at the frame's instant, for the motion blur and rolling shutter
        // below: taken before a `no-horizon` frame is turned to look far up or down, or the
        // turn itself (45–70° in 10 ms) is smeared over the rows and brings the horizon back
        // into the bottom or top rows of a frame whose truth says it is out of view.
        let (rate_roll, rate_pitch) = {
            let (r1, p1, _) = attitude_at(t0 + 0.01);
            ((r1 - roll0) / 0.01, (p1 - pitch0) / 0.01)
        };
        let mut visible = true;
        if self.class == Class::NoHorizon {
            // Half the frames look far up or down (the horizon out of the frame), the rest
            // into fog or cloud that hides it.
            if index % 2 == 0 {
                let sign = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
                pitch0 = sign * rng.range(45.0, 70.0).to_radians();
                roll0 *= 0.5;
            } else {
                scene.fog = true;
            }
            visible = false;
        }
        let glare = self.class == Class::Glare || (self.class == Class::Mixed && index % 3 == 0);
        if glare {
            // The sun low ahead, in or just outside the field of view.
            scene.sun_azimuth = heading0 + rng.range(-0.45, 0.45);
            scene.sun_elevation = rng.range(3.0, 18.0).to_radians();
        }
        let exposure = self.exposure(&mut rng, index);
        // Motion blur and rolling shutter: four instants across the exposure, rows read out
        // over `readout` seconds; the truth is the principal point row's mid-exposure.
        let shutter = if matches!(self.class, Class::Mixed | Class::SensorNoise) {
            0.012
        } else {
            0.004
        };
        let readout = 0.015;
        let (w, h) = (self.width, self.height);
        let cam = self.camera;
        let offsets = [
            (-0.375f32, -0.125f32, -0.375f32),
            (0.125, -0.375, 0.125),
            (0.375, 0.125, -0.125),
            (-0.125, 0.375, 0.375),
        ];
        let mut linear = vec![[0f32; 3]; w * h];
        for v in 0..h {
            let row_time = readout * (v as f32 - cam.cy) / h as f32;
            for u in 0..w {
                let mut sum = [0f32; 3];
                for &(du, dv, dt) in &offsets {
                    let t = row_time + dt * shutter;
                    let roll = roll0 + rate_roll * t;
                    let pitch = pitch0 + rate_pitch * t;
                    let ray = cam
                        .undistort_pixel(u as f32 + du, v as f32 + dv)
                        .map(|(x, y)| to_world(x, y, roll, pitch, heading0));
                    let c = match ray {
                        Some(d) => self.radiance(&scene, d, t0),
                        None => [0.0; 3],
                    };
                    for (s, c) in sum.iter_mut().zip(c) {
                        *s += 0.25 * c;
                    }
                }
                linear[v * w + u] = sum;
            }
        }
        lens_blur(&mut linear, w, h);
        // Vignetting: cos⁴ of the field angle, softened.
        for v in 0..h {
            for u in 0..w {
                let x = (u as f32 - cam.cx) / cam.fx;
                let y = (v as f32 - cam.cy) / cam.fy;
                let c2 = 1.0 / (1.0 + x * x + y * y);
                let fall = 0.35 + 0.65 * c2 * c2;
                for c in linear[v * w + u].iter_mut() {
                    *c *= fall;
                }
            }
        }
        if glare {
            self.sun_glare(&mut linear, &scene, roll0, pitch0, heading0, &mut rng);
        }
        let mut image = self.sensor(&linear, exposure, &mut rng);
        if self.class == Class::Transmission || (self.class == Class::Mixed && index % 4 == 1) {
            transmission(&mut image, &mut rng, self.class == Class::Mixed);
        }
        if self.class == Class::Interference || (self.class == Class::Mixed && index % 4 == 2) {
            interference(&mut image, &mut rng, index);
        }
        let visible = visible && horizon_in_image(&image, &cam, roll0, pitch0);
        (
            image,
            Truth {
                roll_deg: wrap_deg(roll0.to_degrees()),
                pitch_deg: pitch0.to_degrees(),
                visible,
            },
        )
    }

    fn exposure(&self, rng: &mut Rng, index: usize) -> Exposure {
        let mut e = Exposure {
            gain: rng.range(0.9, 1.1),
            full_well: 6000.0,
            read_noise: 3.0,
        };
        match self.class {
            Class::SensorNoise => {
                e.full_well = rng.range(120.0, 400.0);
                e.read_noise = rng.range(3.0, 8.0);
            }
            Class::Exposure => {
                // Alternating over- and under-exposure, a factor 1.8 to 3.5 off.
                let k = rng.range(1.8, 3.5);
                e.gain = if index % 2 == 0 { k } else { 1.0 / k };
                e.full_well = 2000.0;
            }
            Class::Mixed => {
                e.gain = rng.range(0.5, 2.2);
                e.full_well = rng.range(300.0, 3000.0);
                e.read_noise = 4.0;
            }
            _ => {}
        }
        e
    }

    /// Linear radiance along the world direction `d` (north, east, down), unit length.
    fn radiance(&self, s: &Scene, d: [f32; 3], t: f32) -> [f32; 3] {
        let [dn, de, dd] = d;
        let sun = [
            s.sun_elevation.cos() * s.sun_azimuth.cos(),
            s.sun_elevation.cos() * s.sun_azimuth.sin(),
            -s.sun_elevation.sin(),
        ];
        let sun_light = 0.55 + 0.45 * s.sun_elevation.sin();
        let horizon_sky = [0.78 * s.sky_gain, 0.84 * s.sky_gain, 0.92 * s.sky_gain];
        let airlight = [
            horizon_sky[0] * 0.88,
            horizon_sky[1] * 0.88,
            horizon_sky[2] * 0.9,
        ];
        if s.fog {
            // Thick fog: the same grey everywhere but for a faint vertical gradient.
            let g = 0.7 - 0.05 * dd;
            return [g, g * 1.01, g * 1.03];
        }
        if dd <= 0.0 {
            let elevation = (-dd).asin();
            let glow = (-elevation / 0.18).exp();
            let zenith = [0.18 * s.sky_gain, 0.36 * s.sky_gain, 0.85 * s.sky_gain];
            let mut c: [f32; 3] =
                std::array::from_fn(|i| zenith[i] + (horizon_sky[i] - zenith[i]) * glow);
            let cos_sun = dn * sun[0] + de * sun[1] + dd * sun[2];
            let aureole = 0.25 * ((cos_sun - 1.0) / 0.02).exp();
            for ch in c.iter_mut() {
                *ch += aureole;
            }
            if s.cloud_cover > 0.0 && dd < -0.01 {
                let k = 1500.0 / -dd;
                let (x, y) = (dn * k / 900.0 + 0.03 * t, de * k / 900.0);
                let density = turbulence(s.seed ^ 0xC1, x, y, 4) + 0.5;
                let cover = ((density - (1.0 - s.cloud_cover)) * 5.0).clamp(0.0, 1.0);
                let shade = 0.75 + 0.35 * turbulence(s.seed ^ 0xC2, 3.0 * x, 3.0 * y, 2);
                // Clouds far away sink into the horizon glow.
                let fade = (-(k / 25_000.0)).exp();
                for (i, ch) in c.iter_mut().enumerate() {
                    let cloud = shade * s.sky_gain * [0.95, 0.95, 0.98][i];
                    *ch += (cloud - *ch) * cover * fade;
                }
            }
            return c;
        }
        let range = s.altitude_m / dd;
        let (north, east) = (dn * range + t * 25.0, de * range);
        let albedo = self.ground_albedo(s, north, east);
        // Ridges: slope shading from gradient noise (the world stays flat for the truth).
        let ridge = 1.0 - (turbulence(s.seed ^ 0x41D, north / 900.0, east / 900.0, 3)).abs();
        let shading = 0.7 + 0.45 * (ridge - 0.5);
        let mut c: [f32; 3] = std::array::from_fn(|i| albedo[i] * sun_light * shading);
        if albedo[3] > 0.5 {
            // Water: reflects the sky, more at grazing angles (capped: waves).
            let fresnel = (0.02 + 0.98 * (1.0 - dd).powi(5)).min(0.45);
            for (i, ch) in c.iter_mut().enumerate() {
                *ch = *ch * (1.0 - fresnel) + horizon_sky[i] * fresnel;
            }
        }
        let transmittance = (-range / s.haze_m).exp();
        std::array::from_fn(|i| c[i] * transmittance + airlight[i] * (1.0 - transmittance))
    }

    /// RGB albedo and a water flag.
    fn ground_albedo(&self, s: &Scene, north: f32, east: f32) -> [f32; 4] {
        if s.coast {
            let shore = turbulence(s.seed ^ 0xC0A57, north / 4000.0, east / 4000.0, 5);
            if shore > 0.12 {
                return [0.04, 0.08, 0.12, 1.0];
            }
            if shore > 0.09 {
                return [0.55, 0.5, 0.38, 0.0]; // beach
            }
        }
        let (ci, cj, border) = voronoi(s.seed ^ 0xF1E, north, east, 140.0);
        let pick = hash3(s.seed ^ 0xF1F, ci, cj);
        let palette: [[f32; 3]; 6] = [
            [0.10, 0.16, 0.06],
            [0.16, 0.20, 0.08],
            [0.24, 0.20, 0.12],
            [0.08, 0.12, 0.05],
            [0.30, 0.27, 0.16],
            [0.14, 0.18, 0.10],
        ];
        let mut a = palette[((pick * 6.0) as usize).min(5)];
        if s.contrast_fields {
            let k = if pick > 0.6 { 2.4 } else { 0.6 };
            a = a.map(|x| x * k);
            if border < 3.0 {
                a = [0.05, 0.07, 0.04];
            }
        }
        let grain = 1.0 + 0.35 * turbulence(s.seed ^ 0x6A1, north / 12.0, east / 12.0, 3);
        a = a.map(|x| x * grain);
        if s.roads {
            // Three straight roads at the scene's own angles.
            for k in 0..3u64 {
                let angle = hash3(s.seed, k as i64, 7) * PI;
                let off = (hash3(s.seed, k as i64, 9) - 0.5) * 3000.0;
                let d = (north * angle.cos() + east * angle.sin() - off).abs();
                if d < 5.0 {
                    a = if k == 2 {
                        [0.05, 0.05, 0.05]
                    } else {
                        [0.55, 0.55, 0.52]
                    };
                }
            }
        }
        [a[0], a[1], a[2], 0.0]
    }

    fn sun_glare(
        &self,
        linear: &mut [[f32; 3]],
        s: &Scene,
        roll: f32,
        pitch: f32,
        heading: f32,
        rng: &mut Rng,
    ) {
        let sun = [
            s.sun_elevation.cos() * s.sun_azimuth.cos(),
            s.sun_elevation.cos() * s.sun_azimuth.sin(),
            -s.sun_elevation.sin(),
        ];
        let b = to_body(sun, roll, pitch, heading);
        // Camera (x right, y down, z forward) = body (y, z, x).
        if b[0] <= 0.05 {
            return;
        }
        let (su, sv) = self.camera.project(b[1] / b[0], b[2] / b[0]);
        let (w, h) = (self.width, self.height);
        let scale = w as f32 / 320.0;
        let strength = rng.range(0.6, 1.2);
        let rays = 4 + (rng.uniform() * 4.0) as usize;
        let ray_angle0 = rng.range(0.0, PI);
        let (cx, cy) = (self.camera.cx, self.camera.cy);
        for v in 0..h {
            for u in 0..w {
                let (dx, dy) = (u as f32 - su, v as f32 - sv);
                let r = (dx * dx + dy * dy).sqrt() / scale;
                let mut add = 30.0 * (-r / 3.0).exp()
                    + 1.2 * (-r / 25.0).exp()
                    + 0.5 / (1.0 + (r / 60.0).powi(2));
                // Starburst from the aperture blades.
                let a = dy.atan2(dx);
                for k in 0..rays {
                    let ra = ray_angle0 + k as f32 * PI / rays as f32;
                    let off = (a - ra).sin().abs() * r;
                    add += 0.6 * (-off / 1.5).exp() * (-r / 120.0).exp();
                }
                // Ghosts along the line through the principal point.
                for g in [0.5f32, 1.4, 1.9] {
                    let (gx, gy) = (su + (cx - su) * g, sv + (cy - sv) * g);
                    let gr = ((u as f32 - gx).powi(2) + (v as f32 - gy).powi(2)).sqrt() / scale;
                    if gr < 8.0 * g {
                        add += 0.08;
                    }
                }
                let p = &mut linear[v * w + u];
                for (i, c) in p.iter_mut().enumerate() {
                    *c += strength * add * [1.0, 0.93, 0.78][i] + 0.08 * strength;
                }
            }
        }
    }

    /// Exposure, Poisson–Gaussian noise in electrons, row noise, clipping, sRGB gamma, 8 bits.
    fn sensor(&self, linear: &[[f32; 3]], e: Exposure, rng: &mut Rng) -> Image {
        let (w, h) = (self.width, self.height);
        let mut image = Image::new_rgb(w, h);
        let noisy = e.full_well < 5000.0;
        for v in 0..h {
            let row_noise = if noisy {
                rng.normal() * e.read_noise * 0.5
            } else {
                0.0
            };
            for u in 0..w {
                let p = linear[v * w + u];
                for ch in 0..3 {
                    // White balance leaves blue a little noisier (less light through its filter).
                    let filter = [1.0, 1.3, 0.8][ch];
                    let electrons = (p[ch] * e.gain * 0.55).max(0.0) * e.full_well * filter;
                    let mut x = electrons;
                    if noisy {
                        x += electrons.sqrt() * rng.normal()
                            + e.read_noise * rng.normal()
                            + row_noise;
                    }
                    let value = (x / (e.full_well * filter)).clamp(0.0, 1.0);
                    let srgb = if value <= 0.003_130_8 {
                        12.92 * value
                    } else {
                        1.055 * value.powf(1.0 / 2.4) - 0.055
                    };
                    image.data[(v * w + u) * 3 + ch] =
                        (srgb * 255.0).round().clamp(0.0, 255.0) as u8;
                }
            }
        }
        image
    }
}

/// Whether the true horizon can be seen in the finished image: it crosses at least a
/// quarter of the frame's width, and across it the image changes (mean luma 1 to 3 pixels
/// either side differs by at least 3 levels, and not both sides are clipped). An
/// over-exposed frame whose sky and distant ground both clip has no horizon to find.
pub fn horizon_in_image(image: &Image, cam: &Camera, roll: f32, pitch: f32) -> bool {
    let (w, h) = (image.width, image.height);
    let (s, c, o) = (roll.sin(), roll.cos(), pitch.tan());
    let (mut sky, mut ground, mut n_sky, mut n_ground) = (0.0f64, 0.0f64, 0u32, 0u32);
    let (mut sky_clipped, mut ground_clipped) = (0u32, 0u32);
    for v in 0..h {
        for u in 0..w {
            let Some((x, y)) = cam.undistort_pixel(u as f32, v as f32) else {
                continue;
            };
            let d = (s * x + c * y - o) * cam.fy;
            let p = &image.data[(v * w + u) * 3..(v * w + u) * 3 + 3];
            let luma = 0.299 * f64::from(p[0]) + 0.587 * f64::from(p[1]) + 0.114 * f64::from(p[2]);
            if (-3.5..=-1.0).contains(&d) {
                sky += luma;
                n_sky += 1;
                sky_clipped += u32::from(luma >= 250.0);
            } else if (1.0..=3.5).contains(&d) {
                ground += luma;
                n_ground += 1;
                ground_clipped += u32::from(luma >= 250.0);
            }
        }
    }
    let long_enough = n_sky.min(n_ground) as usize >= w / 2;
    if !long_enough {
        return false;
    }
    let both_clipped = sky_clipped * 2 > n_sky && ground_clipped * 2 > n_ground;
    let contrast = (sky / f64::from(n_sky) - ground / f64::from(n_ground)).abs();
    contrast >= 3.0 && !both_clipped
}

fn wrap_deg(a: f32) -> f32 {
    (a + 180.0).rem_euclid(360.0) - 180.0
}

/// Camera ray (normalised undistorted x right, y down, 1 forward) to a unit world direction
/// (north, east, down): body = (z, x, y) of the camera, then `Rz(ψ)·Ry(θ)·Rx(φ)`.
fn to_world(x: f32, y: f32, roll: f32, pitch: f32, heading: f32) -> [f32; 3] {
    let n = (1.0 + x * x + y * y).sqrt();
    let b = [1.0 / n, x / n, y / n];
    let m = rotation(roll, pitch, heading);
    std::array::from_fn(|i| m[i][0] * b[0] + m[i][1] * b[1] + m[i][2] * b[2])
}

/// World direction to body axes (the transpose of the rotation).
fn to_body(d: [f32; 3], roll: f32, pitch: f32, heading: f32) -> [f32; 3] {
    let m = rotation(roll, pitch, heading);
    std::array::from_fn(|i| m[0][i] * d[0] + m[1][i] * d[1] + m[2][i] * d[2])
}

/// `R_nb = Rz(ψ)·Ry(θ)·Rx(φ)` as a matrix (rows: north, east, down).
fn rotation(roll: f32, pitch: f32, heading: f32) -> [[f32; 3]; 3] {
    let (sf, cf) = roll.sin_cos();
    let (st, ct) = pitch.sin_cos();
    let (sp, cp) = heading.sin_cos();
    [
        [cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf],
        [sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf],
        [-st, ct * sf, ct * cf],
    ]
}

/// A mild symmetric lens blur ([0.2 0.6 0.2] each way).
fn lens_blur(p: &mut [[f32; 3]], w: usize, h: usize) {
    let src = p.to_vec();
    for v in 0..h {
        for u in 0..w {
            let l = src[v * w + u.saturating_sub(1)];
            let r = src[v * w + (u + 1).min(w - 1)];
            let c = src[v * w + u];
            p[v * w + u] = std::array::from_fn(|i| 0.2 * l[i] + 0.6 * c[i] + 0.2 * r[i]);
        }
    }
    let src = p.to_vec();
    for v in 0..h {
        for u in 0..w {
            let a = src[v.saturating_sub(1) * w + u];
            let b = src[(v + 1).min(h - 1) * w + u];
            let c = src[v * w + u];
            p[v * w + u] = std::array::from_fn(|i| 0.2 * a[i] + 0.6 * c[i] + 0.2 * b[i]);
        }
    }
}

/// A digital link in trouble: 8×8 DCT quantisation of each channel, a few macroblocks lost
/// (grey) or repeated from the block to the left, and a torn band shifted sideways.
fn transmission(image: &mut Image, rng: &mut Rng, mild: bool) {
    let (w, h) = (image.width, image.height);
    let q = if mild {
        rng.range(12.0, 30.0)
    } else {
        rng.range(30.0, 70.0)
    };
    let mut cos_table = [[0f32; 8]; 8];
    for (x, row) in cos_table.iter_mut().enumerate() {
        for (k, c) in row.iter_mut().enumerate() {
            let ck = if k == 0 { (0.125f32).sqrt() } else { 0.5 };
            *c = ck * ((2 * x + 1) as f32 * k as f32 * PI / 16.0).cos();
        }
    }
    for by in 0..h / 8 {
        for bx in 0..w / 8 {
            for ch in 0..3 {
                let mut block = [[0f32; 8]; 8];
                for (y, row) in block.iter_mut().enumerate() {
                    for (x, b) in row.iter_mut().enumerate() {
                        *b =
                            f32::from(image.data[((by * 8 + y) * w + bx * 8 + x) * 3 + ch]) - 128.0;
                    }
                }
                let mut coef = [[0f32; 8]; 8];
                for (ky, crow) in coef.iter_mut().enumerate() {
                    for (kx, c) in crow.iter_mut().enumerate() {
                        let mut s = 0.0;
                        for (y, row) in block.iter().enumerate() {
                            for (x, b) in row.iter().enumerate() {
                                s += b * cos_table[x][kx] * cos_table[y][ky];
                            }
                        }
                        // Chroma (R and B here) is quantised harder.
                        let step =
                            q * (1.0 + 0.35 * (kx + ky) as f32) * if ch == 1 { 1.0 } else { 1.8 };
                        *c = (s / step).round() * step;
                    }
                }
                for y in 0..8 {
                    for x in 0..8 {
                        let mut s = 0.0;
                        for (ky, crow) in coef.iter().enumerate() {
                            for (kx, c) in crow.iter().enumerate() {
                                s += c * cos_table[x][kx] * cos_table[y][ky];
                            }
                        }
                        image.data[((by * 8 + y) * w + bx * 8 + x) * 3 + ch] =
                            (s + 128.0).round().clamp(0.0, 255.0) as u8;
                    }
                }
            }
        }
    }
    // Lost and repeated 16×16 macroblocks, in runs along a row as a lost packet leaves them.
    let runs = if mild { 2 } else { 6 };
    for _ in 0..runs {
        let my = (rng.uniform() * (h / 16) as f32) as usize;
        let mx0 = (rng.uniform() * (w / 16) as f32) as usize;
        let len = 1 + (rng.uniform() * 8.0) as usize;
        let grey = rng.uniform() < 0.5;
        for mx in mx0..(mx0 + len).min(w / 16) {
            for y in my * 16..(my * 16 + 16).min(h) {
                for x in mx * 16..(mx * 16 + 16).min(w) {
                    for ch in 0..3 {
                        let i = (y * w + x) * 3 + ch;
                        image.data[i] = if grey {
                            128
                        } else {
                            image.data[(y * w + x.saturating_sub(16)) * 3 + ch]
                        };
                    }
                }
            }
        }
    }
    if rng.uniform() < 0.5 {
        let y0 = (rng.uniform() * h as f32) as usize;
        let shift = (rng.range(4.0, 20.0) * w as f32 / 320.0) as usize;
        for y in y0..(y0 + h / 10).min(h) {
            let row: Vec<u8> = image.data[y * w * 3..(y + 1) * w * 3].to_vec();
            for x in 0..w {
                let src = x.saturating_sub(shift);
                for ch in 0..3 {
                    image.data[(y * w + x) * 3 + ch] = row[src * 3 + ch];
                }
            }
        }
    }
}

/// Analogue interference: one or two sinusoidal patterns at shallow angles, and a rolling
/// brighter bar.
fn interference(image: &mut Image, rng: &mut Rng, index: usize) {
    let (w, h) = (image.width, image.height);
    let scale = w as f32 / 320.0;
    let patterns: Vec<(f32, f32, f32, f32)> = (0..1 + (rng.uniform() * 2.0) as usize)
        .map(|_| {
            (
                rng.range(-0.35, 0.35),
                rng.range(6.0, 30.0) * scale,
                rng.range(12.0, 35.0),
                rng.range(0.0, 2.0 * PI),
            )
        })
        .collect();
    let bar_centre = ((index * 53) % h) as f32;
    let bar_half = rng.range(5.0, 15.0) * scale;
    for y in 0..h {
        for x in 0..w {
            let mut add = 0.0;
            for &(angle, period, amp, phase) in &patterns {
                let d = x as f32 * angle.sin() + y as f32 * angle.cos();
                add += amp * (2.0 * PI * d / period + phase).sin();
            }
            if (y as f32 - bar_centre).abs() < bar_half {
                add += 40.0;
            }
            for ch in 0..3 {
                let i = (y * w + x) * 3 + ch;
                image.data[i] = (f32::from(image.data[i]) + add).round().clamp(0.0, 255.0) as u8;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The renderer's world geometry is the conventions' horizon line: a ray is on the ground
    /// exactly where `sin φ·x + cos φ·y > tan θ`.
    #[test]
    fn ground_side_is_the_conventions_line() {
        let mut rng = Rng::new(3);
        for _ in 0..2000 {
            let (roll, pitch, heading) = (
                rng.range(-3.0, 3.0),
                rng.range(-1.2, 1.2),
                rng.range(-3.0, 3.0),
            );
            let (x, y) = (rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
            let lhs = roll.sin() * x + roll.cos() * y - pitch.tan();
            if lhs.abs() < 1e-3 {
                continue;
            }
            let down = to_world(x, y, roll, pitch, heading)[2];
            assert_eq!(
                down > 0.0,
                lhs > 0.0,
                "roll {roll} pitch {pitch} at ({x}, {y})"
            );
        }
    }

    /// World → body is the inverse of body → world.
    #[test]
    fn to_body_inverts_to_world() {
        let (roll, pitch, heading) = (0.4, -0.2, 2.0);
        let d = to_world(0.3, -0.1, roll, pitch, heading);
        let b = to_body(d, roll, pitch, heading);
        let n = (1.0f32 + 0.09 + 0.01).sqrt();
        for (got, want) in b.iter().zip([1.0 / n, 0.3 / n, -0.1 / n]) {
            assert!((got - want).abs() < 1e-5, "{b:?}");
        }
    }

    /// A `no-horizon` frame turned to look far up shows sky in every row: its motion blur and
    /// rolling shutter are the flight's, not the turn's (which smeared the turn over the rows
    /// and put the ground back into the bottom rows of frames whose truth has it out of view).
    #[test]
    fn a_frame_looking_far_up_has_no_ground_in_it() {
        let mut looked_up = 0;
        for seed in 1..=6 {
            let r = TerrainRenderer::new(Class::NoHorizon, 160, 120, seed);
            for index in (0..16).step_by(2) {
                let (image, truth) = r.render(index);
                assert!(!truth.visible);
                if truth.pitch_deg < 45.0 {
                    continue;
                }
                looked_up += 1;
                // Blue over red, row by row: the sky's; the ground's fields and forest are
                // redder than they are blue.
                for v in 0..120 {
                    let row = &image.data[v * 160 * 3..(v + 1) * 160 * 3];
                    let (red, blue) = row.chunks_exact(3).fold((0u32, 0u32), |(r, b), p| {
                        (r + u32::from(p[0]), b + u32::from(p[2]))
                    });
                    assert!(
                        blue > red,
                        "seed {seed} frame {index} (pitch {:.1}°) row {v}: blue {blue} red {red}",
                        truth.pitch_deg
                    );
                }
            }
        }
        assert!(looked_up >= 8, "{looked_up} frames looked far up");
    }

    /// A pixel's samples average to its centre, the integer point: no half-pixel slip.
    #[test]
    fn a_pixels_samples_average_to_its_centre() {
        let offsets = [
            (-0.375f32, -0.125f32),
            (0.125, -0.375),
            (0.375, 0.125),
            (-0.125, 0.375),
        ];
        let (su, sv) = offsets
            .iter()
            .fold((0.0, 0.0), |(a, b), (u, v)| (a + u, b + v));
        assert_eq!((su, sv), (0.0, 0.0));
        // And a frame's truth is where its sky meets its ground: on a clean level frame the
        // rows above the true line are brighter than those below, within a pixel.
        let r = TerrainRenderer::new(Class::Clean, 160, 120, 4);
        let (image, truth) = r.render(0);
        assert!(truth.visible);
        let (roll, pitch) = (truth.roll_deg.to_radians(), truth.pitch_deg.to_radians());
        let cam = r.camera;
        let (mut above, mut below, mut n_above, mut n_below) = (0.0f64, 0.0f64, 0u32, 0u32);
        for v in 0..120 {
            for u in 0..160 {
                let Some((x, y)) = cam.undistort_pixel(u as f32, v as f32) else {
                    continue;
                };
                let d = (roll.sin() * x + roll.cos() * y - pitch.tan()) * cam.fy;
                let luma = f64::from(image.data[(v * 160 + u) * 3 + 1]);
                if (-1.5..-0.5).contains(&d) {
                    above += luma;
                    n_above += 1;
                } else if (0.5..1.5).contains(&d) {
                    below += luma;
                    n_below += 1;
                }
            }
        }
        let (above, below) = (above / f64::from(n_above), below / f64::from(n_below));
        assert!(
            above > below,
            "sky {above} not brighter than ground {below}"
        );
    }
}
