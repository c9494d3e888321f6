//! Horizon detection: roll and pitch from one camera frame, no heap, caller's buffers.
//!
//! Pipeline (each stage answers one of the seed's failures, thesis §6.2.3):
//! 1. working image: luma, binned for frames wider than 400 px ([`edges`]); an analogue
//!    link's periodic pattern found in its spectrum and notched out ([`interference`]); a
//!    coded frame deblocked, or for its edges smoothed over its tiles when it was coded at
//!    half resolution ([`blocks`]);
//! 2. 3×3 Sobel gradient, threshold adapted to the frame's gradient distribution, thinned by
//!    non-maximum suppression, edge points as a list;
//! 3. radial distortion correction of the points only (conventions camera model);
//! 4. Hough voting restricted to each point's gradient direction, full-circle angles so that
//!    the polarity of an edge separates a stripe's two borders ([`hough`]);
//! 5. several local maxima as candidates, plus the best cell near the tracked line;
//! 6. each candidate refined by least squares, then validated by how well it separates the
//!    frame into two statistically different halves (sky and ground), which also says which
//!    side is the sky (the ±180° ambiguity);
//! 7. roll and pitch from the conventions' horizon line, a confidence in [0, 1], and tracking:
//!    a jump away from the tracked line must be clearly better to be taken.

mod attitude;
mod blocks;
mod camera;
mod edges;
mod fft;
mod frame;
mod grid;
mod hough;
mod interference;
mod profile;
mod region;
mod seam;
mod stripes;
mod sync_bar;
#[cfg(test)]
mod tests;
mod upper;

pub use attitude::HorizonAttitude;
pub use camera::Camera;
pub use edges::{EdgePoint, MAX_WORKING_WIDTH, Sample};
pub use frame::{Frame, FrameError, Pixels};
pub use hough::{ANGLE_BINS, MAX_CANDIDATES};
/// The complex values of [`Workspace::spectrum`].
pub use microfft::Complex32;

use core::f32::consts::PI;
use edges::Working;
use hough::{Line, Peak, RhoAxis, Tables, wrap_angle};

/// A detected horizon.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Horizon {
    /// Vehicle roll (rad, conventions: positive right wing down), mount offset removed.
    pub roll_rad: f32,
    /// Vehicle pitch (rad, positive nose up), mount offset removed.
    pub pitch_rad: f32,
    /// How much to trust this answer, in [0, 1].
    pub confidence: f32,
    /// The line in the camera's normalised undistorted coordinates.
    pub line: HorizonLine,
}

/// The horizon as the conventions write it, seen by the camera:
/// `sin(camera_roll)·x + cos(camera_roll)·y = offset` in normalised undistorted coordinates,
/// with the ground where the left-hand side is larger; `offset = tan(camera_pitch)`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HorizonLine {
    pub camera_roll_rad: f32,
    pub offset: f32,
}

impl HorizonLine {
    /// Hough line `line` as the horizon, the sky on its brighter side (`sky_brighter`) or on
    /// its darker one: the ground lies where −n·p > −rho for a bright sky.
    fn of_line(line: Line, sky_brighter: bool) -> Self {
        if sky_brighter {
            HorizonLine {
                camera_roll_rad: wrap_angle(line.angle + PI),
                offset: -line.rho,
            }
        } else {
            HorizonLine {
                camera_roll_rad: wrap_angle(line.angle),
                offset: line.rho,
            }
        }
    }

    /// The line of a camera at roll `roll` and pitch `pitch` (rad).
    pub fn from_attitude(roll: f32, pitch: f32) -> Self {
        HorizonLine {
            camera_roll_rad: wrap_angle(roll),
            offset: libm::tanf(pitch),
        }
    }

    pub fn camera_pitch_rad(&self) -> f32 {
        libm::atanf(self.offset)
    }

    /// True if the normalised undistorted point `(x, y)` is on the ground side.
    pub fn is_ground(&self, x: f32, y: f32) -> bool {
        let (s, c) = (
            libm::sinf(self.camera_roll_rad),
            libm::cosf(self.camera_roll_rad),
        );
        s * x + c * y > self.offset
    }
}

/// Buffer sizes (elements) a [`Workspace`] needs for frames of one size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WorkspaceSizes {
    pub grey: usize,
    pub rows: usize,
    pub edges: usize,
    pub accumulator: usize,
    pub samples: usize,
    pub spectrum: usize,
}

impl WorkspaceSizes {
    /// Total bytes, to plan static buffers.
    pub fn bytes(&self) -> usize {
        self.grey
            + 2 * self.rows
            + core::mem::size_of::<EdgePoint>() * self.edges
            + 2 * self.accumulator
            + core::mem::size_of::<Sample>() * self.samples
            + core::mem::size_of::<Complex32>() * self.spectrum
    }
}

/// The caller's buffers the detector works in. Keep one per frame size and pass it to every
/// call; nothing in it needs to survive between calls.
pub struct Workspace<'a> {
    /// Working (binned luma) image.
    pub grey: &'a mut [u8],
    /// Rows of gradient magnitudes and Sobel components (the edge pass keeps three rows).
    pub rows: &'a mut [u16],
    /// Edge points; when full, the remaining edge pixels are dropped (confidence drops too).
    pub edges: &'a mut [EdgePoint],
    /// Hough accumulator, `ANGLE_BINS` × rho bins.
    pub accumulator: &'a mut [u16],
    /// Sky/ground statistics samples.
    pub samples: &'a mut [Sample],
    /// The working image's spectrum, where a periodic pattern over the frame (an analogue
    /// link's interference) is looked for. Shorter than [`WorkspaceSizes::spectrum`] (empty,
    /// say): no pattern is looked for.
    pub spectrum: &'a mut [Complex32],
}

/// Edge points kept per working pixel of perimeter: the horizon crosses the frame once, so a
/// few times the perimeter holds it with room for clutter.
const EDGES_PER_PERIMETER_PIXEL: usize = 16;

impl Workspace<'_> {
    /// Sizes for frames `width` × `height`.
    pub fn required_sizes(width: usize, height: usize) -> WorkspaceSizes {
        let geo = Working::for_frame(width, height);
        let rho = rho_half_bins(geo);
        WorkspaceSizes {
            grey: geo.width * geo.height,
            rows: edges::EDGE_SCRATCH_ROWS * geo.width,
            edges: EDGES_PER_PERIMETER_PIXEL * (geo.width + geo.height),
            accumulator: ANGLE_BINS * (2 * rho + 1),
            samples: edges::sample_count(geo),
            spectrum: interference::scratch_len(geo.width, geo.height),
        }
    }

    fn fits(&self, sizes: &WorkspaceSizes) -> bool {
        self.grey.len() >= sizes.grey
            && self.rows.len() >= sizes.rows
            && !self.edges.is_empty()
            && self.accumulator.len() >= sizes.accumulator
            && !self.samples.is_empty()
    }
}

/// Rho bins either side of zero, one working pixel each: the lines through the undistorted
/// frame reach at most the half-diagonal; 1.5 times that leaves room for principal points off
/// centre and barrel distortion (undistorted corners move outwards).
fn rho_half_bins(geo: Working) -> usize {
    let diagonal = libm::sqrt((geo.width * geo.width + geo.height * geo.height) as f64);
    libm::ceil(0.75 * diagonal) as usize
}

/// Tuning of the detector. `Default` is what the accuracy tests were run with.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DetectorConfig {
    /// Each edge point votes for normals within this many degrees of its gradient direction.
    pub vote_window_deg: u8,
    /// Candidates validated each frame (at most [`MAX_CANDIDATES`]).
    pub candidates: u8,
    /// Never take gradient magnitudes (`|gx| + |gy|`, Sobel) below this as edges ...
    pub min_gradient: u16,
    /// ... nor below this many times the frame's noise level (the 30th percentile of the
    /// magnitude): a fixed floor high enough for noisy frames drops every edge of an
    /// under-exposed one, whose noise is as dim as its horizon.
    pub noise_floor_factor: u8,
    /// Target edge pixels before thinning, per working pixel of perimeter.
    pub edge_pixels_per_perimeter_pixel: u16,
    /// A candidate this close to the tracked horizon in roll (deg) ...
    pub gate_roll_deg: f32,
    /// ... and in offset (normalised units, ≈ tan of the pitch change) is a continuation.
    pub gate_offset: f32,
    /// A jump out of the gate is taken only if its score beats the best continuation by this
    /// factor.
    pub jump_factor: f32,
    /// Noise level (30th percentile of the Sobel magnitude `|gx| + |gy|`) that each further
    /// 2× binning of a noisy frame is worth.
    pub noise_per_binning: u16,
    /// Frames without a continuation after which the track is dropped and every candidate
    /// competes on its own score.
    pub lost_after_frames: u8,
}

impl Default for DetectorConfig {
    fn default() -> Self {
        DetectorConfig {
            vote_window_deg: 6,
            candidates: 8,
            min_gradient: 12,
            noise_floor_factor: 3,
            edge_pixels_per_perimeter_pixel: 10,
            gate_roll_deg: 10.0,
            gate_offset: 0.08,
            jump_factor: 1.5,
            noise_per_binning: 24,
            lost_after_frames: 5,
        }
    }
}

/// Why the last call found no horizon (or that it found one).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Outcome {
    Found,
    /// A workspace buffer is smaller than [`Workspace::required_sizes`] says.
    WorkspaceTooSmall,
    /// The camera parameters are not usable (non-finite or non-positive focal length).
    BadCamera,
    /// Too few edges: a flat or black frame.
    NoEdges,
    /// No line both long enough and separating two different regions.
    NoCandidate,
}

/// The horizon being followed from frame to frame.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Track {
    line: HorizonLine,
    /// Frames since the last continuation.
    misses: u8,
}

/// A candidate after refinement and validation.
#[derive(Clone, Copy, Debug)]
struct Scored {
    line: Line,
    horizon: HorizonLine,
    explained: f32,
    /// The line's evidence that its brighter side is the sky, cue by cue
    /// ([`hough::Separation::cues`]).
    bright_side_cues: hough::SkyCues,
    coverage: f32,
    score: f32,
    continues_track: bool,
}

impl Scored {
    /// Whether the horizon's sky side is the line's brighter side (a line's normal points to
    /// its brighter side, see `hough::Line`).
    fn sky_brighter(&self) -> bool {
        libm::fabsf(wrap_angle(
            self.horizon.camera_roll_rad - (self.line.angle + PI),
        )) < 0.5 * PI
    }

    /// `line` as the horizon `horizon`, scored by how well it separates the frame and how
    /// much of its length is drawn; not yet on the track.
    fn oriented(
        line: Line,
        horizon: HorizonLine,
        separation: hough::Separation,
        coverage: f32,
    ) -> Self {
        Scored {
            line,
            horizon,
            explained: separation.explained,
            bright_side_cues: separation.cues,
            coverage,
            score: separation.explained * coverage,
            continues_track: false,
        }
    }

    /// [`Scored::oriented`] with the sky on the line's brighter side or not.
    fn new(line: Line, sky_brighter: bool, separation: hough::Separation, coverage: f32) -> Self {
        Self::oriented(
            line,
            HorizonLine::of_line(line, sky_brighter),
            separation,
            coverage,
        )
    }
}

/// The detector: camera, tuning, tables and tracking state. `detect` once per frame.
pub struct HorizonDetector {
    camera: Camera,
    config: DetectorConfig,
    tables: Tables,
    track: Option<Track>,
    outcome: Outcome,
    edge_count: usize,
    working_scale: usize,
    interference: Option<f32>,
    /// Side (frame pixels) of the coded blocks the last frame was found to be made of.
    coded_tile: Option<usize>,
    /// The profiles' undistorted knots and the samples' undistorted positions, for the last
    /// frame's camera and working image.
    knots: upper::Knots,
    sample_points: edges::SamplePoints,
}

/// Share of the quietest gradients that measures a frame's noise.
const NOISE_PERCENTILE: f32 = 0.3;
/// The quiet part of the gradient distribution ([`NOISE_PERCENTILE`]) from which a frame's
/// spectrum is searched for a periodic pattern: a pattern raises the gradient everywhere. On
/// the tuning sets (as rendered and through the camera chain) 2 % of the frames whose pattern
/// was found were under it, and 82 % of the frames with no pattern.
const PATTERN_NOISE: u16 = 16;
/// Narrowest working image noise binning may go to.
const MIN_WORKING_WIDTH: usize = 80;

/// Fewest edge points worth running the Hough stage on.
const MIN_EDGES: usize = 16;
/// Candidates must explain at least this share of the frame's variance to be a horizon.
const MIN_EXPLAINED: f32 = 0.08;
/// Confidence lost per share of the frame clipped (a quarter of the frame clipped: none
/// left) ...
const CLIPPED_FRAME_WEIGHT: f32 = 4.0;
/// ... and per share of the sky clipped right above the line.
const CLIPPED_SKY_WEIGHT: f32 = 2.0;
/// Confidence lost per share of the frame clipped where the line was read clear of the glare
/// and its halves there agree (half the frame clipped: none left; see `read_clear`).
const CLIPPED_FRAME_WEIGHT_READ_CLEAR: f32 = 2.0;

impl HorizonDetector {
    pub fn new(camera: Camera) -> Self {
        Self::with_config(camera, DetectorConfig::default())
    }

    pub fn with_config(camera: Camera, config: DetectorConfig) -> Self {
        HorizonDetector {
            camera,
            config,
            tables: Tables::new(),
            track: None,
            outcome: Outcome::NoEdges,
            edge_count: 0,
            working_scale: 1,
            interference: None,
            coded_tile: None,
            knots: upper::Knots::new(),
            sample_points: edges::SamplePoints::new(),
        }
    }

    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    pub fn config(&self) -> &DetectorConfig {
        &self.config
    }

