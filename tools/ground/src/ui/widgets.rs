//! What each page draws: value tables with units, 60 s charts, the attitude indicator, the
//! GPS and servo pages, the link and log lines.

use crate::model::{FormatState, HISTORY_SPAN_S, VehicleState, column_unit, value_as_f64};
use crate::values::{ack_result_name, value_text};
use ratatui::Frame;
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Modifier, Style, Stylize};
use ratatui::symbols::Marker;
use ratatui::text::{Line, Span};
use ratatui::widgets::canvas::{Canvas, Line as CanvasLine, Points};
use ratatui::widgets::{Axis, Block, Chart, Dataset, Gauge, GraphType, Paragraph, Row, Table};
use std::time::Instant;

/// Battery gauges run from empty to full at these per-cell voltages (LiPo), cells guessed
/// from the voltage itself: a gauge, not a fuel computer.
const CELL_EMPTY_V: f64 = 3.3;
const CELL_FULL_V: f64 = 4.2;

/// The flight log's health: red when records are being lost.
pub(super) fn log_line(log: &skyframe_core::link::messages::LogHealth) -> Line<'static> {
    let free = if log.free_mib == skyframe_core::link::messages::LogHealth::UNKNOWN {
        "free space unknown".to_string()
    } else {
        format!("{} MiB free", log.free_mib)
    };
    let text = format!(
        "log: {free}  records lost {}  streams suspended {}",
        log.records_lost, log.streams_suspended
    );
    if log.records_lost > 0 || log.streams_suspended > 0 {
        Line::styled(text, Style::new().fg(Color::Red).bold())
    } else {
        Line::from(text)
    }
}

/// Datagrams received per second from this vehicle: gaps are link loss.
pub(super) fn draw_arrivals(frame: &mut Frame, area: Rect, vehicle: &VehicleState, now: Instant) {
    let counts = vehicle.arrivals.per_second_until(now);
    let n = counts.len() as f64;
    let points: Vec<(f64, f64)> = counts
        .iter()
        .enumerate()
        .map(|(i, &c)| (i as f64 - n, f64::from(c)))
        .collect();
    let high = counts.iter().copied().max().unwrap_or(0).max(1);
    let last = counts.last().copied().unwrap_or(0);
    let chart = Chart::new(vec![
        Dataset::default()
            .marker(Marker::Braille)
            .graph_type(GraphType::Line)
            .style(Style::new().fg(Color::Cyan))
            .data(&points),
    ])
    .block(Block::bordered().title(format!(" link: {last} datagrams/s ")))
    .x_axis(
        Axis::default()
            .bounds([-n.max(2.0), 0.0])
            .labels([format!("-{n:.0} s"), "now".to_string()]),
    )
    .y_axis(
        Axis::default()
            .bounds([0.0, f64::from(high)])
            .labels(["0".to_string(), high.to_string()]),
    );
    frame.render_widget(chart, area);
}

/// The parameters heard (the answer to `params`, or changes) and the latest
/// acknowledgements: the seed's configuration section.
pub(super) fn draw_params_and_acks(frame: &mut Frame, area: Rect, vehicle: &VehicleState) {
    let [params_area, acks_area] =
        Layout::horizontal([Constraint::Percentage(60), Constraint::Percentage(40)]).areas(area);
    let rows: Vec<Row> = vehicle
        .params
        .values()
        .map(|p| {
            Row::new([
                p.name.as_str().to_string(),
                value_text(&p.value),
                format!("{} … {}", value_text(&p.min), value_text(&p.max)),
            ])
        })
        .collect();
    let empty = rows.is_empty();
    let table = Table::new(
        rows,
        [
            Constraint::Length(20),
            Constraint::Length(10),
            Constraint::Min(10),
        ],
    )
    .header(Row::new(["parameter", "value", "range"]).style(Style::new().bold()))
    .block(Block::bordered().title(if empty {
        " parameters (none heard: p lists them) "
    } else {
        " parameters "
    }));
    frame.render_widget(table, params_area);
    let lines: Vec<Line> = vehicle
        .acks
        .iter()
        .rev()
        .map(|a| {
            Line::from(format!(
                "#{} from {} type 0x{:02x}: {}{}",
                a.command_sequence,
                a.command_sender_id,
                a.command_type,
                ack_result_name(a.result),
                a.value_in_force
                    .map(|v| format!(" ({})", value_text(&v)))
                    .unwrap_or_default()
            ))
        })
        .collect();
    frame.render_widget(
        Paragraph::new(lines).block(Block::bordered().title(" command acknowledgements ")),
        acks_area,
    );
}

