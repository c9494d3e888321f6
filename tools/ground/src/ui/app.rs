//! The UI's state: the model, the tab and the vehicle shown, what the user is typing and
//! the commands waiting for an answer; keys in, commands out, and the frame drawn from it.

use super::widgets::{
    draw_arrivals, draw_control, draw_estimator, draw_generic, draw_gps, draw_imu,
    draw_params_and_acks, draw_servo, log_line,
};
use crate::json::mode_name;
use crate::model::{GroundModel, VehicleState};
use crate::net::{RESEND_AFTER, Received, apply};
use crate::values::{ack_result_name, interval_ms_for_hz, value_text};
use ratatui::Frame;
use ratatui::crossterm::event::{KeyCode, KeyEvent, KeyEventKind, KeyModifiers};
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Style, Stylize};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Cell, Paragraph, Row, Table, Tabs};
use skyframe_core::link::messages::{AckResult, Command, limits};
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
pub(super) struct Pending {
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

/// What a key did to a number being typed.
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
