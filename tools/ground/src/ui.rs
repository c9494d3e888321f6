//! The terminal UI: the seed's property sheet (thesis ch. 5) in a terminal. One tab per
//! task, an Executive tab with the four lights per task, a vehicle list with link quality.
//!
//! [`App`] holds the model and what the user is doing; [`App::draw`] renders it and
//! [`App::handle_key`] turns keys into commands, so tests drive both through ratatui's
//! `TestBackend` without a terminal or a socket. [`run_terminal`] wires them to the real
//! terminal and link; a receive thread keeps draining the socket while the UI draws (as
//! the seed's secondary network thread did), so slow drawing never overflows the socket's
//! buffer.

use crate::json::mode_name;
use crate::model::{
    FormatState, GroundModel, HISTORY_SPAN_S, VehicleState, column_unit, value_as_f64,
};
use crate::net::{CommandTarget, RESEND_AFTER, Received, Session, apply};
use crate::values::{ack_result_name, interval_ms_for_hz, value_text};
use ratatui::Frame;
use ratatui::crossterm::event::{self, Event, KeyCode, KeyEvent, KeyEventKind, KeyModifiers};
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Modifier, Style, Stylize};
use ratatui::symbols::Marker;
use ratatui::text::{Line, Span};
use ratatui::widgets::canvas::{Canvas, Line as CanvasLine, Points};
use ratatui::widgets::{
    Axis, Block, Cell, Chart, Dataset, Gauge, GraphType, Paragraph, Row, Table, Tabs,
};
use skyframe_core::link::messages::{AckResult, Command, limits};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// The task tabs always shown, in this order (tab title, task name on the link).
pub const TASK_TABS: [(&str, &str); 5] = [
    ("IMU", "imu"),
    ("GPS", "gps"),
    ("Estimator", "estimator"),
    ("Servo", "servo"),
    ("Control", "control"),
];
/// Not heard for this long: the vehicle list says the link is lost (it resumes by itself).
pub const LINK_LOST_AFTER: Duration = Duration::from_secs(3);
/// The vehicle list's recent loss is over this many seconds.
pub const RECENT_LOSS_S: usize = 10;
/// A command from the UI with no acknowledgement after this long is reported unanswered
/// (sent every [`RESEND_AFTER`] until then).
pub const ACK_WAIT: Duration = Duration::from_secs(5);
/// Battery gauges run from empty to full at these per-cell voltages (LiPo), cells guessed
/// from the voltage itself: a gauge, not a fuel computer.
const CELL_EMPTY_V: f64 = 3.3;
const CELL_FULL_V: f64 = 4.2;

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Tab {
    Executive,
    /// Title and the task's name on the link.
    Task {
        title: String,
        task: String,
    },
}

impl Tab {
    pub fn title(&self) -> &str {
        match self {
            Tab::Executive => "Executive",
            Tab::Task { title, .. } => title,
        }
    }
}

/// What the keyboard is doing.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Input {
    Normal,
    /// "Stop vehicle N? y/n".
    ConfirmStop {
        vehicle_id: u16,
    },
    /// Typing a telemetry rate in Hz for a task.
    EditRate {
        task_index: u8,
        text: String,
    },
    /// Typing the health period in ms.
    EditHealthPeriod {
        text: String,
    },
}

/// A command the UI wants sent.
#[derive(Clone, Debug, PartialEq)]
pub struct Request {
    pub vehicle_id: u16,
    pub command: Command,
    pub description: String,
}

/// A command sent and not yet answered: every sequence number it went out with (it is
/// resent with a new one each [`RESEND_AFTER`], as the protocol asks of the ground).
#[derive(Clone, Debug)]
struct Pending {
    request: Request,
    sender_id: u8,
    sequences: Vec<u32>,
    first_sent: Instant,
    last_sent: Instant,
}

pub struct App {
    pub model: GroundModel,
    /// The vehicle shown; the first heard until one is chosen.
    pub selected_vehicle: Option<u16>,
    pub tab: usize,
    /// The task row selected on the Executive tab (by frame-table index).
    pub selected_task: u8,
    pub input: Input,
    /// The line under the tabs: results, errors.
    pub status: String,
    pub can_command: bool,
    pub quit: bool,
    pending: Option<Pending>,
}

