//! `plot`: series of a flight against time (`--series`), and the seed thesis's standard
//! figures (chapter 6.1.3) for a whole flight (`--report`).
//!
//! The x axis is the log TIME in seconds from the first record of the streams loaded (for a
//! report: of the whole flight, so every figure shares one time axis).

use skyframe_core::estimation::geo::{GeoPoint, LocalFrame};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::Outcome;
use crate::figure::{Figure, Panel, Series, Style, render};
use crate::flight::{Source, Stream, Table, load_stream};

/// Options shared by both kinds of plot.
pub struct PlotOptions {
    pub size: (u32, u32),
}

/// Parses `WxH`.
pub fn parse_size(text: &str) -> Result<(u32, u32), String> {
    let (w, h) = text
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("size '{text}': expected WIDTHxHEIGHT, e.g. 1280x960"))?;
    let parse = |s: &str| {
        s.trim()
            .parse::<u32>()
            .ok()
            .filter(|&v| (64..=10_000).contains(&v))
            .ok_or_else(|| format!("size '{text}': each side must be 64..=10000 pixels"))
    };
    Ok((parse(w)?, parse(h)?))
}

fn seconds_from(t0_ns: i64, t_ns: i64) -> f64 {
    (t_ns - t0_ns) as f64 * 1e-9
}

/// A series named on the command line, resolved to its stream, format index and column.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SeriesRef {
    pub stream: String,
    pub index: u8,
    pub column: String,
}

impl SeriesRef {
    pub fn label(&self) -> String {
        format!("{}.{}", self.stream, self.column)
    }
}

/// Splits `<stream>.<column>` or `<stream>.<index>.<column>`.
fn split_series(text: &str) -> Result<(String, Option<u8>, String), String> {
    let mut parts = text.splitn(3, '.');
    let stream = parts.next().unwrap_or_default();
    let second = parts.next();
    let third = parts.next();
    match (second, third) {
        (Some(column), None) if !stream.is_empty() && !column.is_empty() => {
            Ok((stream.to_string(), None, column.to_string()))
        }
        (Some(index), Some(column)) if !stream.is_empty() && !column.is_empty() => {
            let index = index.parse::<u8>().map_err(|_| {
                format!("series '{text}': expected <stream>.<column> or <stream>.<index>.<column>")
            })?;
            Ok((stream.to_string(), Some(index), column.to_string()))
        }
        _ => Err(format!(
            "series '{text}': expected <stream>.<column>, e.g. imu.p_rad_s"
        )),
    }
}

