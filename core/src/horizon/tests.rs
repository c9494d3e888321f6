//! Clean hand-made frames: a two-tone horizon drawn from the conventions' formula at a known
//! roll and pitch, which the detector must give back.

use super::*;
use std::vec;
use std::vec::Vec;

const DEG: f32 = PI / 180.0;

/// Buffers for one frame size, owned by the test.
struct Buffers {
    grey: Vec<u8>,
    rows: Vec<u16>,
    edges: Vec<EdgePoint>,
    accumulator: Vec<u16>,
    samples: Vec<Sample>,
}

impl Buffers {
    fn new(width: usize, height: usize) -> Self {
        let s = Workspace::required_sizes(width, height);
        Buffers {
            grey: vec![0; s.grey],
            rows: vec![0; s.rows],
            edges: vec![EdgePoint::ZERO; s.edges],
            accumulator: vec![0; s.accumulator],
            samples: vec![Sample::ZERO; s.samples],
        }
    }

    fn workspace(&mut self) -> Workspace<'_> {
        Workspace {
            grey: &mut self.grey,
            rows: &mut self.rows,
            edges: &mut self.edges,
            accumulator: &mut self.accumulator,
            samples: &mut self.samples,
        }
    }
}

/// Renders sky and ground colours from the conventions' line, 4×4 supersampled so that the
/// edge has sub-pixel position information like a real camera's.
fn render(camera: &Camera, roll: f32, pitch: f32, sky: [u8; 3], ground: [u8; 3]) -> Vec<u8> {
    let line = HorizonLine::from_attitude(roll, pitch);
    let (w, h) = (camera.width as usize, camera.height as usize);
    let mut rgb = vec![0u8; w * h * 3];
    for v in 0..h {
        for u in 0..w {
            let mut ground_hits = 0u32;
            for sy in 0..4 {
                for sx in 0..4 {
                    let pu = u as f32 - 0.375 + 0.25 * sx as f32;
                    let pv = v as f32 - 0.375 + 0.25 * sy as f32;
                    let (x, y) = camera.undistort_pixel(pu, pv).expect("inside the model");
                    if line.is_ground(x, y) {
                        ground_hits += 1;
                    }
                }
            }
            let t = ground_hits as f32 / 16.0;
            for c in 0..3 {
                let value = sky[c] as f32 * (1.0 - t) + ground[c] as f32 * t;
                rgb[(v * w + u) * 3 + c] = (value + 0.5) as u8;
            }
        }
    }
    rgb
}

fn to_grey(rgb: &[u8]) -> Vec<u8> {
    rgb.chunks_exact(3)
        .map(|p| frame::luma(p[0], p[1], p[2]))
        .collect()
}

fn camera_320() -> Camera {
    Camera::ideal(320, 240, 60.0 * DEG)
}

fn detect_once(camera: Camera, pixels: Pixels<'_>) -> Option<Horizon> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let frame = match pixels {
        Pixels::Grey(d) => Frame::grey(w, h, d),
        Pixels::Rgb(d) => Frame::rgb(w, h, d),
    }
    .expect("frame fits");
    let mut buffers = Buffers::new(w, h);
    let mut detector = HorizonDetector::new(camera);
    detector.detect(&frame, &mut buffers.workspace())
}

fn assert_attitude(h: Option<Horizon>, roll_deg: f32, pitch_deg: f32, tolerance_deg: f32) {
    let h = h.expect("a horizon");
    let roll_error = wrap_angle(h.roll_rad - roll_deg * DEG) / DEG;
    let pitch_error = (h.pitch_rad - pitch_deg * DEG) / DEG;
    assert!(
        roll_error.abs() < tolerance_deg && pitch_error.abs() < tolerance_deg,
        "expected roll {roll_deg} pitch {pitch_deg}, got roll {} pitch {} (confidence {})",
        h.roll_rad / DEG,
        h.pitch_rad / DEG,
        h.confidence
    );
}

const SKY: [u8; 3] = [150, 190, 235];
const GROUND: [u8; 3] = [70, 100, 50];

#[test]
fn level_horizon_through_the_centre() {
    let camera = camera_320();
    let grey = to_grey(&render(&camera, 0.0, 0.0, SKY, GROUND));
    let h = detect_once(camera, Pixels::Grey(&grey));
    assert_attitude(h, 0.0, 0.0, 0.3);
    assert!(h.expect("found").confidence > 0.8);
}

