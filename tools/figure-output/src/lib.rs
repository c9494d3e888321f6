//! What the tools' figures share: the embedded font, the series colours and PNG output.
//!
//! plotters draws text through fonts registered by family name; the tools register DejaVu
//! Sans (compiled in) as [`FONT`] once, and draw bitmaps into RGB buffers that
//! [`write_png`] encodes.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;
use std::sync::Once;

use plotters::style::{FontStyle, RGBColor};

/// The font family every figure's text uses.
pub const FONT: &str = "sans-serif";

/// The colours of a figure's series, in order (the Tableau 10 set; blue and red first, so a
/// panel of two reads as a pair).
const SERIES_COLOURS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
    RGBColor(188, 189, 34),
    RGBColor(127, 127, 127),
];

/// The colour of series `i` (the set repeats after ten).
pub fn series_colour(i: usize) -> RGBColor {
    let [first, ..] = SERIES_COLOURS;
    SERIES_COLOURS
        .get(i % SERIES_COLOURS.len())
        .copied()
        .unwrap_or(first)
}

/// Registers the embedded DejaVu Sans as [`FONT`]; the first call does it, later calls are
/// free.
pub fn register_font() -> Result<(), String> {
    static REGISTER: Once = Once::new();
    let mut result = Ok(());
    REGISTER.call_once(|| {
        result = plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular())
            .map_err(|_| "the embedded font could not be loaded".to_string());
    });
    result
}

/// Writes `rgb` (8-bit RGB, `w · h · 3` bytes, row by row) to `path` as a PNG.
pub fn write_png(path: &Path, (w, h): (u32, u32), rgb: &[u8]) -> Result<(), String> {
    let file = File::create(path).map_err(|e| e.to_string())?;
    let mut encoder = png::Encoder::new(BufWriter::new(file), w, h);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
    writer.write_image_data(rgb).map_err(|e| e.to_string())?;
    writer.finish().map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_font_registers_and_a_png_reads_back_pixel_for_pixel() {
        assert_eq!(register_font(), Ok(()));
        assert_eq!(register_font(), Ok(()));
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("probe.png");
        let rgb: Vec<u8> = (0..4 * 3 * 3).map(|i| (i * 7) as u8).collect();
        write_png(&path, (4, 3), &rgb).expect("writes");
        let decoder = png::Decoder::new(std::io::BufReader::new(File::open(&path).expect("open")));
        let mut reader = decoder.read_info().expect("header");
        let mut back = vec![0u8; reader.output_buffer_size().expect("size")];
        let info = reader.next_frame(&mut back).expect("frame");
        assert_eq!((info.width, info.height), (4, 3));
        assert_eq!(back.get(..rgb.len()), Some(rgb.as_slice()));
    }

    #[test]
    fn a_buffer_of_the_wrong_size_is_an_error_not_a_panic() {
        let dir = tempfile::tempdir().expect("tempdir");
        assert!(write_png(&dir.path().join("short.png"), (4, 3), &[0u8; 5]).is_err());
        assert!(write_png(Path::new("/nonexistent/x.png"), (1, 1), &[0u8; 3]).is_err());
    }
}