impl App {
    pub fn new(model: GroundModel, vehicle: Option<u16>, can_command: bool) -> Self {
        Self {
            model,
            selected_vehicle: vehicle,
            tab: 0,
            selected_task: 0,
            input: Input::Normal,
            status: if can_command {
                String::new()
            } else {
                "no link key: monitoring only (pass --key FILE to command)".to_string()
            },
            can_command,
            quit: false,
            pending: None,
        }
    }

    pub fn tabs(&self) -> Vec<Tab> {
        let mut tabs = vec![Tab::Executive];
        tabs.extend(TASK_TABS.iter().map(|(title, task)| Tab::Task {
            title: (*title).to_string(),
            task: (*task).to_string(),
        }));
        // Any other task that sends data gets a tab of its own, named as it names itself.
        if let Some(vehicle) = self.vehicle() {
            let extra = vehicle
                .tasks
                .values()
                .filter(|t| !t.formats.is_empty())
                .filter_map(|t| t.name())
                .filter(|name| !TASK_TABS.iter().any(|(_, n)| n == name));
            for name in extra {
                tabs.push(Tab::Task {
                    title: name.to_string(),
                    task: name.to_string(),
                });
            }
        }
        tabs
    }

    pub fn vehicle_id(&self) -> Option<u16> {
        self.selected_vehicle
            .filter(|id| self.model.vehicles.contains_key(id))
            .or_else(|| self.model.vehicles.keys().next().copied())
    }

    pub fn vehicle(&self) -> Option<&VehicleState> {
        self.vehicle_id().and_then(|id| self.model.vehicle(id))
    }

    pub fn apply(&mut self, received: &Received, now: Instant) {
        apply(&mut self.model, received, now);
    }

    /// Notes a command sent, to report its acknowledgement when it comes. A request equal
    /// to the one pending is its resend.
    pub fn sent(&mut self, request: &Request, sender_id: u8, sequence: u32, now: Instant) {
        match &mut self.pending {
            Some(pending) if pending.request == *request => {
                pending.sequences.push(sequence);
                pending.last_sent = now;
                self.status = format!(
                    "{}: sent again (try {}), waiting for the vehicle…",
                    request.description,
                    pending.sequences.len()
                );
            }
            _ => {
                self.status = format!("{}: sent, waiting for the vehicle…", request.description);
                self.pending = Some(Pending {
                    request: request.clone(),
                    sender_id,
                    sequences: vec![sequence],
                    first_sent: now,
                    last_sent: now,
                });
            }
        }
    }

    /// Reports the pending command's acknowledgement, or that none came; returns the
    /// command to send again when it is due for a resend.
    pub fn tick(&mut self, now: Instant) -> Option<Request> {
        let pending = self.pending.as_ref()?;
        let ack = self
            .model
            .vehicle(pending.request.vehicle_id)
            .and_then(|v| {
                pending
                    .sequences
                    .iter()
                    .find_map(|&s| v.ack_for(pending.sender_id, s))
            });
        if let Some(ack) = ack {
            let value = ack
                .value_in_force
                .map(|v| format!(", value in force {}", value_text(&v)))
                .unwrap_or_default();
            self.status = format!(
                "{}: {}{value}",
                pending.request.description,
                ack_result_name(ack.result)
            );
            if ack.result != AckResult::Accepted {
                self.status.push_str(" (nothing changed)");
            }
            self.pending = None;
            None
        } else if now.saturating_duration_since(pending.first_sent) >= ACK_WAIT {
            self.status = format!(
                "{}: no answer from vehicle {} after {} tries (lost, or the key is wrong)",
                pending.request.description,
                pending.request.vehicle_id,
                pending.sequences.len()
            );
            self.pending = None;
            None
        } else if now.saturating_duration_since(pending.last_sent) >= RESEND_AFTER {
            Some(pending.request.clone())
        } else {
            None
        }
    }

    fn task_indices(&self) -> Vec<u8> {
        self.vehicle()
            .map(|v| v.tasks.keys().copied().collect())
            .unwrap_or_default()
    }