/// Finds `column` in `stream` (`docs/log-streams.md`: the unit suffix may be left out when
/// that is unambiguous): an exact column name first, else the one column named
/// `<column>_<unit>`.
pub fn resolve_column(
    stream: &Stream,
    index: Option<u8>,
    column: &str,
    text: &str,
) -> Result<SeriesRef, String> {
    let tables: Vec<&Table> = stream
        .tables
        .values()
        .filter(|t| index.is_none_or(|i| t.index == i))
        .collect();
    let exact: Vec<(u8, &String)> = tables
        .iter()
        .flat_map(|t| t.columns.iter().map(move |c| (t.index, c)))
        .filter(|(_, c)| c.as_str() == column)
        .collect();
    let prefix = format!("{column}_");
    let candidates = if exact.is_empty() {
        tables
            .iter()
            .flat_map(|t| t.columns.iter().map(move |c| (t.index, c)))
            .filter(|(_, c)| c.starts_with(&prefix) && is_unit(&c[prefix.len()..]))
            .collect()
    } else {
        exact
    };
    let known = || {
        tables
            .iter()
            .flat_map(|t| {
                t.columns
                    .iter()
                    .map(move |c| format!("{c} (format {})", t.index))
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    match candidates.as_slice() {
        [(index, column)] => Ok(SeriesRef {
            stream: stream.name.clone(),
            index: *index,
            column: (*column).clone(),
        }),
        [] => Err(format!(
            "series '{text}': {}: unknown column '{column}'; known columns: {}",
            stream.path.display(),
            known()
        )),
        many => Err(format!(
            "series '{text}': {}: column '{column}' is ambiguous: {}; name it as \
             <stream>.<index>.<column>",
            stream.path.display(),
            many.iter()
                .map(|(i, c)| format!("{c} (format {i})"))
                .collect::<Vec<_>>()
                .join(", ")
        )),
    }
}

/// The unit suffixes of `conventions.md` columns (`p_rad_s` → `rad_s`).
const UNITS: [&str; 14] = [
    "rad_s", "m_s2", "m_s", "m", "deg", "rad", "v", "us", "ns", "ms", "s", "c", "deg_s", "hz",
];

fn is_unit(suffix: &str) -> bool {
    UNITS.contains(&suffix)
}

/// The unit of a column, for grouping series into panels (`""` when it has none).
fn unit_of(column: &str) -> &str {
    // The longest known suffix wins (`m_s2` before `s`).
    let mut best = "";
    for unit in UNITS {
        if column.len() > unit.len()
            && column.ends_with(unit)
            && column.as_bytes().get(column.len() - unit.len() - 1) == Some(&b'_')
            && unit.len() > best.len()
        {
            best = unit;
        }
    }
    best
}

/// Loads the streams a run needs, once each; damage is reported, not fatal.
struct Loaded {
    source: Source,
    streams: BTreeMap<String, Stream>,
}

impl Loaded {
    fn new(path: &Path) -> Result<Self, String> {
        Ok(Self {
            source: Source::new(path)?,
            streams: BTreeMap::new(),
        })
    }

    fn unknown_stream(&self, name: &str) -> String {
        format!(
            "{}: unknown stream '{name}'; streams there: {}",
            self.source.display(),
            self.source.stream_names().join(", ")
        )
    }

    /// Loads stream `name`; `Ok(None)` when the source has no such stream.
    fn load(&mut self, name: &str) -> Result<Option<&Stream>, String> {
        if !self.streams.contains_key(name) {
            let Some(path) = self.source.stream_path(name) else {
                return Ok(None);
            };
            let stream = load_stream(&path)?;
            self.streams.insert(name.to_string(), stream);
        }
        Ok(self.streams.get(name))
    }

    fn problems(&self) -> usize {
        self.streams.values().map(|s| s.problems).sum()
    }

    fn t0_ns(&self) -> i64 {
        self.streams
            .values()
            .filter_map(Stream::first_time_ns)
            .min()
            .unwrap_or(0)
    }
}

fn column_points(table: &Table, column: &str, t0_ns: i64) -> Vec<(f64, f64)> {
    let values = table.column(column).unwrap_or(&[]);
    table
        .times_ns
        .iter()
        .zip(values)
        .map(|(&t, &v)| (seconds_from(t0_ns, t), v))
        .collect()
}

/// `plot FILE --series … -o OUT`.
pub fn run_series(path: &Path, series: &[String], output: &Path, options: &PlotOptions) -> Outcome {
    match plot_series(path, series, output, options) {
        Ok(outcome) => outcome,
        Err(message) => {
            eprintln!("skyframe-log: {message}");
            Outcome::Failed
        }
    }
}

fn plot_series(
    path: &Path,
    series: &[String],
    output: &Path,
    options: &PlotOptions,
) -> Result<Outcome, String> {
    crate::figure::ImageFormat::from_path(output)?;
    let mut loaded = Loaded::new(path)?;
    let names: Vec<&str> = series
        .iter()
        .flat_map(|s| s.split(','))
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .collect();
    if names.is_empty() {
        return Err("--series: no series named".into());
    }
    let mut refs = Vec::new();
    for text in names {
        let (stream, index, column) = split_series(text)?;
        let unknown = loaded.unknown_stream(&stream);
        let found = loaded
            .load(&stream)?
            .ok_or_else(|| format!("series '{text}': {unknown}"))?;
        refs.push(resolve_column(found, index, &column, text)?);
    }
    let t0 = loaded.t0_ns();
    // One panel per unit, in order of first appearance.
    let mut panels: Vec<(String, Panel)> = Vec::new();
    for r in &refs {
        let Some(table) = loaded
            .streams
            .get(&r.stream)
            .and_then(|s| s.tables.get(&r.index))
        else {
            continue;
        };
        let unit = unit_of(&r.column).to_string();
        let line = Series {
            label: r.label(),
            points: column_points(table, &r.column, t0),
            style: Style::Line,
        };
        match panels.iter_mut().find(|(u, _)| *u == unit) {
            Some((_, panel)) => panel.series.push(line),
            None => panels.push((
                unit.clone(),
                Panel {
                    title: String::new(),
                    x_label: "time (s)".into(),
                    y_label: if unit.is_empty() { String::new() } else { unit },
                    series: vec![line],
                    ..Panel::default()
                },
            )),
        }
    }
    let figure = Figure {
        title: format!("{}", path.display()),
        panels: panels.into_iter().map(|(_, p)| p).collect(),
    };
    render(&figure, output, options.size)?;
    Ok(if loaded.problems() > 0 {
        Outcome::Reported
    } else {
        Outcome::Whole
    })
}

/// The statistics of the interval between consecutive entries of one format.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct IntervalStats {
    pub stream: String,
    pub index: u8,
    /// Records of the format (data blocks and byte arrays).
    pub records: usize,
    /// Intervals measured: consecutive records within one Begin Data session.
    pub intervals: usize,
    pub mean_ms: f64,
    pub max_ms: f64,
    pub min_ms: f64,
}

/// The intervals of a table in ms, each at the time (ns) of the later record. A pause
/// between two logging sessions (End Data … Begin Data) is not an interval.
pub fn intervals_ms(table: &Table) -> Vec<(i64, f64)> {
    table
        .times_ns
        .windows(2)
        .zip(table.sessions.windows(2))
        .filter(|(_, s)| s.first() == s.last())
        .filter_map(|(t, _)| match t {
            [a, b] => Some((*b, (b - a) as f64 * 1e-6)),
            _ => None,
        })
        .collect()
}

pub fn interval_stats(stream: &str, table: &Table) -> IntervalStats {
    let intervals = intervals_ms(table);
    let n = intervals.len();
    let sum: f64 = intervals.iter().map(|i| i.1).sum();
    let max = intervals.iter().map(|i| i.1).fold(f64::NAN, f64::max);
    let min = intervals.iter().map(|i| i.1).fold(f64::NAN, f64::min);
    IntervalStats {
        stream: stream.to_string(),
        index: table.index,
        records: table.times_ns.len(),
        intervals: n,
        mean_ms: if n > 0 { sum / n as f64 } else { f64::NAN },
        max_ms: max,
        min_ms: min,
    }
}

/// What `--report --json` prints.
#[derive(Debug, Serialize)]
pub struct ReportSummary {
    pub source: String,
    pub dir: PathBuf,
    /// Files written, per figure.
    pub figures: BTreeMap<String, Vec<PathBuf>>,
    /// Figures skipped, with why.
    pub skipped: BTreeMap<String, String>,
    pub intervals: Vec<IntervalStats>,
    /// Reader problems (damage) over all streams.
    pub problems: usize,
}

/// Why a figure cannot be drawn.
type Skip = String;

/// North/east metres of `(lat, lon)` from `(lat0, lon0)` (degrees), on the WGS-84 plane
/// tangent at the origin: the estimator's own local frame (`estimation::geo`). NaN where the
/// origin is not a position.
pub fn local_north_east(lat0: f64, lon0: f64, lat: f64, lon: f64) -> (f64, f64) {
    let at = |latitude_deg, longitude_deg| GeoPoint {
        latitude_deg,
        longitude_deg,
        altitude_m: 0.0,
    };
    match LocalFrame::new(at(lat0, lon0)) {
        Some(frame) => {
            let ned = frame.to_ned(&at(lat, lon));
            (ned.x, ned.y)
        }
        None => (f64::NAN, f64::NAN),
    }
}

struct Report<'a> {
    loaded: &'a mut Loaded,
    t0: i64,
    size: (u32, u32),
}

impl Report<'_> {
    fn table(&mut self, stream: &str, index: u8) -> Result<&Table, Skip> {
        let unknown = self.loaded.source.missing(stream);
        let s = self.loaded.load(stream)?.ok_or(unknown)?;
        s.tables
            .get(&index)
            .ok_or_else(|| format!("{}: no records of format {index}", s.path.display()))
    }

    fn series(
        &mut self,
        stream: &str,
        index: u8,
        columns: &[&str],
        style: Style,
    ) -> Result<Vec<Series>, Skip> {
        let t0 = self.t0;
        let table = self.table(stream, index)?;
        columns
            .iter()
            .map(|&c| {
                if table.column(c).is_none() {
                    return Err(format!(
                        "{stream}.bin format {index} has no column '{c}' (columns: {})",
                        table.columns.join(",")
                    ));
                }
                Ok(Series {
                    label: c.to_string(),
                    points: column_points(table, c, t0),
                    style,
                })
            })
            .collect()
    }

    fn time_panel(
        &mut self,
        title: &str,
        y_label: &str,
        stream: &str,
        index: u8,
        columns: &[&str],
        style: Style,
    ) -> Result<Panel, Skip> {
        Ok(Panel {
            title: title.into(),
            x_label: "time (s)".into(),
            y_label: y_label.into(),
            series: self.series(stream, index, columns, style)?,
            ..Panel::default()
        })
    }

    fn gps_validity(&mut self) -> Result<Figure, Skip> {
        let covering = |mut panel: Panel, covers| {
            panel.y_covers = Some(covers);
            panel
        };
        Ok(Figure {
            title: "GPS validity".into(),
            panels: vec![
                covering(
                    self.time_panel("fix valid", "valid", "gps", 1, &["valid"], Style::Line)?,
                    (0.0, 1.0),
                ),
                covering(
                    self.time_panel(
                        "fix quality (GGA: 0 none, 1 GPS, 2 DGPS, ...)",
                        "quality",
                        "gps",
                        1,
                        &["quality"],
                        Style::Line,
                    )?,
                    (0.0, 2.0),
                ),
                covering(
                    self.time_panel(
                        "satellites used",
                        "satellites",
                        "gps",
                        1,
                        &["satellites"],
                        Style::Line,
                    )?,
                    (0.0, 4.0),
                ),
            ],
        })
    }

    fn gps_track(&mut self) -> Result<Figure, Skip> {
        let table = self.table("gps", 1)?;
        let (Some(valid), Some(lat), Some(lon)) = (
            table.column("valid"),
            table.column("lat_deg"),
            table.column("lon_deg"),
        ) else {
            return Err("gps.bin format 1 lacks valid, lat_deg or lon_deg".into());
        };
        let fixes: Vec<(f64, f64)> = valid
            .iter()
            .zip(lat.iter().zip(lon))
            .filter(|(v, (la, lo))| **v == 1.0 && la.is_finite() && lo.is_finite())
            .map(|(_, (la, lo))| (*la, *lo))
            .collect();
        let Some(&(lat0, lon0)) = fixes.first() else {
            return Err("gps.bin has no valid fix".into());
        };
        let points = fixes
            .iter()
            .map(|&(la, lo)| {
                let (n, e) = local_north_east(lat0, lon0, la, lo);
                (e, n)
            })
            .collect();
        Ok(Figure {
            title: format!("GPS track from the first valid fix ({lat0:.6}°, {lon0:.6}°)"),
            panels: vec![Panel {
                title: String::new(),
                x_label: "east (m)".into(),
                y_label: "north (m)".into(),
                series: vec![Series {
                    label: "valid fixes".into(),
                    points,
                    style: Style::Line,
                }],
                equal_axes: true,
                ..Panel::default()
            }],
        })
    }

    fn gps_accuracy(&mut self) -> Result<Figure, Skip> {
        Ok(Figure {
            title: "GPS accuracy".into(),
            panels: vec![
                self.time_panel(
                    "dilution of precision",
                    "DOP",
                    "gps",
                    1,
                    &["pdop", "hdop", "vdop"],
                    Style::Line,
                )?,
                self.time_panel(
                    "position standard deviation (GST, 1 sigma)",
                    "m",
                    "gps",
                    1,
                    &["sd_n_m", "sd_e_m", "sd_d_m"],
                    Style::Line,
                )?,
            ],
        })
    }

    fn intervals(&mut self, stats: &mut Vec<IntervalStats>) -> Result<Figure, Skip> {
        let names = self.loaded.source.stream_names();
        let mut panels = Vec::new();
        for name in names {
            let t0 = self.t0;
            let Ok(Some(stream)) = self.loaded.load(&name) else {
                continue;
            };
            for table in stream.tables.values() {
                let s = interval_stats(&stream.name, table);
                let points = intervals_ms(table)
                    .into_iter()
                    .map(|(t, ms)| (seconds_from(t0, t), ms))
                    .collect();
                panels.push(Panel {
                    title: format!("{}.bin format {}", stream.name, table.index),
                    x_label: "time (s)".into(),
                    y_label: "interval (ms)".into(),
                    series: vec![Series {
                        label: format!(
                            "{}.{}: mean {:.1} ms, max {:.1} ms",
                            stream.name, table.index, s.mean_ms, s.max_ms
                        ),
                        points,
                        style: Style::Points,
                    }],
                    ..Panel::default()
                });
                stats.push(s);
            }
        }
        if panels.is_empty() {
            return Err("no stream has records".into());
        }
        let fit = crate::figure::panels_that_fit(self.size);
        if panels.len() > fit {
            eprintln!(
                "skyframe-log: note: intervals: {} of {} formats drawn (a taller --size draws \
                 more; --json lists them all)",
                fit,
                panels.len()
            );
            panels.truncate(fit);
        }
        Ok(Figure {
            title: "Interval between consecutive entries".into(),
            panels,
        })
    }

    fn imu_rates_vs_aileron(&mut self) -> Result<Figure, Skip> {
        Ok(Figure {
            title: "IMU rates vs pilot aileron".into(),
            panels: vec![
                self.time_panel(
                    "angular rates (body FRD)",
                    "rad/s",
                    "imu",
                    1,
                    &["p_rad_s", "q_rad_s", "r_rad_s"],
                    Style::Line,
                )?,
                self.time_panel(
                    "pilot aileron (servo board, normalised, + rolls right)",
                    "aileron",
                    "servo",
                    1,
                    &["aileron"],
                    Style::Line,
                )?,
            ],
        })
    }

    fn battery(&mut self) -> Result<Figure, Skip> {
        Ok(Figure {
            title: "Batteries (servo board)".into(),
            panels: vec![
                self.time_panel(
                    "avionics battery",
                    "V",
                    "servo",
                    1,
                    &["batt_avionics_v"],
                    Style::Line,
                )?,
                self.time_panel(
                    "servo battery",
                    "V",
                    "servo",
                    1,
                    &["batt_servo_v"],
                    Style::Line,
                )?,
            ],
        })
    }
}