    /// What the last [`HorizonDetector::detect`] call ended with.
    pub fn last_outcome(&self) -> Outcome {
        self.outcome
    }

    /// Edge points the last call used.
    pub fn last_edge_count(&self) -> usize {
        self.edge_count
    }

    /// Binning factor of the last frame's working image (1 = full resolution).
    pub fn last_working_scale(&self) -> usize {
        self.working_scale
    }

    /// The period (working pixels) of the periodic pattern the last frame had notched out of
    /// its working image, if one was found.
    pub fn last_interference_period(&self) -> Option<f32> {
        self.interference
    }

    /// Side (frame pixels) of the codec's blocks the last frame was found coded in: 8, or 16
    /// for a frame coded at half resolution (its edges are read smoothed over the tiles, see
    /// `blocks::smooth_tiles`). `None`: not found coded, or wider than 400 pixels (not looked
    /// for).
    pub fn last_coded_tile(&self) -> Option<usize> {
        self.coded_tile
    }

    /// Forgets the tracked horizon (e.g. after a cut in the video).
    pub fn reset_tracking(&mut self) {
        self.track = None;
    }

    /// The horizon in `frame`, or `None` (see [`HorizonDetector::last_outcome`]).
    pub fn detect(&mut self, frame: &Frame<'_>, ws: &mut Workspace<'_>) -> Option<Horizon> {
        match self.detect_inner(frame, ws) {
            Ok(h) => {
                self.outcome = Outcome::Found;
                Some(h)
            }
            Err(outcome) => {
                self.outcome = outcome;
                if let Some(track) = &mut self.track {
                    track.misses = track.misses.saturating_add(1);
                    if track.misses > self.config.lost_after_frames {
                        self.track = None;
                    }
                }
                None
            }
        }
    }