/// How a column is shown: its name without the unit suffix, the value in the unit people
/// read (degrees where the log has radians), and that unit.
pub(super) struct Shown {
    name: String,
    value: f64,
    unit: &'static str,
}

pub(super) fn shown(column: &str, value: f64) -> Shown {
    let unit = column_unit(column);
    let name = strip_unit(column).to_string();
    match unit {
        Some("rad") => Shown {
            name,
            value: value.to_degrees(),
            unit: "°",
        },
        Some("rad/s") => Shown {
            name,
            value: value.to_degrees(),
            unit: "°/s",
        },
        Some("deg") => Shown {
            name,
            value,
            unit: "°",
        },
        Some("m/s^2") => Shown {
            name,
            value,
            unit: "m/s²",
        },
        unit => Shown {
            name,
            value,
            unit: unit.unwrap_or(""),
        },
    }
}

/// A unit suffix is one `_unit` part, or two for compound units (`_m_s`, `_rad_s`, `_m_s2`).
fn unit_suffix_parts(column: &str) -> usize {
    match column_unit(column) {
        Some("m/s" | "rad/s" | "m/s^2") => 2,
        Some(_) => 1,
        None => 0,
    }
}

/// The column's name without its unit suffix: `p_rad_s` → `p`, `alt_m` → `alt`.
pub(super) fn strip_unit(column: &str) -> &str {
    let mut name = column;
    for _ in 0..unit_suffix_parts(column) {
        name = name.rfind('_').map_or(name, |i| &name[..i]);
    }
    if name.is_empty() { column } else { name }
}

pub(super) fn shown_text(shown: &Shown) -> String {
    let v = shown.value;
    // Seven decimals of a degree: 1 cm on the ground.
    if shown.unit == "°" && (shown.name.ends_with("lat") || shown.name.ends_with("lon")) {
        format!("{v:.7}")
    } else if v.fract() == 0.0 && v.abs() < 1e9 {
        format!("{v:.0}")
    } else if v.abs() >= 100.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.3}")
    }
}

/// A log TIME (in tenths of a second) as a person reads it: a time of day in UTC when the
/// vehicle logs wall-clock time (a real-time flight), seconds of flight otherwise.
pub(super) fn log_time_text(tenths: i64) -> String {
    // Any time after 2001 is a wall clock; a flight's own clock never runs that long.
    const WALL_CLOCK_AFTER_S: i64 = 1_000_000_000;
    if tenths / 10 >= WALL_CLOCK_AFTER_S {
        let of_day = tenths.rem_euclid(864_000);
        format!(
            "{:02}:{:02}:{:02}.{} UTC",
            of_day / 36_000,
            of_day / 600 % 60,
            of_day / 10 % 60,
            of_day % 10
        )
    } else {
        format!("{:.1} s", tenths as f64 / 10.0)
    }
}

/// Every format's latest values, as the seed's property sheet: name, value, unit.
fn values_table<'a>(
    task: &str,
    formats: impl Iterator<Item = (&'a u8, &'a FormatState)>,
) -> Table<'a> {
    let mut rows = Vec::new();
    let mut time = None;
    for (index, format) in formats {
        time = time.max(format.latest_time_s().map(|t| (t * 10.0).round() as i64));
        for (i, value) in format.latest.iter().enumerate() {
            let s = shown(&format.column_name(i), value_as_f64(value));
            rows.push(Row::new([
                format!("{index}"),
                s.name.clone(),
                shown_text(&s),
                s.unit.to_string(),
            ]));
        }
    }
    let at = time.map_or(String::new(), |t| format!("at {} ", log_time_text(t)));
    Table::new(
        rows,
        [
            Constraint::Length(2),
            Constraint::Length(15),
            Constraint::Length(13),
            Constraint::Length(5),
        ],
    )
    .header(Row::new(["#", "name", "value", "unit"]).style(Style::new().bold()))
    .block(Block::bordered().title(format!(" {task} latest {at}")))
}

