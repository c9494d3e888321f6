//! Synthetic flight video with ground truth: a camera on an airplane flying a roll/pitch
//! trajectory over textured fields under a graded sky, with the degradations of the seed's
//! flight video (thesis Figures 6-9 to 6-13) laid on top.
//!
//! The renderer traces each pixel's ray: through the camera model (distortion included) into
//! body axes and then the level world frame (conventions: `R = Rz(ψ)·Ry(θ)·Rx(φ)`), so the
//! sky/ground boundary is exactly the conventions' horizon line and the truth is the
//! trajectory's roll and pitch.

use crate::image_io::Image;
use clap::ValueEnum;
use skyframe_core::horizon::Camera;

/// The degradation sets. Each one is one failure of the seed's detector.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, ValueEnum)]
pub enum Degradation {
    /// Sky gradient and mildly textured fields, nothing else.
    Clean,
    /// Gaussian sensor noise on every pixel.
    SensorNoise,
    /// Bursts of radio-link noise: heavy grain, sparkles, torn lines, lost colour (Fig. 6-10).
    TransmissionNoise,
    /// A bright horizontal stripe moving down the frame (lost vertical sync, Fig. 6-11).
    WhiteStripes,
    /// The same stripe, black.
    BlackStripes,
    /// Exposure, contrast, saturation and tint changing from frame to frame (Fig. 6-12).
    Exposure,
    /// Heading into the sun: bloom, smear column, flare ghosts, veiling glare (Fig. 6-13).
    Glare,
    /// Roads and high-contrast field edges on the ground.
    Roads,
    /// Broken cloud with hard edges in the sky.
    Clouds,
    /// A wide-angle lens with strong barrel distortion (Fig. 6-9); the camera file says so.
    Distortion,
    /// Thick haze seen from higher up: the horizon is a small step from the sky to an
    /// airlight nearly as bright, then a long ramp down to the ground's own colour.
    Haze,
    /// All of the above at once, milder each.
    Mixed,
    /// Analog interference (issue 17): a sinusoidal pattern across the frame at some angle,
    /// drifting from frame to frame, and a soft bright hum bar rolling down.
    Interference,
    /// A starved digital link (issue 17): each 8×8 block reduced to its mean and its two
    /// first ramps, quantised coarsely; lost macroblocks concealed by repeating a neighbour;
    /// rows of blocks torn sideways.
    Blocks,
    /// Interference whose crests run within ±6° of the horizon (issue 17's hardest case:
    /// every crest is a long straight edge nearly parallel to it, next to it).
    ParallelInterference,
    /// A dark near field ending at a straight line 6–15° below the horizon, with light
    /// hazy fields beyond it (issue 17): the ground edge is far stronger than the horizon.
    GroundEdge,
    /// Dusk with the gain turned up (issue 17): the scene lit a tenth as brightly, counted in
    /// electrons with their shot noise, read noise and a random offset per row, then
    /// amplified back, over the haze set's scene. The noise grows with brightness and is
    /// correlated along the rows, so a level horizon's small step must be told from the rows'
    /// own offsets.
    LowLight,
    /// No horizon to see (issue 17's honesty): runs of 8 frames looking steeply down at fields
    /// crossed by long straight roads, then 8 steeply up into the sky and its clouds.
    /// Scored only on false confidence.
    NoHorizon,
    /// Analogue interference over a hazy horizon, in linear light (issue 17): the ground
    /// fades into an airlight a little darker than the sky's glow at the horizon (extinction
    /// and airlight blended as radiance), so the horizon is a small step over a long ramp; the
    /// camera adds a short motion blur, vignetting, shot and read noise in electrons, clipping
    /// and the sRGB curve; the interference is a sinusoid at any angle to the horizon (a third
    /// of the frames nearly parallel to it), 3 px to half the frame's height in period and
    /// about as strong as the step, added to the analogue signal before or after the gamma,
    /// and in some frames a broad hum bar, brighter or darker, rolling down the frame.
    /// (After `NoHorizon`: a set's seed follows its place in this list.)
    HazyInterference,
    /// A camera in dim light at high gain over a hazy horizon (a small step from the sky to
    /// the airlight, then a ramp down to the ground): the scene as linear radiance,
    /// vignetting, motion blur, an exposure, then electrons with their shot noise, read
    /// noise, a random offset per row and blotchy chroma noise, clipping at the full well,
    /// and the sRGB curve. Brighter than `low-light`: the step is there to be found.
    CameraNoise,
    /// A digital video link over the same hazy horizon: YCbCr with 4:2:0 chroma, each 8×8
    /// block's DCT quantised with the JPEG tables at a coarse quality, lost macroblocks
    /// concealed by repeating a neighbour, and torn bands of macroblock rows shifted sideways.
    VideoLink,
    /// What real horizons have and the other sets lack (issue 17's real frames): the skyline
    /// is a tree line with hedges, buildings and low hills a few pixels high on a ridge
    /// 2.5–5 km away, lakes on the fields before it, broken cloud down to the horizon and a
    /// sky brighter on the sun's side; seen through a lens with vignetting, auto-exposure,
    /// mild sensor noise and JPEG-like 8×8 DCT compression at moderate quality. Truth: the
    /// level horizon, on which the silhouette's mean top lies (see [`Skyline`]).
    TreeLine,
    /// `ground-edge` with the near field's border turned up to ±35° from square to the view
    /// (seventh session): in the image it runs up to 6° out of parallel with the horizon, its
    /// vanishing point on the horizon outside the frame, as a field's border or a road on level
    /// ground does.
    ObliqueGroundEdge,
    /// A coast (eighth session): sea on one side of a shoreline with bays, fields crossed by
    /// roads and hedges on the other, in some runs a bright beach between them; the coast
    /// turned up to ±70° from square to the view, 250 m to 3 km ahead, the sea beyond it (the
    /// horizon over the sea) or the airplane over the sea (the horizon over the land) in runs
    /// of 20 frames; `ground-edge`'s haze, so the far sea meets the sky in a step of 12–16
    /// levels and the shore below it is the stronger edge. One run of 8 frames in 32 looks
    /// 40–70° down at the shoreline, where the sea is darker, bluer and smoother than the
    /// land, as a sky is: scored only on false confidence.
    Coast,
    /// `coast` with a calm sea that mirrors the sky (sixteenth session): Schlick's Fresnel
    /// term, uncapped, so that at grazing angles the sea is nearly the sky's own colour and
    /// the shore, sea-bright over dark land and tilted by the coast's turn, is a stronger
    /// sky-over-ground step than the horizon's 12–16 levels above it.
    CalmSea,
}

impl Degradation {
    pub const SETS: [Degradation; 24] = [
        Degradation::Clean,
        Degradation::SensorNoise,
        Degradation::TransmissionNoise,
        Degradation::WhiteStripes,
        Degradation::BlackStripes,
        Degradation::Exposure,
        Degradation::Glare,
        Degradation::Roads,
        Degradation::Clouds,
        Degradation::Distortion,
        Degradation::Haze,
        Degradation::Interference,
        Degradation::Blocks,
        Degradation::ParallelInterference,
        Degradation::GroundEdge,
        Degradation::LowLight,
        Degradation::HazyInterference,
        Degradation::NoHorizon,
        Degradation::CameraNoise,
        Degradation::VideoLink,
        Degradation::TreeLine,
        Degradation::ObliqueGroundEdge,
        Degradation::Coast,
        Degradation::CalmSea,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Degradation::Clean => "clean",
            Degradation::SensorNoise => "sensor-noise",
            Degradation::TransmissionNoise => "transmission-noise",
            Degradation::WhiteStripes => "white-stripes",
            Degradation::BlackStripes => "black-stripes",
            Degradation::Exposure => "exposure",
            Degradation::Glare => "glare",
            Degradation::Roads => "roads",
            Degradation::Clouds => "clouds",
            Degradation::Distortion => "distortion",
            Degradation::Haze => "haze",
            Degradation::Mixed => "mixed",
            Degradation::Interference => "interference",
            Degradation::Blocks => "blocks",
            Degradation::ParallelInterference => "parallel-interference",
            Degradation::GroundEdge => "ground-edge",
            Degradation::LowLight => "low-light",
            Degradation::HazyInterference => "hazy-interference",
            Degradation::NoHorizon => "no-horizon",
            Degradation::CameraNoise => "camera-noise",
            Degradation::VideoLink => "video-link",
            Degradation::TreeLine => "tree-line",
            Degradation::ObliqueGroundEdge => "oblique-ground-edge",
            Degradation::Coast => "coast",
            Degradation::CalmSea => "calm-sea",
        }
    }

    fn index(self) -> u64 {
        self as u64
    }
}

/// Deterministic pseudo-random numbers (SplitMix64): the same seed gives the same video on
/// every machine.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed ^ 0x9E37_79B9_7F4A_7C15)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.uniform()
    }

    /// Approximately normal (sum of four uniforms), mean 0, standard deviation 1.
    pub fn normal(&mut self) -> f32 {
        let s: f32 = (0..4).map(|_| self.uniform()).sum();
        (s - 2.0) * 1.732_050_8
    }
}