    fn detect_inner(
        &mut self,
        frame: &Frame<'_>,
        ws: &mut Workspace<'_>,
    ) -> Result<Horizon, Outcome> {
        let (width, height) = (frame.width(), frame.height());
        self.coded_tile = None;
        let camera = self.camera.scaled_to(width as u32, height as u32);
        if !camera.is_valid() {
            return Err(Outcome::BadCamera);
        }
        let sizes = Workspace::required_sizes(width, height);
        if !ws.fits(&sizes) {
            return Err(Outcome::WorkspaceTooSmall);
        }
        // 1: working image; binned further when the frame is noisy. Binning by k divides the
        // noise by k and keeps a long straight edge's contrast (the seed's noisy frames
        // passed the filter "as all-edge"). The noise is read off the quiet part of the
        // gradient distribution: in a clean frame the sky's 30th percentile is nearly flat.
        let base = Working::for_frame(width, height);
        // A frame coded coarsely in blocks has its working image deblocked where a block is
        // more than two working pixels (frames up to 400 px wide, see `blocks::deblock`): at
        // 320 px a block is four, and its borders draw a coded horizon's staircase as
        // separate level and upright edges (`terrain` `transmission` at 320×240, seeds
        // 16–18: 0.52 / 0.82 / 0.40 within 2° before, 0.68 / 0.97 / 0.53 after, with the
        // confidence term below). A frame binned coarser for noise keeps its blocks, whole in
        // its working pixels.
        edges::build_working_image(frame, base, ws.grey);
        let frame_grid = (base.scale <= 2 && blocks::may_show_blocks(ws.grey, base))
            .then(|| blocks::grid(frame));
        let coded = frame_grid
            .filter(|g| g.contrast >= CODED_IN_BLOCKS && g.weaker_axis >= CODED_ON_BOTH_AXES);
        // A frame coded at half resolution is read for edges smoothed over its tiles (see
        // `blocks::smooth_tiles`), and for everything else deblocked like any coded frame: the
        // smoothing would take the ground's texture, which tells it from the sky.
        let tiled = coded.filter(|g| g.tile > blocks::BLOCK);
        self.coded_tile = coded.map(|g| g.tile);
        // What a built working image of a coded frame gets: deblocking, or, for the edge
        // pass of a frame coded at half resolution, smoothing over its tiles.
        let unblock = |geo: Working, grey: &mut [u8], for_edges: bool| match (tiled, coded) {
            (Some(grid), _) if for_edges => blocks::smooth_tiles(grey, geo, grid.tile),
            (_, Some(grid)) => blocks::deblock(grey, geo, grid),
            _ => {}
        };
        let working_image = |geo: Working, grey: &mut [u8]| {
            edges::build_working_image(frame, geo, grey);
            unblock(geo, grey, false);
        };
        // The image the edge points are read from.
        let edge_image = |geo: Working, grey: &mut [u8]| {
            edges::build_working_image(frame, geo, grey);
            unblock(geo, grey, true);
        };
        unblock(base, ws.grey, true);
        let mut histogram = edges::GradientHistogram::measure(ws.grey, base, ws.rows);
        // Only a level above `noise_per_binning` bins further; below it the cap cannot matter.
        // The working image's Laplacian, once measured: when the frame is not binned further,
        // the floor below asks for it again on the same image.
        let mut laplacian = None;
        let noise = noise_level(
            &histogram,
            ws.grey,
            base,
            self.config.noise_per_binning,
            &mut laplacian,
        );
        let extra = usize::from(noise.div_ceil(self.config.noise_per_binning.max(1))).clamp(1, 4);
        let mut geo = base;
        if extra > 1 {
            let coarser = Working::with_scale(width, height, base.scale * extra);
            if coarser.width >= MIN_WORKING_WIDTH && coarser.height >= MIN_WORKING_WIDTH / 2 {
                geo = coarser;
                laplacian = None;
                edge_image(geo, ws.grey);
                histogram = edges::GradientHistogram::measure(ws.grey, geo, ws.rows);
            }
        }
        self.working_scale = geo.scale;
        self.knots.prepare(&camera, geo);
        self.sample_points.prepare(&camera, geo);
        // 1b: a periodic pattern across the frame (an analogue link's interference) found in
        // the working image's spectrum and notched out of it; the gradient's distribution
        // and the noise are measured again on the image without it.
        let pattern = (histogram.percentile(NOISE_PERCENTILE) >= PATTERN_NOISE)
            .then(|| interference::find(ws.grey, geo, ws.spectrum))
            .flatten();
        if let Some(pattern) = pattern {
            interference::remove(ws.grey, geo, pattern, ws.spectrum);
            laplacian = None;
            histogram = edges::GradientHistogram::measure(ws.grey, geo, ws.rows);
        }
        self.interference = pattern.map(|p| p.period());
        let mean_focal = 0.5 * (camera.fx + camera.fy);
        let max_radius2 = undistorted_corner_radius2(&camera, width, height);
        let step = geo.scale as f32 / mean_focal;
        // Every line through the frame lies within its undistorted corner radius of the
        // centre: the accumulator needs no more rho bins than that (a third fewer cells to
        // clear and scan than the workspace's bound for a centred, undistorted camera).
        let needed = libm::ceilf(libm::sqrtf(max_radius2) / step) + 1.0;
        let rho = RhoAxis {
            step,
            half: if needed.is_finite() && needed >= 1.0 {
                (needed as usize).min(rho_half_bins(geo))
            } else {
                rho_half_bins(geo)
            },
        };
        let accumulator = ws
            .accumulator
            .get_mut(..ANGLE_BINS * rho.bins())
            .unwrap_or(&mut []);

        // 2–3: gradient, thinned and undistorted edge points.
        let perimeter = geo.width + geo.height;
        // The noise floor only matters where it is above both the fixed floor and the
        // threshold the edge budget sets; below that the Laplacian pass would change nothing.
        let factor = u16::from(self.config.noise_floor_factor).max(1);
        let budget_threshold = histogram.threshold(
            geo,
            usize::from(self.config.edge_pixels_per_perimeter_pixel) * (geo.width + geo.height),
            0,
        );
        let floor = self.config.min_gradient.max(
            noise_level(
                &histogram,
                ws.grey,
                geo,
                self.config.min_gradient.max(budget_threshold) / factor,
                &mut laplacian,
            )
            .saturating_mul(u16::from(self.config.noise_floor_factor)),
        );
        let threshold = histogram.threshold(
            geo,
            usize::from(self.config.edge_pixels_per_perimeter_pixel) * perimeter,
            floor,
        );
        // A coded frame's blocks show too (its grid contrast is over `CODED_IN_BLOCKS`).
        let blocks_show = frame_grid.is_some_and(|g| g.contrast >= BLOCKS_SHOW);
        let edge_stats = edges::collect_edges(
            ws.grey,
            geo,
            ws.rows,
            threshold,
            &camera,
            ws.edges,
            !blocks_show,
        );
        if tiled.is_some() {
            // Back to the deblocked frame for the regions, profiles and textures.
            working_image(geo, ws.grey);
            if let Some(pattern) = pattern {
                interference::remove(ws.grey, geo, pattern, ws.spectrum);
            }
        }
        let edge_points = ws.edges.get(..edge_stats.count).unwrap_or(&[]);
        self.edge_count = edge_points.len();
        if edge_points.len() < MIN_EDGES {
            return Err(Outcome::NoEdges);
        }

        // 4–5: direction-restricted Hough voting and candidates.
        let window = usize::from(self.config.vote_window_deg).min(ANGLE_BINS / 4);
        hough::vote(edge_points, &self.tables, rho, window, accumulator);
        let mut peaks = [Peak::default(); MAX_CANDIDATES];
        let wanted = usize::from(self.config.candidates).clamp(1, MAX_CANDIDATES - 2);
        // A horizon shorter than a sixth of the frame width is not worth validating.
        let min_votes = (geo.width / 6).max(8) as u16;
        // Twice the candidates wanted, then at most `PER_DIRECTION` of them per direction: a
        // periodic pattern (interference, a ploughed field, a fence) draws a family of parallel
        // lines that out-vote the horizon and would take every candidate slot, each one
        // explaining nothing, so that no line at the horizon's angle was validated.
        let mut found = [Peak::default(); MAX_CANDIDATES];
        let accumulator: &[u16] = accumulator;
        let found_count = hough::find_peaks(
            accumulator,
            rho,
            min_votes,
            found
                .get_mut(..(2 * wanted).min(MAX_CANDIDATES))
                .unwrap_or(&mut []),
        );
        let mut count = diverse_peaks(
            found.get(..found_count).unwrap_or(&[]),
            peaks.get_mut(..wanted).unwrap_or(&mut []),
        );
        // Search near the tracked line first: its best cell competes even when it is not
        // among the global maxima (a stripe or a road may out-vote it for a few frames). Both
        // polarities, as an exposure change can make the ground the brighter side.
        if let Some(track) = self.track {
            for (angle, rho_value) in [
                (track.line.camera_roll_rad + PI, -track.line.offset),
                (track.line.camera_roll_rad, track.line.offset),
            ] {
                let Some(rho_index) = rho.index(rho_value) else {
                    continue;
                };
                // Clamped so that a wild configuration cannot wrap the search around.
                let angle_window =
                    (libm::ceilf(self.config.gate_roll_deg) as usize).min(ANGLE_BINS / 4);
                let rho_window =
                    (libm::ceilf(self.config.gate_offset / rho.step) as usize).min(rho.bins());
                if let Some(p) = hough::peak_near(
                    accumulator,
                    rho,
                    hough::angle_bin(angle),
                    rho_index,
                    angle_window,
                    rho_window,
                ) && p.votes >= min_votes / 2
                    && !peaks.get(..count).unwrap_or(&[]).contains(&p)
                    && let Some(slot) = peaks.get_mut(count)
                {
                    *slot = p;
                    count += 1;
                }
            }
        }
        // No early return without a candidate: the region search below may still find one.

        // 6: refine and validate each candidate.
        // The sky/ground samples of the working image as it is (read again after stripes
        // are subtracted, and after the image is put back).
        let read_samples = |grey: &[u8], samples: &mut [Sample]| {
            edges::collect_samples(frame, grey, geo, (&camera, &self.sample_points), samples)
        };
        let sample_count = read_samples(ws.grey, ws.samples);
        let samples = ws.samples.get(..sample_count).unwrap_or(&[]);
        let bands = [3.0 * rho.step, 1.5 * rho.step];
        // Wide: aliased edges (a staircase) have Sobel directions 20° and more off the line; the
        // distance band does the selecting.
        let max_angle_difference = 30.0 * PI / 180.0;
        let mut scored: [Option<Scored>; MAX_CANDIDATES] = [None; MAX_CANDIDATES];
        for (peak, slot) in peaks.iter().take(count).zip(scored.iter_mut()) {
            let start = Line {
                angle: peak.angle as f32 * hough::ANGLE_STEP,
                rho: rho.value(peak.rho),
            };
            let refined = hough::refine(edge_points, start, &bands, max_angle_difference);
            let Some((line, inliers)) = refined else {
                continue;
            };
            let expected = expected_edge_pixels(&camera, geo, line, rho, max_radius2);
            if expected < 4.0 {
                continue;
            }
            let coverage = (inliers as f32 / expected).min(1.0);
            let separation = hough::separation(samples, line, 2.0 * rho.step);
            *slot = Some(self.scored(line, separation, coverage));
        }

        // A level candidate along a row boundary where a digital link spliced the frame (a
        // concealed or torn slice, see `seam`) is the link's line, not the sky's: it is chosen
        // only when nothing else is, it is not climbed to, and it does not decide whether the
        // region search runs. Under a link's lost slices such a line out-scored a hazy horizon
        // (`aerial` `mixed`, seeds 137–165: 206 of its 710 misses were level lines, the
        // horizon 2.5° and more of roll from level; with this rule 101 more of its 2320
        // frames are read within 2°, 16 more trusted wrong).
        let mut seams: [Option<Line>; MAX_CANDIDATES] = [None; MAX_CANDIDATES];
        for (candidate, seam) in scored.iter().zip(seams.iter_mut()) {
            *seam = candidate
                .filter(|s| seam::near_row_seam(frame, &camera, s.horizon, geo.scale as f32))
                .map(|s| s.line);
        }
        let not_a_seam = |s: &Scored| !seams.contains(&Some(s.line));
        // Nor is a seam one of a family of stripes (see `stripe_family`): seams with a nearly
        // level ground edge made one, and the family kept the climb from that edge to the
        // horizon above it (on the seen sets 13 more frames within 2°, 8 fewer trusted wrong).
        let off_seams = |scored: &[Option<Scored>; MAX_CANDIDATES]| {
            scored.map(|candidate| candidate.filter(|s| not_a_seam(s)))
        };

        // 6b: when no edge line splits the frame, the line that best splits it into two
        // regions (see `region`): interference's stripes out-vote the horizon, whose own edge
        // points it scatters. Only on such frames, so that it costs nothing on the others.
        let mut from_region = false;
        let hough_best = best_of(&scored, not_a_seam);
        // Also when the best edge line is drawn along only part of its length and splits
        // the frame less than clearly, in a frame a block codec coded coarsely: under a video
        // link's blocks the edges follow the haze's lower edge, degrees of roll off the
        // horizon (`synth` `video-link` at 320 px, 5–13°), while the frame's two regions
        // still meet at the horizon. Then only nearby directions are searched, and a line
        // that splits the frame clearly replaces the edge line. Not in a camera's own frame:
        // on a noisy horizon the edge line is as weakly drawn, and the split near it no
        // better (held-out `terrain` seed 8, `sensor-noise`: 0.85 → 0.575 within 2° when it
        // ran on every frame). Not under a family of parallel candidates: those are
        // interference's crests, whose compromise lines a nearby split only joins (they go
        // to `stripes` below).
        let extent = libm::sqrtf(max_radius2);
        // Each way in gives the line found and the bars it must clear (any one of them) to
        // replace the best edge line.
        let found = match hough_best {
            Some(b) if b.explained >= REGION_TRIGGER => {
                if b.explained >= REGION_RECHECK
                    || stripe_family(&off_seams(&scored), rho.step).is_some()
                {
                    None
                } else if b.coverage < REGION_RECHECK_COVERAGE
                    && frame_grid.map_or_else(|| blocks::grid_contrast(frame), |g| g.contrast)
                        >= CODED_IN_BLOCKS
                {
                    region::search_near(samples, extent, b.line)
                        .map(|line| (line, &CODED_FRAME_BARS[..]))
                } else {
                    // A faint hazy horizon over fields crossed by roads and hedges: the edge
                    // line follows the fields' edges in the haze, degrees of roll off the
                    // horizon (`synth` `coast`, 2–13°), while sky and ground still split
                    // the frame clearly. Only a clear split counts: in dim light or a
                    // mixed frame a split explaining less was more often wrong than the edge
                    // line (`low-light` 640 seed 2: 0.58 → 0.25 within 2° with any split).
                    region::clear_split_near(samples, extent, b.line)
                        .map(|line| (line, &CLEAR_SPLIT_BARS[..]))
                }
            }
            _ => region::search(samples, extent).map(|line| {
                let line = colour_split_over(samples, extent, line, 2.0 * rho.step).unwrap_or(line);
                (line, &NO_EDGE_LINE_BARS[..])
            }),
        };
        if let Some((line, bars)) = found {
            let separation = hough::separation(samples, line, 2.0 * rho.step);
            if bars.iter().any(|bar| {
                separation.explained >= bar.least
                    && hough_best.is_none_or(|b| separation.explained > bar.margin * b.explained)
            }) {
                scored = [None; MAX_CANDIDATES];
                if let Some(slot) = scored.first_mut() {
                    *slot = Some(self.scored(line, separation, REGION_COVERAGE));
                }
                from_region = true;
            }
        }

        // 7: choose, with tracking's jump gate.
        // An edge of a bar of blanked rows (lost vertical sync, see `sync_bar`) is chosen only
        // when nothing else is: a level step drawn along the whole width, it can out-score a
        // hazy horizon. So is a seam (above).
        let not_a_bar = |s: &Scored| !sync_bar::along_blank_bar(ws.grey, geo, &camera, s.line);
        let best_overall = best_of(&scored, |s| not_a_bar(s) && not_a_seam(s))
            .or_else(|| best_of(&scored, |_| true))
            .ok_or(Outcome::NoCandidate)?;
        let best_continuation = best_of(&scored, |s| {
            s.continues_track && not_a_bar(s) && not_a_seam(s)
        });
        let mut jumped = false;
        let chosen = match best_continuation {
            Some(c) if c.score * self.config.jump_factor >= best_overall.score => c,
            _ => {
                jumped = self.track.is_some();
                best_overall
            }
        };
        if chosen.explained < MIN_EXPLAINED {
            return Err(Outcome::NoCandidate);
        }

        // 7b: the horizon is the highest sky/ground boundary. A strong ground edge (a road,
        // a shore, a field edge, the border of a glare-washed haze band) can out-score a faint
        // horizon above it; an edge of the same polarity and direction above the chosen one,
        // with textured ground between the two and smooth sky above, is the horizon.
        let context = LineContext {
            camera: &camera,
            knots: &self.knots,
            geo,
            rho,
            edges: edge_points,
            samples,
            max_radius2,
            bands: &bands,
            max_angle_difference,
        };
        let mut chosen = chosen;
        let sky_brighter = chosen.sky_brighter();
        let mut climbed = false;
        // A candidate drawn along the whole frame above the chosen one (a sea's horizon over
        // the shore, the top of a haze band over the ground's edge) is the horizon: a ground
        // edge lies below it (see [`drawn_line_above`]). Not a line a link draws itself: the
        // edge of a white stripe (`synth` `white-stripes`), of a blanked bar, a seam, a family of
        // stripes, and, where a periodic pattern was notched out, a line level with the rows,
        // the edge of the link's hum bar (`terrain` `interference`: 7 frames lost to it, 3 of
        // 40 on seed 16 at 640 px, while the rule skipped no line under a pattern). A family
        // rules the climb out only where the chosen line is parallel to it, one of the
        // stripes' crests itself: a shore turned from a sea's horizon is not, and the family
        // it stands under is that horizon and the field edges beyond the shore, parallel to
        // it (`aerial` `mixed`).
        let drawn_by_the_link = |s: &Scored| {
            !not_a_bar(s)
                || !not_a_seam(s)
                || sync_bar::along_saturated_bar(ws.grey, geo, &camera, s.line)
                || (pattern.is_some() && sync_bar::is_level(s.line))
        };
        // The candidates no longer change: their family of stripes, if any, is read once, here
        // and in 7c.
        let family = stripe_family(&off_seams(&scored), rho.step);
        let mut overtaken = None;
        if !from_region
            && family.is_none_or(|crest| !in_one_family(crest, chosen.line))
            && let Some(upper) =
                drawn_line_above(&context, &scored, &chosen, |s| !drawn_by_the_link(s))
        {
            overtaken = Some(chosen.line);
            chosen = self.tracked(upper);
            climbed = true;
        }
        for _ in 0..if from_region { 0 } else { 2 } {
            match higher_edge(
                &context,
                accumulator,
                &chosen,
                sky_brighter,
                min_votes,
                PARALLEL_TURN_DEG,
            ) {
                // Nor to a seam here (above).
                Some(upper)
                    if seam::near_row_seam(frame, &camera, upper.horizon, geo.scale as f32) =>
                {
                    break;
                }
                Some(upper) => {
                    chosen = self.tracked(upper);
                    climbed = true;
                }
                None => break,
            }
        }
        let sky_ward = if sky_brighter { 1.0 } else { -1.0 };
        // The profile across `line`, the sky on the `sky_ward` side of its normal.
        let across = |line: Line, sky_ward: f32| {
            upper::Profile::measure(
                ws.grey,
                geo,
                (&camera, &self.knots),
                line,
                sky_ward,
                rho.step,
                (HIGHER_EDGE_REACH / rho.step) as usize,
            )
        };
        let mut profile = across(chosen.line, sky_ward);
        if !climbed
            && !from_region
            && let Some(upper) = higher_step(&context, &profile, &chosen, sky_brighter)
        {
            profile = across(upper.line, sky_ward);
            chosen = self.tracked(upper);
            climbed = true;
        }
        // A ground edge out of parallel with the horizon (a field's border or a road not
        // square to the view, on level ground: its vanishing point is on the horizon) is
        // climbed from only where it is a sharp edge drawn along its whole length with
        // hazy ground, less blue than the sky, right above it. Its horizon is looked for among
        // edges turned up to `GROUND_EDGE_TURN_DEG`, then as a step in profiles across turned
        // lines (a parallel profile smears a turned horizon's step). The edge it was climbed
        // from is kept: it is not the turned line's rival.
        let mut turned_from = None;
        if !climbed && !from_region && sharp_ground_edge(&context, &chosen, sky_brighter) {
            let turned = higher_edge(
                &context,
                accumulator,
                &chosen,
                sky_brighter,
                min_votes,
                GROUND_EDGE_TURN_DEG,
            )
            .or_else(|| {
                // The step across each turned line; the best turn, then half a turn step
                // either side of it (a step found across a line turned 3° from the horizon's
                // direction is itself turned by up to 1.5°).
                let step_across = |turn: f32| {
                    let line = turned_about_its_foot(chosen.line, turn * PI / 180.0);
                    let upper =
                        higher_step(&context, &across(line, sky_ward), &chosen, sky_brighter)?;
                    above_across_the_frame(&context, chosen.line, upper.line, sky_ward)
                        .then_some(upper)
                };
                best_turn(
                    &TURNED_PROFILES_DEG,
                    &[0.5 * TURNED_PROFILE_STEP_DEG],
                    step_across,
                    |upper| upper.explained,
                )
                .map(|(upper, _)| upper)
            });
            if let Some(upper) = turned {
                turned_from = Some(chosen.line);
                profile = across(upper.line, sky_ward);
                chosen = self.tracked(upper);
                climbed = true;
            }
        }
        // A dark band under a bright sky: the chosen edge steps down towards the side taken
        // as the sky, though that side as a whole is the brighter. Seen from the land over a
        // hazy sea the shore is such an edge (the sea darker than the fields, fading into the
        // haze up to the horizon); the horizon is the top of the band, the step where the
        // sky's glow ends. Looked for from two working pixels inside the band; where it is not
        // found or not taken, over a shore turned from the horizon by more than the top step's
        // own turns (±3°): the coast at an angle to the view, its shore meeting the horizon at
        // its vanishing point in or near the frame (see [`sea_over_shore`]).
        let mut over_dark_band = false;
        if !climbed
            && !from_region
            && !sky_brighter
            && chosen.bright_side_cues.flipped().brighter > 0.0
        {
            let inside = Line {
                angle: chosen.line.angle,
                rho: chosen.line.rho - 2.0 * rho.step,
            };
            let band_top = region::top_step(ws.grey, geo, &camera, inside, rho.step, -1.0)
                .filter(|top| {
                    top.halves_agree && top.one_transition && top.sky_ward_px > TOP_AMBIGUITY
                })
                .and_then(|top| {
                    let separation = hough::separation(samples, top.line, 2.0 * rho.step);
                    (separation.explained >= MIN_EXPLAINED)
                        .then(|| Scored::new(top.line, true, separation, chosen.coverage))
                });
            if let Some(upper) = band_top.or_else(|| sea_over_shore(&context, ws.grey, &chosen)) {
                turned_from = Some(chosen.line);
                profile = across(upper.line, 1.0);
                chosen = self.tracked(upper);
                climbed = true;
                over_dark_band = true;
            }
        }

        // A shore under a calm sea: the sea mirrors the sky, brightening up to the horizon
        // as the haze does, and the shore below it is the clearest sky-over-ground step in
        // the frame, turned from the horizon by the coast's angle (`synth` `calm-sea`: 8–25°).
        // The profile across the line keeps rising above it; the horizon is the ridge where
        // the sea's brightening meets the sky's darkening, looked for in profiles of the band
        // above the line read across turned lines (see `ridge_over_ramp`).
        let mut on_ridge = false;
        if !climbed
            && !from_region
            && sky_brighter
            && profile.rises_above()
            && let Some(upper) = ridge_over_ramp(
                &context,
                ws.grey,
                &chosen,
                (HIGHER_EDGE_REACH / rho.step) as usize,
            )
        {
            turned_from = Some(chosen.line);
            profile = across(upper.line, sky_ward);
            chosen = self.tracked(upper);
            climbed = true;
            on_ridge = true;
        }
        // 7c: interference (see `stripes`). A striped sky above the chosen line: the line is a
        // crest nearly parallel to the horizon. A family of parallel candidates: the stripes'
        // crests, which scattered the horizon's own edge points (the line chosen is then a
        // compromise, 5–15° off). The sinusoid along the crests is measured and subtracted from
        // the working image, and the region search finds the horizon in regions that no longer
        // hold the stripes; for a family, only a line other than the chosen one replaces it.
        let striped = !climbed && profile.striped();
        let crest = if striped {
            Some(chosen.line)
        } else if !climbed && chosen.score < FAMILY_WEAK_SCORE {
            family
        } else {
            None
        };
        let mut sample_count = sample_count;
        let mut destriped = false;
        if let Some(crest) = crest
            && let Some(wave) = stripes::Wave::estimate(ws.grey, geo, &camera, crest)
        {
            wave.subtract(ws.grey, geo);
            sample_count = read_samples(ws.grey, ws.samples);
            let clean = ws.samples.get(..sample_count).unwrap_or(&[]);
            let found = region::quick_search(clean, libm::sqrtf(max_radius2))
                .map(|line| (line, hough::separation(clean, line, 2.0 * rho.step)))
                .filter(|(line, separation)| {
                    separation.explained >= MIN_EXPLAINED
                        && (striped || !same_line(*line, chosen.line, rho.step))
                });
            if let Some((line, separation)) = found {
                chosen = self.scored(line, separation, REGION_COVERAGE);
                from_region = true;
                destriped = true;
            } else {
                // Back to the frame as it was (without the notched pattern).
                working_image(geo, ws.grey);
                if let Some(pattern) = pattern {
                    interference::remove(ws.grey, geo, pattern, ws.spectrum);
                }
                sample_count = read_samples(ws.grey, ws.samples);
            }
        }
        let samples = ws.samples.get(..sample_count).unwrap_or(&[]);
        let mut sky_brighter = if destriped || over_dark_band {
            chosen.sky_brighter()
        } else {
            sky_brighter
        };
        // A region's split lies anywhere on the flanks of a hazy horizon's ridge (the sky
        // glowing towards it, the ground darkening away from it): the horizon is the step at
        // its top (see `region::top_step`). Where the line's two halves disagree on that
        // step, the line keeps a quarter of its confidence.
        let mut top_disagrees = false;
        // A region line moved to the top step (an edge line moved there keeps the terms of
        // the edges that drew it).
        let mut moved_to_top = false;
        if from_region
            && let Some(top) = region::top_step(
                ws.grey,
                geo,
                &camera,
                chosen.line,
                rho.step,
                if sky_brighter { 1.0 } else { -1.0 },
            )
        {
            let line = top.line;
            let separation = hough::separation(samples, line, 2.0 * rho.step);
            if separation.explained >= MIN_EXPLAINED {
                top_disagrees = !top.halves_agree;
                moved_to_top = true;
                chosen = self.scored(line, separation, REGION_COVERAGE);
                sky_brighter = chosen.sky_brighter();
            }
        }
        // An edge line can lie on the ground's flank of the same ridge: the ramp under a
        // thick haze is steeper at the working resolution than the small step above it
        // (`synth` `low-light` at 320 px was read 8° low). The top step is taken only more
        // than two working pixels above the line, with the two halves agreeing on it and
        // the profile falling all the way from it down to the line (one transition: a cloud's
        // lower edge or a bar above a real horizon has darker sky under it), and keeping most
        // of the line's split ([`TOP_STEP_KEEPS_SPLIT`]). It is looked for wherever the
        // profile keeps rising above the line's own transition, whatever the transition walk
        // saw there: in dim light the walk's clear-step test (six times the bin noise) misses
        // a step that the top step's directional means find (`low-light` seed 1 at 320 px,
        // frames 0 and 2, were read 5° low, one of them confidently). A line the search
        // climbed to from a ground edge may still be on the ramp (`low-light` 640 px, 4–7°
        // low from frame 26 of seed 1 on).
        let mut on_ramp = !from_region && sky_brighter && profile.rises_above();
        if on_ramp
            && let Some(top) = region::top_step(ws.grey, geo, &camera, chosen.line, rho.step, 1.0)
            && top.halves_agree
            && top.one_transition
            && top.sky_ward_px > TOP_AMBIGUITY
        {
            let separation = hough::separation(samples, top.line, 2.0 * rho.step);
            if separation.explained >= (TOP_STEP_KEEPS_SPLIT * chosen.explained).max(MIN_EXPLAINED)
            {
                let upper = Scored::new(top.line, true, separation, chosen.coverage);
                chosen = self.tracked(upper);
                on_ramp = false;
            }
        }
        // A line at the foot of a ramp that no top step was found above within 3° of its
        // direction may be a ground edge turned from the horizon under a band of hazy far
        // ground (`aerial` seed 140 `sensor-noise`: 5–8° turned, 5° under it, trusted on 24
        // frames of 40): the horizon is looked for as a top step across lines turned further.
        // The samples as read last (again, after the frame was destriped or put back).
        let late_context = LineContext {
            camera: &camera,
            knots: &self.knots,
            geo,
            rho,
            edges: edge_points,
            samples,
            max_radius2,
            bands: &bands,
            max_angle_difference,
        };
        // A line under a rise as long as a ramp's whose band above is as little blue as ground
        // ([`GROUND_BLUE_SHARE`]): the band of hazy far ground over a sharp ground edge, which
        // rises to the horizon by less than the edge steps (`aerial` seed 140 `mixed`: 13
        // frames wrong and trusted at 0.3–0.8, most 4–7° under the horizon). Over a horizon,
        // the band is the sky's glow, bluer than that. Measured across the line the profile
        // was read across, and kept only while the line stays there: a turned top step found
        // above the band moves the line to its top (`on_ramp` asks for a sky brighter than
        // the ground: the sky is on the normal's side).
        let mut under_ground_coloured_band = on_ramp
            && profile
                .rise_above()
                .is_some_and(|rise| rise.reaches(RAMP_EXTENT))
            && band_blue_share(&late_context, chosen.line, 1.0)
                .is_some_and(|share| share <= GROUND_BLUE_SHARE);
        if on_ramp
            && !climbed
            && let Some(upper) = turned_top_over_ramp(&late_context, ws.grey, &chosen)
        {
            // `on_ramp` stays: where the line was at the foot of its ramp (more of the rise
            // above it than across it), the step found above may be dusk haze's noise
            // (`synth` `low-light` seed 2 at 320 px: 5 more frames trusted wrong), and the
            // line keeps the ramp's quarter of its confidence below.
            turned_from = Some(chosen.line);
            chosen = self.tracked(upper);
            under_ground_coloured_band = false;
        }
        // A destriped line may still lie inside the transition rather than at its top (the
        // top step found nothing clearer); a clear step above it in the same transition
        // makes the answer a guess between the two. Measured on `synth`, moving the line to
        // that walk's step read more crests and sky gradients than ramps: it stays, at a
        // lower confidence.
        let mut ambiguous = false;
        if destriped {
            profile = upper::Profile::measure(
                ws.grey,
                geo,
                (&camera, &self.knots),
                chosen.line,
                if sky_brighter { 1.0 } else { -1.0 },
                rho.step,
                (HIGHER_EDGE_REACH / rho.step) as usize,
            );
            ambiguous = profile.top_of_transition().is_some_and(|top| {
                libm::fabsf(top.rho - chosen.line.rho) > TOP_AMBIGUITY * rho.step
            });
        }

        // Confidence: the line must split the frame into clearly different halves, be drawn
        // by edges along most of its length, and have no comparable rival elsewhere.
        // A ground edge the search climbed over is below the horizon by construction, not a
        // rival to it.
        let climbed_over = |s: &Scored| {
            (climbed
                && libm::fabsf(wrap_angle(s.line.angle - chosen.line.angle)) < 3.0 * PI / 180.0)
                || turned_from.is_some_and(|edge| same_line(s.line, edge, rho.step))
                || overtaken.is_some_and(|edge| same_line(s.line, edge, rho.step))
        };
        let rival = scored
            .iter()
            .flatten()
            .filter(|s| !same_line(s.line, chosen.line, rho.step) && !climbed_over(s))
            .map(|s| s.score)
            .fold(0.0f32, f32::max);
        let explained_term = ((chosen.explained - 0.15) / 0.45).clamp(0.0, 1.0);
        let coverage_term = ((chosen.coverage - 0.25) / 0.5).clamp(0.0, 1.0);
        let margin = if chosen.score > 0.0 {
            (1.0 - rival / chosen.score).clamp(0.0, 1.0)
        } else {
            0.0
        };
        // A line from the region search was not drawn by edges: no coverage or rival terms,
        // and what a clear full-resolution edge adds below.
        let mut confidence = if from_region {
            REGION_CONFIDENCE * explained_term
        } else {
            explained_term * coverage_term * (0.3 + 0.7 * margin)
        };
        if edge_stats.dropped > 0 {
            confidence *= 0.8;
        }
        if profile.striped() || ambiguous || top_disagrees {
            confidence *= STRIPED_CONFIDENCE;
        }
        // Which side is the sky must be clear: brighter, bluer and smoother together. Looking
        // down at fields, a field's border splits the frame as well as a horizon does, but
        // the lighter field is no smoother than the darker and less blue; looking up, a
        // cloud's edge has sky on both sides. The cues are those of the side chosen as the
        // sky: where the track or the upright prior chose it against the image's own
        // evidence, the image does not vouch for the line.
        let sky_cues = if chosen.sky_brighter() {
            chosen.bright_side_cues
        } else {
            chosen.bright_side_cues.flipped()
        };
        confidence *= (sky_cues.agreed() / CLEAR_SKY_EVIDENCE).clamp(0.0, 1.0);
        // A sky darker than the ground is rare over land (snow, a sunlit beach), while a sea
        // seen steeply from above is darker than the fields, yet bluer and smoother, so it
        // passes as a sky on two cues of three (`synth` `coast`, frames looking down at the
        // shore, past the gate at 0.3–0.67). The mean alone does not tell it from a hazy
        // frame filled with a deep blue sky, darker on the whole than its hazy ground (the
        // brighter cue −0.6 on `haze`, −0.8 to −1.5 on the sea), but such a sky still glows
        // at the horizon: its brightest part outshines the ground, and the sea's does not.
        // Through a camera and link chain the sea's speckle can lift its brightest part to
        // the ground's median, but not to the ground's own brightest part: a haze's glow
        // comes up to the airlight that the far ground's bright fields fade to too.
        if sky_cues.brighter < 0.0 && !sky_outshines_ground(samples, chosen.horizon, 2.0 * rho.step)
        {
            confidence *= DARKER_SKY_CONFIDENCE;
        }
        if jumped {
            confidence *= 0.7;
        }
        // The profile kept rising above the line and no top step was found there: in dim
        // light the horizon's small step is lost in the noise and the edge line is the foot
        // of the ramp up to the airlight, 3–12° low (`synth` `low-light`: 8 and 16 frames of
        // 40 past the gate on seeds 1 and 2). Where more of the rise is above the line than
        // across it, the line is not trusted; a horizon's own step is larger than what the
        // sky above it adds.
        // So is a line under a band of hazy ground (`under_ground_coloured_band` above).
        if on_ramp && (profile.at_foot_of_ramp(RAMP_EXTENT) || under_ground_coloured_band) {
            confidence *= RAMP_CONFIDENCE;
        }
        // A ridge's top is placed by a profile's brightest bin at a turn searched in steps
        // of 1.5°, not drawn by edges: on a noisy frame it can be a few degrees out.
        if on_ridge {
            confidence *= RIDGE_CONFIDENCE;
        }
        // The edge of a bar of blanked rows chosen for want of another line (see `sync_bar`).
        if sync_bar::along_blank_bar(ws.grey, geo, &camera, chosen.line) {
            confidence *= SYNC_BAR_CONFIDENCE;
        }

        // 8: the line's place in the transition, at full resolution (see `profile`). The
        // search reaches past the coarse line's smoothing on the sky side.
        let search_px = (3 * geo.scale + 3) as f32;
        let (placed, placement) =
            profile::place(frame, &camera, chosen.horizon, search_px, sky_brighter);

        // Honesty about what the frame can show. Clipped pixels (the sun and its bloom in
        // view, an over-exposed sky) hide where the sky ends: the edge found may be where the
        // clipping ends, and the horizon may be anywhere under it. A line with no clear edge
        // at full resolution is a guess from the binned image.
        let clipped = samples
            .iter()
            .filter(|s| s.luma >= hough::SATURATED)
            .count();
        let clipped_share = clipped as f32 / samples.len().max(1) as f32;
        // Where the sun is in view beside the horizon, not on all of it, the line is read
        // again only where the sky next to it is clear (`profile::clear_of_glare`): a run of
        // at least 35 % of the columns it crosses, whose two halves find the edge on the line
        // through them, clearly. There the horizon is in view, and the sky clipped elsewhere along
        // the line hides none of it; the frame's clipped share still counts, at half the
        // weight (a haze of glare over the whole frame, an over-exposed key). Before this, a
        // sun in view took the trust from frames read right to a tenth of a degree (`aerial`
        // seed 149 `clean`: 40 of 40 within 2°, none trusted). On the seen sets (13520
        // frames) right and trusted 7690 → 8274, trusted and wrong 225 → 233. Coded frames
        // are left out: their clear run's edge may be a block's.
        let read_clear = placement.clear_of_glare
            && placement.halves == profile::Halves::Confirmed
            && coded.is_none();
        let frame_weight = if read_clear {
            CLIPPED_FRAME_WEIGHT_READ_CLEAR
        } else {
            CLIPPED_FRAME_WEIGHT
        };
        confidence *= (1.0 - frame_weight * clipped_share).clamp(0.0, 1.0);
        // ... unless the clipped sky ends at a sharp step onto clearly unclipped, flat-ish
        // ground: that edge is the ground's own top, so the horizon is in view.
        if !placement.sharp_clip_end && !read_clear {
            confidence *= (1.0 - CLIPPED_SKY_WEIGHT * placement.clipped_sky).clamp(0.0, 1.0);
        }
        if placement.significance < profile::MIN_SIGNIFICANCE {
            confidence *= 0.5;
        }
        // The frame's halves each find a clear edge, on a roll more than 1.7° from the line's,
        // and no clearer line runs through them: the roll is only the binned image's guess.
        if placement.halves == profile::Halves::Contradicted {
            confidence *= CONTRADICTED_ROLL_CONFIDENCE;
        }
        // A level line on a row boundary where the frame is spliced (see `seam`).
        if seam::along_row_seam(frame, &camera, placed) {
            confidence *= SEAM_CONFIDENCE;
        }
        // A frame coded at half resolution: its edges were read through tiles a few pixels
        // either way of the horizon (see `blocks::smooth_tiles`).
        if tiled.is_some() {
            confidence *= TILED_CONFIDENCE;
        }
        if coded.is_some() && !from_region {
            // An edge line in a deblocked coded frame (see `blocks::deblock`): the ramps that
            // join its blocks also join a haze's lower edge or a field's into a long line, and
            // such a line has only a faint step where it was placed at full resolution, as a
            // region line has. On `synth` `video-link` and `blocks` (seeds 1–3) and `terrain`
            // `transmission` and `mixed` (seeds 16–18) at 320×240, the trusted lines more
            // than 2° wrong were placed at 3.4–12 times the noise (one at 82), the right ones
            // at 7.8 and more for nine in ten (median 27). With this term 3 of the 8 wrong
            // lines stay trusted, and 260 of the 280 right ones; half the span kept 272 right
            // ones and 5 wrong, one of them 2.9° of roll off at 0.42 (`video-link` seed 1,
            // frame 21).
            confidence *= ((placement.significance - profile::MIN_SIGNIFICANCE)
                / (CODED_SIGNIFICANCE_SPAN * profile::MIN_SIGNIFICANCE))
                .clamp(0.0, 1.0);
        }
        if from_region {
            // Without a clear edge where it was placed at full resolution, a region line's
            // place is only as good as the sample grid (a few pixels). A region line moved to
            // a ridge's top step needs a clearer one: a residual stripe or a hum bar's flank
            // also makes a step near a hazy ridge's top (`synth` `hazy-interference`: the
            // wrong ones placed at 11–15 times the noise, most right ones at 15–100).
            let span = if moved_to_top {
                TOP_STEP_SIGNIFICANCE_SPAN
            } else {
                3.0
            };
            confidence *= ((placement.significance - profile::MIN_SIGNIFICANCE)
                / (span * profile::MIN_SIGNIFICANCE))
                .clamp(0.0, 1.0);
        }
        let chosen = Scored {
            horizon: placed,
            ..chosen
        };

        let misses = if chosen.continues_track || self.track.is_none() {
            0
        } else {
            self.track.map_or(0, |t| t.misses.saturating_add(1))
        };
        // A jump replaces the track at once only when the old track is lost or the new line
        // is confident; otherwise the old line stays the reference for the next frame.
        self.track = match self.track {
            Some(old) if jumped && confidence < 0.5 && misses <= self.config.lost_after_frames => {
                Some(Track {
                    line: old.line,
                    misses,
                })
            }
            _ => Some(Track {
                line: chosen.horizon,
                misses: 0,
            }),
        };

        Ok(Horizon {
            roll_rad: wrap_angle(chosen.horizon.camera_roll_rad - camera.mount_roll_rad),
            pitch_rad: chosen.horizon.camera_pitch_rad() - camera.mount_pitch_rad,
            confidence: confidence.clamp(0.0, 1.0),
            line: chosen.horizon,
        })
    }