/// Beyond this magnitude a value is left out of charts: the chart's scale would lose the
/// rest (and bounds near f64::MAX overflow the canvas's arithmetic).
const PLOT_LIMIT: f64 = 1e12;

fn plottable(v: f64) -> bool {
    v.is_finite() && v.abs() < PLOT_LIMIT
}

const CHART_COLORS: [Color; 6] = [
    Color::Cyan,
    Color::Yellow,
    Color::Magenta,
    Color::Green,
    Color::Red,
    Color::Blue,
];

/// The last minute of some columns (by name, units may be left out) from one or more
/// formats, against the vehicle's clock: x is seconds before the newest record.
fn history_chart(frame: &mut Frame, area: Rect, title: &str, series: &[(&FormatState, &str)]) {
    let series: Vec<(String, Vec<(f64, f64)>)> = series
        .iter()
        .filter_map(|&(format, column)| {
            let index = format.column_index(column)?;
            let s = shown(&format.column_name(index), 0.0);
            let scale = if s.unit == "°" || s.unit == "°/s" {
                // Shown in degrees; the history is in the log's unit.
                if format.column_name(index).ends_with("_deg") {
                    1.0
                } else {
                    1f64.to_degrees()
                }
            } else {
                1.0
            };
            let points = format
                .recent(index, HISTORY_SPAN_S)
                .into_iter()
                .map(|(age, v)| (age, v * scale))
                .filter(|(_, v)| plottable(*v))
                .collect();
            let label = if s.unit.is_empty() {
                s.name
            } else {
                format!("{} {}", s.name, s.unit)
            };
            Some((label, points))
        })
        .collect();
    let (mut low, mut high) = (f64::INFINITY, f64::NEG_INFINITY);
    for (_, points) in &series {
        for &(_, v) in points {
            low = low.min(v);
            high = high.max(v);
        }
    }
    if !low.is_finite() || !high.is_finite() {
        (low, high) = (-1.0, 1.0);
    }
    if high - low < 1e-6 {
        low -= 1.0;
        high += 1.0;
    }
    let datasets: Vec<Dataset> = series
        .iter()
        .enumerate()
        .map(|(i, (name, points))| {
            Dataset::default()
                .name(name.clone())
                .marker(Marker::Braille)
                .graph_type(GraphType::Line)
                .style(Style::new().fg(CHART_COLORS[i % CHART_COLORS.len()]))
                .data(points)
        })
        .collect();
    let chart = Chart::new(datasets)
        .block(Block::bordered().title(format!(" {title} ")))
        // The legend names the series and their units: keep it on charts down to a few rows.
        .hidden_legend_constraints((Constraint::Ratio(1, 2), Constraint::Ratio(3, 4)))
        .x_axis(Axis::default().bounds([-HISTORY_SPAN_S, 0.0]).labels([
            format!("-{HISTORY_SPAN_S:.0} s"),
            format!("-{:.0} s", HISTORY_SPAN_S / 2.0),
            "now".to_string(),
        ]))
        .y_axis(
            Axis::default()
                .bounds([low, high])
                .labels([format!("{low:.1}"), format!("{high:.1}")]),
        );
    frame.render_widget(chart, area);
}

fn waiting(frame: &mut Frame, area: Rect, task: &str) {
    frame.render_widget(
        Paragraph::new(format!("No data from task {task} yet.")).block(Block::bordered()),
        area,
    );
}

/// The latest values of every format beside charts: one chart per group of columns of
/// its first format, or its first four columns.
pub(super) fn draw_generic(
    frame: &mut Frame,
    area: Rect,
    vehicle: &VehicleState,
    task: &str,
    title: &str,
    charts: &[(&str, &[&str])],
) {
    let Some((_, state)) = vehicle.task_by_name(task) else {
        return waiting(frame, area, task);
    };
    let [table_area, chart_area] =
        Layout::horizontal([Constraint::Length(40), Constraint::Min(20)]).areas(area);
    frame.render_widget(values_table(title, state.formats.iter()), table_area);
    let Some(format) = state.formats.values().next() else {
        return;
    };
    let first_columns: Vec<String> = (0..format.history.len().min(4))
        .map(|i| format.column_name(i))
        .collect();
    let default_chart: Vec<&str> = first_columns.iter().map(String::as_str).collect();
    let default_charts = [("history", default_chart.as_slice())];
    let charts = if charts.is_empty() {
        &default_charts[..]
    } else {
        charts
    };
    let areas = Layout::vertical(vec![Constraint::Fill(1); charts.len()]).split(chart_area);
    for (&(chart_title, columns), &area) in charts.iter().zip(areas.iter()) {
        let series: Vec<(&FormatState, &str)> = columns.iter().map(|&c| (format, c)).collect();
        history_chart(frame, area, &format!("{title} {chart_title}"), &series);
    }
}

