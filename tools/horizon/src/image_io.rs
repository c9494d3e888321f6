//! Frames in and out: PNG, PGM/PPM (binary), and YUV4MPEG2 streams.

use crate::Error;
use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

/// An 8-bit image, grey (1 channel) or RGB (3 channels), rows packed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    pub data: Vec<u8>,
}

impl Image {
    pub fn new_rgb(width: usize, height: usize) -> Self {
        Image {
            width,
            height,
            channels: 3,
            data: vec![0; width * height * 3],
        }
    }

    /// The same image as RGB (grey repeated).
    pub fn to_rgb(&self) -> Image {
        if self.channels == 3 {
            return self.clone();
        }
        Image {
            width: self.width,
            height: self.height,
            channels: 3,
            data: self.data.iter().flat_map(|&g| [g, g, g]).collect(),
        }
    }

    /// Luma only.
    pub fn to_grey(&self) -> Image {
        if self.channels == 1 {
            return self.clone();
        }
        Image {
            width: self.width,
            height: self.height,
            channels: 1,
            data: self
                .data
                .chunks_exact(3)
                .map(|p| {
                    ((77 * p[0] as u32 + 150 * p[1] as u32 + 29 * p[2] as u32 + 128) >> 8) as u8
                })
                .collect(),
        }
    }
}

fn io_error(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::input(format!("{}: {e}", path.display()))
}

/// Reads a PNG (any colour type, 8 or 16 bits, palettes expanded; alpha dropped).
pub fn read_png(path: &Path) -> Result<Image, Error> {
    let file = File::open(path).map_err(|e| io_error(path, e))?;
    let mut decoder = png::Decoder::new(BufReader::new(file));
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder.read_info().map_err(|e| io_error(path, e))?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| io_error(path, "image too large"))?;
    let mut buffer = vec![0; size];
    let info = reader
        .next_frame(&mut buffer)
        .map_err(|e| io_error(path, e))?;
    buffer.truncate(info.buffer_size());
    let (width, height) = (info.width as usize, info.height as usize);
    let source_channels = match info.color_type {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Indexed => return Err(io_error(path, "palette was not expanded")),
    };
    let pixels = buffer.chunks_exact(source_channels);
    let (channels, data): (usize, Vec<u8>) = match source_channels {
        1 | 2 => (1, pixels.map(|p| p[0]).collect()),
        _ => (3, pixels.flat_map(|p| [p[0], p[1], p[2]]).collect()),
    };
    Ok(Image {
        width,
        height,
        channels,
        data,
    })
}

pub fn write_png(path: &Path, image: &Image) -> Result<(), Error> {
    let file = File::create(path).map_err(|e| io_error(path, e))?;
    let mut encoder = png::Encoder::new(
        BufWriter::new(file),
        image.width as u32,
        image.height as u32,
    );
    encoder.set_color(if image.channels == 3 {
        png::ColorType::Rgb
    } else {
        png::ColorType::Grayscale
    });
    encoder.set_depth(png::BitDepth::Eight);
    // Test frames are written once and read many times, and fast compression keeps the bench
    // set-up short.
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder.write_header().map_err(|e| io_error(path, e))?;
    writer
        .write_image_data(&image.data)
        .map_err(|e| io_error(path, e))?;
    writer.finish().map_err(|e| io_error(path, e))
}

/// Reads a binary PGM (P5) or PPM (P6) with maxval ≤ 255.
pub fn read_pnm(path: &Path) -> Result<Image, Error> {
    let bytes = std::fs::read(path).map_err(|e| io_error(path, e))?;
    parse_pnm(&bytes)
        .map_err(|(offset, message)| io_error(path, format!("byte {offset}: {message}")))
}