    /// Which side of a Hough line is the sky. Evidence from the image (brighter, bluer,
    /// smoother), a prior that the airplane is rarely upside down, and continuity with the
    /// tracked line, which settles it when the image is ambiguous.
    fn orient(&self, line: Line, bright_is_sky: f32) -> HorizonLine {
        // Bright side is sky: ground on the dark side, where −n·p > −rho.
        let sky_bright = HorizonLine::of_line(line, true);
        let sky_dark = HorizonLine::of_line(line, false);
        let mut evidence = bright_is_sky + 0.5 * libm::cosf(sky_bright.camera_roll_rad);
        if let Some(track) = self.track {
            evidence += 2.0 * libm::cosf(sky_bright.camera_roll_rad - track.line.camera_roll_rad);
        }
        if evidence >= 0.0 {
            sky_bright
        } else {
            sky_dark
        }
    }

    /// `line` scored as a candidate: its sky side from the image and the track, and whether
    /// it continues the track.
    fn scored(&self, line: Line, separation: hough::Separation, coverage: f32) -> Scored {
        let horizon = self.orient(line, separation.bright_is_sky());
        self.tracked(Scored::oriented(line, horizon, separation, coverage))
    }

    /// `scored` with whether it continues the track.
    fn tracked(&self, scored: Scored) -> Scored {
        Scored {
            continues_track: self.continues_track(&scored.horizon),
            ..scored
        }
    }

