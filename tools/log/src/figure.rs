//! Figures as data (panels stacked vertically, each with lines or point clouds) and their
//! drawing with plotters into PNG or SVG.
//!
//! Text needs a font: the bitmap backend draws glyphs with ab_glyph from DejaVu Sans, embedded
//! in the binary and registered by skyframe-figure-output (no system fonts, no fontconfig).
//! SVG keeps text as `<text>` elements. PNG files are encoded there too, from plotters' RGB
//! buffer.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use skyframe_figure_output::{FONT, register_font, write_png};

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    Line,
    Points,
}

#[derive(Clone, Debug)]
pub struct Series {
    pub label: String,
    /// (x, y); a NaN in either breaks the line.
    pub points: Vec<(f64, f64)>,
    pub style: Style,
}

#[derive(Clone, Debug, Default)]
pub struct Panel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    /// One metre on x is as long as one metre on y (a map).
    pub equal_axes: bool,
    /// The y axis covers at least this range (e.g. 0 and 1 for a flag).
    pub y_covers: Option<(f64, f64)>,
}

#[derive(Clone, Debug, Default)]
pub struct Figure {
    pub title: String,
    pub panels: Vec<Panel>,
}

/// The image formats, from the output file's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    Png,
    Svg,
}

impl ImageFormat {
    pub fn from_path(path: &Path) -> Result<ImageFormat, String> {
        match path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .as_deref()
        {
            Some("png") => Ok(ImageFormat::Png),
            Some("svg") => Ok(ImageFormat::Svg),
            _ => Err(format!(
                "{}: unknown image format: the output must end in .png or .svg",
                path.display()
            )),
        }
    }
}

/// The largest magnitude an axis extends to.
const MAX_AXIS: f64 = 1e300;
/// The shortest panel drawn: a figure keeps its first panels that fit.
pub const MIN_PANEL_HEIGHT: u32 = 80;
/// Points per series drawn at most; longer series keep each bucket's first, min, max and last
/// point, so spikes (the intervals' peaks) survive.
const MAX_DRAWN_POINTS: usize = 8000;
/// The same for point clouds (each point is a circle element in SVG).
const MAX_DRAWN_MARKERS: usize = 3000;

/// How many panels a figure of `size` draws: each at least [`MIN_PANEL_HEIGHT`] pixels high
/// (minus the title's room).
pub fn panels_that_fit(size: (u32, u32)) -> usize {
    usize::try_from(size.1.saturating_sub(40) / MIN_PANEL_HEIGHT)
        .unwrap_or(1)
        .max(1)
}

/// Draws `figure` into `path` (`.png` or `.svg`), `size` pixels.
pub fn render(figure: &Figure, path: &Path, size: (u32, u32)) -> Result<(), String> {
    let format = ImageFormat::from_path(path)?;
    register_font()?;
    let fail = |e: String| format!("{}: {e}", path.display());
    match format {
        ImageFormat::Svg => {
            let root = SVGBackend::new(path, size).into_drawing_area();
            draw(figure, &root).map_err(fail)?;
            root.present().map_err(|e| fail(e.to_string()))
        }
        ImageFormat::Png => {
            let (w, h) = size;
            let len = usize::try_from(u64::from(w) * u64::from(h) * 3)
                .map_err(|_| fail("image too large".into()))?;
            let mut rgb = vec![0u8; len];
            {
                let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
                draw(figure, &root).map_err(fail)?;
                root.present().map_err(|e| fail(e.to_string()))?;
            }
            write_png(path, size, &rgb).map_err(fail)
        }
    }
}

/// Finite (min, max) of some values; `None` when none is finite.
/// Values beyond ±[`MAX_AXIS`] are left off the axes (drawn clipped), so a span stays finite.
fn extent(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values
        .filter(|v| v.is_finite() && v.abs() <= MAX_AXIS)
        .fold(None, |acc, v| match acc {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })
}

/// A range with a margin, never empty.
fn padded((lo, hi): (f64, f64)) -> (f64, f64) {
    let span = hi - lo;
    if span <= f64::EPSILON * hi.abs().max(1.0) {
        let pad = (hi.abs() * 0.05).max(0.5);
        (lo - pad, hi + pad)
    } else {
        (lo - span * 0.05, hi + span * 0.05)
    }
}

/// Splits a series where a coordinate is not finite (or beyond ±[`MAX_AXIS`]: plotters'
/// pixel arithmetic overflows there) and thins it to at most
/// [`MAX_DRAWN_POINTS`] per segment.
fn segments(points: &[(f64, f64)], max: usize) -> Vec<Vec<(f64, f64)>> {
    let mut out = Vec::new();
    let mut current = Vec::new();
    let drawable = |v: f64| v.is_finite() && v.abs() <= MAX_AXIS;
    for &(x, y) in points {
        if drawable(x) && drawable(y) {
            current.push((x, y));
        } else if !current.is_empty() {
            out.push(std::mem::take(&mut current));
        }
    }
    if !current.is_empty() {
        out.push(current);
    }
    out.into_iter().map(|s| thin(&s, max)).collect()
}

fn thin(points: &[(f64, f64)], max: usize) -> Vec<(f64, f64)> {
    if points.len() <= max {
        return points.to_vec();
    }
    let buckets = (max / 4).max(1);
    let per = points.len().div_ceil(buckets);
    let mut out = Vec::with_capacity(max);
    for chunk in points.chunks(per) {
        let (Some(&first), Some(&last)) = (chunk.first(), chunk.last()) else {
            continue;
        };
        let mut min = first;
        let mut max = first;
        let mut min_at = 0;
        let mut max_at = 0;
        for (i, &p) in chunk.iter().enumerate() {
            if p.1 < min.1 {
                min = p;
                min_at = i;
            }
            if p.1 > max.1 {
                max = p;
                max_at = i;
            }
        }
        out.push(first);
        if min_at <= max_at {
            out.extend([min, max]);
        } else {
            out.extend([max, min]);
        }
        out.push(last);
    }
    out
}