/// Hash of integer lattice coordinates to [0, 1): the static texture of the world.
fn lattice(seed: u64, x: i64, y: i64) -> f32 {
    let mut h = seed
        ^ (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
    h = (h ^ (h >> 31)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 29;
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// Smooth value noise in [0, 1) at unit lattice spacing.
fn value_noise(seed: u64, x: f32, y: f32) -> f32 {
    let (xf, yf) = (x.floor(), y.floor());
    let (tx, ty) = (x - xf, y - yf);
    let (sx, sy) = (tx * tx * (3.0 - 2.0 * tx), ty * ty * (3.0 - 2.0 * ty));
    let (xi, yi) = (xf as i64, yf as i64);
    let a = lattice(seed, xi, yi);
    let b = lattice(seed, xi + 1, yi);
    let c = lattice(seed, xi, yi + 1);
    let d = lattice(seed, xi + 1, yi + 1);
    let top = a + (b - a) * sx;
    let bottom = c + (d - c) * sx;
    top + (bottom - top) * sy
}

fn fbm(seed: u64, x: f32, y: f32, octaves: u32) -> f32 {
    let (mut sum, mut amplitude, mut frequency, mut norm) = (0.0, 0.5, 1.0, 0.0);
    for o in 0..octaves {
        sum += amplitude * value_noise(seed.wrapping_add(o as u64), x * frequency, y * frequency);
        norm += amplitude;
        amplitude *= 0.5;
        frequency *= 2.0;
    }
    sum / norm
}

/// The true attitude of one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Truth {
    pub roll_deg: f32,
    pub pitch_deg: f32,
    /// Whether the horizon can be seen at all (out of the frame, fogged or clipped away:
    /// no). A frame without one is scored only on honesty.
    pub visible: bool,
}

/// Header of `truth.csv`; `visible` is 1 when the horizon can be seen in the frame.
pub const TRUTH_HEADER: &str = "frame,roll_deg,pitch_deg,visible\n";

/// One line of `truth.csv`.
pub fn truth_line(frame: usize, t: &Truth) -> String {
    format!(
        "{frame},{:.4},{:.4},{}\n",
        t.roll_deg,
        t.pitch_deg,
        u8::from(t.visible)
    )
}

/// A flight-like trajectory: banked turns with faster wobble, pitch changes of a few degrees,
/// sampled at 10 frames per second of flight, heading turning with the bank.
pub fn trajectory(frame: usize, seed: u64) -> (Truth, f32) {
    let mut rng = Rng::new(seed);
    let phases: [f32; 5] = std::array::from_fn(|_| rng.range(0.0, std::f32::consts::TAU));
    let t = frame as f32 / 10.0;
    let tau = std::f32::consts::TAU;
    let roll = 30.0 * (tau * t / 7.0 + phases[0]).sin() + 12.0 * (tau * t / 2.3 + phases[1]).sin();
    let pitch =
        2.0 + 6.0 * (tau * t / 5.0 + phases[2]).sin() + 3.0 * (tau * t / 1.7 + phases[3]).sin();
    let heading = phases[4] + 0.15 * t + 0.2 * (tau * t / 7.0).sin();
    (
        Truth {
            roll_deg: roll,
            pitch_deg: pitch,
            visible: true,
        },
        heading,
    )
}

/// The camera used for a degradation set at a frame size.
pub fn camera_for(degradation: Degradation, width: usize, height: usize) -> Camera {
    let mut camera = Camera::ideal(width as u32, height as u32, 60f32.to_radians());
    if matches!(degradation, Degradation::Distortion | Degradation::Mixed) {
        camera = Camera::ideal(width as u32, height as u32, 80f32.to_radians());
        camera.k1 = if degradation == Degradation::Distortion {
            -0.28
        } else {
            -0.15
        };
        camera.k2 = if degradation == Degradation::Distortion {
            0.08
        } else {
            0.03
        };
    }
    camera
}

/// Renders sequences of one degradation set. Rays through every pixel are computed once.
pub struct Renderer {
    pub degradation: Degradation,
    pub camera: Camera,
    pub width: usize,
    pub height: usize,
    seed: u64,
    /// Normalised undistorted rays of 2×2 points inside each pixel (a sensor integrates
    /// over the pixel's area; point sampling would draw the horizon as a hard staircase).
    rays: Vec<[(f32, f32); 4]>,
    /// Off only in tests: the same frame without its interference.
    with_interference: bool,
    /// The `tree-line` world's skyline.
    skyline: Option<Skyline>,
}

/// Altitude above the fields (m) and of the cloud base above the airplane (m).
const ALTITUDE_M: f32 = 120.0;
const CLOUD_BASE_M: f32 = 900.0;
/// Ground speed (m per frame at 10 frames per second of flight).
const METRES_PER_FRAME: f32 = 2.5;

impl Renderer {
    pub fn new(degradation: Degradation, width: usize, height: usize, seed: u64) -> Self {
        let camera = camera_for(degradation, width, height);
        let rays = (0..height)
            .flat_map(|v| (0..width).map(move |u| (u, v)))
            .map(|(u, v)| {
                [(-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25)].map(|(du, dv)| {
                    camera
                        .undistort_pixel(u as f32 + du, v as f32 + dv)
                        .unwrap_or((f32::NAN, f32::NAN))
                })
            })
            .collect();
        let seed = seed.wrapping_mul(31).wrapping_add(degradation.index());
        Renderer {
            degradation,
            camera,
            width,
            height,
            seed,
            rays,
            with_interference: true,
            skyline: (degradation == Degradation::TreeLine).then(|| Skyline::new(seed)),
        }
    }

    fn has(&self, d: Degradation) -> bool {
        self.degradation == d || self.degradation == Degradation::Mixed
    }

    /// Frame `index` of the sequence and its truth.
    pub fn render(&self, index: usize) -> (Image, Truth) {
        let (mut truth, heading) = trajectory(index, self.seed);
        let no_horizon = self.degradation == Degradation::NoHorizon;
        // Runs of 8 frames down, then 8 up: within a run the view drifts slowly, so a steady
        // road or cloud edge persists from frame to frame as a horizon would, and the tracker
        // must not lend it confidence.
        let looking_down = no_horizon && (index / 8) % 2 == 0;
        let at_the_coast = matches!(self.degradation, Degradation::Coast | Degradation::CalmSea);
        let down_at_the_coast = at_the_coast && (index / 8) % 4 == 3;
        // 40–70° nose down or up: the horizon is outside the frame at any roll (the frame's
        // corner is 36° off the axis), from 17° past its edge to far away.
        let away = 55.0 + 15.0 * (index as f32 * 0.21).sin();
        if no_horizon {
            truth.pitch_deg = if looking_down { -away } else { away };
        } else if down_at_the_coast {
            truth.pitch_deg = -away;
        }
        let (roll, pitch) = (truth.roll_deg.to_radians(), truth.pitch_deg.to_radians());
        let (sr, cr, sp, cp, sh, ch) = (
            roll.sin(),
            roll.cos(),
            pitch.sin(),
            pitch.cos(),
            heading.sin(),
            heading.cos(),
        );
        let north = index as f32 * METRES_PER_FRAME * ch;
        let east = index as f32 * METRES_PER_FRAME * sh;
        let mut frame_rng =
            Rng::new(self.seed ^ (index as u64).wrapping_mul(0xA24B_AED4_963E_E407));
        let roads = self.has(Degradation::Roads) || looking_down;
        let clouds = self.has(Degradation::Clouds) || (no_horizon && !looking_down);
        let cloud_cover = if self.degradation == Degradation::Clouds {
            0.6
        } else {
            0.3
        };
        let world = self.seed;
        // The near field's far boundary: a straight line across the view at a depression
        // (straight ahead) drifting between 6° and 15°, square to the heading or (oblique)
        // its normal turned from the heading by up to ±35°.
        let ground_edge = matches!(
            self.degradation,
            Degradation::GroundEdge | Degradation::ObliqueGroundEdge
        )
        .then(|| {
            let phase = (self.seed % 1000) as f32;
            let depression = 10.5 + 4.5 * (index as f32 * 0.11 + phase).sin();
            let oblique = if self.degradation == Degradation::ObliqueGroundEdge {
                (35.0 * (index as f32 * 0.07 + 2.0 * phase).sin()).to_radians()
            } else {
                0.0
            };
            let (so, co) = (oblique.sin(), oblique.cos());
            // The normal (north, east) and the line's distance along it.
            let normal = (ch * co - sh * so, sh * co + ch * so);
            (normal, ALTITUDE_M * co / depression.to_radians().tan())
        });
        let coast = at_the_coast.then(|| {
            let phase = (self.seed % 1000) as f32;
            let turn = (70.0 * (index as f32 * 0.05 + 3.0 * phase).sin()).to_radians();
            let (so, co) = (turn.sin(), turn.cos());
            // Ahead of the airplane along the normal: where the view's centre meets the
            // ground when looking down, else 250 m to 3 km (25° to 2.3° below the horizon).
            let distance = if down_at_the_coast {
                ALTITUDE_M / away.to_radians().tan()
                    * (1.0 + 0.25 * (index as f32 * 0.6 + phase).sin())
            } else {
                250.0 * 12f32.powf(0.5 + 0.5 * (index as f32 * 0.09 + 5.0 * phase).sin())
            };
            Coast {
                normal: (ch * co - sh * so, sh * co + ch * so),
                distance,
                sea_beyond: (index / 20 + self.seed as usize) % 2 == 0,
                beach_m: if (index / 16 + index / 40) % 2 == 0 {
                    12.0
                } else {
                    0.0
                },
                mirror: self.degradation == Degradation::CalmSea,
            }
        });
        let haze = if self.degradation == Degradation::Haze {
            Haze {
                distance_m: 500.0,
                colour: [182.0, 195.0, 212.0],
                linear: false,
            }
        } else if self.degradation == Degradation::LowLight {
            // Dusk is hazy: an airlight 6–16 levels under of the sky at the horizon (the
            // flight's own shade), so the horizon is a step smaller than the pixels' noise.
            let below =
                6.0 + 10.0 * ((self.seed.wrapping_mul(0x9E37_79B9) >> 16) % 1000) as f32 / 1000.0;
            let sky = sky_colour(0.0);
            Haze {
                distance_m: 700.0,
                colour: sky.map(|c| c - below),
                linear: false,
            }
        } else if self.degradation == Degradation::HazyInterference {
            // Thick haze: the steepest part of the ramp lies `altitude / 2·distance` below
            // the horizon (1.7–7°); the airlight is 70–92 % of the sky's radiance at the
            // horizon, a step of about 5–25 levels.
            let sky = sky_colour(0.0);
            let airlight = frame_rng.range(0.70, 0.92);
            Haze {
                distance_m: frame_rng.range(500.0, 2000.0),
                colour: sky.map(|c| srgb_encode(airlight * srgb_decode(c))),
                linear: true,
            }
        } else if matches!(
            self.degradation,
            Degradation::CameraNoise | Degradation::VideoLink
        ) {
            hazy_horizon(&mut Rng::new(
                self.seed ^ (index as u64).wrapping_mul(0x5851_F42D_4C95_7F2D) ^ 0x4A2E,
            ))
        } else {
            Haze::NORMAL
        };
        let shade = |x: f32, y: f32| -> [f32; 3] {
            if x.is_nan() {
                return [0.0; 3];
            }
            // Body FRD ray (forward, right, down) = camera (z, x, y); then Rx(roll), Ry(pitch).
            let (bx, by, bz) = (1.0, x, y);
            let (rx, ry, rz) = (bx, cr * by - sr * bz, sr * by + cr * bz);
            let (px, py, pz) = (cp * rx + sp * rz, ry, -sp * rx + cp * rz);
            // Then Rz(heading) into north/east.
            let (wn, we, wd) = (ch * px - sh * py, sh * px + ch * py, pz);
            let length = (wn * wn + we * we + wd * wd).sqrt();
            if let Some(skyline) = &self.skyline {
                return skyline.shade(world, north, east, (wn, we, wd));
            }
            if wd > 0.0 {
                let t = ALTITUDE_M / wd;
                let (gn, ge) = (north + t * wn, east + t * we);
                if let Some(coast) = &coast {
                    return coast.colour(world, (north, east), (t * wn, t * we), t * length);
                }
                if let Some(((nn, ne), edge)) = ground_edge {
                    let ahead = t * (wn * nn + we * ne);
                    return edge_field_colour(world, gn, ge, t * length, ahead < edge);
                }
                return ground_colour(world, gn, ge, t * length, roads, haze);
            }
            let elevation = (-wd / length).clamp(0.0, 1.0);
            let mut c = sky_colour(elevation);
            if clouds && wd < -1e-3 {
                let t = CLOUD_BASE_M / -wd;
                let (cn, ce) = (north + t * wn, east + t * we);
                let density = fbm(world ^ 0xC10D, cn / 700.0, ce / 700.0, 4);
                let cover = ((density - (1.0 - cloud_cover)) * 6.0).clamp(0.0, 1.0);
                // Distant clouds fade into the haze at the horizon.
                let fade = (-(t * length) / 20_000.0).exp();
                let grey = 170.0 + 80.0 * fbm(world ^ 0x5AD, cn / 150.0, ce / 150.0, 2);
                let k = cover * fade;
                for channel in c.iter_mut() {
                    *channel = *channel * (1.0 - k) + grey * k;
                }
            }
            c
        };
        let mut pixels: Vec<[f32; 3]> = self
            .rays
            .iter()
            .map(|rays| {
                let mut sum = [0f32; 3];
                for &(x, y) in rays {
                    for (s, c) in sum.iter_mut().zip(shade(x, y)) {
                        *s += 0.25 * c;
                    }
                }
                sum
            })
            .collect();
        blur_121(&mut pixels, self.width, self.height);
        self.degrade(&mut pixels, index, &mut frame_rng, roll, pitch, heading);
        let mut image = Image::new_rgb(self.width, self.height);
        for (out, p) in image.data.chunks_exact_mut(3).zip(&pixels) {
            for (o, v) in out.iter_mut().zip(p) {
                *o = v.round().clamp(0.0, 255.0) as u8;
            }
        }
        // Over-exposure can clip sky and distant ground alike: then there is no horizon in
        // the image to find, and the frame is scored on honesty only.
        let visible = crate::terrain::horizon_in_image(&image, &self.camera, roll, pitch);
        (image, Truth { visible, ..truth })
    }

    fn degrade(
        &self,
        pixels: &mut [[f32; 3]],
        index: usize,
        rng: &mut Rng,
        roll: f32,
        pitch: f32,
        heading: f32,
    ) {
        let (w, h) = (self.width, self.height);
        let scale = w as f32 / 320.0;
        let mixed = self.degradation == Degradation::Mixed;
        if self.has(Degradation::Glare) {
            self.glare(pixels, roll, pitch, heading, mixed);
        }
        if self.has(Degradation::Exposure) {
            // Exposure drifts with the view and jumps when the camera's auto-exposure steps.
            let drift = ((index as f32) * 0.7).sin() * 0.5 + ((index as f32) * 0.23).cos() * 0.3;
            let jump = if rng.uniform() < 0.3 {
                rng.range(-0.5, 0.5)
            } else {
                0.0
            };
            let gain = (1.0 + drift + jump).clamp(0.3, 2.0);
            let contrast = rng.range(0.5, 1.3);
            let saturation = rng.range(0.1, 1.6);
            let tint = [
                rng.range(0.75, 1.25),
                rng.range(0.8, 1.2),
                rng.range(0.75, 1.25),
            ];
            for p in pixels.iter_mut() {
                let grey = 0.3 * p[0] + 0.59 * p[1] + 0.11 * p[2];
                for (c, t) in p.iter_mut().zip(tint) {
                    let saturated = grey + (*c - grey) * saturation;
                    *c = ((saturated - 128.0) * contrast + 128.0) * gain * t;
                }
            }
        }
        if self.has(Degradation::SensorNoise) {
            let sigma = if mixed { 6.0 } else { 14.0 };
            for p in pixels.iter_mut() {
                for c in p.iter_mut() {
                    *c += sigma * rng.normal();
                }
            }
        }
        if self.has(Degradation::TransmissionNoise) && rng.uniform() < if mixed { 0.3 } else { 0.7 }
        {
            // A burst: grain whose strength varies down the frame, torn (shifted) lines,
            // sparkles (short bright and dark dashes), and sometimes the colour drops out.
            let sigma = rng.range(20.0, 55.0);
            let lose_colour = rng.uniform() < 0.4;
            let mut row_copy = vec![[0f32; 3]; w];
            for y in 0..h {
                let row = &mut pixels[y * w..(y + 1) * w];
                let strength =
                    sigma * (0.5 + 0.5 * ((y as f32 / h as f32) * 5.0 + index as f32).sin().abs());
                if rng.uniform() < 0.05 {
                    let shift = (rng.range(-8.0, 8.0) * scale) as isize;
                    row_copy.copy_from_slice(row);
                    for (x, p) in row.iter_mut().enumerate() {
                        let src = (x as isize - shift).clamp(0, w as isize - 1) as usize;
                        *p = row_copy[src];
                    }
                }
                for p in row.iter_mut() {
                    let common = strength * rng.normal();
                    for c in p.iter_mut() {
                        *c += common + 0.3 * strength * rng.normal();
                    }
                    if lose_colour {
                        let grey = (p[0] + p[1] + p[2]) / 3.0;
                        *p = [grey; 3];
                    }
                }
                let sparkles = (rng.uniform() * 3.0 * scale) as usize;
                for _ in 0..sparkles {
                    let x0 = (rng.uniform() * w as f32) as usize;
                    let length = (rng.range(3.0, 14.0) * scale) as usize;
                    let value = if rng.uniform() < 0.5 { 255.0 } else { 0.0 };
                    for p in row.iter_mut().skip(x0).take(length) {
                        *p = [value; 3];
                    }
                }
            }
        }
        // Interference and blocks are not part of `mixed` (its figures stay comparable with
        // the runs before they were added).
        if self.degradation == Degradation::Interference {
            let angle = rng.range(-1.2, 1.2);
            interference(pixels, w, h, index, angle, rng);
        }
        if self.degradation == Degradation::ParallelInterference {
            // Crests along the horizon's image direction, which is at −roll to the rows.
            let angle = -roll + rng.range(-6.0, 6.0).to_radians();
            interference(pixels, w, h, index, angle, rng);
        }
        if self.degradation == Degradation::Blocks {
            blocks(pixels, w, h, rng);
        }
        if self.degradation == Degradation::HazyInterference {
            analogue_camera(pixels, w, h, index, roll, rng, self.with_interference);
        }
        if self.degradation == Degradation::LowLight {
            low_light(pixels, w, rng);
        }
        if self.degradation == Degradation::CameraNoise {
            camera_noise(pixels, w, h, &CameraNoise::draw(rng, scale), rng);
        }
        if self.degradation == Degradation::VideoLink {
            // A little sensor grain first: the codec quantises it into its blocks.
            for p in pixels.iter_mut() {
                for c in p.iter_mut() {
                    *c += 2.0 * rng.normal();
                }
            }
            video_link(pixels, w, h, &VideoLink::draw(rng, scale), rng);
        }
        if self.degradation == Degradation::TreeLine {
            consumer_camera(pixels, w, h, rng);
        }
        let stripe = if self.has(Degradation::WhiteStripes) {
            Some(255.0)
        } else if self.degradation == Degradation::BlackStripes {
            Some(0.0)
        } else {
            None
        };
        if let Some(value) = stripe
            && rng.uniform() < if mixed { 0.3 } else { 0.75 }
        {
            // The stripe moves down the frame from one frame to the next.
            let thickness = (rng.range(4.0, 18.0) * scale) as usize;
            let top = (index * 37 + (rng.uniform() * 20.0) as usize) * h / 240 % h;
            for y in top..(top + thickness).min(h) {
                for p in pixels[y * w..(y + 1) * w].iter_mut() {
                    let jitter = 8.0 * rng.normal();
                    *p = [value + jitter; 3];
                }
            }
        }
    }

    /// The sun ahead and low: a bloom around it, a vertical smear column through it (CCD
    /// smear), ghosts along the line through the image centre, and a veil lifting the blacks.
    fn glare(&self, pixels: &mut [[f32; 3]], roll: f32, pitch: f32, heading: f32, mixed: bool) {
        let (w, h) = (self.width, self.height);
        // Sun direction in the world: azimuth near the initial heading, 12° up.
        let (sun_azimuth, sun_elevation) = (heading - 0.15, 12f32.to_radians());
        let world = [
            sun_elevation.cos() * sun_azimuth.cos(),
            sun_elevation.cos() * sun_azimuth.sin(),
            -sun_elevation.sin(),
        ];
        // World → body: transpose of Rz·Ry·Rx.
        let (sh, ch) = heading.sin_cos();
        let (sp, cp) = pitch.sin_cos();
        let (sr, cr) = roll.sin_cos();
        let (n1, e1) = (
            ch * world[0] + sh * world[1],
            -sh * world[0] + ch * world[1],
        );
        let (f2, d2) = (cp * n1 - sp * world[2], sp * n1 + cp * world[2]);
        let (r3, d3) = (cr * e1 + sr * d2, -sr * e1 + cr * d2);
        if f2 <= 0.05 {
            return;
        }
        let (su, sv) = self.camera.project(r3 / f2, d3 / f2);
        let strength = if mixed { 0.5 } else { 1.0 };
        let radius = 0.35 * w as f32;
        let (cx, cy) = (w as f32 / 2.0, h as f32 / 2.0);
        for y in 0..h {
            for x in 0..w {
                let (dx, dy) = (x as f32 - su, y as f32 - sv);
                let r2 = (dx * dx + dy * dy) / (radius * radius);
                let bloom = 220.0 * (-r2 * 3.0).exp() + 70.0 * (-r2 * 0.4).exp();
                let smear = if (dx.abs() / w as f32) < 0.012 {
                    120.0
                } else {
                    0.0
                };
                let mut ghost = 0.0;
                for k in [0.6f32, 1.3, 1.8] {
                    let (gx, gy) = (su + (cx - su) * k, sv + (cy - sv) * k);
                    let gr = ((x as f32 - gx).powi(2) + (y as f32 - gy).powi(2)).sqrt();
                    let ring = 0.04 * w as f32 * k;
                    if gr < ring {
                        ghost += 45.0;
                    }
                }
                let p = &mut pixels[y * w + x];
                for (i, c) in p.iter_mut().enumerate() {
                    let warm = [1.0, 0.95, 0.8][i];
                    let veiled = *c * (1.0 - 0.35 * strength) + 70.0 * strength;
                    *c = veiled + strength * warm * (bloom + smear + ghost);
                }
            }
        }
    }
}

/// A dim scene read by a sensor at high gain. The 8-bit values are taken as sRGB, turned
/// into linear light, and a full-scale pixel collects `full_well` electrons (60–400: a tenth
/// of daylight or less). Each pixel adds its shot noise (√electrons), 2–5 electrons of read
/// noise and its row's offset (0.5–2.5 electrons, one draw a row: the row's reset and
/// amplifier), is quantised by a 10-bit converter over the full well, and is scaled back
/// to full brightness and gamma-encoded.
fn low_light(pixels: &mut [[f32; 3]], w: usize, rng: &mut Rng) {
    let full_well = rng.range(60.0, 400.0);
    let read_noise = rng.range(2.0, 5.0);
    let row_noise = rng.range(0.5, 2.5);
    let step = full_well / 1024.0;
    let mut row_offset = 0.0;
    for (i, p) in pixels.iter_mut().enumerate() {
        if i % w == 0 {
            row_offset = row_noise * rng.normal();
        }
        for c in p.iter_mut() {
            let linear = (c.clamp(0.0, 255.0) / 255.0).powf(2.2);
            let electrons = linear * full_well;
            let read = electrons
                + electrons.sqrt() * rng.normal()
                + read_noise * rng.normal()
                + row_offset;
            let digital = ((read / step).round() * step / full_well).max(0.0);
            *c = 255.0 * digital.powf(1.0 / 2.2);
        }
    }
}

/// A hazy horizon as real haze draws it: the airlight at the horizon 8–30 levels under the
/// sky's glow there (a small step), and distant ground coming out of it over 800–3000 m of
/// extinction (a ramp a few degrees deep below the horizon). One draw a frame.
fn hazy_horizon(rng: &mut Rng) -> Haze {
    let below = rng.range(8.0, 30.0);
    let sky = sky_colour(0.0);
    // Airlight is a little greyer than the sky's glow just above it.
    let grey = rng.range(0.0, 8.0);
    Haze {
        distance_m: rng.range(800.0, 3000.0),
        colour: [
            sky[0] - below,
            sky[1] - below - 0.5 * grey,
            sky[2] - below - grey,
        ],
        linear: false,
    }
}

/// One frame's camera for `camera-noise`: dim light read at high gain.
#[derive(Clone, Copy, Debug)]
pub struct CameraNoise {
    /// Linear gain of the exposure (the scene's linear radiance times this is the share of
    /// the full well collected).
    pub exposure: f32,
    /// Electrons at full scale: 120–600, a dim scene at high gain.
    pub full_well: f32,
    /// Read noise (electrons, per pixel and channel).
    pub read_noise: f32,
    /// Standard deviation of each row's offset (electrons, one draw a row for all channels).
    pub row_noise: f32,
    /// Chroma noise: colour-only noise, constant over 2×2-pixel cells (the demosaicing spreads
    /// it), as a share of the pixel's shot noise.
    pub chroma: f32,
    /// Vignetting: light lost at the corners (share).
    pub vignetting: f32,
    /// Motion blur during the exposure (px, along `blur_angle`).
    pub blur_px: f32,
    pub blur_angle: f32,
}

impl CameraNoise {
    /// A random camera for a frame `scale` × 320 px wide.
    pub fn draw(rng: &mut Rng, scale: f32) -> Self {
        CameraNoise {
            exposure: rng.range(0.55, 1.1),
            full_well: rng.range(120.0, 600.0),
            read_noise: rng.range(2.0, 6.0),
            row_noise: rng.range(0.5, 2.5),
            chroma: rng.range(0.4, 1.0),
            vignetting: rng.range(0.1, 0.4),
            blur_px: rng.range(0.0, 2.5) * scale,
            blur_angle: rng.range(0.0, std::f32::consts::PI),
        }
    }
}

/// The sensor of `camera-noise` on an sRGB scene: linear light, vignetting, motion blur,
/// exposure into electrons with shot noise (Gaussian with the Poisson variance), read noise,
/// a per-row offset and blotchy chroma noise, clipping at the full well, a 10-bit converter,
/// gain back to full brightness and the sRGB curve.
fn camera_noise(pixels: &mut [[f32; 3]], w: usize, h: usize, camera: &CameraNoise, rng: &mut Rng) {
    let (cx, cy) = (0.5 * (w as f32 - 1.0), 0.5 * (h as f32 - 1.0));
    let corner2 = cx * cx + cy * cy;
    let mut linear: Vec<[f32; 3]> = pixels
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let (dx, dy) = ((i % w) as f32 - cx, (i / w) as f32 - cy);
            let light = 1.0 - camera.vignetting * (dx * dx + dy * dy) / corner2;
            p.map(|c| srgb_decode(c.min(255.0)) * light * camera.exposure)
        })
        .collect();
    // Motion blur: the mean of the image at whole-pixel steps along the motion.
    let taps = camera.blur_px.round() as isize;
    if taps > 0 {
        let (dx, dy) = (camera.blur_angle.cos(), camera.blur_angle.sin());
        let source = linear.clone();
        for (i, out) in linear.iter_mut().enumerate() {
            let (x, y) = ((i % w) as isize, (i / w) as isize);
            let mut sum = [0f32; 3];
            for t in -taps..=taps {
                let tf = 0.5 * t as f32;
                let sx = (x + (tf * dx).round() as isize).clamp(0, w as isize - 1) as usize;
                let sy = (y + (tf * dy).round() as isize).clamp(0, h as isize - 1) as usize;
                for (s, c) in sum.iter_mut().zip(source[sy * w + sx]) {
                    *s += c;
                }
            }
            *out = sum.map(|s| s / (2 * taps + 1) as f32);
        }
    }
    let step = camera.full_well / 1024.0;
    let cells_wide = w.div_ceil(2);
    let mut chroma_cells = vec![[0f32; 3]; cells_wide * h.div_ceil(2)];
    for cell in chroma_cells.iter_mut() {
        // Colour only: the three draws minus their mean.
        let n = [rng.normal(), rng.normal(), rng.normal()];
        let mean = (n[0] + n[1] + n[2]) / 3.0;
        *cell = n.map(|v| camera.chroma * (v - mean));
    }
    let mut row_offset = 0.0;
    for (i, (p, l)) in pixels.iter_mut().zip(&linear).enumerate() {
        if i % w == 0 {
            row_offset = camera.row_noise * rng.normal();
        }
        let cell = chroma_cells[(i / w / 2) * cells_wide + (i % w) / 2];
        for ((c, &light), colour) in p.iter_mut().zip(l).zip(cell) {
            let electrons = light * camera.full_well;
            let shot = electrons.max(0.0).sqrt();
            let read = electrons
                + shot * (rng.normal() + colour)
                + camera.read_noise * rng.normal()
                + row_offset;
            let digital = (read.clamp(0.0, camera.full_well) / step).round() * step;
            *c = srgb_encode((digital / camera.full_well).min(1.0));
        }
    }
}