    /// Whether `candidate` lies within tracking's jump gate of the tracked line (none: no).
    fn continues_track(&self, candidate: &HorizonLine) -> bool {
        self.track.is_some_and(|t| self.in_gate(&t.line, candidate))
    }

    fn in_gate(&self, tracked: &HorizonLine, candidate: &HorizonLine) -> bool {
        let roll_difference = libm::fabsf(wrap_angle(
            candidate.camera_roll_rad - tracked.camera_roll_rad,
        ));
        roll_difference <= self.config.gate_roll_deg * PI / 180.0
            && libm::fabsf(candidate.offset - tracked.offset) <= self.config.gate_offset
    }
}

/// What scoring a line needs besides the line.
struct LineContext<'a> {
    camera: &'a Camera,
    knots: &'a upper::Knots,
    geo: Working,
    rho: RhoAxis,
    edges: &'a [EdgePoint],
    samples: &'a [Sample],
    max_radius2: f32,
    bands: &'a [f32],
    max_angle_difference: f32,
}

/// Farthest the search for a higher edge reaches above the chosen line (normalised units,
/// tan 15°): ground edges that out-score the horizon lie within a few degrees of it.
const HIGHER_EDGE_REACH: f32 = 0.27;
/// Ground between two edges is this much more textured than the sky above the upper one.
const GROUND_TEXTURE_RATIO: f32 = 1.5;

/// Most a horizon found above a ground edge of the same direction turns from it, in degrees
/// (the Hough bins searched either side; the refined line may turn one degree more).
const PARALLEL_TURN_DEG: f32 = 2.0;

/// The edge above `chosen` (same polarity, its direction within `turn_deg` of the chosen
/// line's: [`PARALLEL_TURN_DEG`], or [`GROUND_EDGE_TURN_DEG`] for an oblique ground edge) that
/// is the real horizon, if there is one: it must separate the frame at least half as well, be
/// drawn along a third of its length, and have textured ground between it and `chosen` under
/// smooth sky; a turned line must lie above `chosen` across the whole frame.
fn higher_edge(
    c: &LineContext<'_>,
    accumulator: &[u16],
    chosen: &Scored,
    sky_brighter: bool,
    min_votes: u16,
    turn_deg: f32,
) -> Option<Scored> {
    let bins = c.rho.bins();
    let centre = hough::angle_bin(chosen.line.angle);
    let start = c.rho.index(chosen.line.rho)? as isize;
    let sign: isize = if sky_brighter { 1 } else { -1 };
    let reach = (HIGHER_EDGE_REACH / c.rho.step) as isize;
    let mut best = Peak::default();
    let turns = turn_deg as usize;
    for da in 0..=2 * turns {
        let a = (centre + ANGLE_BINS + da - turns) % ANGLE_BINS;
        for k in 4..=reach {
            let r = start + sign * k;
            if r < 0 || r >= bins as isize {
                break;
            }
            let votes = accumulator.get(a * bins + r as usize).copied().unwrap_or(0);
            if votes > best.votes {
                best = Peak {
                    angle: a,
                    rho: r as usize,
                    votes,
                };
            }
        }
    }
    if best.votes < min_votes {
        return None;
    }
    let start_line = Line {
        angle: best.angle as f32 * hough::ANGLE_STEP,
        rho: c.rho.value(best.rho),
    };
    let (line, inliers) = hough::refine(c.edges, start_line, c.bands, c.max_angle_difference)?;
    let sky_ward = if sky_brighter { 1.0 } else { -1.0 };
    let near_parallel =
        libm::fabsf(wrap_angle(line.angle - chosen.line.angle)) < (turn_deg + 1.0) * PI / 180.0;
    // Above the edge at the frame's centre and, for a turned line, at both ends of the edge.
    if !near_parallel
        || sky_ward * (line.rho - chosen.line.rho) < 2.0 * c.rho.step
        || (turn_deg > PARALLEL_TURN_DEG && !above_across_the_frame(c, chosen.line, line, sky_ward))
    {
        return None;
    }
    let expected = expected_edge_pixels(c.camera, c.geo, line, c.rho, c.max_radius2);
    if expected < 4.0 {
        return None;
    }
    let coverage = (inliers as f32 / expected).min(1.0);
    let separation = hough::separation(c.samples, line, 2.0 * c.rho.step);
    if coverage < 0.33 || separation.explained < 0.5 * chosen.explained {
        return None;
    }
    if !textured_under_smoother_sky(c, (chosen.line, line, sky_ward), GROUND_TEXTURE) {
        return None;
    }
    Some(Scored::new(line, sky_brighter, separation, coverage))
}

/// Least coverage of a candidate taken over the chosen line by [`drawn_line_above`]: drawn
/// along most of its length, as a horizon is and a cloud's edge seldom is. Most, not nearly
/// all: a haze band's top under a link's stripes or in a sun's glow is drawn along 60–80 %
/// of it. At 0.8 before, on the seen sets (`aerial` seeds 137–165 and the tuning sets of seed
/// 1, 23600 frames) 0.6 reads 32 more frames within 2° and trusts 13 fewer wrong (`mixed`
/// +27); 0.5 read 10 more, but lost 8 on the tuning seeds 2 and 3 (0.6: one), to the
/// edges of a sun's halo above the horizon.
const DRAWN_ABOVE_COVERAGE: f32 = 0.6;
/// ... and least share of the chosen line's explained variance it must explain.
const DRAWN_ABOVE_EXPLAINED: f32 = 0.4;

/// The best-scored candidate of the chosen line's polarity drawn along nearly its whole
/// length ([`DRAWN_ABOVE_COVERAGE`]) that lies above the chosen line across the frame and
/// splits the frame at least [`DRAWN_ABOVE_EXPLAINED`] as well. A shore under a sea's
/// horizon, or the ground's edge under a haze band, splits the frame better than the horizon
/// (the sea or the haze is as bright as the sky), and [`higher_edge`] does not climb to it:
/// the two are degrees out of parallel, and there is no textured ground between them.
/// `usable` excludes the lines the caller knows a link drew (a bar's edge, a hum bar's).
fn drawn_line_above(
    c: &LineContext<'_>,
    scored: &[Option<Scored>],
    chosen: &Scored,
    usable: impl Fn(&Scored) -> bool,
) -> Option<Scored> {
    let sky_brighter = chosen.sky_brighter();
    let sky_ward = if sky_brighter { 1.0 } else { -1.0 };
    scored
        .iter()
        .flatten()
        .filter(|s| {
            s.sky_brighter() == sky_brighter
                && s.coverage >= DRAWN_ABOVE_COVERAGE
                && s.explained >= DRAWN_ABOVE_EXPLAINED * chosen.explained
                && above_across_the_frame(c, chosen.line, s.line, sky_ward)
                && usable(s)
        })
        .max_by(|a, b| a.score.total_cmp(&b.score))
        .copied()
}

/// Whether `candidate` lies on the sky side (`sky_ward`) of `edge`, by at least two rho bins,
/// at both ends of `edge` within the frame: a line across the edge inside the frame is not the
/// horizon above it.
fn above_across_the_frame(c: &LineContext<'_>, edge: Line, candidate: Line, sky_ward: f32) -> bool {
    let (nx, ny) = edge.normal();
    let (cx, cy) = candidate.normal();
    let extent = libm::sqrtf(c.max_radius2);
    [-extent, extent].iter().all(|&along| {
        let (x, y) = (edge.rho * nx - along * ny, edge.rho * ny + along * nx);
        sky_ward * (candidate.rho - (x * cx + y * cy)) >= 2.0 * c.rho.step
    })
}

/// Whether `candidate` lies on the sky side of `edge` (the sky on its normal's side) by at
/// least `steps` rho steps all along `edge` within the frame (its points inside the
/// rectangle of the frame's undistorted borders), and `edge` crosses the frame.
fn above_within_the_frame(c: &LineContext<'_>, edge: Line, candidate: Line, steps: f32) -> bool {
    let camera = c.camera;
    let (left, right) = (
        (-0.5 - camera.cx) / camera.fx,
        (camera.width as f32 - 0.5 - camera.cx) / camera.fx,
    );
    let (top, bottom) = (
        (-0.5 - camera.cy) / camera.fy,
        (camera.height as f32 - 0.5 - camera.cy) / camera.fy,
    );
    let (nx, ny) = edge.normal();
    let (cx, cy) = candidate.normal();
    let extent = libm::sqrtf(c.max_radius2);
    let mut inside = 0;
    for i in 0..=ALONG_THE_EDGE {
        let along = extent * (2.0 * i as f32 / ALONG_THE_EDGE as f32 - 1.0);
        let (x, y) = (edge.rho * nx - along * ny, edge.rho * ny + along * nx);
        if (left..=right).contains(&x) && (top..=bottom).contains(&y) {
            inside += 1;
            if candidate.rho - (x * cx + y * cy) < steps * c.rho.step {
                return false;
            }
        }
    }
    inside > 0
}

