//! Running the core's detector over frames from files, and the CSV of the conventions.

use crate::Error;
use crate::image_io::{self, Image};
use skyframe_core::horizon::{
    Camera, Complex32, EdgePoint, Frame, Horizon, HorizonDetector, Pixels, Sample, Workspace,
};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Owned workspace buffers for one frame size.
pub struct Buffers {
    size: (usize, usize),
    grey: Vec<u8>,
    rows: Vec<u16>,
    edges: Vec<EdgePoint>,
    accumulator: Vec<u16>,
    samples: Vec<Sample>,
    spectrum: Vec<Complex32>,
}

impl Buffers {
    pub fn new(width: usize, height: usize) -> Self {
        let s = Workspace::required_sizes(width, height);
        Buffers {
            size: (width, height),
            grey: vec![0; s.grey],
            rows: vec![0; s.rows],
            edges: vec![EdgePoint::ZERO; s.edges],
            accumulator: vec![0; s.accumulator],
            samples: vec![Sample::ZERO; s.samples],
            spectrum: vec![Complex32::new(0.0, 0.0); s.spectrum],
        }
    }

    pub fn workspace(&mut self) -> Workspace<'_> {
        Workspace {
            grey: &mut self.grey,
            rows: &mut self.rows,
            edges: &mut self.edges,
            accumulator: &mut self.accumulator,
            samples: &mut self.samples,
            spectrum: &mut self.spectrum,
        }
    }
}

/// The detector with buffers sized on the first frame (and re-sized if the size changes).
pub struct Runner {
    pub detector: HorizonDetector,
    buffers: Option<Buffers>,
}

/// One frame's result.
#[derive(Clone, Copy, Debug)]
pub struct FrameResult {
    pub horizon: Option<Horizon>,
    pub ms: f64,
}

impl Runner {
    pub fn new(camera: Camera) -> Self {
        Runner {
            detector: HorizonDetector::new(camera),
            buffers: None,
        }
    }

    /// Detects on one image; the time covers the detector only (not decoding).
    pub fn run(&mut self, image: &Image) -> Result<FrameResult, String> {
        let pixels = if image.channels == 3 {
            Pixels::Rgb(&image.data)
        } else {
            Pixels::Grey(&image.data)
        };
        let stride = image.width * image.channels;
        let frame = Frame::new(image.width, image.height, stride, pixels)
            .map_err(|e| format!("frame {}×{} unusable: {e:?}", image.width, image.height))?;
        let size = (image.width, image.height);
        let buffers = match &mut self.buffers {
            Some(b) if b.size == size => b,
            slot => slot.insert(Buffers::new(size.0, size.1)),
        };
        let start = Instant::now();
        let horizon = self.detector.detect(&frame, &mut buffers.workspace());
        let ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(FrameResult { horizon, ms })
    }
}

/// `frame,roll_deg,pitch_deg,confidence,ms`
pub const CSV_HEADER: &str = "frame,roll_deg,pitch_deg,confidence,ms";

pub fn csv_line(frame: usize, result: &FrameResult) -> String {
    match result.horizon {
        Some(h) => format!(
            "{frame},{:.3},{:.3},{:.3},{:.3}",
            h.roll_rad.to_degrees(),
            h.pitch_rad.to_degrees(),
            h.confidence,
            result.ms
        ),
        None => format!("{frame},,,0.000,{:.3}", result.ms),
    }
}

/// Where frames come from.
pub enum Source {
    /// An open stream: its header has been read and checked.
    Y4m(image_io::Y4mReader<Box<dyn std::io::BufRead>>),
    Directory(Vec<PathBuf>),
    Image(PathBuf),
}

impl Source {
    /// A directory, `-` (stdin, y4m), a `.y4m` file, or an image.
    pub fn open(input: &Path) -> Result<Source, Error> {
        if input.as_os_str() == "-" {
            return Ok(Source::Y4m(image_io::open_y4m(input)?));
        }
        if input.is_dir() {
            return Ok(Source::Directory(image_io::list_frames(input)?));
        }
        if !input.exists() {
            return Err(Error::input(format!(
                "{}: no such file or directory",
                input.display()
            )));
        }
        match image_io::extension(input).as_deref() {
            Some("png" | "pgm" | "ppm" | "pnm") => Ok(Source::Image(input.to_path_buf())),
            _ => Ok(Source::Y4m(image_io::open_y4m(input)?)),
        }
    }

    /// Calls `each(index, image)` for each frame in order; the first frame decides the camera
    /// size if none is given.
    pub fn for_each(
        self,
        mut each: impl FnMut(usize, &Image) -> Result<(), Error>,
    ) -> Result<usize, Error> {
        match self {
            Source::Y4m(mut reader) => {
                let mut index = 0;
                while let Some(image) = reader.next_frame()? {
                    each(index, &image)?;
                    index += 1;
                }
                Ok(index)
            }
            Source::Directory(files) => {
                for (index, file) in files.iter().enumerate() {
                    each(index, &image_io::read_image(file)?)?;
                }
                Ok(files.len())
            }
            Source::Image(path) => {
                each(0, &image_io::read_image(&path)?)?;
                Ok(1)
            }
        }
    }
}

/// Draws the detected horizon on a copy of the frame: green for confident, orange below 0.5;
/// the ground side gets a short tick so that the ±180° choice is visible.
pub fn annotate(image: &Image, camera: &Camera, horizon: Option<&Horizon>) -> Image {
    let mut out = image.to_rgb();
    let Some(h) = horizon else {
        return out;
    };
    let camera = camera.scaled_to(image.width as u32, image.height as u32);
    let colour = if h.confidence >= 0.5 {
        [0, 255, 0]
    } else {
        [255, 140, 0]
    };
    let (s, c) = h.line.camera_roll_rad.sin_cos();
    // Foot of the normal and the line's direction in normalised undistorted coordinates.
    let (ox, oy) = (s * h.line.offset, c * h.line.offset);
    let (dx, dy) = (c, -s);
    let step = 0.5 / camera.fx;
    let extent = 4.0;
    let mut put = |u: f32, v: f32| {
        let (x, y) = (u.round() as i64, v.round() as i64);
        for (px, py) in [(x, y), (x, y + 1), (x + 1, y)] {
            if px >= 0 && py >= 0 && (px as usize) < out.width && (py as usize) < out.height {
                let i = (py as usize * out.width + px as usize) * 3;
                out.data[i..i + 3].copy_from_slice(&colour);
            }
        }
    };
    let mut t = -extent;
    while t <= extent {
        let (x, y) = (ox + t * dx, oy + t * dy);
        // Beyond the corners a barrel model folds back; stop where it stops being monotonic.
        if x * x + y * y < 4.0 {
            let (u, v) = camera.project(x, y);
            put(u, v);
        }
        t += step;
    }
    // Ground tick at the foot of the normal, towards the ground (+normal).
    for k in 0..12 {
        let d = k as f32 / camera.fx;
        let (u, v) = camera.project(ox + s * d, oy + c * d);
        put(u, v);
    }
    out
}

/// Writes the CSV (stdout or a file) as frames are processed.
pub fn csv_output(path: Option<&Path>) -> Result<Box<dyn Write>, Error> {
    Ok(match path {
        Some(p) => Box::new(std::io::BufWriter::new(
            std::fs::File::create(p).map_err(|e| Error::input(format!("{}: {e}", p.display())))?,
        )),
        None => Box::new(std::io::BufWriter::new(std::io::stdout())),
    })
}