/// The control loops: each target beside what the estimate says it is.
pub(super) fn draw_control(frame: &mut Frame, area: Rect, vehicle: &VehicleState) {
    let Some((_, state)) = vehicle.task_by_name("control") else {
        return waiting(frame, area, "control");
    };
    let Some(format) = state.formats.get(&1) else {
        return draw_generic(frame, area, vehicle, "control", "Control", &[]);
    };
    let [table_area, chart_area] =
        Layout::horizontal([Constraint::Length(40), Constraint::Min(20)]).areas(area);
    frame.render_widget(values_table("Control", state.formats.iter()), table_area);
    let [top, bottom] =
        Layout::vertical([Constraint::Fill(1), Constraint::Fill(1)]).areas(chart_area);
    let [a, b] = Layout::horizontal([Constraint::Fill(1), Constraint::Fill(1)]).areas(top);
    let [c, d] = Layout::horizontal([Constraint::Fill(1), Constraint::Fill(1)]).areas(bottom);
    for (area, title, actual, target) in [
        (a, "roll: target vs actual", "roll", "roll_c"),
        (b, "pitch: target vs actual", "pitch", "pitch_c"),
        (c, "altitude: target vs actual", "alt", "alt_c"),
        (d, "course: target vs actual", "course", "course_c"),
    ] {
        history_chart(frame, area, title, &[(format, target), (format, actual)]);
    }
}

/// Rates and specific force, each in its own chart (their scales differ by 10×).
pub(super) fn draw_imu(frame: &mut Frame, area: Rect, vehicle: &VehicleState) {
    draw_generic(
        frame,
        area,
        vehicle,
        "imu",
        "IMU",
        &[
            ("angular rates", &["p", "q", "r"]),
            ("specific force", &["fx", "fy", "fz"]),
        ],
    );
}

pub(super) fn draw_gps(frame: &mut Frame, area: Rect, vehicle: &VehicleState) {
    let Some(format) = vehicle
        .task_by_name("gps")
        .and_then(|(_, t)| t.formats.get(&1))
    else {
        return waiting(frame, area, "gps");
    };
    let [text_area, right_area] =
        Layout::horizontal([Constraint::Length(40), Constraint::Min(20)]).areas(area);
    let [track_area, accuracy_area] =
        Layout::vertical([Constraint::Percentage(65), Constraint::Min(6)]).areas(right_area);
    history_chart(
        frame,
        accuracy_area,
        "accuracy: σ N, E, D and HDOP",
        &[
            (format, "sd_n"),
            (format, "sd_e"),
            (format, "sd_d"),
            (format, "hdop"),
        ],
    );
    let get = |c: &str| format.latest_by_name(c).unwrap_or(f64::NAN);
    let lines = vec![
        Line::from(format!(
            "fix {}  quality {}  satellites {}",
            if get("valid") == 1.0 { "valid" } else { "NONE" },
            get("quality"),
            get("satellites")
        )),
        Line::from(format!(
            "lat {:.7}°  lon {:.7}°",
            get("lat_deg"),
            get("lon_deg")
        )),
        Line::from(format!("alt {:.1} m MSL", get("alt_m"))),
        Line::from(format!(
            "v N {:.1}  E {:.1}  D {:.1} m/s",
            get("vn_m_s"),
            get("ve_m_s"),
            get("vd_m_s")
        )),
        Line::from(format!(
            "DOP p {:.1}  h {:.1}  v {:.1}",
            get("pdop"),
            get("hdop"),
            get("vdop")
        )),
        Line::from(format!(
            "σ N {:.1}  E {:.1}  D {:.1} m",
            get("sd_n_m"),
            get("sd_e_m"),
            get("sd_d_m")
        )),
    ];
    frame.render_widget(
        Paragraph::new(lines).block(Block::bordered().title(" GPS ")),
        text_area,
    );
    // Track in local metres from the oldest fix kept: flat-earth, fine over a few km.
    let (Some(lat), Some(lon)) = (
        format.history_by_name("lat_deg"),
        format.history_by_name("lon_deg"),
    ) else {
        return;
    };
    let fixes: Vec<(f64, f64)> = lat
        .iter()
        .zip(lon)
        .filter(|(a, o)| a.abs() <= 90.0 && o.abs() <= 180.0) // only positions on Earth
        .map(|(&a, &o)| (a, o))
        .collect();
    let Some(&(lat0, lon0)) = fixes.first() else {
        return;
    };
    const EARTH_RADIUS_M: f64 = 6_371_000.0;
    let track: Vec<(f64, f64)> = fixes
        .iter()
        .map(|&(a, o)| {
            let east = (o - lon0).to_radians() * EARTH_RADIUS_M * lat0.to_radians().cos();
            let north = (a - lat0).to_radians() * EARTH_RADIUS_M;
            (east, north)
        })
        .collect();
    let extent = track
        .iter()
        .fold(10.0f64, |m, &(e, n)| m.max(e.abs()).max(n.abs()))
        * 1.1;
    let last = track.last().copied();
    frame.render_widget(
        Canvas::default()
            .block(
                Block::bordered()
                    .title(format!(" track, local metres (E →, N ↑), ±{extent:.0} m ")),
            )
            .marker(Marker::Braille)
            .x_bounds([-extent, extent])
            .y_bounds([-extent, extent])
            .paint(move |ctx| {
                ctx.draw(&Points {
                    coords: &track,
                    color: Color::Cyan,
                });
                if let Some(p) = last {
                    ctx.print(p.0, p.1, Span::styled("✈", Style::new().fg(Color::Yellow)));
                }
            }),
        track_area,
    );
}