/// Points along a line at which [`above_within_the_frame`] compares.
const ALONG_THE_EDGE: usize = 32;

/// Most a ground edge's direction turns from the horizon's, in degrees: a straight field edge
/// or road on level ground, seen 6–15° below the horizon, runs out of parallel with it by up
/// to 6° where it is 35° out of square with the view (`synth` `oblique-ground-edge`).
const GROUND_EDGE_TURN_DEG: f32 = 8.0;

/// Turns of the lines the profile is also read across above a ground edge (degrees).
const TURNED_PROFILES_DEG: [f32; 4] = [
    -2.0 * TURNED_PROFILE_STEP_DEG,
    -TURNED_PROFILE_STEP_DEG,
    TURNED_PROFILE_STEP_DEG,
    2.0 * TURNED_PROFILE_STEP_DEG,
];
const TURNED_PROFILE_STEP_DEG: f32 = 3.0;

/// `line` turned by `turn` (radians) about its point nearest the frame's centre.
fn turned_about_its_foot(line: Line, turn: f32) -> Line {
    Line {
        angle: wrap_angle(line.angle + turn),
        rho: line.rho * libm::cosf(turn),
    }
}

/// Whether `chosen` is a sharp ground edge with hazy ground right above it: it splits the frame
/// and is drawn along nearly its whole length ([`SHARP_EDGE_EXPLAINED`],
/// [`SHARP_EDGE_COVERAGE`]), and the band above it (from 3 rho bins to [`HIGHER_EDGE_REACH`] / 2
/// on the sky side) is clearly less blue than the sky beyond ([`GROUND_BLUE_SHARE`]). Colour
/// frames under a blue sky only (a grey frame's chroma is 0).
fn sharp_ground_edge(c: &LineContext<'_>, chosen: &Scored, sky_brighter: bool) -> bool {
    if chosen.explained < SHARP_EDGE_EXPLAINED || chosen.coverage < SHARP_EDGE_COVERAGE {
        return false;
    }
    let sky_ward = if sky_brighter { 1.0 } else { -1.0 };
    band_blue_share(c, chosen.line, sky_ward).is_some_and(|share| share <= GROUND_BLUE_SHARE)
}

/// The blue (B − R) of the band above `line` (from 3 rho bins to [`HIGHER_EDGE_REACH`] / 2 on
/// the `sky_ward` side) as a share of the blue of the sky beyond it; `None` where either holds
/// under 8 samples or the sky beyond is not blue ([`BLUE_SKY_CHROMA`]).
fn band_blue_share(c: &LineContext<'_>, line: Line, sky_ward: f32) -> Option<f32> {
    let (nx, ny) = line.normal();
    let (band_from, band_to) = (3.0 * c.rho.step, 0.5 * HIGHER_EDGE_REACH);
    let (mut band, mut beyond) = ((0.0f32, 0u32), (0.0f32, 0u32));
    for s in c.samples {
        let d = sky_ward * (s.x * nx + s.y * ny - line.rho);
        if d >= band_to {
            beyond = (beyond.0 + s.chroma, beyond.1 + 1);
        } else if d > band_from {
            band = (band.0 + s.chroma, band.1 + 1);
        }
    }
    if band.1 < 8 || beyond.1 < 8 {
        return None;
    }
    let (band, beyond) = (band.0 / band.1 as f32, beyond.0 / beyond.1 as f32);
    (beyond >= BLUE_SKY_CHROMA).then_some(band / beyond)
}

/// Least share of the frame's variance a ground edge explains, and of its length drawn by
/// edges, for [`sharp_ground_edge`]: on `oblique-ground-edge` seed 3 the borders explained
/// 0.54–0.77 and were drawn along 0.98–1.00 (the weakly drawn lines the region search's second
/// opinion looks at are drawn along under [`REGION_RECHECK_COVERAGE`]).
const SHARP_EDGE_EXPLAINED: f32 = 0.5;
const SHARP_EDGE_COVERAGE: f32 = 0.9;
/// Least blue (B − R, levels) of a sky for [`sharp_ground_edge`] to compare a band with.
const BLUE_SKY_CHROMA: f32 = 20.0;
/// Most of the sky's blue a band above a ground edge keeps ([`sharp_ground_edge`]). On `synth`
/// seed 1 the band above a horizon held 0.67–0.70 of the blue of the sky beyond (`clean`,
/// `haze`, `roads`: the sky's glow at the horizon); above an oblique ground edge whose horizon
/// no parallel search found, 0.30 and less (`oblique-ground-edge` seeds 1–3).
const GROUND_BLUE_SHARE: f32 = 0.45;

/// Textured ground in the band between a ground edge (`edge`) and a candidate horizon above
/// it (`candidate`, the sky on its `sky_ward` side), under smoother sky: enough samples in
/// both, and the band's texture at least `ratio` times the sky's plus `plus` (for a ground
/// edge: [`GROUND_TEXTURE_RATIO`] and half a level).
fn textured_under_smoother_sky(
    c: &LineContext<'_>,
    (edge, candidate, sky_ward): (Line, Line, f32),
    (ratio, plus): (f32, f32),
) -> bool {
    let texture = hough::band_textures(c.samples, edge, candidate, sky_ward, c.rho.step);
    // Written as the refusal it negates: a NaN texture is not a refusal.
    let refused = texture.between_count < 8
        || texture.above_count < 8
        || texture.between < ratio * texture.above + plus;
    !refused
}

/// The ground edge's bar for [`textured_under_smoother_sky`].
const GROUND_TEXTURE: (f32, f32) = (GROUND_TEXTURE_RATIO, 0.5);

/// How well `line` splits the samples more than two rho steps on the sky side (`sky_ward`)
/// of `chosen`: the part of the frame above a ground edge.
fn separation_above(
    c: &LineContext<'_>,
    chosen: Line,
    line: Line,
    sky_ward: f32,
) -> hough::Separation {
    let (nx, ny) = chosen.normal();
    let margin = 2.0 * c.rho.step;
    hough::separation_of(c.samples, line, margin, |s| {
        sky_ward * (s.x * nx + s.y * ny - chosen.rho) > margin
    })
}

/// The best of `at(turn)` over the coarse `turns` (degrees), then about the best turn so far
/// by each of `refinements` either side; `key` ranks. Ties keep the later candidate, and at
/// each refinement the turn already found is the last.
fn best_turn<T>(
    turns: &[f32],
    refinements: &[f32],
    at: impl Fn(f32) -> Option<T>,
    key: impl Fn(&T) -> f32,
) -> Option<(T, f32)> {
    let best = |a: &(T, f32), b: &(T, f32)| key(&a.0).total_cmp(&key(&b.0));
    let mut found = turns
        .iter()
        .filter_map(|&turn| Some((at(turn)?, turn)))
        .max_by(best)?;
    for &step in refinements {
        let turn = found.1;
        found = [turn - step, turn + step]
            .into_iter()
            .filter_map(|t| Some((at(t)?, t)))
            .chain([found])
            .max_by(best)?;
    }
    Some(found)
}

/// The step above `chosen` that is the real horizon, found on a profile across the line
/// (see [`upper`]) when its edge points were too few for [`higher_edge`]: the same conditions
/// on the regions (it separates the frame at least half as well, textured ground between the
/// two lines under smooth sky), and on its length drawn by the profile instead of edges.
fn higher_step(
    c: &LineContext<'_>,
    profile: &upper::Profile,
    chosen: &Scored,
    sky_brighter: bool,
) -> Option<Scored> {
    let sky_ward = if sky_brighter { 1.0 } else { -1.0 };
    let step = profile.highest_step()?;
    let line = step.line;
    let separation = hough::separation(c.samples, line, 2.0 * c.rho.step);
    // Sky, far ground and near ground are three regions: a step that splits the frame less
    // than half as well as the ground edge may still be the clear boundary of what lies
    // above that edge (sky over a wide hazy band), which is what the horizon must be.
    let above_chosen = separation_above(c, chosen.line, line, sky_ward);
    if separation.explained < MIN_EXPLAINED
        || (separation.explained < 0.5 * chosen.explained
            && above_chosen.explained < ABOVE_EDGE_EXPLAINED)
    {
        return None;
    }
    if !textured_under_smoother_sky(c, (chosen.line, line, sky_ward), GROUND_TEXTURE) {
        return None;
    }
    Some(Scored::new(line, sky_brighter, separation, chosen.coverage))
}

/// Turns (degrees) of the lines across which the band above a line on a ramp is read for a
/// ridge; the best is refined by half and a quarter of the step either side.
const RIDGE_TURNS_DEG: [f32; 9] = [-24.0, -18.0, -12.0, -6.0, 0.0, 6.0, 12.0, 18.0, 24.0];
const RIDGE_TURN_STEP_DEG: f32 = 6.0;
/// Rho steps above the chosen line from which the band is read: clear of its own transition.
const RIDGE_FLOOR_MARGIN: f32 = 2.0;
/// Least prominence of a ridge (levels) above a line on a ramp: `calm-sea`'s horizons stood
/// 5.3–7.8 levels over both flanks in the profile across their own direction; the ridges
/// that profiles across other turns find in a plain sky, 1–5.
const RIDGE_PROMINENCE: f32 = 5.0;
/// Share of the variance above the chosen line that the ridge line must explain: the sky
/// over a sea splits from it (`calm-sea` 0.34–0.47), a glow or a cloud within a sky does not
/// (`terrain` `ground-edges`, ridges found above right lines: 0.04–0.24).
const RIDGE_ABOVE_EXPLAINED: f32 = 0.3;

/// Least ratio of the texture of the band between the chosen line and a ridge to that of the
/// sky above the ridge: a sea's ripples under a smooth sky (`calm-sea` 1.5–3.5), where a
/// cloud band in a cloudy sky is as textured as the clouds above it.
const RIDGE_BAND_TEXTURE_RATIO: f32 = 1.25;

/// The horizon above a line on a ramp (see [`upper::Profile::rises_above`]) where it is the
/// top of a ridge rather than a step: a calm sea mirrors the sky, brightening up to the
/// horizon, and the sky darkens away from it. Profiles of the band above `chosen` (its
/// pixels only) are read across lines turned by [`RIDGE_TURNS_DEG`]; the most prominent
/// ridge is kept when it is at least [`RIDGE_PROMINENCE`], splits the part of the frame above
/// `chosen` ([`RIDGE_ABOVE_EXPLAINED`]) and has sky above it smoother than the band under it
/// ([`RIDGE_BAND_TEXTURE_RATIO`]).
fn ridge_over_ramp(
    c: &LineContext<'_>,
    grey: &[u8],
    chosen: &Scored,
    reach: usize,
) -> Option<Scored> {
    // The caller asks for a sky brighter than the ground: the sky is on the normal's side.
    let sky_ward = 1.0;
    let ridge_at = |turn_deg: f32| {
        let line = turned_about_its_foot(chosen.line, turn_deg * PI / 180.0);
        upper::Profile::measure_above(
            grey,
            c.geo,
            (c.camera, c.knots),
            (line, sky_ward, c.rho.step, reach),
            (chosen.line, RIDGE_FLOOR_MARGIN),
        )
        .ridge()
    };
    let refinements = [0.5 * RIDGE_TURN_STEP_DEG, 0.25 * RIDGE_TURN_STEP_DEG];
    let (ridge, _) = best_turn(&RIDGE_TURNS_DEG, &refinements, ridge_at, |r| r.prominence)?;
    if ridge.prominence < RIDGE_PROMINENCE {
        return None;
    }
    let above_chosen = separation_above(c, chosen.line, ridge.line, sky_ward);
    if above_chosen.explained < RIDGE_ABOVE_EXPLAINED
        || !textured_under_smoother_sky(
            c,
            (chosen.line, ridge.line, sky_ward),
            (RIDGE_BAND_TEXTURE_RATIO, 0.0),
        )
    {
        return None;
    }
    let separation = hough::separation(c.samples, ridge.line, 2.0 * c.rho.step);
    Some(Scored::new(ridge.line, true, separation, chosen.coverage))
}

/// Least texture of the band between a shore and the sea's horizon found above it, as a
/// share of the sky's above that horizon ([`sea_over_shore`]). The sea's ripples and the
/// clouds in its sky measured about alike (`aerial` seed 142 `ground-edges`: 0.8–1.0 of the
/// sky's), so the ridge's bar (a band rougher than its sky, [`RIDGE_BAND_TEXTURE_RATIO`])
/// refused them; a glow under a hazy horizon that was read right is far smoother than its
/// sky (`synth` `haze`, the one such frame: 0.29) and must not be taken for a sea.
const SEA_BAND_TEXTURE_SHARE: f32 = 0.5;