    /// Handles one key; returns a command to send, if the key made one.
    pub fn handle_key(&mut self, key: KeyEvent) -> Option<Request> {
        if key.kind != KeyEventKind::Press {
            return None;
        }
        if key.code == KeyCode::Char('c') && key.modifiers.contains(KeyModifiers::CONTROL) {
            self.quit = true;
            return None;
        }
        match std::mem::replace(&mut self.input, Input::Normal) {
            Input::Normal => self.normal_key(key),
            Input::ConfirmStop { vehicle_id } => {
                if matches!(key.code, KeyCode::Char('y' | 'Y')) {
                    return Some(Request {
                        vehicle_id,
                        command: Command::Stop,
                        description: format!("stop vehicle {vehicle_id}"),
                    });
                }
                self.status = "stop cancelled".to_string();
                None
            }
            Input::EditRate {
                task_index,
                mut text,
            } => match edit_text(&mut text, key) {
                Editing::Continue => {
                    self.input = Input::EditRate { task_index, text };
                    None
                }
                Editing::Cancel => None,
                Editing::Done => {
                    let vehicle_id = self.vehicle_id()?;
                    let Some(interval_ms) =
                        text.trim().parse::<f64>().ok().and_then(interval_ms_for_hz)
                    else {
                        self.status = format!("{text:?}: a rate is 0 (off) or up to 20 Hz");
                        return None;
                    };
                    Some(Request {
                        vehicle_id,
                        command: Command::SetTelemetryRate {
                            task_index,
                            interval_ms,
                        },
                        description: format!(
                            "{} telemetry {} Hz",
                            self.task_label(task_index),
                            text.trim()
                        ),
                    })
                }
            },
            Input::EditHealthPeriod { mut text } => match edit_text(&mut text, key) {
                Editing::Continue => {
                    self.input = Input::EditHealthPeriod { text };
                    None
                }
                Editing::Cancel => None,
                Editing::Done => {
                    let vehicle_id = self.vehicle_id()?;
                    let range = limits::MIN_HEALTH_PERIOD_MS..=limits::MAX_HEALTH_PERIOD_MS;
                    let Some(period_ms) = text
                        .trim()
                        .parse::<u32>()
                        .ok()
                        .filter(|p| range.contains(p))
                    else {
                        self.status = format!(
                            "{text:?}: the health period is {}..={} ms",
                            range.start(),
                            range.end()
                        );
                        return None;
                    };
                    Some(Request {
                        vehicle_id,
                        command: Command::SetHealthPeriod { period_ms },
                        description: format!("health period {period_ms} ms"),
                    })
                }
            },
        }
    }

    fn task_label(&self, task_index: u8) -> String {
        self.vehicle()
            .and_then(|v| v.tasks.get(&task_index))
            .and_then(|t| t.name())
            .map_or_else(|| format!("task {task_index}"), str::to_string)
    }

    fn normal_key(&mut self, key: KeyEvent) -> Option<Request> {
        let tab_count = self.tabs().len();
        match key.code {
            KeyCode::Char('q') | KeyCode::Esc => self.quit = true,
            KeyCode::Tab => self.tab = (self.tab + 1) % tab_count,
            KeyCode::BackTab => self.tab = (self.tab + tab_count - 1) % tab_count,
            KeyCode::Char(c @ '1'..='9') => {
                let index = usize::from(c as u8 - b'1');
                if index < tab_count {
                    self.tab = index;
                }
            }
            KeyCode::Char('v') => {
                // Next vehicle in the list.
                let ids = self.model.vehicle_ids();
                let current = self.vehicle_id();
                let next = ids
                    .iter()
                    .position(|&id| Some(id) == current)
                    .map_or(0, |i| (i + 1) % ids.len().max(1));
                self.selected_vehicle = ids.get(next).copied();
            }
            KeyCode::Down | KeyCode::Char('j') => self.move_task(1),
            KeyCode::Up | KeyCode::Char('k') => self.move_task(-1),
            KeyCode::Char('s' | 'r' | 'h' | 'p') if !self.can_command => {
                self.status = "no link key: commands need --key FILE".to_string();
            }
            KeyCode::Char('s') => match self.vehicle_id() {
                Some(vehicle_id) => self.input = Input::ConfirmStop { vehicle_id },
                None => self.status = "no vehicle heard".to_string(),
            },
            KeyCode::Char('r') => {
                let task_index = match self.tabs().get(self.tab) {
                    Some(Tab::Task { task, .. }) => self
                        .vehicle()
                        .and_then(|v| v.task_by_name(task))
                        .map(|(i, _)| i),
                    _ => Some(self.selected_task),
                };
                match task_index.filter(|i| self.task_indices().contains(i)) {
                    Some(task_index) => {
                        self.input = Input::EditRate {
                            task_index,
                            text: String::new(),
                        }
                    }
                    None => self.status = "no such task heard yet".to_string(),
                }
            }
            KeyCode::Char('p') => {
                let vehicle_id = self.vehicle_id()?;
                return Some(Request {
                    vehicle_id,
                    command: Command::ListParams,
                    description: format!("list parameters of vehicle {vehicle_id}"),
                });
            }
            KeyCode::Char('h') => {
                self.input = Input::EditHealthPeriod {
                    text: String::new(),
                }
            }
            _ => {}
        }
        None
    }