fn parse_pnm(bytes: &[u8]) -> Result<Image, (usize, String)> {
    let mut pos = 0usize;
    let token = |pos: &mut usize| -> Result<(usize, String), (usize, String)> {
        // Skip whitespace and comments.
        loop {
            match bytes.get(*pos) {
                Some(b) if b.is_ascii_whitespace() => *pos += 1,
                Some(b'#') => {
                    while bytes.get(*pos).is_some_and(|&b| b != b'\n') {
                        *pos += 1;
                    }
                }
                Some(_) => break,
                None => return Err((*pos, "header ends early".into())),
            }
        }
        let start = *pos;
        while bytes.get(*pos).is_some_and(|b| !b.is_ascii_whitespace()) {
            *pos += 1;
        }
        Ok((
            start,
            String::from_utf8_lossy(&bytes[start..*pos]).into_owned(),
        ))
    };
    let (_, magic) = token(&mut pos)?;
    let channels = match magic.as_str() {
        "P5" => 1,
        "P6" => 3,
        other => {
            return Err((
                0,
                format!("not a binary PGM/PPM (magic {other:?}, want P5 or P6)"),
            ));
        }
    };
    let number = |pos: &mut usize, what: &str| -> Result<usize, (usize, String)> {
        let (at, t) = token(pos)?;
        t.parse::<usize>()
            .map_err(|_| (at, format!("{what} {t:?} is not a number")))
    };
    let width = number(&mut pos, "width")?;
    let height = number(&mut pos, "height")?;
    let maxval_at = pos;
    let maxval = number(&mut pos, "maxval")?;
    if maxval == 0 || maxval > 255 {
        return Err((
            maxval_at,
            format!("maxval {maxval} unsupported (8-bit only)"),
        ));
    }
    // Exactly one whitespace byte separates the header from the pixels.
    pos += 1;
    let needed = width * height * channels;
    let data = bytes.get(pos..pos + needed).ok_or_else(|| {
        (
            pos,
            format!(
                "pixel data truncated: need {needed} bytes, have {}",
                bytes.len().saturating_sub(pos)
            ),
        )
    })?;
    let data = if maxval == 255 {
        data.to_vec()
    } else {
        data.iter()
            .map(|&v| ((v as usize * 255 + maxval / 2) / maxval).min(255) as u8)
            .collect()
    };
    Ok(Image {
        width,
        height,
        channels,
        data,
    })
}

pub fn write_pnm(path: &Path, image: &Image) -> Result<(), Error> {
    let magic = if image.channels == 3 { "P6" } else { "P5" };
    let mut out = BufWriter::new(File::create(path).map_err(|e| io_error(path, e))?);
    write!(out, "{magic}\n{} {}\n255\n", image.width, image.height)
        .and_then(|_| out.write_all(&image.data))
        .and_then(|_| out.flush())
        .map_err(|e| io_error(path, e))
}

/// Reads a PNG, PGM or PPM by its extension.
pub fn read_image(path: &Path) -> Result<Image, Error> {
    match extension(path).as_deref() {
        Some("png") => read_png(path),
        Some("pgm" | "ppm" | "pnm") => read_pnm(path),
        _ => Err(Error::input(format!(
            "{}: not a PNG, PGM or PPM (by its extension)",
            path.display()
        ))),
    }
}

pub fn extension(path: &Path) -> Option<String> {
    path.extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
}

/// Frame files of a directory (PNG, PGM, PPM) in file-name order.
pub fn list_frames(dir: &Path) -> Result<Vec<PathBuf>, Error> {
    let entries = std::fs::read_dir(dir).map_err(|e| io_error(dir, e))?;
    let mut files = Vec::new();
    for entry in entries {
        let path = entry.map_err(|e| io_error(dir, e))?.path();
        if path.is_file()
            && matches!(
                extension(&path).as_deref(),
                Some("png" | "pgm" | "ppm" | "pnm")
            )
        {
            files.push(path);
        }
    }
    files.sort_by(|a, b| a.file_name().cmp(&b.file_name()));
    if files.is_empty() {
        return Err(Error::input(format!(
            "{}: no .png, .pgm or .ppm frames in this directory",
            dir.display()
        )));
    }
    Ok(files)
}

/// Largest frame side accepted from a stream header (a corrupt header must not make the tool
/// allocate gigabytes).
const MAX_SIDE: usize = 16_384;

/// Chroma layout of a YUV4MPEG2 stream (8-bit only).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Chroma {
    /// 4:2:0; `full_range` for the JPEG variant.
    C420 {
        full_range: bool,
    },
    C422,
    C444,
    Mono,
}