#[test]
fn rolled_and_pitched_grey() {
    let camera = camera_320();
    for (roll, pitch) in [(20.0, 5.0), (-35.0, -8.0), (60.0, 0.0), (-5.0, 12.0)] {
        let grey = to_grey(&render(&camera, roll * DEG, pitch * DEG, SKY, GROUND));
        assert_attitude(detect_once(camera, Pixels::Grey(&grey)), roll, pitch, 0.5);
    }
}

#[test]
fn rolled_and_pitched_rgb() {
    let camera = camera_320();
    let rgb = render(&camera, -25.0 * DEG, 6.0 * DEG, SKY, GROUND);
    assert_attitude(detect_once(camera, Pixels::Rgb(&rgb)), -25.0, 6.0, 0.5);
}

#[test]
fn positive_roll_lifts_the_right_end() {
    // The conventions' sign: with positive roll the horizon is higher (smaller v) on the right.
    let camera = camera_320();
    let line = HorizonLine::from_attitude(20.0 * DEG, 0.0);
    let (right_x, _) = camera.undistort_pixel(300.0, 120.0).expect("inside");
    // On the centre row at the right, the point is below the horizon: ground.
    assert!(line.is_ground(right_x, 0.0));
    let grey = to_grey(&render(&camera, 20.0 * DEG, 0.0, SKY, GROUND));
    let h = detect_once(camera, Pixels::Grey(&grey)).expect("found");
    assert!(h.roll_rad > 0.0);
}

#[test]
fn upside_down_when_the_sky_is_clearly_the_bright_side() {
    let camera = camera_320();
    let rgb = render(&camera, 160.0 * DEG, 3.0 * DEG, SKY, GROUND);
    assert_attitude(detect_once(camera, Pixels::Rgb(&rgb)), 160.0, 3.0, 0.5);
}

#[test]
fn dark_sky_bright_ground_resolved_by_colour() {
    // Sunset-like: the sky darker than a sunlit ground but still bluer and smoother.
    let camera = camera_320();
    let rgb = render(
        &camera,
        10.0 * DEG,
        -4.0 * DEG,
        [60, 80, 140],
        [170, 160, 90],
    );
    assert_attitude(detect_once(camera, Pixels::Rgb(&rgb)), 10.0, -4.0, 0.5);
}

#[test]
fn radial_distortion_is_corrected() {
    let mut camera = Camera::ideal(320, 240, 70.0 * DEG);
    camera.k1 = -0.25;
    camera.k2 = 0.05;
    let grey = to_grey(&render(&camera, 15.0 * DEG, 10.0 * DEG, SKY, GROUND));
    assert_attitude(detect_once(camera, Pixels::Grey(&grey)), 15.0, 10.0, 0.5);
}

#[test]
fn binned_large_frame() {
    let camera = Camera::ideal(1280, 720, 70.0 * DEG);
    let grey = to_grey(&render(&camera, -12.0 * DEG, 4.0 * DEG, SKY, GROUND));
    assert_attitude(detect_once(camera, Pixels::Grey(&grey)), -12.0, 4.0, 0.5);
}

#[test]
fn mount_offsets_are_removed() {
    let mut camera = camera_320();
    let grey = to_grey(&render(&camera, 10.0 * DEG, 5.0 * DEG, SKY, GROUND));
    camera.mount_roll_rad = 2.0 * DEG;
    camera.mount_pitch_rad = -3.0 * DEG;
    assert_attitude(detect_once(camera, Pixels::Grey(&grey)), 8.0, 8.0, 0.5);
}

#[test]
fn flat_frame_has_no_horizon() {
    let camera = camera_320();
    let grey = vec![128u8; 320 * 240];
    let frame = Frame::grey(320, 240, &grey).expect("fits");
    let mut buffers = Buffers::new(320, 240);
    let mut detector = HorizonDetector::new(camera);
    assert!(detector.detect(&frame, &mut buffers.workspace()).is_none());
    assert_eq!(detector.last_outcome(), Outcome::NoEdges);
}

#[test]
fn small_workspace_is_refused_not_overrun() {
    let camera = camera_320();
    let grey = to_grey(&render(&camera, 0.0, 0.0, SKY, GROUND));
    let frame = Frame::grey(320, 240, &grey).expect("fits");
    let mut buffers = Buffers::new(64, 48);
    let mut detector = HorizonDetector::new(camera);
    assert!(detector.detect(&frame, &mut buffers.workspace()).is_none());
    assert_eq!(detector.last_outcome(), Outcome::WorkspaceTooSmall);
}

#[test]
fn frame_view_checks_its_slice() {
    let data = [0u8; 100];
    assert_eq!(
        Frame::grey(20, 20, &data).err(),
        Some(FrameError::BufferTooShort {
            needed: 400,
            got: 100
        })
    );
    assert_eq!(Frame::grey(4, 4, &data).err(), Some(FrameError::TooSmall));
}