pub(super) fn draw_estimator(frame: &mut Frame, area: Rect, vehicle: &VehicleState) {
    let Some((_, state)) = vehicle.task_by_name("estimator") else {
        return waiting(frame, area, "estimator");
    };
    let Some(format) = state
        .formats
        .values()
        .find(|f| f.column_index("roll").is_some())
    else {
        return draw_generic(frame, area, vehicle, "estimator", "Estimator", &[]);
    };
    let [left_area, chart_area] =
        Layout::horizontal([Constraint::Length(44), Constraint::Min(20)]).areas(area);
    let [indicator_area, text_area] =
        Layout::vertical([Constraint::Min(8), Constraint::Length(8)]).areas(left_area);
    let get = |c: &str| format.latest_by_name(c).unwrap_or(f64::NAN);
    draw_attitude(
        frame,
        indicator_area,
        get("roll"),
        get("pitch"),
        format.latest_by_name("yaw"),
    );
    // The estimator's position is north-east-down from its origin (its first fix); the
    // control task logs the estimate as altitude above sea level and as airspeed.
    let control = vehicle
        .task_by_name("control")
        .and_then(|(_, t)| t.formats.get(&1));
    let from_control = |c: &str| {
        control
            .and_then(|f| f.latest_by_name(c))
            .unwrap_or(f64::NAN)
    };
    let ground_speed = get("vn").hypot(get("ve"));
    let health = state
        .formats
        .values()
        .find_map(|f| f.latest_by_name("healthy"))
        .map_or("?", |h| if h >= 0.5 { "healthy" } else { "UNHEALTHY" });
    let lines = vec![
        Line::from(format!("altitude {:.1} m above home", from_control("alt"))),
        Line::from(format!(
            "height {:.1} m above the filter's origin",
            -get("pd")
        )),
        Line::from(format!(
            "airspeed {:.1} m/s   ground speed {ground_speed:.1} m/s",
            from_control("speed")
        )),
        Line::from(format!("climb {:+.1} m/s", -get("vd"))),
        Line::from(format!(
            "from origin N {:.1}  E {:.1} m",
            get("pn"),
            get("pe")
        )),
        Line::from(format!("filter {health}")),
    ];
    frame.render_widget(
        Paragraph::new(lines).block(Block::bordered().title(" estimate ")),
        text_area,
    );
    let [attitude_area, altitude_area, speed_area] = Layout::vertical([
        Constraint::Fill(2),
        Constraint::Fill(1),
        Constraint::Fill(1),
    ])
    .areas(chart_area);
    history_chart(
        frame,
        attitude_area,
        "attitude",
        &[(format, "roll"), (format, "pitch")],
    );
    match control {
        Some(control) => {
            history_chart(frame, altitude_area, "altitude", &[(control, "alt")]);
            history_chart(frame, speed_area, "airspeed", &[(control, "speed")]);
        }
        None => {
            history_chart(frame, altitude_area, "down from origin", &[(format, "pd")]);
            history_chart(
                frame,
                speed_area,
                "velocity",
                &[(format, "vn"), (format, "ve")],
            );
        }
    }
}