    fn move_task(&mut self, step: i32) {
        let tasks = self.task_indices();
        let position = tasks
            .iter()
            .position(|&t| t == self.selected_task)
            .unwrap_or(0);
        let len = tasks.len() as i32;
        if len == 0 {
            return;
        }
        let next = (position as i32 + step).rem_euclid(len);
        if let Some(&t) = tasks.get(next as usize) {
            self.selected_task = t;
        }
    }

    pub fn draw(&self, frame: &mut Frame, now: Instant) {
        let vehicle_rows = self.model.vehicles.len().clamp(1, 5) as u16;
        let [vehicles_area, tabs_area, body, status_area, help_area] = Layout::vertical([
            Constraint::Length(vehicle_rows + 2),
            Constraint::Length(1),
            Constraint::Min(10),
            Constraint::Length(1),
            Constraint::Length(1),
        ])
        .areas(frame.area());
        self.draw_vehicles(frame, vehicles_area, now);
        let tabs = self.tabs();
        let titles: Vec<Line> = tabs
            .iter()
            .enumerate()
            .map(|(i, t)| Line::from(format!("{} {}", i + 1, t.title())))
            .collect();
        frame.render_widget(
            Tabs::new(titles)
                .select(self.tab)
                .highlight_style(Style::new().reversed()),
            tabs_area,
        );
        match (self.vehicle(), tabs.get(self.tab)) {
            (None, _) => frame.render_widget(
                Paragraph::new("Listening… no vehicle heard yet.").block(Block::bordered()),
                body,
            ),
            (Some(v), Some(Tab::Executive) | None) => self.draw_executive(frame, body, v, now),
            (Some(v), Some(Tab::Task { task, title })) => match task.as_str() {
                "gps" => draw_gps(frame, body, v),
                "estimator" => draw_estimator(frame, body, v),
                "servo" => draw_servo(frame, body, v),
                "imu" => draw_imu(frame, body, v),
                "control" => draw_control(frame, body, v),
                _ => draw_generic(frame, body, v, task, title, &[]),
            },
        }
        let prompt = match &self.input {
            Input::Normal => Line::from(self.status.clone()),
            Input::ConfirmStop { vehicle_id } => Line::from(vec![
                Span::styled(
                    format!(" STOP vehicle {vehicle_id}? "),
                    Style::new().fg(Color::White).bg(Color::Red).bold(),
                ),
                Span::raw(" y to stop, any other key cancels"),
            ]),
            Input::EditRate { task_index, text } => Line::from(format!(
                "{} telemetry rate in Hz (0 off, ≤ 20): {text}▏ enter sends, esc cancels",
                self.task_label(*task_index)
            )),
            Input::EditHealthPeriod { text } => Line::from(format!(
                "health period in ms (100..=60000): {text}▏ enter sends, esc cancels"
            )),
        };
        frame.render_widget(Paragraph::new(prompt), status_area);
        frame.render_widget(
            Paragraph::new(
                "tab/1-9 tabs  v vehicle  ↑↓ task  r rate  h health period  p parameters  s stop  q quit",
            )
            .style(Style::new().dim()),
            help_area,
        );
    }