#[test]
fn undistortion_inverts_distortion() {
    let mut camera = Camera::ideal(640, 480, 80.0 * DEG);
    camera.k1 = -0.3;
    camera.k2 = 0.08;
    for &(x, y) in &[(0.0, 0.0), (0.3, -0.2), (-0.6, 0.4), (0.7, 0.5)] {
        let (xd, yd) = camera.distort_normalised(x, y);
        let (xu, yu) = camera.undistort_normalised(xd, yd).expect("invertible");
        assert!(
            (xu - x).abs() < 1e-4 && (yu - y).abs() < 1e-4,
            "{x},{y} -> {xu},{yu}"
        );
    }
}

#[test]
fn tracking_follows_a_moving_horizon() {
    let camera = camera_320();
    let mut buffers = Buffers::new(320, 240);
    let mut detector = HorizonDetector::new(camera);
    for i in 0..6 {
        let roll = -10.0 + 4.0 * i as f32;
        let pitch = 2.0 - i as f32;
        let grey = to_grey(&render(&camera, roll * DEG, pitch * DEG, SKY, GROUND));
        let frame = Frame::grey(320, 240, &grey).expect("fits");
        assert_attitude(
            detector.detect(&frame, &mut buffers.workspace()),
            roll,
            pitch,
            0.5,
        );
    }
}

mod never_panics {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]

        /// Any pixels, any size in range, odd cameras and tunings: an answer in range or
        /// `None`, never a panic (the detector runs inside the flight executive).
        #[test]
        fn random_frames(
            width in 16usize..420,
            height in 16usize..260,
            colour in any::<bool>(),
            seed in any::<u64>(),
            k1 in -0.5f32..0.5,
            fov_deg in 20.0f32..120.0,
            gate_roll_deg in 0.0f32..1000.0,
            window in 0u8..255,
        ) {
            let channels = if colour { 3 } else { 1 };
            let mut state = seed | 1;
            let pixels: Vec<u8> = (0..width * height * channels)
                .map(|i| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    // Half noise, half a ramp, so that some frames have lines.
                    if (state & 1) == 0 { (state >> 8) as u8 } else { (i % 251) as u8 }
                })
                .collect();
            let frame = if colour {
                Frame::rgb(width, height, &pixels)
            } else {
                Frame::grey(width, height, &pixels)
            }
            .expect("sized to fit");
            let mut camera = Camera::ideal(width as u32, height as u32, fov_deg * DEG);
            camera.k1 = k1;
            let config = DetectorConfig {
                gate_roll_deg,
                vote_window_deg: window,
                ..DetectorConfig::default()
            };
            let mut detector = HorizonDetector::with_config(camera, config);
            let mut buffers = Buffers::new(width, height);
            for _ in 0..2 {
                if let Some(h) = detector.detect(&frame, &mut buffers.workspace()) {
                    prop_assert!((0.0..=1.0).contains(&h.confidence));
                    prop_assert!(h.roll_rad.abs() <= PI + 1e-4);
                    prop_assert!(h.pitch_rad.is_finite());
                }
            }
        }
    }
}

#[test]
fn tracking_keeps_the_sky_side_when_brightness_flips() {
    // Grey frames: on its own, a frame whose ground is brighter than its sky reads upside
    // down (the brighter side is taken for the sky); after a tracked sequence, continuity
    // keeps the right side.
    let camera = camera_320();
    let dark_sky = to_grey(&render(&camera, 10.0 * DEG, 2.0 * DEG, [70; 3], [190; 3]));
    let alone = detect_once(camera, Pixels::Grey(&dark_sky)).expect("a line");
    assert!(wrap_angle(alone.roll_rad - 10.0 * DEG).abs() > 170.0 * DEG);

    let mut buffers = Buffers::new(320, 240);
    let mut detector = HorizonDetector::new(camera);
    for _ in 0..3 {
        let normal = to_grey(&render(&camera, 10.0 * DEG, 2.0 * DEG, SKY, GROUND));
        let frame = Frame::grey(320, 240, &normal).expect("fits");
        assert_attitude(
            detector.detect(&frame, &mut buffers.workspace()),
            10.0,
            2.0,
            0.5,
        );
    }
    let frame = Frame::grey(320, 240, &dark_sky).expect("fits");
    assert_attitude(
        detector.detect(&frame, &mut buffers.workspace()),
        10.0,
        2.0,
        0.5,
    );
}