/// A YUV4MPEG2 reader over any byte stream (a file or stdin), frame by frame, converting to
/// RGB (BT.601) so that colour reaches the detector.
pub struct Y4mReader<R: BufRead> {
    input: R,
    name: String,
    offset: u64,
    pub width: usize,
    pub height: usize,
    chroma: Chroma,
    frame_index: usize,
    plane: Vec<u8>,
}

impl<R: BufRead> Y4mReader<R> {
    pub fn new(mut input: R, name: &str) -> Result<Self, Error> {
        let mut header = Vec::new();
        input
            .read_until(b'\n', &mut header)
            .map_err(|e| Error::input(format!("{name}: byte 0: {e}")))?;
        let fail = |m: String| Error::input(format!("{name}: byte 0: {m}"));
        let text = String::from_utf8_lossy(&header);
        let mut fields = text.trim_end().split(' ');
        if fields.next() != Some("YUV4MPEG2") {
            return Err(fail(
                "not a YUV4MPEG2 stream (no 'YUV4MPEG2' signature)".into(),
            ));
        }
        let (mut width, mut height, mut chroma) =
            (0usize, 0usize, Chroma::C420 { full_range: false });
        for field in fields {
            let (tag, value) = field.split_at(field.len().min(1));
            match tag {
                "W" => {
                    width = value
                        .parse()
                        .map_err(|_| fail(format!("bad width {value:?}")))?
                }
                "H" => {
                    height = value
                        .parse()
                        .map_err(|_| fail(format!("bad height {value:?}")))?
                }
                "C" => {
                    chroma = match value {
                        "420jpeg" => Chroma::C420 { full_range: true },
                        "420" | "420mpeg2" | "420paldv" => Chroma::C420 { full_range: false },
                        "422" => Chroma::C422,
                        "444" => Chroma::C444,
                        "mono" => Chroma::Mono,
                        other => {
                            return Err(fail(format!(
                                "colour space C{other} unsupported (8-bit 420, 422, 444 or mono)"
                            )));
                        }
                    }
                }
                _ => {}
            }
        }
        if width == 0 || height == 0 {
            return Err(fail("header lacks W or H".into()));
        }
        if width > MAX_SIDE || height > MAX_SIDE {
            return Err(fail(format!(
                "{width}×{height} is larger than {MAX_SIDE} a side"
            )));
        }
        Ok(Y4mReader {
            input,
            name: name.to_string(),
            offset: header.len() as u64,
            width,
            height,
            chroma,
            frame_index: 0,
            plane: Vec::new(),
        })
    }

    fn plane_sizes(&self) -> (usize, usize, usize) {
        let (w, h) = (self.width, self.height);
        match self.chroma {
            Chroma::C420 { .. } => (w * h, w.div_ceil(2), h.div_ceil(2)),
            Chroma::C422 => (w * h, w.div_ceil(2), h),
            Chroma::C444 => (w * h, w, h),
            Chroma::Mono => (w * h, 0, 0),
        }
    }

    /// The next frame as RGB (or grey for a mono stream), `None` at a clean end of stream.
    pub fn next_frame(&mut self) -> Result<Option<Image>, Error> {
        let mut header = Vec::new();
        let at = self.offset;
        let n = self
            .input
            .read_until(b'\n', &mut header)
            .map_err(|e| self.fail(at, &e.to_string()))?;
        if n == 0 {
            return Ok(None);
        }
        if !header.starts_with(b"FRAME") || header.last() != Some(&b'\n') {
            return Err(self.fail(
                at,
                &format!("frame {}: expected a 'FRAME' header line", self.frame_index),
            ));
        }
        self.offset += n as u64;
        let (luma, cw, ch) = self.plane_sizes();
        let total = luma + 2 * cw * ch;
        self.plane.resize(total, 0);
        let data_at = self.offset;
        let mut got = 0;
        while got < total {
            match self.input.read(&mut self.plane[got..]) {
                Ok(0) => break,
                Ok(k) => got += k,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(self.fail(data_at + got as u64, &e.to_string())),
            }
        }
        if got < total {
            return Err(self.fail(
                data_at,
                &format!(
                    "frame {} truncated: {got} of {total} bytes",
                    self.frame_index
                ),
            ));
        }
        self.offset += total as u64;
        self.frame_index += 1;
        Ok(Some(self.to_rgb(cw, ch)))
    }