/// One frame's link for `video-link`.
#[derive(Clone, Copy, Debug)]
pub struct VideoLink {
    /// JPEG quality (1–100) the quantisation tables are scaled to: 12–40 is coarse.
    pub quality: f32,
    /// Share of the 16×16 macroblocks lost and concealed.
    pub loss: f32,
    /// A torn band of macroblock rows: (first row, rows, shift in px), or none.
    pub tear: Option<(usize, usize, isize)>,
}

impl VideoLink {
    pub fn draw(rng: &mut Rng, scale: f32) -> Self {
        let quality = rng.range(12.0, 40.0);
        let loss = rng.range(0.01, 0.06);
        let tear = (rng.uniform() < 0.4).then(|| {
            let first = (rng.uniform() * 1000.0) as usize;
            let rows = 1 + (rng.uniform() * 3.0) as usize;
            let shift = (rng.range(4.0, 24.0) * scale) as isize;
            (
                first,
                rows,
                if rng.uniform() < 0.5 { -shift } else { shift },
            )
        });
        VideoLink {
            quality,
            loss,
            tear,
        }
    }
}

/// The JPEG standard's luma and chroma quantisation tables (Annex K), row by row.
const JPEG_LUMA: [f32; 64] = [
    16., 11., 10., 16., 24., 40., 51., 61., 12., 12., 14., 19., 26., 58., 60., 55., 14., 13., 16.,
    24., 40., 57., 69., 56., 14., 17., 22., 29., 51., 87., 80., 62., 18., 22., 37., 56., 68., 109.,
    103., 77., 24., 35., 55., 64., 81., 104., 113., 92., 49., 64., 78., 87., 103., 121., 120.,
    101., 72., 92., 95., 98., 112., 100., 103., 99.,
];
const JPEG_CHROMA: [f32; 64] = [
    17., 18., 24., 47., 99., 99., 99., 99., 18., 21., 26., 66., 99., 99., 99., 99., 24., 26., 56.,
    99., 99., 99., 99., 99., 47., 66., 99., 99., 99., 99., 99., 99., 99., 99., 99., 99., 99., 99.,
    99., 99., 99., 99., 99., 99., 99., 99., 99., 99., 99., 99., 99., 99., 99., 99., 99., 99., 99.,
    99., 99., 99., 99., 99., 99., 99.,
];