/// The horizon over a sea beyond a shore turned from it (the coast at an angle to the view).
/// The chosen line is the shore, stepping down towards a side darker near it that is, as a
/// whole, the brighter (the caller asks): the sea darkens away from the horizon, under a
/// step there of a few levels (seed 142 `ground-edges`: 6–8), and is darkest at the shore.
/// The part of the frame on that side of the shore is split in two ([`region::search_above`]):
/// sea and sky, the split somewhere on the sea's long ramp. It is taken when its brighter
/// side faces away from the shore (the sky over the sea: a split the other way round is no
/// horizon over this shore), it splits that part well ([`RIDGE_ABOVE_EXPLAINED`], as the
/// ridge's), the band between it and the shore is textured at least
/// [`SEA_BAND_TEXTURE_SHARE`] of the sky above it, and it splits the frame
/// ([`MIN_EXPLAINED`]); the top of its transition must be one step the two halves of the line
/// agree on ([`region::top_step`]) and split the frame as well: the horizon is that step. Not
/// required: that the horizon lies above the shore all across the frame, as a shore turned
/// 20–30° meets it in the frame.
fn sea_over_shore(c: &LineContext<'_>, grey: &[u8], chosen: &Scored) -> Option<Scored> {
    // The shore with its normal towards its sky side.
    let shore = Line {
        angle: chosen.line.angle + PI,
        rho: -chosen.line.rho,
    };
    let split = region::search_above(
        c.samples,
        libm::sqrtf(c.max_radius2),
        shore,
        2.0 * c.rho.step,
    )?;
    // The split's normal points to its brighter side, which the measures below take for
    // the sky's.
    let faces_away = libm::cosf(split.angle - shore.angle) > 0.0;
    if !faces_away || separation_above(c, shore, split, 1.0).explained < RIDGE_ABOVE_EXPLAINED {
        return None;
    }
    let textured =
        textured_under_smoother_sky(c, (shore, split, 1.0), (SEA_BAND_TEXTURE_SHARE, 0.0));
    if !textured || hough::separation(c.samples, split, 2.0 * c.rho.step).explained < MIN_EXPLAINED
    {
        return None;
    }
    let top = region::top_step(grey, c.geo, c.camera, split, c.rho.step, 1.0)
        .filter(|top| top.halves_agree && top.one_transition)?;
    let separation = hough::separation(c.samples, top.line, 2.0 * c.rho.step);
    (separation.explained >= MIN_EXPLAINED)
        .then(|| Scored::new(top.line, true, separation, chosen.coverage))
}

/// The split of the frame by colour alone ([`region::search_by_colour`]) where it explains
/// at least [`COLOUR_SPLIT_GAIN`] more of the colour's variance than `line`, the region
/// search's split by luma and colour, does; `band` leaves out the samples on the lines.
/// Colour frames only. Where no edge line splits the frame, a sun's glow over a hazy horizon
/// pulls the region split along the glow (`aerial` seed 140 `glare`: 20–65° of roll off, on
/// every frame with the sun in view) while the blue sky still splits from the grey ground by
/// colour at the horizon.
fn colour_split_over(samples: &[Sample], extent: f32, line: Line, band: f32) -> Option<Line> {
    if samples.iter().all(|s| s.chroma == 0.0) {
        return None;
    }
    let by_colour = region::search_by_colour(samples, extent)?;
    let gain = hough::separation(samples, by_colour, band).colour_explained
        - hough::separation(samples, line, band).colour_explained;
    (gain >= COLOUR_SPLIT_GAIN).then_some(by_colour)
}

/// How much more of the colour's variance the split by colour must explain than the region
/// search's own to replace it ([`colour_split_over`]). Measured on the 240 frames with a
/// horizon and no edge line of the tuning sets (seed 1) and the seen `aerial` seeds 137–143:
/// taking the colour's split on all of them put 89 right that were wrong and 16 wrong that
/// were right; on those whose gain was at least 0.3, 73 and 2 (seed 140 `mixed` 320, frames
/// 37–38), at least 0.4, 60 and the same 2.
/// `terrain` `transmission`'s frames, where colour alone lost 4 of the 16, gained 0.26–0.29:
/// 0.4 keeps clear of them.
const COLOUR_SPLIT_GAIN: f32 = 0.4;

/// Turns (degrees) about which [`turned_top_over_ramp`] looks for a top step; each search
/// covers ±3° about its turn.
const RAMP_TOP_TURNS_DEG: [f32; 2] = [-6.0, 6.0];
/// Bins above the line from which the turned top step is looked for: clear of the line's own
/// fall, which a turned profile smears over a few bins.
const RAMP_TOP_ABOVE_BINS: usize = 3;
/// The step must start within this share of the profile's range of its highest bin (the top
/// step's own: 0.25): the band's lower ramp, up from the edge, is often steeper than the
/// horizon's step, but its top is the band's level, well under the sky's.
const RAMP_TOP_SHARE: f32 = 0.15;
/// Most of the sky's blue the band above the line keeps for the turned top step to be looked
/// for ([`band_blue_share`]; the band it measures reaches past the horizon into the sky).
/// Measured with this rule's first form (no [`RAMP_TOP_SHARE`], a clearance of 3 steps): the
/// lines it moved to the horizon on the tuning sets and seeds 137–140 had 0.20–0.46; of the
/// 5600 frames it ran on 1062 ungated, 767 at 0.6 and 292 at 0.45 (the search reads 18 turned
/// profiles: ungated it cost 10 % of the median frame on seeds 137–140).
const RAMP_BAND_BLUE_SHARE: f32 = 0.5;
/// Least distance (rho steps) of the turned top step above the line anywhere in the frame: a
/// horizon and a ground edge turned from it nearly meet at one side of the frame.
const RAMP_TOP_CLEAR_STEPS: f32 = 1.0;
/// Share of the chosen line's split that a turned top step must keep.
const RAMP_TOP_KEEPS_SPLIT: f32 = 0.5;

/// The horizon above a line at the foot of a ramp, where the line is a ground edge turned
/// from the horizon by more than the top step's own search reaches (±3°): a crisp step at
/// the top of a hazy band whose foot is the edge, where the band is far less blue than the
/// sky ([`RAMP_BAND_BLUE_SHARE`]). Looked for across lines turned by [`RAMP_TOP_TURNS_DEG`],
/// from [`RAMP_TOP_ABOVE_BINS`] above the line and near the sky's level ([`RAMP_TOP_SHARE`]);
/// the step must lie above the line all across the frame ([`RAMP_TOP_CLEAR_STEPS`]), the two
/// halves agree on it, the profile fall all the way from it to the line, and it keep
/// [`RAMP_TOP_KEEPS_SPLIT`] of the line's split (the band is nearly as bright as the sky, so
/// the horizon splits the frame less well than the edge: 0.45–0.58 against 0.77–0.87 of the
/// variance on `aerial` seed 140's `sensor-noise` frames).
fn turned_top_over_ramp(c: &LineContext<'_>, grey: &[u8], chosen: &Scored) -> Option<Scored> {
    if !band_blue_share(c, chosen.line, 1.0).is_some_and(|share| share <= RAMP_BAND_BLUE_SHARE) {
        return None;
    }
    RAMP_TOP_TURNS_DEG
        .iter()
        .filter_map(|&turn| {
            let line = turned_about_its_foot(chosen.line, turn * PI / 180.0);
            let top = region::top_step_above(
                grey,
                c.geo,
                c.camera,
                line,
                Some(region::AboveLine {
                    bins: RAMP_TOP_ABOVE_BINS,
                    top_share: RAMP_TOP_SHARE,
                }),
                c.rho.step,
                1.0,
            )?;
            let drawn_above = top.halves_agree
                && top.one_transition
                && above_within_the_frame(c, chosen.line, top.line, RAMP_TOP_CLEAR_STEPS);
            if !drawn_above {
                return None;
            }
            let separation = hough::separation(c.samples, top.line, 2.0 * c.rho.step);
            (separation.explained >= (RAMP_TOP_KEEPS_SPLIT * chosen.explained).max(MIN_EXPLAINED))
                .then(|| Scored::new(top.line, true, separation, chosen.coverage))
        })
        .max_by(|a, b| a.explained.total_cmp(&b.explained))
}

/// Share of the variance above a ground edge that a step found there must explain to be taken
/// for the horizon when it splits the whole frame less than half as well as the edge.
const ABOVE_EDGE_EXPLAINED: f32 = 0.5;

/// The frame's noise level in units of the Sobel magnitude: the quiet part of the gradient
/// distribution ([`NOISE_PERCENTILE`]), but no more than white noise with the frame's
/// Laplacian would give. White noise of σ gives a 30th percentile of about 3.7σ and a
/// Laplacian mean of 4.8σ, so on noisy frames the cap does not bind; a smooth periodic
/// pattern (interference) raises the gradient everywhere but not the Laplacian, and is no
/// longer taken for noise that every edge must be three times stronger than.
///
/// `matters_above`: a level at or below this decides nothing for the caller, so the
/// percentile is returned as it is without the Laplacian pass (the cap only lowers the level).
/// `laplacian`: the pass's result on this working image, if it was measured (and then kept).
fn noise_level(
    histogram: &edges::GradientHistogram,
    grey: &[u8],
    geo: Working,
    matters_above: u16,
    laplacian: &mut Option<f32>,
) -> u16 {
    let percentile = histogram.percentile(NOISE_PERCENTILE);
    if percentile <= matters_above {
        return percentile;
    }
    let cap = *laplacian.get_or_insert_with(|| edges::laplacian_mean_abs(grey, geo));
    if f32::from(percentile) > cap {
        cap as u16
    } else {
        percentile
    }
}

/// Evidence that one side is the sky ([`hough::SkyCues::agreed`]) at and above which
/// it costs the confidence nothing; below it the confidence falls in proportion. Measured with
/// the cues' plain sum (fourth session) on `synth` seeds 1 and 2: the no-horizon frames' lines
/// 0.7 at most, real horizons (low light included) 1.4 and up; 1.5 began to cost those.
const CLEAR_SKY_EVIDENCE: f32 = 1.0;

/// Confidence kept by a line under a striped sky (see [`upper::Profile::striped`]): a
/// crest next to the horizon explains nearly as much of the frame, and it is not known which.
const STRIPED_CONFIDENCE: f32 = 0.25;

/// A destriped line with a clear step more than this many working pixels above it, in the same
/// transition, is ambiguous (see `upper::Profile::top_of_transition`).
const TOP_AMBIGUITY: f32 = 2.0;
/// A region line moved to a ridge's top step keeps its full confidence only when its
/// full-resolution edge is this many times [`profile::MIN_SIGNIFICANCE`] above it (other region
/// lines: 3).
const TOP_STEP_SIGNIFICANCE_SPAN: f32 = 6.0;

/// An edge line moved to the top step above it must keep this share of the variance it
/// explained: below a thick ramp a split mid-ramp explains a little more than the ridge's top
/// (`synth` `low-light` 640: 0.94 of it), the top of a bright stripe above a real horizon far
/// less (`white-stripes`: 0.66).
const TOP_STEP_KEEPS_SPLIT: f32 = 0.85;

/// The region search runs when no edge line explains this share of the frame's variance ...
const REGION_TRIGGER: f32 = 0.3;
/// ... and its line replaces them when it explains this many times more than the best.
const REGION_MARGIN: f32 = 1.5;
/// The region search also runs, near the best edge line's direction, when that line explains
/// less than this share and is drawn along less than [`REGION_RECHECK_COVERAGE`] of its
/// length ...
const REGION_RECHECK: f32 = 0.75;
const REGION_RECHECK_COVERAGE: f32 = 0.8;
/// ... and its line replaces the edge lines when it explains this many times more.
const REGION_RECHECK_MARGIN: f32 = 1.15;
/// A frame whose luma steps this many times more on an 8-pixel grid than off it
/// ([`blocks::grid_contrast`]) was coded in blocks, coarsely. On `synth` seed 1 (40 frames a
/// set, 320×240; `video-link` and `blocks` also at 640×480, seed 1, 20 frames): camera frames
/// 1.0–1.4, up to 2.0 under glare's bloom and 12 where lost rows fall on the grid (the
/// stripes); `tree-line`, coded at a high quality, 1.4–2.5; `video-link` 2.9–13.5, `blocks`
/// 5.6–16.3. Between the codec's high and low qualities.
const CODED_IN_BLOCKS: f32 = 2.7;
/// A frame whose luma steps this many times more on the 8-pixel grid than off it shows its
/// codec's blocks, coded or not by [`CODED_IN_BLOCKS`]: its edge points keep their Sobel
/// directions (see `edges::step_gradient`), the block borders around them being no smooth
/// ramp. Camera frames 1.0–1.4, up to 2.0 under glare's bloom (see above); on the seen `aerial`
/// sets, `transmission` 320 px lost 17 frames within 2° to ramps taken out (read at two
/// pixels) under blocks that showed at 2.0–2.7 (seed 155 frame 23: 2.56, tiles of 16 pixels).
const BLOCKS_SHOW: f32 = 2.0;
// A coded frame shows its blocks: the edge pass reads `coded` through `BLOCKS_SHOW` alone.
const _: () = assert!(BLOCKS_SHOW <= CODED_IN_BLOCKS);
/// ... and its blocks show across rows and across columns alike, each this many times more
/// on the grid than off it ([`blocks::Grid::weaker_axis`]): on `synth` seed 1 at 320×240 (a
/// numpy model of the figure), 2.7 or more on 95 % of `video-link`'s frames and 4.8 or more
/// on 95 % of `blocks`', 1.0–1.1 on `white-stripes`' and `black-stripes`' (their bars fall on
/// the rows' grid, the combined figure up to 12).
const CODED_ON_BOTH_AXES: f32 = 2.0;
/// Confidence kept by a line of a frame coded at half resolution. On the `synth` and
/// `terrain` tuning sets at 320×240 through `camera_chain.py --stages jpeg-half
/// --jpeg-quality 4,22` (1454 frames found so coded), the answers past the gate right / wrong
/// were 328 / 70 before the tiles were smoothed, 504 / 89 after, and with this factor 459 /
/// 69 (0.8: 482 / 75; 0.6: 433 / 54): the most it keeps without more trusted wrong answers.
const TILED_CONFIDENCE: f32 = 0.7;
/// How far above `profile::MIN_SIGNIFICANCE`, in its units, an edge line of a deblocked
/// coded frame must be placed to keep all its confidence (none at the minimum).
const CODED_SIGNIFICANCE_SPAN: f32 = 1.0;
/// A clear split (explaining at least [`REGION_RECHECK`]) replaces an edge line explaining
/// less than that when it explains this much more.
const CLEAR_SPLIT_MARGIN: f32 = 1.03;

