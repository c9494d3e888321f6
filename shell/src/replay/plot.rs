//! `--plot DIR`: our attitude beside the onboard one, and their differences, over the
//! flight (PNG, the tools' embedded font).

use std::path::Path;

use plotters::prelude::*;
use skyframe_figure_output::{FONT, register_font, write_png};

use super::agreement::{Series, wrap};

const SIZE: (u32, u32) = (1400, 1000);

fn fail(path: &Path, e: impl std::fmt::Display) -> String {
    format!("{}: {e}", path.display())
}

/// Writes `attitude.png`, `attitude_difference.png` and the numbers behind them
/// (`attitude.csv`) into `dir` (created if missing); returns the paths written.
pub fn write(dir: &Path, title: &str, series: &Series) -> Result<Vec<String>, String> {
    register_font()?;
    std::fs::create_dir_all(dir).map_err(|e| fail(dir, e))?;
    let mut written = Vec::new();
    let csv = dir.join("attitude.csv");
    let mut text = String::from(
        "t_s,phase,roll_deg,pitch_deg,yaw_deg,onboard_roll_deg,onboard_pitch_deg,onboard_yaw_deg\n",
    );
    for ((t, phase), (m, o)) in series
        .t_s
        .iter()
        .zip(&series.phase)
        .zip(series.ours_deg.iter().zip(&series.onboard_deg))
    {
        text.push_str(&format!(
            "{t:.4},{phase},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3}\n",
            m[0], m[1], m[2], o[0], o[1], o[2]
        ));
    }
    std::fs::write(&csv, text).map_err(|e| fail(&csv, e))?;
    written.push(csv.display().to_string());
    let csv = dir.join("estimates.csv");
    let mut text = String::from(
        "t_s,phase,healthy,roll_deg,pitch_deg,yaw_deg,vn_m_s,ve_m_s,vd_m_s,pn_m,pe_m,pd_m,\
         bgx_rad_s,bgy_rad_s,bgz_rad_s,bax_m_s2,bay_m_s2,baz_m_s2\n",
    );
    for (t, e) in &series.estimates {
        let row: Vec<String> = [e.roll_rad, e.pitch_rad, e.yaw_rad]
            .iter()
            .map(|a| format!("{:.3}", a.to_degrees()))
            .chain(
                e.velocity_ned_mps
                    .iter()
                    .chain(&e.position_ned_m)
                    .map(|v| format!("{v:.3}")),
            )
            .chain(
                e.gyro_bias_radps
                    .iter()
                    .chain(&e.accel_bias_mps2)
                    .map(|v| format!("{v:.5}")),
            )
            .collect();
        text.push_str(&format!(
            "{t:.3},{:?},{},{}\n",
            e.health.phase,
            u8::from(e.health.healthy),
            row.join(",")
        ));
    }
    std::fs::write(&csv, text).map_err(|e| fail(&csv, e))?;
    written.push(csv.display().to_string());
    for (file, difference) in [("attitude.png", false), ("attitude_difference.png", true)] {
        let path = dir.join(file);
        let mut rgb = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area();
            draw(&root, title, series, difference).map_err(|e| fail(&path, e))?;
            root.present().map_err(|e| fail(&path, e))?;
        }
        write_png(&path, SIZE, &rgb).map_err(|e| fail(&path, e))?;
        written.push(path.display().to_string());
    }
    Ok(written)
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    s: &Series,
    difference: bool,
) -> Result<(), String> {
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let heading = if difference {
        format!("{title}: ours − onboard (agreement, not error)")
    } else {
        format!("{title}: ours (blue) and onboard (red)")
    };
    let root = root
        .titled(&heading, (FONT, 22))
        .map_err(|e| e.to_string())?;
    let panels = root.split_evenly((3, 1));
    let t_max = s.t_s.last().copied().unwrap_or(1.0).max(1.0);
    let t_min = s.t_s.first().copied().unwrap_or(0.0).min(t_max - 1.0);
    for (k, (panel, name)) in panels.iter().zip(["roll", "pitch", "yaw"]).enumerate() {
        let ours: Vec<(f64, f64)> = s
            .t_s
            .iter()
            .zip(&s.ours_deg)
            .zip(&s.onboard_deg)
            .map(|((&t, m), o)| {
                let v = if difference {
                    wrap((m[k] - o[k]).to_radians()).to_degrees()
                } else {
                    m[k]
                };
                (t, v)
            })
            .collect();
        let onboard: Vec<(f64, f64)> = s
            .t_s
            .iter()
            .zip(&s.onboard_deg)
            .map(|(&t, o)| (t, o[k]))
            .collect();
        let range = if difference {
            let m = ours
                .iter()
                .map(|p| p.1.abs())
                .filter(|v| v.is_finite())
                .fold(1.0f64, f64::max)
                .min(180.0);
            -m..m
        } else if k == 1 {
            -90.0..90.0
        } else {
            -180.0..180.0
        };
        let mut chart = ChartBuilder::on(panel)
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(60)
            .build_cartesian_2d(t_min..t_max, range)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("s")
            .y_desc(format!("{name} deg"))
            .label_style((FONT, 14))
            .draw()
            .map_err(|e| e.to_string())?;
        if !difference {
            chart
                .draw_series(LineSeries::new(onboard, RED.stroke_width(1)))
                .map_err(|e| e.to_string())?;
        }
        chart
            .draw_series(LineSeries::new(ours, BLUE.stroke_width(1)))
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}