/// An 8×8 block (row by row) through the DCT, quantised by `table` × `factor`, and back.
fn dct_quantise(block: &mut [f32; 64], table: &[f32; 64], factor: f32) {
    let basis: [[f32; 8]; 8] = std::array::from_fn(|k| {
        std::array::from_fn(|n| {
            let a = if k == 0 { (1.0f32 / 8.0).sqrt() } else { 0.5 };
            a * ((2 * n + 1) as f32 * k as f32 * std::f32::consts::PI / 16.0).cos()
        })
    });
    let mut coefficients = [0f32; 64];
    for v in 0..8 {
        for u in 0..8 {
            let mut s = 0.0;
            for y in 0..8 {
                for x in 0..8 {
                    s += basis[v][y] * basis[u][x] * block[y * 8 + x];
                }
            }
            let q = (table[v * 8 + u] * factor).max(1.0);
            coefficients[v * 8 + u] = (s / q).round() * q;
        }
    }
    for y in 0..8 {
        for x in 0..8 {
            let mut s = 0.0;
            for v in 0..8 {
                for u in 0..8 {
                    s += basis[v][y] * basis[u][x] * coefficients[v * 8 + u];
                }
            }
            block[y * 8 + x] = s;
        }
    }
}

/// A digital video link on an sRGB frame: YCbCr (BT.601), the chroma averaged over 2×2
/// pixels (4:2:0), every 8×8 block of each plane through the DCT quantised with the JPEG
/// tables at `link.quality`, chroma replicated back; then lost 16×16 macroblocks concealed by
/// repeating the one above (or to the left on the top row), and the torn band shifted
/// sideways.
#[allow(clippy::needless_range_loop)] // block, row and column indices, as in a codec
fn video_link(pixels: &mut [[f32; 3]], w: usize, h: usize, link: &VideoLink, rng: &mut Rng) {
    let factor = if link.quality < 50.0 {
        50.0 / link.quality
    } else {
        (200.0 - 2.0 * link.quality) / 100.0
    };
    let (cw, ch) = (w.div_ceil(2), h.div_ceil(2));
    let mut luma = vec![0f32; w * h];
    let mut chroma = [vec![0f32; cw * ch], vec![0f32; cw * ch]];
    for (i, p) in pixels.iter().enumerate() {
        let [r, g, b] = *p;
        let y = 0.299 * r + 0.587 * g + 0.114 * b;
        luma[i] = y;
        let (x, row) = (i % w, i / w);
        let c = (row / 2) * cw + x / 2;
        chroma[0][c] += 0.25 * (0.564 * (b - y));
        chroma[1][c] += 0.25 * (0.713 * (r - y));
    }
    let code = |plane: &mut [f32], pw: usize, ph: usize, table: &[f32; 64]| {
        for by in 0..ph / 8 {
            for bx in 0..pw / 8 {
                let mut block = [0f32; 64];
                for y in 0..8 {
                    for x in 0..8 {
                        block[y * 8 + x] = plane[(by * 8 + y) * pw + bx * 8 + x] - 128.0;
                    }
                }
                dct_quantise(&mut block, table, factor);
                for y in 0..8 {
                    for x in 0..8 {
                        plane[(by * 8 + y) * pw + bx * 8 + x] = block[y * 8 + x] + 128.0;
                    }
                }
            }
        }
    };
    code(&mut luma, w, h, &JPEG_LUMA);
    for plane in chroma.iter_mut() {
        for v in plane.iter_mut() {
            *v += 128.0;
        }
        code(plane, cw, ch, &JPEG_CHROMA);
        for v in plane.iter_mut() {
            *v -= 128.0;
        }
    }
    for (i, p) in pixels.iter_mut().enumerate() {
        let (x, row) = (i % w, i / w);
        let c = (row / 2) * cw + x / 2;
        let (y, cb, cr) = (luma[i], chroma[0][c], chroma[1][c]);
        *p = [y + 1.403 * cr, y - 0.344 * cb - 0.714 * cr, y + 1.773 * cb];
    }
    for my in 0..h / 16 {
        for mx in 0..w / 16 {
            if rng.uniform() >= link.loss || (my == 0 && mx == 0) {
                continue;
            }
            let (sx, sy) = if my > 0 { (mx, my - 1) } else { (mx - 1, my) };
            for y in 0..16 {
                for x in 0..16 {
                    pixels[(my * 16 + y) * w + mx * 16 + x] =
                        pixels[(sy * 16 + y) * w + sx * 16 + x];
                }
            }
        }
    }
    if let Some((first, rows, shift)) = link.tear
        && h >= 16
    {
        let first = first % (h / 16);
        for y in first * 16..((first + rows) * 16).min(h) {
            let line: Vec<[f32; 3]> = pixels[y * w..(y + 1) * w].to_vec();
            for (x, p) in pixels[y * w..(y + 1) * w].iter_mut().enumerate() {
                *p = line[(x as isize - shift).clamp(0, w as isize - 1) as usize];
            }
        }
    }
}

/// The `tree-line` world beyond the fields: a ridge `distance_m` away, its crest crowned by
/// woods, hedges and buildings, held as the height of the silhouette's top above the camera
/// (m) at each azimuth. A tree 10–25 m high 1.2–5 km away is 1–8 px at 480 px over 60°.
///
/// Truth: the level horizon (the trajectory's attitude, as in every set). A labeller of
/// real video clicks the visible sky/ground boundary, which on such a skyline is a line
/// through an irregular silhouette, neither the tree tops nor the gaps. The heights are
/// shifted so that their mean over the full circle is zero: the silhouette's mean top lies
/// on the level horizon, its tops above and its gaps below, and the line fitted through
/// the visible boundary is the level horizon to within about ±0.3° over one view (the
/// hills' ±0.1–0.2° and how woods and fields fall in it). The base of the trees is not visible (the ridge behind them is as dark), so the
/// base is no candidate for the truth.
struct Skyline {
    distance_m: f32,
    heights: Vec<f32>,
    haze: Haze,
    sun_azimuth: f32,
    /// 0: a clear blue sky; towards 1: hazy or overcast white.
    whiteness: f32,
    /// Share of the sky under cloud.
    cloud_cover: f32,
}

/// Azimuth bins of the skyline: about half a metre each at 5 km.
const SKYLINE_BINS: usize = 1 << 16;