/// An attitude indicator: the horizon as the pilot sees it. A positive roll (right wing
/// down) lifts the horizon's right end; a positive pitch (nose up) lowers it; 1 unit = 10°.
/// The ground side is dotted.
fn draw_attitude(frame: &mut Frame, area: Rect, roll: f64, pitch: f64, yaw: Option<f64>) {
    let roll = if roll.is_finite() { roll } else { 0.0 };
    let pitch = if pitch.is_finite() { pitch } else { 0.0 };
    let title = format!(
        " attitude: roll {:+.1}° pitch {:+.1}°{} ",
        roll.to_degrees(),
        pitch.to_degrees(),
        yaw.filter(|y| y.is_finite())
            .map(|y| format!(" yaw {:.0}°", y.to_degrees().rem_euclid(360.0)))
            .unwrap_or_default()
    );
    // Beyond ±90° of pitch the horizon is off the dial anyway.
    let offset = (-pitch.to_degrees() / 10.0).clamp(-9.0, 9.0);
    let (sin, cos) = roll.sin_cos();
    // Screen point of horizon-frame point (along, up): rotated by the roll.
    let to_screen = move |along: f64, up: f64| (along * cos - up * sin, along * sin + up * cos);
    // Horizon-frame height of a screen point: below `offset` is ground.
    let height = move |x: f64, y: f64| -x * sin + y * cos;
    const HALF_WIDTH: f64 = 4.0;
    // Terminal cells are about twice as tall as wide: size the y range so that a unit is as
    // long up as across, or the roll angle would look steeper than it is.
    let columns = f64::from(area.width.saturating_sub(2).max(1));
    let rows = f64::from(area.height.saturating_sub(2).max(1));
    let half_height = HALF_WIDTH * 2.0 * rows / columns;
    let inside = move |&(x, y): &(f64, f64)| x.abs() <= HALF_WIDTH && y.abs() <= half_height;
    let horizon: Vec<(f64, f64)> = (-400..=400)
        .map(|i| to_screen(f64::from(i) * 0.02, offset))
        .filter(inside)
        .collect();
    let mut ground = Vec::new();
    let grid_rows = (half_height / 0.25).ceil() as i32;
    for i in -16..=16 {
        for j in -grid_rows..=grid_rows {
            let (x, y) = (f64::from(i) * 0.25, f64::from(j) * 0.25);
            if height(x, y) < offset - 0.15 {
                ground.push((x, y));
            }
        }
    }
    let rungs: Vec<(f64, f64)> = [-2, -1, 1, 2]
        .into_iter()
        .flat_map(|rung| {
            (-20..=20).map(move |i| to_screen(f64::from(i) * 0.03, offset + f64::from(rung)))
        })
        .filter(inside)
        .collect();
    frame.render_widget(
        Canvas::default()
            .block(Block::bordered().title(title))
            .marker(Marker::Braille)
            .x_bounds([-HALF_WIDTH, HALF_WIDTH])
            .y_bounds([-half_height, half_height])
            .paint(move |ctx| {
                ctx.draw(&Points {
                    coords: &ground,
                    color: Color::Rgb(140, 90, 40),
                });
                ctx.draw(&Points {
                    coords: &rungs,
                    color: Color::DarkGray,
                });
                ctx.draw(&Points {
                    coords: &horizon,
                    color: Color::Green,
                });
                // The aircraft symbol stays fixed.
                for (x1, x2) in [(-1.6, -0.5), (0.5, 1.6)] {
                    ctx.draw(&CanvasLine {
                        x1,
                        y1: 0.0,
                        x2,
                        y2: 0.0,
                        color: Color::Yellow,
                    });
                }
                ctx.print(0.0, 0.0, Span::styled("▲", Style::new().fg(Color::Yellow)));
            }),
        area,
    );
}