    fn fail(&self, offset: u64, message: &str) -> Error {
        Error::input(format!("{}: byte {offset}: {message}", self.name))
    }

    fn to_rgb(&self, cw: usize, ch: usize) -> Image {
        let (w, h) = (self.width, self.height);
        let (y_plane, rest) = self.plane.split_at(w * h);
        if self.chroma == Chroma::Mono {
            return Image {
                width: w,
                height: h,
                channels: 1,
                data: y_plane.to_vec(),
            };
        }
        let (u_plane, v_plane) = rest.split_at(cw * ch);
        let (sx, sy) = (w.div_ceil(cw.max(1)), h.div_ceil(ch.max(1)));
        let full_range = matches!(self.chroma, Chroma::C420 { full_range: true });
        let mut image = Image::new_rgb(w, h);
        for y in 0..h {
            for x in 0..w {
                let c = (y / sy) * cw + x / sx;
                let (yy, u, v) = (
                    y_plane[y * w + x] as f32,
                    u_plane[c] as f32 - 128.0,
                    v_plane[c] as f32 - 128.0,
                );
                let (yy, k) = if full_range {
                    (yy, 1.0)
                } else {
                    ((yy - 16.0) * 1.164, 1.138)
                };
                let r = yy + 1.402 * k * v;
                let g = yy - 0.344 * k * u - 0.714 * k * v;
                let b = yy + 1.772 * k * u;
                let i = (y * w + x) * 3;
                image.data[i] = r.round().clamp(0.0, 255.0) as u8;
                image.data[i + 1] = g.round().clamp(0.0, 255.0) as u8;
                image.data[i + 2] = b.round().clamp(0.0, 255.0) as u8;
            }
        }
        image
    }
}

/// Opens a y4m file, or stdin for `-`.
pub fn open_y4m(path: &Path) -> Result<Y4mReader<Box<dyn BufRead>>, Error> {
    let (input, name): (Box<dyn BufRead>, String) = if path.as_os_str() == "-" {
        (Box::new(BufReader::new(std::io::stdin())), "stdin".into())
    } else {
        let file = File::open(path).map_err(|e| io_error(path, e))?;
        (
            Box::new(BufReader::with_capacity(1 << 20, file)),
            path.display().to_string(),
        )
    };
    Y4mReader::new(input, &name)
}

/// Writes frames as a 4:4:4 full-range YUV4MPEG2 stream (lossless enough for tests).
pub struct Y4mWriter<W: Write> {
    out: W,
}

impl<W: Write> Y4mWriter<W> {
    pub fn new(mut out: W, width: usize, height: usize, fps: u32) -> std::io::Result<Self> {
        writeln!(out, "YUV4MPEG2 W{width} H{height} F{fps}:1 Ip A1:1 C444")?;
        Ok(Y4mWriter { out })
    }

    pub fn write(&mut self, image: &Image) -> std::io::Result<()> {
        let rgb = image.to_rgb();
        let n = rgb.width * rgb.height;
        let mut planes = vec![0u8; 3 * n];
        for (i, p) in rgb.data.chunks_exact(3).enumerate() {
            let (r, g, b) = (p[0] as f32, p[1] as f32, p[2] as f32);
            // Studio-range BT.601, the inverse of what the reader does for non-jpeg streams.
            let y = 16.0 + (0.299 * r + 0.587 * g + 0.114 * b) * 219.0 / 255.0;
            let u = 128.0 + (-0.168_736 * r - 0.331_264 * g + 0.5 * b) * 224.0 / 255.0;
            let v = 128.0 + (0.5 * r - 0.418_688 * g - 0.081_312 * b) * 224.0 / 255.0;
            planes[i] = y.round().clamp(0.0, 255.0) as u8;
            planes[n + i] = u.round().clamp(0.0, 255.0) as u8;
            planes[2 * n + i] = v.round().clamp(0.0, 255.0) as u8;
        }
        self.out.write_all(b"FRAME\n")?;
        self.out.write_all(&planes)
    }