impl Skyline {
    fn new(seed: u64) -> Self {
        let mut rng = Rng::new(seed ^ 0x7EE5_11E5);
        let distance_m = rng.range(1200.0, 5000.0);
        let circumference = std::f32::consts::TAU * distance_m;
        let metres_per_bin = circumference / SKYLINE_BINS as f32;
        let mut heights = vec![0f32; SKYLINE_BINS];
        // Stamps `profile(d)` (height at `d` metres from `centre`, or None outside) as the
        // upper envelope, so that crowns overlap as real ones do.
        let mut stamp = |centre: f32, half_width: f32, profile: &dyn Fn(f32) -> f32| {
            let first = ((centre - half_width) / metres_per_bin).floor() as i64;
            let last = ((centre + half_width) / metres_per_bin).ceil() as i64;
            for bin in first..=last {
                let d = bin as f32 * metres_per_bin - centre;
                if d.abs() > half_width {
                    continue;
                }
                let slot = &mut heights[bin.rem_euclid(SKYLINE_BINS as i64) as usize];
                *slot = slot.max(profile(d));
            }
        };
        let mut at = 0.0;
        while at < circumference {
            let kind = rng.uniform();
            let length = if kind < 0.45 {
                // Woods: round crowns of 3–7 m radius, a canopy 12–24 m high.
                let length = rng.range(40.0, 500.0);
                let canopy = rng.range(12.0, 24.0);
                let mut x = at;
                while x < at + length {
                    let radius = rng.range(3.0, 7.0);
                    let top = canopy + rng.range(-4.0, 4.0);
                    stamp(x + radius, radius, &|d: f32| {
                        top - radius + radius * (1.0 - (d / radius).powi(2)).max(0.0).sqrt()
                    });
                    x += radius * rng.range(1.2, 2.2);
                }
                length
            } else if kind < 0.65 {
                // A hedge 2–4 m high with a tree standing out of it now and then.
                let length = rng.range(50.0, 300.0);
                let hedge = rng.range(2.0, 4.0);
                stamp(at + 0.5 * length, 0.5 * length, &|_| hedge);
                let mut x = at + rng.range(10.0, 60.0);
                while x < at + length {
                    let radius = rng.range(3.0, 6.0);
                    let top = rng.range(10.0, 20.0);
                    stamp(x, radius, &|d: f32| {
                        top - radius + radius * (1.0 - (d / radius).powi(2)).max(0.0).sqrt()
                    });
                    x += rng.range(20.0, 80.0);
                }
                length
            } else if kind < 0.75 {
                // A farm or village: flat-topped blocks 8–30 m wide, 5–14 m high.
                let length = rng.range(20.0, 120.0);
                let mut x = at;
                while x < at + length {
                    let width = rng.range(8.0, 30.0);
                    let top = rng.range(5.0, 14.0);
                    stamp(x + 0.5 * width, 0.5 * width, &|_| top);
                    x += width + rng.range(2.0, 20.0);
                }
                length
            } else {
                // Open fields: the bare crest.
                rng.range(20.0, 400.0)
            };
            at += length;
        }
        // Low hills under it all, over a kilometre or two, periodic around the circle: ±0.1–0.2°
        // seen from the camera, so that one view's skyline stays on the level horizon within
        // about that.
        let hills = distance_m * rng.range(0.1, 0.2).to_radians();
        let hill_seed = rng.next_u64();
        let loops = circumference / (std::f32::consts::TAU * 800.0);
        for (bin, h) in heights.iter_mut().enumerate() {
            let angle = bin as f32 / SKYLINE_BINS as f32 * std::f32::consts::TAU;
            let n = value_noise(hill_seed, loops * angle.cos(), loops * angle.sin());
            *h += hills * 2.0 * (n - 0.5);
        }
        let mean = heights.iter().sum::<f32>() / SKYLINE_BINS as f32;
        for h in heights.iter_mut() {
            *h -= mean;
        }
        let visibility = rng.range(3000.0, 6000.0);
        Skyline {
            distance_m,
            heights,
            haze: Haze {
                distance_m: visibility,
                colour: [172.0, 184.0, 198.0],
                linear: false,
            },
            sun_azimuth: rng.range(0.0, std::f32::consts::TAU),
            whiteness: rng.range(0.0, 0.8),
            cloud_cover: rng.range(0.15, 0.5),
        }
    }

    /// Height of the silhouette's top above the camera (m) at `azimuth` (rad from north).
    fn height_at(&self, azimuth: f32) -> f32 {
        let bin = (azimuth / std::f32::consts::TAU * SKYLINE_BINS as f32).floor() as i64;
        self.heights[bin.rem_euclid(SKYLINE_BINS as i64) as usize]
    }

    /// The colour along the world ray `(wn, we, wd)` from the camera at `north`, `east`:
    /// fields and lakes up to the ridge, the ridge and its silhouette, or the sky.
    fn shade(&self, world: u64, north: f32, east: f32, (wn, we, wd): (f32, f32, f32)) -> [f32; 3] {
        let horizontal = (wn * wn + we * we).sqrt().max(1e-6);
        let length = (horizontal * horizontal + wd * wd).sqrt();
        let rise = -wd / horizontal;
        let azimuth = we.atan2(wn);
        if wd > 0.0 {
            let t = ALTITUDE_M / wd;
            if t * horizontal < self.distance_m {
                let (gn, ge) = (north + t * wn, east + t * we);
                return field_or_lake(world, gn, ge, t * length, self.haze);
            }
        }
        let along = azimuth * self.distance_m;
        if rise < self.height_at(azimuth) / self.distance_m {
            // Woods in shade, some texture, faded by the distance.
            let up = rise * self.distance_m;
            let texture = (fbm(world ^ 0x7EE, along / 5.0, up / 5.0, 2) - 0.5) * 30.0;
            let k = 1.0 - (-self.distance_m / self.haze.distance_m).exp();
            let forest = [40.0, 54.0, 34.0];
            return std::array::from_fn(|i| {
                (forest[i] + texture) * (1.0 - k) + self.haze.colour[i] * k
            });
        }
        let elevation = (-wd / length).clamp(0.0, 1.0);
        let overcast = [228.0, 230.0, 234.0];
        let mut c = sky_colour(elevation);
        for (channel, white) in c.iter_mut().zip(overcast) {
            *channel += (white - *channel) * self.whiteness;
        }
        // The sun 35° up, out of view: the sky around its azimuth is brighter and warmer.
        let sun = [
            35f32.to_radians().cos() * self.sun_azimuth.cos(),
            35f32.to_radians().cos() * self.sun_azimuth.sin(),
            -35f32.to_radians().sin(),
        ];
        let cosine = (sun[0] * wn + sun[1] * we + sun[2] * wd) / length;
        let angle = cosine.clamp(-1.0, 1.0).acos();
        let glow = 45.0 * (-angle / 0.5).exp() + 20.0 * (-angle / 1.5).exp();
        for (channel, warm) in c.iter_mut().zip([1.0, 0.93, 0.8]) {
            *channel += glow * warm;
        }
        // Broken cloud down to the horizon (fading over 40 km, not 20: a cloud bank low on
        // the skyline is what real horizons often have).
        if wd < -1e-3 {
            let t = CLOUD_BASE_M / -wd;
            let (cn, ce) = (north + t * wn, east + t * we);
            let density = fbm(world ^ 0xC10D, cn / 700.0, ce / 700.0, 4);
            let cover = ((density - (1.0 - self.cloud_cover)) * 6.0).clamp(0.0, 1.0);
            let fade = (-(t * length) / 40_000.0).exp();
            let grey = 175.0 + 70.0 * fbm(world ^ 0x5AD, cn / 150.0, ce / 150.0, 2);
            let k = cover * fade;
            for channel in c.iter_mut() {
                *channel = *channel * (1.0 - k) + grey * k;
            }
        }
        c
    }
}

/// The `tree-line` fields: [`ground_colour`]'s fields, with one field in ten a lake that
/// mirrors the sky (darker than it, lightly rippled).
fn field_or_lake(world: u64, north: f32, east: f32, distance: f32, haze: Haze) -> [f32; 3] {
    let (fi, fj) = ((north / 80.0).floor() as i64, (east / 80.0).floor() as i64);
    if lattice(world ^ 0x1A4E, fi, fj) < 0.1 {
        let ripple = (fbm(world ^ 0x217, north / 3.0, east / 3.0, 2) - 0.5) * 20.0;
        let water = sky_colour(0.05).map(|c| 0.8 * c + ripple);
        let k = 1.0 - (-distance / haze.distance_m).exp();
        return std::array::from_fn(|i| water[i] * (1.0 - k) + haze.colour[i] * k);
    }
    ground_colour(world, north, east, distance, false, haze)
}

/// An ordinary video camera: vignetting (the corners 15–35 % darker), auto-exposure bringing
/// the frame's mean to 105–150 (a bright sky may clip), mild sensor noise (σ 1.5–4 levels), 8-bit clipping and
/// JPEG-like compression at quality 50–85 ([`video_link`] with nothing lost).
fn consumer_camera(pixels: &mut [[f32; 3]], w: usize, h: usize, rng: &mut Rng) {
    let vignetting = rng.range(0.15, 0.35);
    let (cx, cy) = (0.5 * w as f32, 0.5 * h as f32);
    let corner2 = cx * cx + cy * cy;
    for (i, p) in pixels.iter_mut().enumerate() {
        let (dx, dy) = ((i % w) as f32 + 0.5 - cx, (i / w) as f32 + 0.5 - cy);
        let k = 1.0 - vignetting * (dx * dx + dy * dy) / corner2;
        for c in p.iter_mut() {
            *c *= k;
        }
    }
    let mean = pixels
        .iter()
        .map(|p| 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2])
        .sum::<f32>()
        / pixels.len().max(1) as f32;
    let gain = (rng.range(105.0, 150.0) / mean.max(1.0)).clamp(0.6, 1.6);
    let sigma = rng.range(1.5, 4.0);
    for p in pixels.iter_mut() {
        for c in p.iter_mut() {
            *c = (*c * gain + sigma * rng.normal()).round().clamp(0.0, 255.0);
        }
    }
    let quality = rng.range(50.0, 85.0);
    let codec = VideoLink {
        quality,
        loss: 0.0,
        tear: None,
    };
    video_link(pixels, w, h, &codec, rng);
    for c in pixels.iter_mut().flatten() {
        *c = c.round().clamp(0.0, 255.0);
    }
}

/// The lens: a separable [1 2 1]/4 blur (no real lens draws a one-pixel-sharp edge).
fn blur_121(pixels: &mut [[f32; 3]], width: usize, height: usize) {
    let mut copy = pixels.to_vec();
    for (pass, (step, count, length)) in [(1, height, width), (width, width, height)]
        .into_iter()
        .enumerate()
    {
        let source: &[[f32; 3]] = if pass == 0 { pixels } else { &copy };
        let mut out = source.to_vec();
        for line in 0..count {
            let base = if pass == 0 { line * width } else { line };
            for i in 0..length {
                let at = |k: usize| source[base + k.min(length - 1) * step];
                let (a, b, c) = (at(i.saturating_sub(1)), at(i), at(i + 1));
                for ch in 0..3 {
                    out[base + i * step][ch] = 0.25 * a[ch] + 0.5 * b[ch] + 0.25 * c[ch];
                }
            }
        }
        if pass == 0 {
            copy = out;
        } else {
            pixels.copy_from_slice(&out);
        }
    }
}

fn sky_colour(elevation: f32) -> [f32; 3] {
    let horizon = [200.0, 214.0, 232.0];
    let zenith = [80.0, 130.0, 210.0];
    let t = elevation.sqrt();
    std::array::from_fn(|i| horizon[i] + (zenith[i] - horizon[i]) * t)
}

/// Haze on the ground: the distance over which it thickens (1 − e⁻¹) and its colour.
#[derive(Clone, Copy)]
struct Haze {
    distance_m: f32,
    colour: [f32; 3],
    /// Extinction and airlight added as radiance (linear light), as light does, rather than
    /// blended in 8-bit values.
    linear: bool,
}