pub(super) fn ratio(value: f64, low: f64, high: f64) -> f64 {
    let r = (value - low) / (high - low);
    if r.is_finite() {
        r.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

pub(super) fn draw_servo(frame: &mut Frame, area: Rect, vehicle: &VehicleState) {
    let Some((_, state)) = vehicle.task_by_name("servo") else {
        return waiting(frame, area, "servo");
    };
    let pilot = state.formats.get(&1);
    let computer = state.formats.get(&2);
    let [bars_area, battery_area, chart_area] = Layout::vertical([
        Constraint::Length(10),
        Constraint::Length(4),
        Constraint::Min(4),
    ])
    .areas(area);
    if let Some(pilot) = pilot {
        let mut series: Vec<(&FormatState, &str)> = ["aileron", "elevator", "throttle"]
            .iter()
            .map(|&c| (pilot, c))
            .collect();
        if let Some(computer) = computer {
            series.extend(
                ["aileron_cmd", "elevator_cmd", "throttle_cmd"]
                    .iter()
                    .map(|&c| (computer, c)),
            );
        }
        history_chart(frame, chart_area, "pilot sticks vs computer", &series);
    }
    let channels = ["aileron", "elevator", "throttle", "rudder"];
    let rows = Layout::vertical(vec![Constraint::Length(2); channels.len() + 1]).split(bars_area);
    let mode = pilot
        .and_then(|p| p.latest_by_name("auto"))
        .map_or("?", |a| {
            if a >= 0.5 {
                "AUTO (computer flies)"
            } else {
                "MANUAL (pilot flies)"
            }
        });
    if let Some(&header) = rows.first() {
        frame.render_widget(
            Paragraph::new(format!(
                "switch: {mode}    bars: pilot (blue) vs computer (magenta), surfaces -1..1, throttle 0..1"
            )),
            header,
        );
    }
    for (i, channel) in channels.iter().enumerate() {
        let Some(&row) = rows.get(i + 1) else {
            continue;
        };
        let (low, high) = if *channel == "throttle" {
            (0.0, 1.0)
        } else {
            (-1.0, 1.0)
        };
        let [label_area, pilot_area, computer_area] = Layout::horizontal([
            Constraint::Length(10),
            Constraint::Percentage(50),
            Constraint::Percentage(50),
        ])
        .areas(row);
        frame.render_widget(Paragraph::new(*channel), label_area);
        for (source, bar_area, color, name) in [
            (
                pilot.and_then(|p| p.latest_by_name(channel)),
                pilot_area,
                Color::Blue,
                "pilot",
            ),
            (
                computer.and_then(|c| c.latest_by_name(&format!("{channel}_cmd"))),
                computer_area,
                Color::Magenta,
                "computer",
            ),
        ] {
            let (r, label) = match source {
                Some(v) if v.is_finite() => (ratio(v, low, high), format!("{name} {v:+.2}")),
                _ => (0.0, format!("{name} —")),
            };
            frame.render_widget(
                Gauge::default()
                    .ratio(r)
                    .label(label)
                    .gauge_style(Style::new().fg(color)),
                Rect {
                    height: bar_area.height.min(1),
                    ..bar_area
                },
            );
        }
    }
    let [avionics, servos] =
        Layout::horizontal([Constraint::Percentage(50), Constraint::Percentage(50)])
            .areas(battery_area);
    for (column, title, bar_area) in [
        ("batt_avionics_v", "avionics battery", avionics),
        ("batt_servo_v", "servo battery", servos),
    ] {
        let volts = pilot.and_then(|p| p.latest_by_name(column));
        let (r, label) = match volts {
            Some(v) if v.is_finite() && v > 0.0 => {
                let cells = (v / 3.8).round().max(1.0);
                (
                    ratio(v, CELL_EMPTY_V * cells, CELL_FULL_V * cells),
                    format!("{v:.2} V ({cells:.0}S)"),
                )
            }
            _ => (0.0, "—".to_string()),
        };
        let color = if r < 0.2 { Color::Red } else { Color::Green };
        frame.render_widget(
            Gauge::default()
                .block(Block::bordered().title(format!(" {title} ")))
                .ratio(r)
                .label(label)
                .gauge_style(Style::new().fg(color).add_modifier(Modifier::BOLD)),
            bar_area,
        );
    }
}