    pub fn finish(mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stream(header: &str, frames: &[Vec<u8>]) -> Vec<u8> {
        let mut bytes = header.as_bytes().to_vec();
        for f in frames {
            bytes.extend_from_slice(b"FRAME\n");
            bytes.extend_from_slice(f);
        }
        bytes
    }

    #[test]
    fn y4m_420_as_ffmpeg_writes_it() {
        // 4×2, 4:2:0 full range: Y 200 on top, 50 below; chroma neutral except a blue-ish
        // right half (U high).
        let y = [200, 200, 200, 200, 50, 50, 50, 50];
        let u = [128, 200];
        let v = [128, 128];
        let frame: Vec<u8> = y.iter().chain(&u).chain(&v).copied().collect();
        let bytes = stream(
            "YUV4MPEG2 W4 H2 F30:1 Ip A1:1 C420jpeg XYSCSS=420JPEG\n",
            &[frame],
        );
        let mut reader = Y4mReader::new(&bytes[..], "test").expect("header");
        let image = reader.next_frame().expect("frame").expect("one frame");
        assert_eq!((image.width, image.height, image.channels), (4, 2, 3));
        assert_eq!(&image.data[0..3], &[200, 200, 200]);
        assert_eq!(&image.data[12..15], &[50, 50, 50]);
        let right = &image.data[9..12];
        assert!(right[2] > right[0], "blue-ish: {right:?}");
        assert!(reader.next_frame().expect("clean end").is_none());
    }

    #[test]
    fn y4m_mono_and_studio_range() {
        let bytes = stream("YUV4MPEG2 W2 H2 Cmono\n", &[vec![1, 2, 3, 4]]);
        let mut reader = Y4mReader::new(&bytes[..], "test").expect("header");
        let image = reader.next_frame().expect("frame").expect("one");
        assert_eq!((image.channels, image.data.clone()), (1, vec![1, 2, 3, 4]));

        // Studio range (no colour-space tag: 4:2:0 mpeg2): Y 16 is black, 235 white.
        let frame = vec![16, 235, 16, 235, 128, 128];
        let bytes = stream("YUV4MPEG2 W2 H2\n", &[frame]);
        let mut reader = Y4mReader::new(&bytes[..], "test").expect("header");
        let image = reader.next_frame().expect("frame").expect("one");
        assert_eq!(&image.data[0..6], &[0, 0, 0, 255, 255, 255]);
    }

    #[test]
    fn y4m_errors_name_the_offset() {
        let err = Y4mReader::new(&b"YUV4MPEG2 W2 H2 C420p10\n"[..], "s.y4m").err();
        assert!(err.is_some_and(|e| {
            e.to_string()
                .contains("s.y4m: byte 0: colour space C420p10")
        }));
        let bytes = stream("YUV4MPEG2 W2 H2 Cmono\n", &[vec![1, 2, 3, 4]]);
        let mut broken = bytes.clone();
        broken.extend_from_slice(b"FRAMX\n");
        let mut reader = Y4mReader::new(&broken[..], "s.y4m").expect("header");
        assert!(reader.next_frame().is_ok());
        let e = reader.next_frame().expect_err("bad header");
        assert!(e.to_string().contains("byte 32: frame 1"), "{e}");
    }

    #[test]
    fn y4m_round_trip_is_close() {
        let mut image = Image::new_rgb(4, 2);
        for (i, v) in image.data.iter_mut().enumerate() {
            *v = (i * 29 % 256) as u8;
        }
        let mut bytes = Vec::new();
        let mut writer = Y4mWriter::new(&mut bytes, 4, 2, 10).expect("header");
        writer.write(&image).expect("frame");
        writer.finish().expect("flush");
        let mut reader = Y4mReader::new(&bytes[..], "rt").expect("header");
        let back = reader.next_frame().expect("frame").expect("one");
        for (a, b) in image.data.iter().zip(&back.data) {
            assert!((*a as i32 - *b as i32).abs() <= 3, "{a} vs {b}");
        }
    }

    #[test]
    fn pnm_header_errors() {
        assert!(parse_pnm(b"P2\n2 2\n255\n").is_err_and(|(at, m)| at == 0 && m.contains("P5")));
        assert!(parse_pnm(b"P5\n2 x\n255\n").is_err_and(|(at, m)| at == 5 && m.contains("height")));
        let ok = parse_pnm(b"P5\n# comment\n2 1\n255\n\x07\x08").expect("valid");
        assert_eq!(ok.data, vec![7, 8]);
    }
}