impl Haze {
    const NORMAL: Haze = Haze {
        distance_m: 2500.0,
        colour: [150.0, 160.0, 170.0],
        linear: false,
    };
    /// The `ground-edge` and `coast` worlds': the far ground 12–16 levels darker than the
    /// sky at the horizon.
    const NEAR_SKY: Haze = Haze {
        distance_m: 1800.0,
        colour: [188.0, 200.0, 216.0],
        linear: false,
    };
}

/// An 8-bit sRGB value (0–255, not clamped) to linear light (0–1).
fn srgb_decode(value: f32) -> f32 {
    let v = value.max(0.0) / 255.0;
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear light (0–1) to an 8-bit sRGB value (0–255, not clamped).
fn srgb_encode(linear: f32) -> f32 {
    let l = linear.max(0.0);
    255.0
        * if l <= 0.003_130_8 {
            12.92 * l
        } else {
            1.055 * l.powf(1.0 / 2.4) - 0.055
        }
}

/// Fields (patches with their own colour), fine texture, optionally roads and strong field
/// edges; distant ground fades into haze (which is what makes real horizons low-contrast).
fn ground_colour(
    world: u64,
    north: f32,
    east: f32,
    distance: f32,
    roads: bool,
    haze: Haze,
) -> [f32; 3] {
    const PALETTE: [[f32; 3]; 5] = [
        [78.0, 110.0, 52.0],
        [96.0, 120.0, 60.0],
        [120.0, 108.0, 70.0],
        [70.0, 96.0, 48.0],
        [140.0, 132.0, 80.0],
    ];
    let field_size = 80.0;
    let (fi, fj) = (
        (north / field_size).floor() as i64,
        (east / field_size).floor() as i64,
    );
    let pick = lattice(world ^ 0xF1E1D, fi, fj);
    let mut c = PALETTE[((pick * PALETTE.len() as f32) as usize).min(PALETTE.len() - 1)];
    if roads {
        // Stronger field contrast (ploughed, harvested, green) and dark hedges on the edges.
        let boost = (pick - 0.5) * 90.0;
        for ch in c.iter_mut() {
            *ch += boost;
        }
        let (dn, de) = (
            (north - fi as f32 * field_size).min((fi + 1) as f32 * field_size - north),
            (east - fj as f32 * field_size).min((fj + 1) as f32 * field_size - east),
        );
        if dn.min(de) < 2.0 {
            c = [40.0, 55.0, 30.0];
        }
        // A straight bright road across the heading, another diagonal, a dark one.
        if (north - 400.0 * (north / 400.0).round()).abs() < 4.0 {
            c = [185.0, 185.0, 180.0];
        }
        if (east - 0.4 * north - 150.0).abs() % 600.0 < 5.0 {
            c = [175.0, 170.0, 160.0];
        }
        if (east + 0.7 * north).rem_euclid(500.0) < 6.0 {
            c = [50.0, 50.0, 55.0];
        }
    }
    let texture = (fbm(world ^ 0x7E7, north / 6.0, east / 6.0, 3) - 0.5) * 40.0;
    hazed(c.map(|b| b + texture), distance, haze)
}

/// The `ground-edge` world: dark woodland up to a straight line, light fields beyond it that
/// fade into a haze nearly as bright as the sky at the horizon, so the horizon is a step of
/// 10–30 levels and the woodland's edge one of about 100.
fn edge_field_colour(world: u64, north: f32, east: f32, distance: f32, near: bool) -> [f32; 3] {
    let texture = (fbm(world ^ 0x7E7, north / 6.0, east / 6.0, 3) - 0.5) * 40.0;
    let base = if near {
        [42.0, 58.0, 34.0]
    } else {
        let pick = lattice(world ^ 0xF1E1D, (north / 80.0) as i64, (east / 80.0) as i64);
        [
            150.0 + 30.0 * pick,
            152.0 + 25.0 * pick,
            118.0 + 20.0 * pick,
        ]
    };
    hazed(base.map(|b| b + texture), distance, Haze::NEAR_SKY)
}

/// The `coast` world in one frame: a shoreline square to `normal` (north, east) at `distance`
/// metres ahead of the airplane along it.
struct Coast {
    normal: (f32, f32),
    distance: f32,
    /// The sea lies beyond the shoreline (the horizon is the sea's), else on the airplane's
    /// side of it.
    sea_beyond: bool,
    /// The width of the sand between the fields and the sea (none: the fields reach the water).
    beach_m: f32,
    /// A calm sea mirroring the sky rather than the dark blue water of `coast`.
    mirror: bool,
}

impl Coast {
    /// The colour of the ground at `offset` (north, east) from the airplane at `airplane`,
    /// `distance` metres along the ray.
    fn colour(
        &self,
        world: u64,
        airplane: (f32, f32),
        offset: (f32, f32),
        distance: f32,
    ) -> [f32; 3] {
        let (gn, ge) = (airplane.0 + offset.0, airplane.1 + offset.1);
        let ahead = offset.0 * self.normal.0 + offset.1 * self.normal.1;
        // Bays and headlands fixed to the ground, up to an eighth of the distance either way.
        let along_shore = ge * self.normal.0 - gn * self.normal.1;
        let bays = 0.25 * self.distance * (fbm(world ^ 0xC0A5, along_shore / 300.0, 0.5, 3) - 0.5);
        let beyond = ahead - (self.distance + bays);
        let seaward = if self.sea_beyond { beyond } else { -beyond };
        if seaward < 0.0 && seaward > -self.beach_m {
            let sand = (fbm(world ^ 0x5A4D, gn / 3.0, ge / 3.0, 2) - 0.5) * 20.0;
            return hazed(
                [196.0 + sand, 186.0 + sand, 150.0 + sand],
                distance,
                Haze::NEAR_SKY,
            );
        }
        if seaward < 0.0 {
            return ground_colour(world, gn, ge, distance, true, Haze::NEAR_SKY);
        }
        if self.mirror {
            // The ray meets the water at incidence cos i = altitude / distance and sees the
            // sky at that elevation; mixed with the dark water body as light mixes (linear).
            let cos_i = (ALTITUDE_M / distance.max(ALTITUDE_M)).clamp(0.0, 1.0);
            let fresnel = 0.02 + 0.98 * (1.0 - cos_i).powi(5);
            let ripple = 1.0 + 0.12 * (fbm(world ^ 0x5EB, gn / 6.0, ge / 15.0, 2) - 0.5);
            let sky = sky_colour(cos_i);
            let water = [14.0, 26.0, 34.0];
            let sea: [f32; 3] = std::array::from_fn(|i| {
                srgb_encode(
                    ripple
                        * (fresnel * srgb_decode(sky[i]) + (1.0 - fresnel) * srgb_decode(water[i])),
                )
            });
            return hazed(sea, distance, Haze::NEAR_SKY);
        }
        let waves = (fbm(world ^ 0x5EA, gn / 4.0, ge / 9.0, 2) - 0.5) * 14.0;
        hazed(
            [36.0 + waves, 60.0 + waves, 86.0 + waves],
            distance,
            Haze::NEAR_SKY,
        )
    }
}

/// `colour` seen through `distance` metres of `haze`: the haze's share grows as
/// 1 − e^(−distance / its distance), blended in 8-bit values or as radiance.
fn hazed(colour: [f32; 3], distance: f32, haze: Haze) -> [f32; 3] {
    let k = 1.0 - (-distance / haze.distance_m).exp();
    if haze.linear {
        return std::array::from_fn(|i| {
            srgb_encode(srgb_decode(colour[i]) * (1.0 - k) + srgb_decode(haze.colour[i]) * k)
        });
    }
    std::array::from_fn(|i| colour[i] * (1.0 - k) + haze.colour[i] * k)
}

/// A sinusoid of period 5–30 px (at 320 px) and amplitude 10–40 levels whose crests run at
/// `angle` to the rows (within ±70° for `interference`; near the horizon's own direction is
/// the hard case),
/// drifting by a random phase every frame, plus a hum bar: a third of the frame brighter by
/// up to 30 levels, its raised-cosine profile moving down the frame.
fn interference(
    pixels: &mut [[f32; 3]],
    w: usize,
    h: usize,
    index: usize,
    angle: f32,
    rng: &mut Rng,
) {
    let scale = w as f32 / 320.0;
    let period = rng.range(5.0, 30.0) * scale;
    let amplitude = rng.range(10.0, 40.0);
    let phase = rng.range(0.0, std::f32::consts::TAU);
    let (ku, kv) = (
        -angle.sin() * std::f32::consts::TAU / period,
        angle.cos() * std::f32::consts::TAU / period,
    );
    let bar = rng.range(0.0, 30.0);
    let bar_centre = ((index as f32 * 0.13 + rng.range(0.0, 0.05)) % 1.3 - 0.15) * h as f32;
    let bar_half = h as f32 / 6.0;
    for (i, p) in pixels.iter_mut().enumerate() {
        let (u, v) = ((i % w) as f32, (i / w) as f32);
        let wave = amplitude * (ku * u + kv * v + phase).sin();
        let d = (v - bar_centre) / bar_half;
        let hum = if d.abs() < 1.0 {
            bar * 0.5 * (1.0 + (d * std::f32::consts::PI).cos())
        } else {
            0.0
        };
        for c in p.iter_mut() {
            *c += wave + hum;
        }
    }
}

/// The `hazy-interference` camera and link, on a frame of 8-bit sRGB values. In linear light:
/// a motion blur of 0–3 px (at 320 px) along a random direction, vignetting (the corners
/// 10–35 % darker), an exposure putting the horizon's sky at 55–95 % of full scale, shot
/// noise and 4–12 electrons of read noise over a full well of 2000–12000, clipping, then the
/// sRGB curve. The interference is drawn every frame (so that the rest of the frame is the
/// same with it or without it, see the tests) and added to the analogue signal in half of
/// the frames before the gamma (as radiance, where it is clipped with the scene), in the
/// others after it: a sinusoid whose crests run at any angle to the horizon's image direction
/// (a third of the frames within ±8° of it), period 3 px to half the frame's height
/// (log-uniform), amplitude 3–22 levels; and in three frames of five a hum bar a fifth to half
/// of the frame high, 4–25 levels brighter or darker at its middle, rolling down.
fn analogue_camera(
    pixels: &mut [[f32; 3]],
    w: usize,
    h: usize,
    index: usize,
    roll: f32,
    rng: &mut Rng,
    with_interference: bool,
) {
    let scale = w as f32 / 320.0;
    // Motion blur: the mean of samples along a short segment (rounded to whole pixels).
    let blur_length = rng.range(0.0, 3.0) * scale;
    let blur_angle = rng.range(0.0, std::f32::consts::PI);
    let taps = (blur_length.ceil() as usize).max(1) + 1;
    let mut linear: Vec<[f32; 3]> = pixels
        .iter()
        .map(|p| p.map(srgb_decode))
        .collect::<Vec<_>>();
    if blur_length >= 0.5 {
        let source = linear.clone();
        let (du, dv) = (blur_angle.cos(), blur_angle.sin());
        for (i, out) in linear.iter_mut().enumerate() {
            let (u, v) = ((i % w) as f32, (i / w) as f32);
            let mut sum = [0.0f32; 3];
            for t in 0..taps {
                let along = blur_length * (t as f32 / (taps - 1) as f32 - 0.5);
                let su = (u + along * du).round().clamp(0.0, w as f32 - 1.0) as usize;
                let sv = (v + along * dv).round().clamp(0.0, h as f32 - 1.0) as usize;
                for (s, c) in sum.iter_mut().zip(source[sv * w + su]) {
                    *s += c / taps as f32;
                }
            }
            *out = sum;
        }
    }
    let vignetting = rng.range(0.10, 0.35);
    let exposure = rng.range(0.55, 0.95) / srgb_decode(sky_colour(0.0)[2]);
    let full_well = rng.range(2000.0, 12000.0);
    let read_noise = rng.range(4.0, 12.0);
    // The interference, in 8-bit levels at the level of the horizon's sky.
    let near_parallel = rng.uniform() < 1.0 / 3.0;
    let relative = if near_parallel {
        rng.range(-8.0, 8.0)
    } else {
        rng.range(-90.0, 90.0)
    };
    let angle = -roll + relative.to_radians();
    let period = (rng.range((3.0 * scale).ln(), (0.5 * h as f32).ln())).exp();
    let amplitude = rng.range(3.0, 22.0);
    let phase = rng.range(0.0, std::f32::consts::TAU);
    let before_gamma = rng.uniform() < 0.5;
    let hum = if rng.uniform() < 0.6 {
        let sign = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
        let strength = sign * rng.range(4.0, 25.0);
        let half = rng.range(0.1, 0.25) * h as f32;
        let centre = ((index as f32 * 0.09 + rng.range(0.0, 1.4)) % 1.4 - 0.2) * h as f32;
        Some((strength, half, centre))
    } else {
        None
    };
    let (ku, kv) = (
        -angle.sin() * std::f32::consts::TAU / period,
        angle.cos() * std::f32::consts::TAU / period,
    );
    let signal = |i: usize| -> f32 {
        if !with_interference {
            return 0.0;
        }
        let (u, v) = ((i % w) as f32, (i / w) as f32);
        let bar = hum.map_or(0.0, |(strength, half, centre)| {
            let d = (v - centre) / half;
            if d.abs() < 1.0 {
                strength * 0.5 * (1.0 + (d * std::f32::consts::PI).cos())
            } else {
                0.0
            }
        });
        amplitude * (ku * u + kv * v + phase).sin() + bar
    };
    // Levels to radiance at the horizon sky's brightness (the sRGB curve's slope there).
    let sky_linear = 0.75;
    let levels_per_linear = srgb_encode(sky_linear + 0.01) - srgb_encode(sky_linear - 0.01);
    let linear_per_level = 0.02 / levels_per_linear;
    let (cx, cy) = (0.5 * w as f32, 0.5 * h as f32);
    let corner2 = cx * cx + cy * cy;
    for (i, (p, l)) in pixels.iter_mut().zip(&linear).enumerate() {
        let (u, v) = ((i % w) as f32 - cx, (i / w) as f32 - cy);
        let gain = exposure * (1.0 - vignetting * (u * u + v * v) / corner2);
        let added = signal(i);
        for (c, &radiance) in p.iter_mut().zip(l) {
            let mut x = radiance * gain;
            if before_gamma {
                x += added * linear_per_level;
            }
            let electrons = x.max(0.0) * full_well;
            let read = electrons + electrons.sqrt() * rng.normal() + read_noise * rng.normal();
            let mut out = srgb_encode((read / full_well).clamp(0.0, 1.0));
            if !before_gamma {
                out += added;
            }
            *c = out;
        }
    }
}

/// Each 8×8 block of each channel keeps its mean and its horizontal and vertical ramps, each
/// quantised to a step of 6–24 levels (a coarse DCT keeps about that much); 2–8 % of the 16×16
/// macroblocks are lost and concealed by repeating the macroblock to their left (or mid-grey
/// in the first column); one frame in three has a row of blocks torn sideways by 8–32 px.
#[allow(clippy::needless_range_loop)] // block, row, column and channel indices, as in a codec
fn blocks(pixels: &mut [[f32; 3]], w: usize, h: usize, rng: &mut Rng) {
    let q = rng.range(6.0, 24.0);
    let quantise = |x: f32| (x / q).round() * q;
    // Ramp basis over a block: (i − 3.5) for i in 0..8, Σ(i − 3.5)² = 42 per row, 8 rows.
    for by in 0..h / 8 {
        for bx in 0..w / 8 {
            for c in 0..3 {
                let (mut sum, mut sx, mut sy) = (0.0f32, 0.0f32, 0.0f32);
                for y in 0..8 {
                    for x in 0..8 {
                        let p = pixels[(by * 8 + y) * w + bx * 8 + x][c];
                        sum += p;
                        sx += (x as f32 - 3.5) * p;
                        sy += (y as f32 - 3.5) * p;
                    }
                }
                let mean = quantise(sum / 64.0);
                // The ramps as the change across the block (7 px), quantised.
                let gx = quantise(sx / 336.0 * 7.0) / 7.0;
                let gy = quantise(sy / 336.0 * 7.0) / 7.0;
                for y in 0..8 {
                    for x in 0..8 {
                        pixels[(by * 8 + y) * w + bx * 8 + x][c] =
                            mean + gx * (x as f32 - 3.5) + gy * (y as f32 - 3.5);
                    }
                }
            }
        }
    }
    let loss = rng.range(0.02, 0.08);
    for my in 0..h / 16 {
        for mx in 0..w / 16 {
            if rng.uniform() >= loss {
                continue;
            }
            for y in my * 16..my * 16 + 16 {
                for x in mx * 16..mx * 16 + 16 {
                    pixels[y * w + x] = if mx > 0 {
                        pixels[y * w + x - 16]
                    } else {
                        [128.0; 3]
                    };
                }
            }
        }
    }
    if rng.uniform() < 1.0 / 3.0 && h >= 8 {
        let row = (rng.uniform() * (h / 8) as f32) as usize % (h / 8);
        let shift = 8 * (1 + (rng.uniform() * 4.0) as usize);
        for y in row * 8..(row * 8 + 8).min(h) {
            let line: Vec<[f32; 3]> = pixels[y * w..(y + 1) * w].to_vec();
            for (x, p) in pixels[y * w..(y + 1) * w].iter_mut().enumerate() {
                *p = line[x.saturating_sub(shift)];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Mean luma of the pixels whose distance from the true horizon (px, ground side
    /// positive) lies in `[from, to)`.
    fn band_luma(image: &Image, camera: &Camera, truth: &Truth, from: f32, to: f32) -> f32 {
        let (roll, pitch) = (truth.roll_deg.to_radians(), truth.pitch_deg.to_radians());
        let (s, c, o) = (roll.sin(), roll.cos(), pitch.tan());
        let (mut sum, mut n) = (0.0f64, 0u32);
        for v in 0..image.height {
            for u in 0..image.width {
                let Some((x, y)) = camera.undistort_pixel(u as f32, v as f32) else {
                    continue;
                };
                let d = (s * x + c * y - o) * camera.fy;
                if (from..to).contains(&d) {
                    let p = &image.data[(v * image.width + u) * 3..][..3];
                    sum +=
                        0.299 * f64::from(p[0]) + 0.587 * f64::from(p[1]) + 0.114 * f64::from(p[2]);
                    n += 1;
                }
            }
        }
        assert!(n > 100, "band {from}..{to}: {n} pixels");
        (sum / f64::from(n)) as f32
    }

    /// The hazy horizon is a small step over a long ramp under a sky glowing towards it, and
    /// the interference is really there: the same frame rendered without it (the same noise)
    /// differs by a pattern of several levels.
    #[test]
    fn hazy_interference_frames_hold_a_small_step_over_a_ramp_and_stripes() {
        let mut renderer = Renderer::new(Degradation::HazyInterference, 320, 240, 3);
        for index in 0..6 {
            renderer.with_interference = false;
            let (scene, truth) = renderer.render(index);
            renderer.with_interference = true;
            let (striped, _) = renderer.render(index);
            let camera = renderer.camera;
            let band = |from, to| band_luma(&scene, &camera, &truth, from, to);
            let (high_sky, sky, ground, far_ramp) = (
                band(-30.0, -20.0),
                band(-3.0, -1.0),
                band(1.0, 3.0),
                band(25.0, 35.0),
            );
            let step = sky - ground;
            assert!((2.0..40.0).contains(&step), "frame {index}: step {step}");
            assert!(
                sky - high_sky > 3.0,
                "frame {index}: no glow, {high_sky} → {sky}"
            );
            assert!(
                ground - far_ramp > 5.0,
                "frame {index}: no ramp, {ground} → {far_ramp}"
            );
            let differences: Vec<f32> = scene
                .data
                .iter()
                .zip(&striped.data)
                .map(|(&a, &b)| f32::from(b) - f32::from(a))
                .collect();
            let mean = differences.iter().sum::<f32>() / differences.len() as f32;
            let spread = (differences.iter().map(|d| (d - mean).powi(2)).sum::<f32>()
                / differences.len() as f32)
                .sqrt();
            assert!(
                spread > 1.5,
                "frame {index}: interference of {spread} levels"
            );
        }
    }

    fn mean_and_variance(values: impl Iterator<Item = f32> + Clone) -> (f32, f32) {
        let n = values.clone().count() as f32;
        let mean = values.clone().sum::<f32>() / n;
        let variance = values.map(|v| (v - mean) * (v - mean)).sum::<f32>() / n;
        (mean, variance)
    }

    /// `camera-noise` is what it claims: noise counted in electrons in linear light (its
    /// variance grows with the light, as shot noise does), an offset per row, colour noise
    /// shared by 2×2-pixel cells, clipping at the full well; and its horizon is a small step
    /// under the sky's glow.
    #[test]
    fn camera_noise_is_shot_read_row_and_chroma_noise_in_electrons() {
        let (w, h) = (320, 240);
        let camera = CameraNoise {
            exposure: 1.0,
            full_well: 200.0,
            read_noise: 3.0,
            row_noise: 2.0,
            chroma: 0.8,
            vignetting: 0.0,
            blur_px: 0.0,
            blur_angle: 0.0,
        };
        let electrons_of = |p: &[f32; 3]| p.map(|c| srgb_decode(c.min(255.0)) * camera.full_well);
        let mut by_level = Vec::new();
        for (level, seed) in [(60.0f32, 1u64), (200.0, 2)] {
            let mut pixels = vec![[level; 3]; w * h];
            camera_noise(&mut pixels, w, h, &camera, &mut Rng::new(seed));
            let green: Vec<f32> = pixels.iter().map(|p| electrons_of(p)[1]).collect();
            let (mean, variance) = mean_and_variance(green.iter().copied());
            by_level.push((mean, variance));
            // Row offsets: the rows' means spread more than w pixels' noise would, by about the
            // rows' own variance.
            let row_means: Vec<f32> = green
                .chunks_exact(w)
                .map(|row| row.iter().sum::<f32>() / w as f32)
                .collect();
            let (_, row_variance) = mean_and_variance(row_means.iter().copied());
            assert!(
                row_variance - variance / w as f32 > 0.5 * camera.row_noise.powi(2),
                "level {level}: rows vary {row_variance}, pixels {variance}"
            );
            // Chroma: red minus green is correlated within a 2×2 cell, not across cells.
            let chroma = |i: usize| {
                let e = electrons_of(&pixels[i]);
                e[0] - e[1]
            };
            let (mut same, mut across) = (0.0f32, 0.0f32);
            for v in (0..h).step_by(2) {
                for u in (0..w - 2).step_by(2) {
                    let i = v * w + u;
                    same += chroma(i) * chroma(i + 1);
                    across += chroma(i + 1) * chroma(i + 2);
                }
            }
            assert!(
                same > 0.2 * variance * (w * h / 4) as f32 && same > 3.0 * across.abs(),
                "level {level}: chroma correlation within cells {same}, across {across}"
            );
        }
        // Shot noise: the variance in electrons follows the light (Poisson), over the read
        // and row noise's constant floor.
        let [(dark_mean, dark_var), (bright_mean, bright_var)] = [by_level[0], by_level[1]];
        let floor = camera.read_noise.powi(2) + camera.row_noise.powi(2);
        let expected = (bright_mean + floor) / (dark_mean + floor);
        let ratio = bright_var / dark_var;
        assert!(
            (ratio / expected - 1.0).abs() < 0.35,
            "variance ratio {ratio}, shot noise gives {expected}"
        );
        // Clipping at the full well.
        let mut white = vec![[250.0f32; 3]; w * h];
        camera_noise(&mut white, w, h, &camera, &mut Rng::new(3));
        let clipped = white.iter().filter(|p| p[1] >= 254.5).count();
        assert!(clipped > w * h / 4, "{clipped} clipped");
        // The scene: airlight 8–30 levels under the sky's glow at the horizon.
        let sky = sky_colour(0.0);
        let mut rng = Rng::new(4);
        for _ in 0..50 {
            let haze = hazy_horizon(&mut rng);
            let step = sky[0] - haze.colour[0];
            assert!((8.0..=30.0).contains(&step), "step {step}");
            assert!((800.0..=3000.0).contains(&haze.distance_m));
        }
    }

    /// `video-link` is what it claims: 8×8 DCT blocks (the picture's jumps fall on the block
    /// grid), chroma shared by 2×2 pixels, lost macroblocks repeating the one above, and a
    /// torn band shifted sideways.
    #[test]
    fn video_link_is_dct_blocks_420_chroma_lost_macroblocks_and_tears() {
        let (w, h) = (320, 240);
        // A smooth diagonal gradient with colour: no edges of its own.
        let scene: Vec<[f32; 3]> = (0..w * h)
            .map(|i| {
                let (u, v) = ((i % w) as f32, (i / w) as f32);
                let t = 60.0 + 0.3 * u + 0.4 * v;
                [t, 0.8 * t + 20.0, 255.0 - t]
            })
            .collect();
        let coarse = VideoLink {
            quality: 15.0,
            loss: 0.0,
            tear: None,
        };
        let mut pixels = scene.clone();
        video_link(&mut pixels, w, h, &coarse, &mut Rng::new(1));
        let luma = |p: &[f32; 3]| 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
        let (mut on_grid, mut inside) = (0.0f32, 0.0f32);
        for v in 0..h {
            for u in 1..w {
                let jump = (luma(&pixels[v * w + u]) - luma(&pixels[v * w + u - 1])).abs();
                if u % 8 == 0 {
                    on_grid += jump;
                } else {
                    inside += jump / 7.0;
                }
            }
        }
        assert!(
            on_grid > 3.0 * inside,
            "jumps on the grid {on_grid}, inside {inside}"
        );
        // 4:2:0: the blue difference is the same over each 2×2 cell.
        for v in (0..h).step_by(2) {
            for u in (0..w).step_by(2) {
                let cb = |i: usize| pixels[i][2] - luma(&pixels[i]);
                let i = v * w + u;
                for j in [i + 1, i + w, i + w + 1] {
                    assert!((cb(i) - cb(j)).abs() < 0.05, "cell ({u}, {v})");
                }
            }
        }
        // Every macroblock lost: each one repeats the one above (the top row, the left one).
        let mut lost = scene.clone();
        let all_lost = VideoLink {
            quality: 40.0,
            loss: 1.0,
            tear: None,
        };
        video_link(&mut lost, w, h, &all_lost, &mut Rng::new(2));
        for v in 16..h {
            for u in 0..w {
                assert_eq!(lost[v * w + u], lost[(v - 16) * w + u], "({u}, {v})");
            }
        }
        // A tear: the band's rows shifted right by 16 px.
        let torn_link = VideoLink {
            quality: 40.0,
            loss: 0.0,
            tear: Some((3, 1, 16)),
        };
        let mut whole = scene.clone();
        video_link(&mut whole, w, h, &coarse_at(40.0), &mut Rng::new(3));
        let mut torn = scene;
        video_link(&mut torn, w, h, &torn_link, &mut Rng::new(3));
        for v in 48..64 {
            for u in 16..w {
                assert_eq!(torn[v * w + u], whole[v * w + u - 16], "({u}, {v})");
            }
        }
        assert_eq!(torn[47 * w + 100], whole[47 * w + 100]);
    }

    fn coarse_at(quality: f32) -> VideoLink {
        VideoLink {
            quality,
            loss: 0.0,
            tear: None,
        }
    }

    /// The tree-line skyline is what it claims: its mean top is the level horizon over the
    /// circle and within 0.35° over any 60° view; it is ragged (crowns above, gaps below),
    /// 2 to 14 px from its lowest to its highest point across a view at 480 px.
    #[test]
    fn tree_line_skyline_is_ragged_and_centred_on_the_horizon() {
        let focal_480 = 240.0 / 30f32.to_radians().tan();
        for seed in 1..=3u64 {
            let skyline = Skyline::new(seed);
            let mean = skyline.heights.iter().sum::<f32>() / SKYLINE_BINS as f32;
            assert!(mean.abs() < 1e-3, "seed {seed}: mean {mean}");
            let above = skyline.heights.iter().filter(|&&h| h > 0.0).count();
            let share = above as f32 / SKYLINE_BINS as f32;
            assert!((0.1..0.9).contains(&share), "seed {seed}: {share} above");
            for view in 0..12 {
                let centre = view as f32 * 30f32.to_radians();
                let tops: Vec<f32> = (0..480)
                    .map(|u| {
                        let azimuth = centre + ((u as f32 - 239.5) / focal_480).atan();
                        skyline.height_at(azimuth) / skyline.distance_m
                    })
                    .collect();
                let view_mean = tops.iter().sum::<f32>() / tops.len() as f32;
                let (low, high) = tops
                    .iter()
                    .fold((f32::MAX, f32::MIN), |(l, h), &t| (l.min(t), h.max(t)));
                let span_px = (high - low) * focal_480;
                assert!(
                    view_mean.atan().to_degrees().abs() < 0.35,
                    "seed {seed} view {view}: mean {}°",
                    view_mean.atan().to_degrees()
                );
                assert!(
                    (2.0..14.0).contains(&span_px),
                    "seed {seed} view {view}: {span_px} px"
                );
            }
        }
    }

    /// The camera of the tree-line set: a flat grey scene comes out darker in the corners
    /// than in the centre, brought to a mean of 105–150, noisy, and with 8×8 blocks: the
    /// steps across block borders are larger than those inside the blocks.
    #[test]
    fn tree_line_camera_vignettes_exposes_and_compresses() {
        let (w, h) = (480, 480);
        let mut pixels: Vec<[f32; 3]> = (0..w * h)
            .map(|i| {
                // A gentle ramp so that the blocks have something to quantise.
                let v = 90.0 + 60.0 * (i / w) as f32 / h as f32;
                [v, v + 5.0, v + 12.0]
            })
            .collect();
        consumer_camera(&mut pixels, w, h, &mut Rng::new(5));
        let luma = |p: &[f32; 3]| 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
        let mean = pixels.iter().map(luma).sum::<f32>() / pixels.len() as f32;
        assert!((100.0..155.0).contains(&mean), "mean {mean}");
        let patch = |x0: usize, y0: usize| {
            (0..16)
                .flat_map(|y| (0..16).map(move |x| (x0 + x, y0 + y)))
                .map(|(x, y)| luma(&pixels[y * w + x]))
                .sum::<f32>()
                / 256.0
        };
        let (centre, corner) = (patch(232, 232), patch(0, 232).min(patch(464, 232)));
        assert!(corner < 0.92 * centre, "corner {corner}, centre {centre}");
        let step = |x: usize| {
            (0..h)
                .map(|y| (luma(&pixels[y * w + x + 1]) - luma(&pixels[y * w + x])).abs())
                .sum::<f32>()
        };
        let (across, inside): (f32, f32) = (1..w / 8 - 1)
            .map(|b| (step(8 * b - 1), step(8 * b + 3)))
            .fold((0.0, 0.0), |(a, i), (x, y)| (a + x, i + y));
        assert!(across > 1.2 * inside, "across {across}, inside {inside}");
    }

    /// The honesty set holds no horizon: every frame is pitched out of it, so the bench
    /// scores it on false confidence only (a frame marked visible would be scored on angles).
    #[test]
    fn no_horizon_frames_show_no_horizon() {
        let renderer = Renderer::new(Degradation::NoHorizon, 160, 120, 4);
        for index in (0..40).step_by(3) {
            let (image, truth) = renderer.render(index);
            assert!(!truth.visible, "frame {index}: {truth:?}");
            assert!(truth.pitch_deg.abs() >= 40.0, "frame {index}: {truth:?}");
            // Looking down: all ground, no sky-blue pixel; looking up: all sky.
            let blue = image
                .data
                .chunks_exact(3)
                .filter(|p| p[2] > p[0].saturating_add(20))
                .count();
            let pixels = image.width * image.height;
            if (index / 8) % 2 == 0 {
                assert_eq!(blue, 0, "frame {index} looks down");
            } else {
                assert!(blue > pixels / 2, "frame {index} looks up: {blue} blue");
            }
        }
    }

    #[test]
    fn coast_frames_show_sea_and_fields_and_look_down_at_the_shore_one_run_in_four() {
        let renderer = Renderer::new(Degradation::Coast, 160, 120, 1);
        let (mut sea_beyond, mut over_the_sea) = (0, 0);
        for index in (0..80).step_by(3) {
            let (image, truth) = renderer.render(index);
            let share = |keep: &dyn Fn(&[u8]) -> bool| {
                image.data.chunks_exact(3).filter(|p| keep(p)).count() as f32
                    / (image.width * image.height) as f32
            };
            // Sea: dark and blue; fields: greener than blue; sky: light and blue.
            let sea = share(&|p| p[2] > p[0].saturating_add(25) && p[2] < 150);
            let fields = share(&|p| p[1] > p[2].saturating_add(10));
            if (index / 8) % 4 == 3 {
                assert!(!truth.visible, "frame {index}: {truth:?}");
                assert!(truth.pitch_deg <= -40.0, "frame {index}: {truth:?}");
                assert!(
                    sea > 0.1 && fields > 0.1,
                    "frame {index} looks down at the shore: sea {sea}, fields {fields}"
                );
                continue;
            }
            assert!(truth.visible, "frame {index}: {truth:?}");
            // Along the bottom row: the sea when the airplane is over it, else fields.
            let bottom = &image.data[(image.height - 1) * image.width * 3..];
            let sea_below = bottom
                .chunks_exact(3)
                .filter(|p| p[2] > p[0].saturating_add(25))
                .count()
                > image.width / 2;
            if sea_below {
                over_the_sea += 1;
            } else {
                sea_beyond += 1;
            }
        }
        assert!(
            sea_beyond >= 5 && over_the_sea >= 5,
            "{sea_beyond} {over_the_sea}"
        );
    }

    #[test]
    fn a_calm_sea_mirrors_the_sky_at_grazing_angles_and_darkens_below_them() {
        // The sea beyond a shore 10 km ahead, seen at 0.7° and at 14° of depression.
        let coast = Coast {
            normal: (1.0, 0.0),
            distance: 10.0,
            sea_beyond: true,
            beach_m: 0.0,
            mirror: true,
        };
        let luma = |c: [f32; 3]| 0.3 * c[0] + 0.59 * c[1] + 0.11 * c[2];
        let at = |depression_deg: f32| {
            let ahead = ALTITUDE_M / depression_deg.to_radians().tan();
            let distance = ahead.hypot(ALTITUDE_M);
            luma(coast.colour(1, (0.0, 0.0), (ahead, 0.0), distance))
        };
        let sky = luma(sky_colour(0.0));
        let (far, near) = (at(0.7), at(14.0));
        assert!(
            (sky - far).abs() < 16.0,
            "the far sea {far} is not the sky's {sky}"
        );
        assert!(near < far - 40.0, "the near sea {near}, the far {far}");
        // Without the mirror, `coast`'s dark blue water.
        let dark = Coast {
            mirror: false,
            ..coast
        };
        let ahead = ALTITUDE_M / 14f32.to_radians().tan();
        let water = luma(dark.colour(1, (0.0, 0.0), (ahead, 0.0), ahead.hypot(ALTITUDE_M)));
        assert!(water < near, "coast's water {water}, the calm sea {near}");
    }
}