/// The report's figures, in order.
pub const REPORT_FIGURES: [&str; 6] = [
    "gps_validity",
    "gps_track",
    "gps_accuracy",
    "intervals",
    "imu_rates_vs_aileron",
    "battery",
];

/// `plot FILE --report DIR [--json]`.
pub fn run_report(path: &Path, dir: &Path, json: bool, options: &PlotOptions) -> Outcome {
    match report(path, dir, options) {
        Ok(summary) => {
            if json {
                if let Err(e) = crate::print_json(&summary) {
                    eprintln!("skyframe-log: {e}");
                    return Outcome::Failed;
                }
            }
            if summary.problems > 0 {
                Outcome::Reported
            } else {
                Outcome::Whole
            }
        }
        Err(message) => {
            eprintln!("skyframe-log: {message}");
            Outcome::Failed
        }
    }
}

pub fn report(path: &Path, dir: &Path, options: &PlotOptions) -> Result<ReportSummary, String> {
    let mut loaded = Loaded::new(path)?;
    std::fs::create_dir_all(dir)
        .map_err(|e| format!("{}: cannot create directory: {e}", dir.display()))?;
    for name in loaded.source.stream_names() {
        loaded.load(&name)?;
    }
    let t0 = loaded.t0_ns();
    let mut report = Report {
        loaded: &mut loaded,
        t0,
        size: options.size,
    };
    let mut summary = ReportSummary {
        source: path.display().to_string(),
        dir: dir.to_path_buf(),
        figures: BTreeMap::new(),
        skipped: BTreeMap::new(),
        intervals: Vec::new(),
        problems: 0,
    };
    for name in REPORT_FIGURES {
        let figure = match name {
            "gps_validity" => report.gps_validity(),
            "gps_track" => report.gps_track(),
            "gps_accuracy" => report.gps_accuracy(),
            "intervals" => report.intervals(&mut summary.intervals),
            "imu_rates_vs_aileron" => report.imu_rates_vs_aileron(),
            _ => report.battery(),
        };
        match figure {
            Ok(figure) => {
                let mut files = Vec::new();
                for ext in ["png", "svg"] {
                    let file = dir.join(format!("{name}.{ext}"));
                    render(&figure, &file, options.size)?;
                    files.push(file);
                }
                summary.figures.insert(name.to_string(), files);
            }
            Err(why) => {
                eprintln!("skyframe-log: note: {name} skipped: {why}");
                summary.skipped.insert(name.to_string(), why);
            }
        }
    }
    summary.problems = loaded.problems();
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_and_series_names() {
        assert_eq!(unit_of("p_rad_s"), "rad_s");
        assert_eq!(unit_of("fz_m_s2"), "m_s2");
        assert_eq!(unit_of("batt_servo_v"), "v");
        assert_eq!(unit_of("aileron"), "");
        assert_eq!(
            split_series("imu.p").expect("ok"),
            ("imu".into(), None, "p".into())
        );
        assert_eq!(
            split_series("servo.2.aileron_cmd").expect("ok"),
            ("servo".into(), Some(2), "aileron_cmd".into())
        );
        assert!(split_series("imu").is_err());
        assert!(split_series("imu.x.p").is_err());
    }

    #[test]
    fn local_coordinates_of_a_known_offset() {
        // 0.001° of latitude is about 111 m at 45°; of longitude, cos(45°) of ~111.4 km.
        let (n, e) = local_north_east(45.0, 7.0, 45.001, 7.001);
        assert!((n - 111.13).abs() < 0.05, "{n}");
        assert!((e - 78.85).abs() < 0.05, "{e}");
        assert_eq!(local_north_east(45.0, 7.0, 45.0, 7.0), (0.0, 0.0));
    }

    #[test]
    fn intervals_skip_pauses_between_sessions() {
        let table = Table {
            index: 1,
            times_ns: vec![0, 100_000_000, 240_000_000, 10_000_000_000, 10_100_000_000],
            sessions: vec![1, 1, 1, 2, 2],
            ..Table::default()
        };
        let s = interval_stats("gps", &table);
        assert_eq!(s.records, 5);
        assert_eq!(s.intervals, 3);
        assert!((s.mean_ms - 340.0 / 3.0).abs() < 1e-9);
        assert!((s.max_ms - 140.0).abs() < 1e-9);
        assert!((s.min_ms - 100.0).abs() < 1e-9);
    }
}