    fn draw_vehicles(&self, frame: &mut Frame, area: Rect, now: Instant) {
        let selected = self.vehicle_id();
        let lines: Vec<Line> = if self.model.vehicles.is_empty() {
            vec![Line::from("none heard yet")]
        } else {
            self.model
                .vehicles
                .values()
                .map(|v| {
                    let ago = v.seen_ago(now);
                    let lost = ago >= LINK_LOST_AFTER;
                    let seen = Span::styled(
                        format!(
                            "last seen {:.1}s ago{}",
                            ago.as_secs_f64(),
                            if lost { " LINK LOST" } else { "" }
                        ),
                        Style::new().fg(if lost { Color::Red } else { Color::Green }),
                    );
                    let mode = v.executive.map_or("?", |e| mode_name(e.mode));
                    let marker = if Some(v.id) == selected { "▶" } else { " " };
                    let refused =
                        v.link.bad_crc + v.link.bad_signature + v.link.malformed + v.link.unsigned;
                    let refused = if refused > 0 {
                        format!("refused {refused}  ")
                    } else {
                        String::new()
                    };
                    Line::from(vec![
                        Span::raw(format!(
                            "{marker} vehicle {:<5} {:<21} run {:08x} {:<9} loss {}/10s {:.1}%/run  {refused}",
                            v.id,
                            v.address.to_string(),
                            v.run_id,
                            mode,
                            v.arrivals
                                .recent_loss_percent(now, RECENT_LOSS_S)
                                .map_or("   –  ".to_string(), |l| format!("{l:5.1}%")),
                            v.link.loss_percent(),
                        )),
                        seen,
                    ])
                })
                .collect()
        };
        frame.render_widget(
            Paragraph::new(lines).block(Block::bordered().title(" skyframe ground · vehicles ")),
            area,
        );
    }