/// What a region line must explain to replace the best edge line: `margin` times as much as
/// that line, and `least` of the frame's variance itself.
struct SplitBar {
    margin: f32,
    least: f32,
}

/// No edge line splits the frame (the best explains under [`REGION_TRIGGER`]).
const NO_EDGE_LINE_BARS: [SplitBar; 1] = [SplitBar {
    margin: REGION_MARGIN,
    least: MIN_EXPLAINED,
}];
/// A clear split: explaining most of the frame, and a little more than the edge line.
const CLEAR_SPLIT: SplitBar = SplitBar {
    margin: CLEAR_SPLIT_MARGIN,
    least: REGION_RECHECK,
};
/// A clear split near a weak edge line.
const CLEAR_SPLIT_BARS: [SplitBar; 1] = [CLEAR_SPLIT];
/// A frame coded in blocks: any split well ahead of the edge line, or a clear one a little
/// ahead (`synth` `video-link` seed 3: splits explaining 0.77–0.80 against edge lines at
/// 0.71–0.74, 7° of roll off the horizon, were held back by the first bar alone).
const CODED_FRAME_BARS: [SplitBar; 2] = [
    SplitBar {
        margin: REGION_RECHECK_MARGIN,
        least: MIN_EXPLAINED,
    },
    CLEAR_SPLIT,
];
/// What confidence a sky darker than its ground keeps, where even the sky's brightest part
/// does not outshine the ground (see [`sky_outshines_ground`]).
const DARKER_SKY_CONFIDENCE: f32 = 0.25;
/// The sky's brightest part: this share of its samples is darker.
const SKY_BRIGHT_QUANTILE: f32 = 0.9;
/// Most levels the brightest part of a sky darker than its ground falls short of the
/// ground's brightest part (both [`SKY_BRIGHT_QUANTILE`]). On the tuning sets as rendered and
/// through the camera-and-link chains, the sky over the right lines fell short by 24 levels
/// at most (312 frames, `synth` `haze` through the `interference` link the closest); the sea
/// seen from above that `calm-sea` passed through the chains offered as a sky, by 44 and more
/// (19 frames past the gate).
const SKY_GLOW_SHORTFALL: usize = 32;

/// Share of its confidence a line keeps when the frame's halves contradict its roll (see
/// `profile::Halves`). On the tuning sets passed through a camera-and-link chain
/// (`tools/horizon/camera_chain.py`: a Bayer sensor, an analogue link, libjpeg; 6720 frames),
/// it takes 72 of 245 false confidences away, and 107 of 1818 right answers out of the
/// estimator's reach; on the tuning sets as rendered (7920 frames), 16 of 108 and 22 of 5084.
/// Halving as well the confidence of lines whose halves only put the edge elsewhere on the same
/// roll (`Halves::Apart`: a hill on one side) took 3.6–4.6 right answers out of reach for each
/// further false confidence, and 23 of the real Horizon-UAV frames' right answers for one.
const CONTRADICTED_ROLL_CONFIDENCE: f32 = 0.5;

/// Share of its confidence a line along a seam of the frame's rows keeps (see `seam`), as a
/// bar's edge does: a splice of two pictures is where the horizon is only by chance. On the
/// tuning sets through the camera-and-link chain it took 54 of 173 false confidences away and
/// 4 of 1711 right answers out of the estimator's reach (lines on a splice that happened to
/// lie within 2° of the horizon); on the sets as rendered, 1 and 3; none on Horizon-UAV.
const SEAM_CONFIDENCE: f32 = 0.25;

/// What confidence an edge line keeps at the foot of a ramp (see
/// `upper::Profile::at_foot_of_ramp`) with no top step found to move to ...
const RAMP_CONFIDENCE: f32 = 0.25;
/// ... a ramp whose transition reaches this far above the line (normalised units, tan 5.7°:
/// 14 working pixels at 320×240 and 640×480, 60° wide). Measured on `synth`, most lines right
/// under a hazy glow have transitions ending 5–10 working pixels above them, the feet of
/// dim light's ramps 16–37; above real horizons the sky may go on brightening as far, but
/// by less than across the horizon (`at_foot_of_ramp`'s second test).
const RAMP_EXTENT: f32 = 0.1;
/// Share of its confidence a line along a bar of blanked rows keeps (see `sync_bar`): on
/// `synth` `black-stripes` seed 2, frame 29's bar edge (9° off) was its only candidate.
const SYNC_BAR_CONFIDENCE: f32 = 0.25;
/// Share of its confidence a horizon found as a ridge above a line on a ramp keeps (see
/// `ridge_over_ramp`): placed by a profile's brightest bin, not by edges, such lines added 11
/// false confidences on the camera-and-link chain (2.5–12° out) while taking 7 away.
const RIDGE_CONFIDENCE: f32 = 0.7;
/// Most confidence a line found by regions gets (its edges are not what drew it).
const REGION_CONFIDENCE: f32 = 0.8;
/// A region line is not drawn by edges: it counts as covered along its length, so that its
/// score is how well it splits the frame.
const REGION_COVERAGE: f32 = 1.0;

/// A family of stripes is looked for only under a chosen line scoring less than this (its
/// edges drawing under half its length, or its split weak): a clear horizon needs no second
/// look, and the measurement costs about 0.1 ms.
const FAMILY_WEAK_SCORE: f32 = 0.5;
/// Parallel candidates (within [`FAMILY_ANGLE`]) that make a family of stripes.
const FAMILY: usize = 3;
const FAMILY_ANGLE: f32 = 1.5 * PI / 180.0;

/// Whether the brightest part of the sky side of `horizon` (its [`SKY_BRIGHT_QUANTILE`]
/// luma) is at least as bright as the ground side's median, and within
/// [`SKY_GLOW_SHORTFALL`] of the ground's own brightest part: a sky glows at the horizon even
/// where its blue zenith is darker than a hazy ground; a sea seen from above does not. Samples
/// within `band` of the line, and clipped ones, are left out.
fn sky_outshines_ground(samples: &[Sample], horizon: HorizonLine, band: f32) -> bool {
    const BINS: usize = 64;
    let (s, c) = (
        libm::sinf(horizon.camera_roll_rad),
        libm::cosf(horizon.camera_roll_rad),
    );
    let (mut sky, mut ground) = ([0u32; BINS], [0u32; BINS]);
    for sample in samples.iter().filter(|p| p.luma < hough::SATURATED) {
        let d = s * sample.x + c * sample.y - horizon.offset;
        let side = if d < -band {
            &mut sky
        } else if d > band {
            &mut ground
        } else {
            continue;
        };
        let bin = ((sample.luma.max(0.0) * BINS as f32 / 256.0) as usize).min(BINS - 1);
        if let Some(count) = side.get_mut(bin) {
            *count += 1;
        }
    }
    // The bin below which `share` of the side's samples lie.
    let quantile = |side: &[u32; BINS], share: f32| {
        let total: u32 = side.iter().sum();
        let wanted = (share * total as f32) as u32;
        let mut seen = 0;
        side.iter()
            .position(|&n| {
                seen += n;
                seen > wanted
            })
            .unwrap_or(BINS)
    };
    let sky_glow = quantile(&sky, SKY_BRIGHT_QUANTILE);
    sky_glow >= quantile(&ground, 0.5)
        && sky_glow + SKY_GLOW_SHORTFALL * BINS / 256 >= quantile(&ground, SKY_BRIGHT_QUANTILE)
}

/// A candidate with at least [`FAMILY`] − 1 others parallel to it (either polarity) and not
/// the same line: the crests of a periodic pattern (several candidates refined onto one
/// horizon are not a family). The one with the most parallels, the best scored among equals.
fn stripe_family(scored: &[Option<Scored>], rho_step: f32) -> Option<Line> {
    let parallel = |a: Line, b: Line| in_one_family(a, b) && !same_line(a, b, rho_step);
    let mut best: Option<(usize, f32, Line)> = None;
    for s in scored.iter().flatten() {
        let count = 1 + scored
            .iter()
            .flatten()
            .filter(|o| parallel(o.line, s.line))
            .count();
        if count >= FAMILY && best.is_none_or(|(c, score, _)| (count, s.score) > (c, score)) {
            best = Some((count, s.score, s.line));
        }
    }
    best.map(|(_, _, line)| line)
}

/// Whether two lines are parallel within [`FAMILY_ANGLE`], either polarity: members of one
/// family of stripes.
fn in_one_family(a: Line, b: Line) -> bool {
    let d = libm::fabsf(wrap_angle(a.angle - b.angle));
    d < FAMILY_ANGLE || PI - d < FAMILY_ANGLE
}

/// Candidates kept per direction (either polarity, within [`DIRECTION_BINS`] angle bins).
const PER_DIRECTION: usize = 2;
const DIRECTION_BINS: usize = 3;

/// Copies `found` (strongest first) into `out`, at most [`PER_DIRECTION`] per direction, then
/// fills what room is left with the others in their order. Returns how many were written.
fn diverse_peaks(found: &[Peak], out: &mut [Peak]) -> usize {
    let same_direction = |a: &Peak, b: &Peak| {
        let d = (a.angle + ANGLE_BINS - b.angle) % (ANGLE_BINS / 2);
        d <= DIRECTION_BINS || d >= ANGLE_BINS / 2 - DIRECTION_BINS
    };
    let mut taken = [false; MAX_CANDIDATES];
    let mut count = 0usize;
    for (i, p) in found.iter().enumerate() {
        if count >= out.len() {
            break;
        }
        let chosen = out.get(..count).unwrap_or(&[]);
        if chosen.iter().filter(|c| same_direction(c, p)).count() >= PER_DIRECTION {
            continue;
        }
        if let (Some(slot), Some(t)) = (out.get_mut(count), taken.get_mut(i)) {
            *slot = *p;
            *t = true;
            count += 1;
        }
    }
    for (p, &t) in found.iter().zip(&taken) {
        if count >= out.len() {
            break;
        }
        if !t && let Some(slot) = out.get_mut(count) {
            *slot = *p;
            count += 1;
        }
    }
    count
}

fn best_of(scored: &[Option<Scored>], keep: impl Fn(&Scored) -> bool) -> Option<Scored> {
    scored
        .iter()
        .flatten()
        .filter(|s| keep(s))
        .fold(None, |best: Option<Scored>, s| match best {
            Some(b) if b.score >= s.score => Some(b),
            _ => Some(*s),
        })
}

/// Two lines within 3° and 4 rho steps of each other, in either polarity.
fn same_line(a: Line, b: Line, rho_step: f32) -> bool {
    let close = |angle: f32, rho: f32| {
        libm::fabsf(wrap_angle(angle - b.angle)) < 3.0 * PI / 180.0
            && libm::fabsf(rho - b.rho) < 4.0 * rho_step
    };
    close(a.angle, a.rho) || close(a.angle + PI, -a.rho)
}

/// Edge pixels a line would have if it were an edge all the way across the frame: its length
/// inside the (distorted) frame in working pixels, times the pixels a thinned edge has per
/// unit of length in its direction (1 along an axis, 1/√2 diagonally).
/// Largest squared normalised radius of the undistorted frame: points beyond it are outside
/// the frame, and beyond it a barrel model can fold back into the frame.
fn undistorted_corner_radius2(camera: &Camera, width: usize, height: usize) -> f32 {
    let (w, h) = (width as f32 - 0.5, height as f32 - 0.5);
    let corner = [(-0.5, -0.5), (w, -0.5), (-0.5, h), (w, h)]
        .iter()
        .filter_map(|&(u, v)| camera.undistort_pixel(u, v))
        .map(|(x, y)| x * x + y * y)
        .fold(0.0, f32::max);
    if corner > 0.0 {
        corner * 1.05
    } else {
        f32::INFINITY
    }
}

fn expected_edge_pixels(
    camera: &Camera,
    geo: Working,
    line: Line,
    rho: RhoAxis,
    max_radius2: f32,
) -> f32 {
    let (nx, ny) = line.normal();
    let (dx, dy) = (ny, -nx);
    let (ox, oy) = (nx * line.rho, ny * line.rho);
    let (w, h) = (
        (geo.width * geo.scale) as f32,
        (geo.height * geo.scale) as f32,
    );
    let half = rho.half as i32;
    let mut inside = 0u32;
    // Every other rho step is precise enough for a share of the length.
    for k in (-half..=half).step_by(2) {
        let t = k as f32 * rho.step;
        let (x, y) = (ox + t * dx, oy + t * dy);
        if x * x + y * y > max_radius2 {
            continue;
        }
        let (u, v) = camera.project(x, y);
        if u >= 0.0 && v >= 0.0 && u < w && v < h {
            inside += 1;
        }
    }
    let (px, py) = (libm::fabsf(dx) * camera.fx, libm::fabsf(dy) * camera.fy);
    let mean_focal = 0.5 * (camera.fx + camera.fy);
    2.0 * inside as f32 * px.max(py) / mean_focal
}
