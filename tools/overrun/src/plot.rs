//! The report's figures, PNG and SVG each: `latency_histogram` (frame start latency),
//! `exec_vs_budget` (execution-time box per task with its budget), `worst_frames` (timeline
//! of the worst frames' tasks).
//!
//! Drawn as skyframe-log draws: plotters' bitmap and SVG backends, with the embedded font and
//! the PNG encoding of skyframe-figure-output.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use skyframe_core::executive::FrameRecord;
use skyframe_figure_output::{FONT, register_font, write_png};

use crate::report::{self, Report};

const SIZE: (u32, u32) = (1000, 600);

/// The name of the category drawn at integer position `at` of a category axis; nothing
/// between categories (the mesh asks for labels there too).
fn category_label(names: &[String], at: f64) -> String {
    let i = at.round();
    if (at - i).abs() < 1e-6 && i >= 0.0 {
        names.get(i as usize).cloned().unwrap_or_default()
    } else {
        String::new()
    }
}

fn colour(i: usize) -> RGBColor {
    skyframe_figure_output::series_colour(i)
}

#[derive(Clone, Copy)]
enum Kind {
    Histogram,
    ExecVsBudget,
    WorstFrames,
}

struct Data<'a> {
    report: &'a Report,
    frames: &'a [FrameRecord],
    tasks: &'a [String],
}

/// Draws every figure into `dir` (created if missing).
pub fn draw_all(
    dir: &Path,
    report: &Report,
    frames: &[FrameRecord],
    tasks: &[String],
) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: cannot create: {e}", dir.display()))?;
    register_font()?;
    let data = Data {
        report,
        frames,
        tasks,
    };
    for (name, kind) in [
        ("latency_histogram", Kind::Histogram),
        ("exec_vs_budget", Kind::ExecVsBudget),
        ("worst_frames", Kind::WorstFrames),
    ] {
        let svg = dir.join(format!("{name}.svg"));
        let fail = |path: &Path, e: String| format!("{}: {e}", path.display());
        {
            let root = SVGBackend::new(&svg, SIZE).into_drawing_area();
            draw(kind, &data, &root).map_err(|e| fail(&svg, e))?;
            root.present().map_err(|e| fail(&svg, e.to_string()))?;
        }
        let png = dir.join(format!("{name}.png"));
        let (w, h) = SIZE;
        let mut rgb = vec![0u8; (w as usize) * (h as usize) * 3];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area();
            draw(kind, &data, &root).map_err(|e| fail(&png, e))?;
            root.present().map_err(|e| fail(&png, e.to_string()))?;
        }
        write_png(&png, SIZE, &rgb).map_err(|e| fail(&png, e))?;
    }
    Ok(())
}

fn draw<DB: DrawingBackend>(
    kind: Kind,
    data: &Data<'_>,
    root: &DrawingArea<DB, Shift>,
) -> Result<(), String> {
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    match kind {
        Kind::Histogram => histogram(data, root),
        Kind::ExecVsBudget => exec_vs_budget(data, root),
        Kind::WorstFrames => match report::matching_table(data.tasks) {
            Some(table) => {
                worst_major_frames(data, table.minor_frames(), table.minor_frame_ns, root)
            }
            None => worst_frames(data, root),
        },
    }
}

fn err(e: impl std::fmt::Display) -> String {
    e.to_string()
}