    fn draw_executive(&self, frame: &mut Frame, area: Rect, vehicle: &VehicleState, now: Instant) {
        let task_rows = vehicle.tasks.len().max(1) as u16;
        let [table_area, info_area, lower_area] = Layout::vertical([
            Constraint::Length(task_rows + 3),
            Constraint::Length(8),
            Constraint::Min(3),
        ])
        .areas(area);
        let [params_acks_area, link_area] =
            Layout::horizontal([Constraint::Percentage(65), Constraint::Percentage(35)])
                .areas(lower_area);
        draw_params_and_acks(frame, params_acks_area, vehicle);
        draw_arrivals(frame, link_area, vehicle, now);
        let header = Row::new([
            "task",
            "I R F A",
            "releases",
            "overruns b/f/m",
            "resets",
            "faults",
            "exec mean/max µs",
            "budget µs",
            "log drop",
            "tlm Hz",
        ])
        .style(Style::new().bold());
        let rows: Vec<Row> = vehicle
            .tasks
            .iter()
            .map(|(&index, task)| {
                let name = task
                    .name()
                    .map_or_else(|| format!("task {index}"), str::to_string);
                let style = if index == self.selected_task {
                    Style::new().reversed()
                } else {
                    Style::new()
                };
                let Some(s) = &task.status else {
                    return Row::new([Cell::from(name), Cell::from("? ? ? ?")]).style(style);
                };
                let light = |on: bool| {
                    Span::styled(
                        if on { "●" } else { "○" },
                        Style::new().fg(if on { Color::Green } else { Color::DarkGray }),
                    )
                };
                let lights = Line::from(vec![
                    light(s.initialised),
                    Span::raw(" "),
                    light(s.running),
                    Span::raw(" "),
                    light(s.in_frame),
                    Span::raw(" "),
                    light(s.alive),
                ]);
                let over_budget = s.budget_ns > 0 && s.exec_max_ns > s.budget_ns;
                let rate = match s.telemetry_interval_ms {
                    0 => "off".to_string(),
                    ms => format!("{:.2}", 1000.0 / f64::from(ms)),
                };
                Row::new([
                    Cell::from(name),
                    Cell::from(lights),
                    Cell::from(s.releases.to_string()),
                    Cell::from(format!(
                        "{}/{}/{}",
                        s.overruns_budget, s.overruns_frame, s.overruns_missed
                    )),
                    Cell::from(s.resets.to_string()),
                    Cell::from(s.faults.to_string()),
                    Cell::from(format!(
                        "{:.0}/{:.0}",
                        s.exec_mean_ns as f64 / 1e3,
                        s.exec_max_ns as f64 / 1e3
                    ))
                    .style(if over_budget {
                        Style::new().fg(Color::Red)
                    } else {
                        Style::new()
                    }),
                    Cell::from(format!("{:.0}", s.budget_ns as f64 / 1e3)),
                    Cell::from(s.log_records_dropped.to_string()),
                    Cell::from(rate),
                ])
                .style(style)
            })
            .collect();
        let widths = [
            Constraint::Length(10),
            Constraint::Length(8),
            Constraint::Length(9),
            Constraint::Length(15),
            Constraint::Length(6),
            Constraint::Length(6),
            Constraint::Length(17),
            Constraint::Length(9),
            Constraint::Length(8),
            Constraint::Length(6),
        ];
        frame.render_widget(
            Table::new(rows, widths).header(header).block(
                Block::bordered().title(" tasks · lights: initialised running in-frame alive "),
            ),
            table_area,
        );
        let lines = match &vehicle.executive {
            None => vec![Line::from("no executive status yet (sent every 2 s)")],
            Some(e) => {
                let duration = if e.duration_ns == 0 {
                    "until stopped".to_string()
                } else {
                    format!("{:.0} s", e.duration_ns as f64 * 1e-9)
                };
                let f = &e.frames;
                let l = &e.link;
                vec![
                    Line::from(vec![
                        Span::raw(format!(
                            "elapsed {:.1} s of {duration}   mode {}   health period {} ms   ",
                            e.elapsed_ns as f64 * 1e-9,
                            mode_name(e.mode),
                            e.health_period_ms
                        )),
                        Span::styled(" s: STOP ", Style::new().fg(Color::White).bg(Color::Red)),
                    ]),
                    log_line(&e.log),
                    Line::from(format!(
                        "frames {}  missed {}  late {}  overrun {}  max start latency {:.0} µs  max frame work {:.0} µs  timing records dropped {}",
                        f.frames,
                        f.missed,
                        f.late,
                        f.overrun,
                        f.max_start_latency_ns as f64 / 1e3,
                        f.max_frame_work_ns as f64 / 1e3,
                        f.timing_records_dropped
                    )),
                    Line::from(format!(
                        "vehicle's link: commands received {} accepted {}; refused: bad crc {} malformed {} unsigned {} bad signature {} wrong run {} replayed {}",
                        l.received,
                        l.accepted,
                        l.bad_crc,
                        l.malformed,
                        l.unsigned,
                        l.bad_signature,
                        l.wrong_run,
                        l.replayed,
                    )),
                    Line::from(format!(
                        "                out of range {} unknown param {} wrong type {} rate-limited {}; telemetry sent {} failed {}",
                        l.out_of_range,
                        l.unknown_param,
                        l.wrong_type,
                        l.rate_limited,
                        l.telemetry_sent,
                        l.telemetry_send_failed
                    )),
                    Line::from(format!(
                        "ground's link: received {}  missed {} ({:.1}%)  late {}  refused: bad crc {} bad signature {} malformed {} unsigned {}",
                        vehicle.link.received,
                        vehicle.link.missed,
                        vehicle.link.loss_percent(),
                        vehicle.link.late,
                        vehicle.link.bad_crc,
                        vehicle.link.bad_signature,
                        vehicle.link.malformed,
                        vehicle.link.unsigned
                    )),
                ]
            }
        };
        frame.render_widget(
            Paragraph::new(lines).block(Block::bordered().title(" executive ")),
            info_area,
        );
    }
}