// Space taken around a panel's plotting area, in pixels (used for equal axes).
const MARGIN: u32 = 8;
const X_LABEL_AREA: u32 = 40;
const Y_LABEL_AREA: u32 = 70;
const CAPTION_FONT: u32 = 16;

fn draw<DB: DrawingBackend>(figure: &Figure, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(err)?;
    let area = if figure.title.is_empty() {
        root.clone()
    } else {
        root.titled(&figure.title, (FONT, 22)).map_err(err)?
    };
    let fit = panels_that_fit(root.dim_in_pixel());
    let count = figure.panels.len().clamp(1, fit);
    let areas = area.split_evenly((count, 1));
    // Panels past `fit` are left out (the caller says so: see `panels_that_fit`).
    for (panel, area) in figure.panels.iter().zip(&areas) {
        draw_panel(panel, area)?;
    }
    Ok(())
}

fn draw_panel<DB: DrawingBackend>(
    panel: &Panel,
    area: &DrawingArea<DB, Shift>,
) -> Result<(), String> {
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let xs = extent(
        panel
            .series
            .iter()
            .flat_map(|s| s.points.iter().filter(|p| p.1.is_finite()).map(|p| p.0)),
    );
    let ys = extent(
        panel
            .series
            .iter()
            .flat_map(|s| s.points.iter().filter(|p| p.0.is_finite()).map(|p| p.1)),
    );
    let (mut x0, mut x1) = padded(xs.unwrap_or((0.0, 1.0)));
    let ys = match (ys, panel.y_covers) {
        (Some((lo, hi)), Some((a, b))) => Some((lo.min(a), hi.max(b))),
        (None, covers) => covers,
        (ys, None) => ys,
    };
    let (mut y0, mut y1) = padded(ys.unwrap_or((0.0, 1.0)));
    if panel.equal_axes {
        let (w, h) = area.dim_in_pixel();
        let caption = if panel.title.is_empty() {
            0
        } else {
            CAPTION_FONT + 10
        };
        let pw = f64::from(w.saturating_sub(2 * MARGIN + Y_LABEL_AREA).max(1));
        let ph = f64::from(h.saturating_sub(2 * MARGIN + X_LABEL_AREA + caption).max(1));
        // Metres per pixel: the larger of the two, then both spans widened to it.
        let scale = ((x1 - x0) / pw).max((y1 - y0) / ph);
        let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
        (x0, x1) = (cx - scale * pw / 2.0, cx + scale * pw / 2.0);
        (y0, y1) = (cy - scale * ph / 2.0, cy + scale * ph / 2.0);
    }
    let mut builder = ChartBuilder::on(area);
    builder
        .margin(MARGIN)
        .x_label_area_size(X_LABEL_AREA)
        .y_label_area_size(Y_LABEL_AREA);
    if !panel.title.is_empty() {
        builder.caption(&panel.title, (FONT, CAPTION_FONT));
    }
    let mut chart = builder.build_cartesian_2d(x0..x1, y0..y1).map_err(err)?;
    // About one y label per 40 pixels, so short panels stay legible.
    let (_, height) = area.dim_in_pixel();
    let y_labels = usize::try_from(height / 40).unwrap_or(10).clamp(3, 10);
    chart
        .configure_mesh()
        .y_labels(y_labels)
        .x_desc(panel.x_label.as_str())
        .y_desc(panel.y_label.as_str())
        .label_style((FONT, 12))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(err)?;
    for (i, series) in panel.series.iter().enumerate() {
        let colour = skyframe_figure_output::series_colour(i);
        // The legend entry first (an empty series), then the segments.
        let legend = chart
            .draw_series(LineSeries::new(std::iter::empty::<(f64, f64)>(), colour))
            .map_err(err)?;
        legend.label(series.label.as_str()).legend(move |(x, y)| {
            PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
        });
        let max = match series.style {
            Style::Line => MAX_DRAWN_POINTS,
            Style::Points => MAX_DRAWN_MARKERS,
        };
        for segment in segments(&series.points, max) {
            match series.style {
                Style::Line => {
                    chart
                        .draw_series(LineSeries::new(segment, colour.stroke_width(1)))
                        .map_err(err)?;
                }
                Style::Points => {
                    chart
                        .draw_series(
                            segment
                                .into_iter()
                                .map(|p| Circle::new(p, 2, colour.filled())),
                        )
                        .map_err(err)?;
                }
            }
        }
    }
    if !panel.series.is_empty() {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font((FONT, 13))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(err)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thinning_keeps_the_peaks() {
        let mut points: Vec<(f64, f64)> = (0..100_000).map(|i| (f64::from(i), 1.0)).collect();
        points[54_321].1 = 300.0;
        points[77_777].1 = -5.0;
        let thinned = thin(&points, MAX_DRAWN_POINTS);
        assert!(thinned.len() <= MAX_DRAWN_POINTS);
        assert!(thinned.contains(&(54_321.0, 300.0)));
        assert!(thinned.contains(&(77_777.0, -5.0)));
        assert!(thinned.windows(2).all(|w| w[0].0 <= w[1].0));
    }

    #[test]
    fn nan_breaks_lines() {
        let points = [(0.0, 1.0), (1.0, f64::NAN), (2.0, 2.0), (3.0, 3.0)];
        assert_eq!(
            segments(&points, 100),
            vec![vec![(0.0, 1.0)], vec![(2.0, 2.0), (3.0, 3.0)]]
        );
    }
}