/// Frame start latency histogram, counts on a log axis (the tail stays visible).
fn histogram<DB: DrawingBackend>(
    data: &Data<'_>,
    root: &DrawingArea<DB, Shift>,
) -> Result<(), String> {
    const BINS: usize = 60;
    let values: Vec<f64> = data
        .frames
        .iter()
        .map(|f| f64::from(f.start_latency_ns) / 1000.0)
        .collect();
    let max = values.iter().copied().fold(0.0, f64::max).max(1.0);
    let width = max / BINS as f64;
    let mut counts = [0u64; BINS];
    for v in &values {
        let bin = ((v / width) as usize).min(BINS - 1);
        if let Some(c) = counts.get_mut(bin) {
            *c += 1;
        }
    }
    let top = counts.iter().copied().max().unwrap_or(1).max(1) as f64;
    let mut chart = ChartBuilder::on(root)
        .caption(
            format!("Frame start latency ({} frames)", values.len()),
            (FONT, 22),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..max * 1.02, (0.5..top * 2.0).log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("start latency (us)")
        .y_desc("frames")
        .label_style((FONT, 14))
        .draw()
        .map_err(err)?;
    chart
        .draw_series(
            counts
                .iter()
                .enumerate()
                .filter(|(_, c)| **c > 0)
                .map(|(i, &c)| {
                    let x0 = i as f64 * width;
                    Rectangle::new([(x0, 0.5), (x0 + width, c as f64)], colour(0).filled())
                }),
        )
        .map_err(err)?;
    Ok(())
}

/// Execution-time boxes per task (quartiles, whiskers min..max, p99 dot) with the budget.
fn exec_vs_budget<DB: DrawingBackend>(
    data: &Data<'_>,
    root: &DrawingArea<DB, Shift>,
) -> Result<(), String> {
    const FLOOR_US: f64 = 0.1;
    let tasks = &data.report.tasks;
    let us = |ns: u64| (ns as f64 / 1000.0).max(FLOOR_US);
    let top = tasks
        .iter()
        .flat_map(|t| {
            [
                t.exec_ns.as_ref().map_or(FLOOR_US, |e| us(e.max)),
                t.budget_ns.map_or(FLOOR_US, us),
            ]
        })
        .fold(1.0, f64::max);
    let n = tasks.len().max(1);
    let names: Vec<String> = tasks.iter().map(|t| t.name.clone()).collect();
    let mut chart = ChartBuilder::on(root)
        .caption(
            "Execution time per task (box p25-p75, line p50, whiskers min-max, dot p99; red: budget)",
            (FONT, 18),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(-0.5..n as f64 - 0.5, (FLOOR_US..top * 2.0).log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(n + 1)
        .x_label_formatter(&|x: &f64| category_label(&names, *x))
        .y_desc("execution time (us, log)")
        .label_style((FONT, 14))
        .draw()
        .map_err(err)?;
    for (i, t) in tasks.iter().enumerate() {
        let x = i as f64;
        let c = colour(i);
        if let Some(e) = &t.exec_ns {
            chart
                .draw_series([
                    PathElement::new(vec![(x, us(e.min)), (x, us(e.max))], c.stroke_width(1)),
                    PathElement::new(
                        vec![(x - 0.15, us(e.max)), (x + 0.15, us(e.max))],
                        c.stroke_width(1),
                    ),
                    PathElement::new(
                        vec![(x - 0.15, us(e.min)), (x + 0.15, us(e.min))],
                        c.stroke_width(1),
                    ),
                ])
                .map_err(err)?;
            chart
                .draw_series([Rectangle::new(
                    [(x - 0.25, us(e.p25)), (x + 0.25, us(e.p75))],
                    c.mix(0.5).filled(),
                )])
                .map_err(err)?;
            chart
                .draw_series([
                    PathElement::new(
                        vec![(x - 0.25, us(e.p50)), (x + 0.25, us(e.p50))],
                        BLACK.stroke_width(2),
                    ),
                    PathElement::new(vec![(x, us(e.p99)), (x, us(e.p99))], BLACK),
                ])
                .map_err(err)?;
            chart
                .draw_series([Circle::new((x, us(e.p99)), 3, BLACK.filled())])
                .map_err(err)?;
        }
        if let Some(b) = t.budget_ns {
            chart
                .draw_series([PathElement::new(
                    vec![(x - 0.4, us(b)), (x + 0.4, us(b))],
                    RED.stroke_width(3),
                )])
                .map_err(err)?;
        }
    }
    Ok(())
}

/// The worst frames as timelines from their release: start latency, then each task's step in
/// table order, then the executive's overhead. Drawn when the frame table is not known.
fn worst_frames<DB: DrawingBackend>(
    data: &Data<'_>,
    root: &DrawingArea<DB, Shift>,
) -> Result<(), String> {
    let worst = report::worst(data.frames, data.report.worst_frames.len().max(1));
    let rows = worst
        .iter()
        .map(|f| (format!("frame {}", f.frame), vec![(*f, 0)]))
        .collect();
    timeline(
        data,
        Timeline {
            caption: "Worst frames: latency (grey), tasks in table order, overhead (dark)",
            x_desc: "time since the frame's release (us)",
            unit_ns: 1e3,
            rows,
            releases_ns: Vec::new(),
        },
        root,
    )
}

/// The worst major frames as timelines from the major frame's first release: each minor
/// frame's start latency (grey), its tasks' steps in table order, its overhead (dark); thin
/// lines mark the minor frames' releases. Drawn when the frame table is known.
fn worst_major_frames<DB: DrawingBackend>(
    data: &Data<'_>,
    minor_frames: usize,
    minor_ns: u64,
    root: &DrawingArea<DB, Shift>,
) -> Result<(), String> {
    let worst = report::worst_major(
        data.frames,
        minor_frames,
        data.report.worst_frames.len().max(1),
    );
    let per = (minor_frames as u64).max(1);
    let rows = worst
        .iter()
        .map(|(m, frames)| {
            let placed = frames
                .iter()
                .map(|f| (*f, (f.frame % per) * minor_ns))
                .collect();
            (format!("major {m}"), placed)
        })
        .collect();
    timeline(
        data,
        Timeline {
            caption: "Worst major frames: latency (grey), tasks in table order, overhead (dark)",
            x_desc: "time since the major frame's first release (ms)",
            unit_ns: 1e6,
            rows,
            releases_ns: (0..=per).map(|k| k * minor_ns).collect(),
        },
        root,
    )
}

/// Frames laid out as horizontal bars, one row per label.
struct Timeline<'f> {
    caption: &'static str,
    x_desc: &'static str,
    /// Nanoseconds per unit of the x axis.
    unit_ns: f64,
    /// Each row's label and frames, each frame with where its release sits (ns).
    rows: Vec<(String, Vec<(&'f FrameRecord, u64)>)>,
    /// Where to draw release lines (ns); none: a plain x mesh.
    releases_ns: Vec<u64>,
}

fn timeline<DB: DrawingBackend>(
    data: &Data<'_>,
    t: Timeline<'_>,
    root: &DrawingArea<DB, Shift>,
) -> Result<(), String> {
    let x = |ns: u64| ns as f64 / t.unit_ns;
    let rows = t.rows.len().max(1);
    let right = t
        .rows
        .iter()
        .flat_map(|(_, frames)| frames.iter().map(|(f, at)| x(at + report::end_ns(f))))
        .chain(t.releases_ns.iter().map(|&r| x(r)))
        .fold(1e-3, f64::max);
    let labels: Vec<String> = t.rows.iter().map(|(label, _)| label.clone()).collect();
    let mut chart = ChartBuilder::on(root)
        .caption(t.caption, (FONT, 18))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(110)
        .build_cartesian_2d(0.0..right * 1.03, -0.5..rows as f64 - 0.5)
        .map_err(err)?;
    let mut mesh = chart.configure_mesh();
    if t.releases_ns.is_empty() {
        mesh.disable_y_mesh();
    } else {
        mesh.disable_mesh();
    }
    mesh.y_labels(rows + 1)
        .y_label_formatter(&|y: &f64| category_label(&labels, *y))
        .x_desc(t.x_desc)
        .label_style((FONT, 14))
        .draw()
        .map_err(err)?;
    chart
        .draw_series(t.releases_ns.iter().map(|&r| {
            PathElement::new(
                vec![(x(r), -0.5), (x(r), rows as f64 - 0.5)],
                RGBColor(220, 220, 220),
            )
        }))
        .map_err(err)?;
    let bar = |row: usize, from: f64, to: f64| {
        let y = row as f64;
        [(from, y - 0.35), (to, y + 0.35)]
    };
    // (row, frame, its release, where its next step starts)
    let mut steps: Vec<(usize, &FrameRecord, u64, f64)> = t
        .rows
        .iter()
        .enumerate()
        .flat_map(|(row, (_, frames))| {
            frames
                .iter()
                .map(move |(f, at)| (row, *f, *at, x(at + u64::from(f.start_latency_ns))))
        })
        .collect();
    chart
        .draw_series(steps.iter().map(|(row, _, at, start)| {
            Rectangle::new(bar(*row, x(*at), *start), RGBColor(200, 200, 200).filled())
        }))
        .map_err(err)?;
    for (i, name) in data.tasks.iter().enumerate() {
        let mut bars = Vec::new();
        for (row, f, _, start) in &mut steps {
            if i < 32 && f.ran & (1 << i) != 0 {
                let exec = x(u64::from(f.exec_ns.get(i).copied().unwrap_or(0)));
                bars.push(Rectangle::new(
                    bar(*row, *start, *start + exec),
                    colour(i).filled(),
                ));
                *start += exec;
            }
        }
        let c = colour(i);
        chart
            .draw_series(bars)
            .map_err(err)?
            .label(name.clone())
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 10, y + 5)], c.filled()));
    }
    chart
        .draw_series(steps.iter().map(|(row, f, at, start)| {
            Rectangle::new(
                bar(*row, *start, x(at + report::end_ns(f))),
                RGBColor(60, 60, 60).filled(),
            )
        }))
        .map_err(err)?;
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font((FONT, 13))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(err)?;
    Ok(())
}