/// The flight log's health: red when records are being lost.
fn log_line(log: &skyframe_core::link::messages::LogHealth) -> Line<'static> {
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
fn draw_arrivals(frame: &mut Frame, area: Rect, vehicle: &VehicleState, now: Instant) {
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
fn draw_params_and_acks(frame: &mut Frame, area: Rect, vehicle: &VehicleState) {
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

enum Editing {
    Continue,
    Done,
    Cancel,
}

fn edit_text(text: &mut String, key: KeyEvent) -> Editing {
    match key.code {
        KeyCode::Enter => Editing::Done,
        KeyCode::Esc => Editing::Cancel,
        KeyCode::Backspace => {
            text.pop();
            Editing::Continue
        }
        KeyCode::Char(c) if (c.is_ascii_digit() || c == '.') && text.len() < 12 => {
            text.push(c);
            Editing::Continue
        }
        _ => Editing::Continue,
    }
}

/// How a column is shown: its name without the unit suffix, the value in the unit people
/// read (degrees where the log has radians), and that unit.
struct Shown {
    name: String,
    value: f64,
    unit: &'static str,
}

fn shown(column: &str, value: f64) -> Shown {
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
fn strip_unit(column: &str) -> &str {
    let mut name = column;
    for _ in 0..unit_suffix_parts(column) {
        name = name.rfind('_').map_or(name, |i| &name[..i]);
    }
    if name.is_empty() { column } else { name }
}

fn shown_text(shown: &Shown) -> String {
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
fn log_time_text(tenths: i64) -> String {
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
fn draw_generic(
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
fn draw_control(frame: &mut Frame, area: Rect, vehicle: &VehicleState) {
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
fn draw_imu(frame: &mut Frame, area: Rect, vehicle: &VehicleState) {
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

fn draw_gps(frame: &mut Frame, area: Rect, vehicle: &VehicleState) {
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

fn draw_estimator(frame: &mut Frame, area: Rect, vehicle: &VehicleState) {
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

fn ratio(value: f64, low: f64, high: f64) -> f64 {
    let r = (value - low) / (high - low);
    if r.is_finite() {
        r.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

fn draw_servo(frame: &mut Frame, area: Rect, vehicle: &VehicleState) {
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

/// Runs the UI on the real terminal until `q`.
pub fn run_terminal(session: Session, vehicle: Option<u16>) -> std::io::Result<()> {
    let Session {
        link,
        model,
        mut sender,
    } = session;
    let receiver_link = link.try_clone()?;
    let (tx, rx) = mpsc::channel::<(Received, Instant)>();
    std::thread::spawn(move || {
        let mut receiver_link = receiver_link;
        loop {
            match receiver_link.receive(Duration::from_millis(200)) {
                Ok(Some(received)) => {
                    if tx.send((received, Instant::now())).is_err() {
                        return;
                    }
                }
                Ok(None) => {}
                Err(_) => std::thread::sleep(Duration::from_millis(200)),
            }
        }
    });
    let mut app = App::new(model, vehicle, sender.is_some());
    let mut terminal = ratatui::init();
    let result = (|| -> std::io::Result<()> {
        while !app.quit {
            while let Ok((received, at)) = rx.try_recv() {
                app.apply(&received, at);
            }
            let now = Instant::now();
            let resend = app.tick(now);
            terminal.draw(|frame| app.draw(frame, now))?;
            let request = match resend {
                Some(request) => request,
                None => {
                    if !event::poll(Duration::from_millis(100))? {
                        continue;
                    }
                    let Event::Key(key) = event::read()? else {
                        continue;
                    };
                    let Some(request) = app.handle_key(key) else {
                        continue;
                    };
                    request
                }
            };
            let Some(sender) = sender.as_mut() else {
                app.status = "no link key: commands need --key FILE".to_string();
                continue;
            };
            let Some(v) = app.model.vehicle(request.vehicle_id) else {
                continue;
            };
            let target = CommandTarget {
                vehicle_id: v.id,
                run_id: v.run_id,
                address: v.address,
            };
            match link.send_command(&target, sender, &request.command) {
                Ok(sequence) => app.sent(&request, sender.sender_id, sequence, Instant::now()),
                Err(e) => app.status = format!("{}: {e}", request.description),
            }
        }
        Ok(())
    })();
    ratatui::restore();
    result
}

#[cfg(test)]
mod tests {
    use super::{log_time_text, strip_unit};

    #[test]
    fn log_times_read_as_flight_seconds_or_utc_time_of_day() {
        assert_eq!(log_time_text(29), "2.9 s");
        // 2026-11-25T01:14:39.3Z
        assert_eq!(log_time_text(17_955_692_793), "01:14:39.3 UTC");
    }

    #[test]
    fn names_lose_their_unit_suffix_only() {
        assert_eq!(strip_unit("p_rad_s"), "p");
        assert_eq!(strip_unit("fz_m_s2"), "fz");
        assert_eq!(strip_unit("alt_c_m"), "alt_c");
        assert_eq!(strip_unit("satellites"), "satellites");
        assert_eq!(strip_unit("_m"), "_m");
    }
}
