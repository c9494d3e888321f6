//! The UI rendered into ratatui's TestBackend from a scripted message stream: what each
//! tab shows, and what the keys do.

use ratatui::Terminal;
use ratatui::backend::TestBackend;
use ratatui::crossterm::event::{KeyCode, KeyEvent, KeyModifiers};
use skyframe_core::control::mode::FlightMode;
use skyframe_core::link::frame::{Envelope, Header};
use skyframe_core::link::messages::{
    AckResult, Command, CommandAck, ExecutiveStatus, TaskData, TaskFormat, Telemetry, Value,
    message_type,
};
use skyframe_core::logfmt::Time;
use skyframe_ground::fake_vehicle::{TASKS, sample_task_status, sample_values};

/// Where a column sits in a task's format of the fake vehicle.
fn column_index(task: usize, format: u8, column: &str) -> usize {
    let columns = TASKS[task]
        .1
        .iter()
        .find(|(i, _)| *i == format)
        .expect("format")
        .1;
    columns
        .split(',')
        .position(|c| c == column)
        .expect("column")
}
use skyframe_ground::model::GroundModel;
use skyframe_ground::net::{Incoming, Received};
use skyframe_ground::ui::{App, Input, Request};
use std::net::SocketAddr;
use std::time::{Duration, Instant};

const VEHICLE: u16 = 7;
const RUN: u32 = 0x2026_1122;

struct Script {
    app: App,
    sequence: u32,
    start: Instant,
    from: SocketAddr,
}

impl Script {
    fn new() -> Self {
        Self {
            app: App::new(GroundModel::default(), None, true),
            sequence: 0,
            start: Instant::now(),
            from: SocketAddr::from(([127, 0, 0, 1], 47201)),
        }
    }

    fn send(&mut self, vehicle_id: u16, t_ns: u64, telemetry: Telemetry) {
        self.sequence += 1;
        let header = Header {
            envelope: Envelope {
                vehicle_id,
                sender_id: 0,
                run_id: RUN,
                sequence: self.sequence,
                t_ns,
            },
            message_type: telemetry.message_type(),
            signed: false,
            payload_len: 0,
        };
        let received = Received {
            from: self.from,
            incoming: Incoming::Telemetry { header, telemetry },
        };
        let at = self.start + Duration::from_nanos(t_ns);
        self.app.apply(&received, at);
    }

    /// `seconds` of a vehicle: formats first, then every task's data at 10 Hz, a status
    /// per task and executive status each second.
    fn fly(&mut self, vehicle_id: u16, seconds: u64) {
        for (task_index, (_, formats)) in TASKS.iter().enumerate() {
            for &(format_index, columns) in formats.iter() {
                let format = TaskFormat {
                    task_index: task_index as u8,
                    format_index,
                    columns: heapless::Vec::from_slice(columns.as_bytes()).expect("fits"),
                };
                self.send(vehicle_id, 0, Telemetry::TaskFormat(format));
            }
        }
        for step in 0..seconds * 10 {
            let t_ns = step * 100_000_000;
            for (task_index, (_, formats)) in TASKS.iter().enumerate() {
                for &(format_index, _) in formats.iter() {
                    let data = TaskData {
                        task_index: task_index as u8,
                        format_index,
                        time: Time::from_ns(t_ns).expect("in range"),
                        values: sample_values(task_index as u8, format_index, t_ns),
                    };
                    self.send(vehicle_id, t_ns, Telemetry::TaskData(data));
                }
                if step % 10 == 0 {
                    let status = sample_task_status(task_index as u8, 100, step * 10);
                    self.send(vehicle_id, t_ns, Telemetry::TaskStatus(status));
                }
            }
            if step % 10 == 0 {
                let status = ExecutiveStatus {
                    elapsed_ns: t_ns,
                    duration_ns: 600_000_000_000,
                    mode: Some(FlightMode::Stabilise),
                    task_count: TASKS.len() as u8,
                    health_period_ms: 1000,
                    ..ExecutiveStatus::default()
                };
                self.send(vehicle_id, t_ns, Telemetry::ExecutiveStatus(status));
            }
        }
    }

    fn now(&self, after_s: f64) -> Instant {
        self.start + Duration::from_secs_f64(after_s)
    }

    fn screen(&self, now: Instant) -> String {
        let mut terminal = Terminal::new(TestBackend::new(120, 40)).expect("terminal");
        terminal
            .draw(|frame| self.app.draw(frame, now))
            .expect("draw");
        let buffer = terminal.backend().buffer().clone();
        let width = usize::from(buffer.area.width);
        let screen = buffer
            .content()
            .chunks(width)
            .map(|row| row.iter().map(|c| c.symbol()).collect::<String>())
            .collect::<Vec<_>>()
            .join("\n");
        // To look at the screens: SKYFRAME_PRINT_SCREENS=1 cargo test --test ui_tabs -- --nocapture
        if std::env::var_os("SKYFRAME_PRINT_SCREENS").is_some() {
            println!("{screen}");
        }
        screen
    }

    fn key(&mut self, code: KeyCode) -> Option<Request> {
        self.app.handle_key(KeyEvent::new(code, KeyModifiers::NONE))
    }
}

fn line_with<'a>(screen: &'a str, needle: &str) -> &'a str {
    screen
        .lines()
        .find(|l| l.contains(needle))
        .unwrap_or_else(|| panic!("no line with {needle:?} in\n{screen}"))
}

#[test]
fn before_anything_is_heard_the_ui_says_it_is_listening() {
    let script = Script::new();
    let screen = script.screen(script.now(0.0));
    assert!(
        screen.contains("Listening… no vehicle heard yet."),
        "{screen}"
    );
    assert!(screen.contains("1 Executive"));
}

#[test]
fn executive_tab_shows_four_lights_counters_and_timing_per_task() {
    let mut script = Script::new();
    script.fly(VEHICLE, 3);
    let screen = script.screen(script.now(3.0));
    // Every task of the frame table, in order, with its lights.
    let imu = line_with(&screen, "imu ");
    assert!(imu.contains("● ● ● ●"), "{imu}");
    let telemetry = line_with(&screen, "telemetry ");
    assert!(telemetry.contains("● ● ○ ●"), "out of frame: {telemetry}");
    let estimator = line_with(&screen, "estimator ");
    assert!(estimator.contains("3/0/0"), "budget overruns: {estimator}");
    // Mean/max exec against the budget, in µs: estimator's budget is 1250 µs.
    assert!(estimator.contains("312/938"), "{estimator}");
    assert!(estimator.contains("1250"), "{estimator}");
    assert!(
        estimator.contains("10.00"),
        "telemetry rate in Hz: {estimator}"
    );
    assert!(line_with(&screen, "gps ").contains("1 "), "log drops");
    assert!(screen.contains("mode stabilise"), "{screen}");
    assert!(
        line_with(&screen, "vehicle 7").contains("stabilise"),
        "{screen}"
    );
    assert!(screen.contains("of 600 s"), "{screen}");
    assert!(
        screen.contains("log: free space unknown  records lost 0"),
        "{screen}"
    );
    assert!(screen.contains("s: STOP"), "{screen}");
    // 3 s of 10 Hz data from 8 tasks (6 formats) + statuses: about 66 datagrams a second.
    assert!(screen.contains("link: 6"), "{screen}");
    // Vehicle list: one vehicle, no loss, just seen.
    let vehicle = line_with(&screen, "vehicle 7");
    assert!(vehicle.contains("loss   0.0%/10s 0.0%/run"), "{vehicle}");
    assert!(vehicle.contains("last seen"), "{vehicle}");
}

#[test]
fn imu_tab_shows_rates_in_degrees_and_a_history_chart() {
    let mut script = Script::new();
    script.fly(VEHICLE, 3);
    script.key(KeyCode::Char('2'));
    let screen = script.screen(script.now(3.0));
    // The last record streamed is at 2.9 s: its values, by name, in the units people read.
    assert!(screen.contains("IMU latest at 2.9 s"), "{screen}");
    let rate = |column: &str| match sample_values(0, 1, 2_900_000_000)[column_index(0, 1, column)] {
        Value::F32(v) => f64::from(v).to_degrees(),
        ref other => panic!("{other:?}"),
    };
    for column in ["p_rad_s", "q_rad_s", "r_rad_s"] {
        let row = line_with(&screen, &format!("│1  {} ", &column[..1]));
        assert!(row.contains(&format!("{:.3}", rate(column))), "{row}");
        assert!(row.contains("°/s"), "{row}");
    }
    let fz = line_with(&screen, "│1  fz ");
    assert!(fz.contains("-9.807") && fz.contains("m/s²"), "{fz}");
    // Two charts of the last minute, each with its legend.
    assert!(screen.contains("IMU angular rates"), "{screen}");
    assert!(screen.contains("IMU specific force"), "{screen}");
    assert!(screen.contains("p °/s"), "{screen}");
    assert!(screen.contains("fz m/s²"), "{screen}");
    assert!(screen.contains("-60 s"), "{screen}");
}

#[test]
fn gps_tab_shows_fix_accuracy_and_a_track_in_local_metres() {
    let mut script = Script::new();
    script.fly(VEHICLE, 5);
    script.key(KeyCode::Char('3'));
    let screen = script.screen(script.now(5.0));
    assert!(
        screen.contains("fix valid  quality 1  satellites 9"),
        "{screen}"
    );
    assert!(screen.contains("DOP p 1.8  h 0.9  v 1.5"), "{screen}");
    assert!(screen.contains("σ N 1.2  E 1.1  D 2.5 m"), "{screen}");
    assert!(screen.contains("lat 47.39"), "{screen}");
    assert!(screen.contains("track, local metres"), "{screen}");
    assert!(screen.contains('✈'), "{screen}");
}

#[test]
fn estimator_tab_draws_an_attitude_indicator_in_degrees() {
    let mut script = Script::new();
    script.fly(VEHICLE, 2);
    script.key(KeyCode::Char('4'));
    let screen = script.screen(script.now(2.0));
    // sample: roll 0.26 + 0.05 sin(0.5 t) rad at t = 1.9 s → about 17.3°.
    let title = line_with(&screen, "attitude: roll");
    assert!(title.contains("roll +17."), "{title}");
    assert!(screen.contains(" attitude "), "{screen}");
    // Altitude and airspeed come from the control task's estimate; the height above the
    // estimator's origin from its own north-east-down position (pd = -88 - 2 sin(0.19) m).
    let altitude = line_with(&screen, "above home");
    let expected_alt = 488.0 + 2.0 * (0.19f64).sin();
    assert!(
        altitude.contains(&format!("altitude {expected_alt:.1} m above home")),
        "{altitude}"
    );
    let height = format!(
        "height {:.1} m above the filter's origin",
        88.0 + 2.0 * (0.19f64).sin()
    );
    assert!(screen.contains(&height), "{height}: {screen}");
    assert!(screen.contains("airspeed 12.0 m/s"), "{screen}");
    assert!(screen.contains("filter healthy"), "{screen}");
    // The horizon (braille dots) is drawn inside the indicator.
    assert!(
        screen
            .chars()
            .any(|c| ('\u{2801}'..='\u{28FF}').contains(&c)),
        "{screen}"
    );
}

#[test]
fn servo_tab_has_pilot_and_computer_bars_and_battery_gauges() {
    let mut script = Script::new();
    script.fly(VEHICLE, 2);
    script.key(KeyCode::Char('5'));
    let screen = script.screen(script.now(2.0));
    assert!(screen.contains("MANUAL (pilot flies)"), "{screen}");
    let throttle = line_with(&screen, "pilot +0.60");
    assert!(throttle.starts_with("throttle"), "{throttle}");
    assert!(throttle.contains("pilot +0.60"), "{throttle}");
    assert!(throttle.contains("computer +0.55"), "{throttle}");
    assert!(line_with(&screen, "elevator").contains("pilot -0.10"));
    assert!(screen.contains("avionics battery"), "{screen}");
    assert!(screen.contains("11.80 V (3S)"), "{screen}");
    assert!(screen.contains("5.10 V (1S)"), "{screen}");
    assert!(screen.contains("pilot sticks vs computer"), "{screen}");
}

#[test]
fn control_tab_shows_its_columns_generically() {
    let mut script = Script::new();
    script.fly(VEHICLE, 2);
    script.key(KeyCode::Char('6'));
    let screen = script.screen(script.now(2.0));
    assert!(screen.contains("Control latest"), "{screen}");
    // roll_c_rad = 0.26 rad, shown in degrees.
    let roll_c = line_with(&screen, "│1  roll_c ");
    assert!(
        roll_c.contains(&format!("{:.3}", 0.26f32.to_degrees())) && roll_c.contains('°'),
        "radians shown in degrees: {roll_c}"
    );
    for chart in [
        "roll: target",
        "pitch: target",
        "altitude: target",
        "course: target",
    ] {
        assert!(screen.contains(chart), "{chart}: {screen}");
    }
}

#[test]
fn tab_keys_cycle_and_digits_jump() {
    let mut script = Script::new();
    script.fly(VEHICLE, 1);
    script.key(KeyCode::Tab);
    assert_eq!(script.app.tab, 1);
    script.key(KeyCode::BackTab);
    script.key(KeyCode::BackTab);
    assert_eq!(script.app.tab, script.app.tabs().len() - 1);
    script.key(KeyCode::Char('1'));
    assert_eq!(script.app.tab, 0);
}

#[test]
fn stop_asks_for_confirmation_and_only_y_sends_it() {
    let mut script = Script::new();
    script.fly(VEHICLE, 1);
    assert_eq!(script.key(KeyCode::Char('s')), None);
    assert_eq!(
        script.app.input,
        Input::ConfirmStop {
            vehicle_id: VEHICLE
        }
    );
    assert!(script.screen(script.now(1.0)).contains("STOP vehicle 7?"));
    assert_eq!(script.key(KeyCode::Char('n')), None);
    assert_eq!(script.app.input, Input::Normal);
    script.key(KeyCode::Char('s'));
    let request = script.key(KeyCode::Char('y')).expect("stop sent");
    assert_eq!(request.command, Command::Stop);
    assert_eq!(request.vehicle_id, VEHICLE);
    // The acknowledgement shows on the status line.
    script.app.sent(&request, 1, 41, script.now(1.0));
    let ack = CommandAck {
        command_sender_id: 1,
        command_sequence: 41,
        command_type: message_type::STOP,
        result: AckResult::Accepted,
        value_in_force: None,
    };
    script.send(VEHICLE, 1_100_000_000, Telemetry::CommandAck(ack));
    script.app.tick(script.now(1.2));
    assert!(
        script
            .screen(script.now(1.2))
            .contains("stop vehicle 7: accepted"),
        "{}",
        script.app.status
    );
}

#[test]
fn an_unanswered_command_is_resent_each_second_then_reported() {
    let mut script = Script::new();
    script.fly(VEHICLE, 1);
    script.key(KeyCode::Char('s'));
    let request = script.key(KeyCode::Char('y')).expect("stop");
    script.app.sent(&request, 1, 10, script.now(1.0));
    assert_eq!(script.app.tick(script.now(1.5)), None);
    let again = script.app.tick(script.now(2.0)).expect("resent after 1 s");
    assert_eq!(again, request);
    script.app.sent(&again, 1, 11, script.now(2.0));
    assert!(script.app.status.contains("try 2"), "{}", script.app.status);
    // The answer to the second try settles it.
    let ack = CommandAck {
        command_sender_id: 1,
        command_sequence: 11,
        command_type: message_type::STOP,
        result: AckResult::Accepted,
        value_in_force: None,
    };
    script.send(VEHICLE, 2_100_000_000, Telemetry::CommandAck(ack));
    assert_eq!(script.app.tick(script.now(2.2)), None);
    assert_eq!(script.app.status, "stop vehicle 7: accepted");
    // No answer at all: after 5 s it says so and stops trying.
    script.key(KeyCode::Char('s'));
    let request = script.key(KeyCode::Char('y')).expect("stop");
    script.app.sent(&request, 1, 12, script.now(3.0));
    assert_eq!(script.app.tick(script.now(8.0)), None);
    assert!(
        script.app.status.contains("no answer"),
        "{}",
        script.app.status
    );
}

#[test]
fn r_edits_the_selected_tasks_telemetry_rate() {
    let mut script = Script::new();
    script.fly(VEHICLE, 1);
    script.key(KeyCode::Down); // estimator, task 1
    script.key(KeyCode::Char('r'));
    for c in "5".chars() {
        script.key(KeyCode::Char(c));
    }
    assert!(
        script
            .screen(script.now(1.0))
            .contains("estimator telemetry rate in Hz")
    );
    let request = script.key(KeyCode::Enter).expect("rate sent");
    assert_eq!(
        request.command,
        Command::SetTelemetryRate {
            task_index: 1,
            interval_ms: 200
        }
    );
    // Out of the protocol's range: not sent, said why.
    script.key(KeyCode::Char('r'));
    script.key(KeyCode::Char('5'));
    script.key(KeyCode::Char('0'));
    assert_eq!(script.key(KeyCode::Enter), None);
    assert!(
        script.app.status.contains("up to 20 Hz"),
        "{}",
        script.app.status
    );
}

#[test]
fn several_vehicles_are_listed_and_a_silent_one_shows_link_lost() {
    let mut script = Script::new();
    script.fly(3, 1);
    script.fly(VEHICLE, 6);
    let screen = script.screen(script.now(6.0));
    let silent = line_with(&screen, "vehicle 3 ");
    assert!(silent.contains("LINK LOST"), "{silent}");
    let live = line_with(&screen, "vehicle 7 ");
    assert!(!live.contains("LINK LOST"), "{live}");
    // `v` moves to the next vehicle.
    assert!(
        silent.starts_with("│▶"),
        "first heard is shown first: {silent}"
    );
    script.key(KeyCode::Char('v'));
    assert_eq!(script.app.vehicle_id(), Some(VEHICLE));
    // Data resumes by itself: the lost vehicle is live again on its next datagram.
    let ack = CommandAck {
        command_sender_id: 1,
        command_sequence: 1,
        command_type: message_type::LIST_PARAMS,
        result: AckResult::Accepted,
        value_in_force: Some(Value::Bool(true)),
    };
    script.send(3, 6_000_000_000, Telemetry::CommandAck(ack));
    let screen = script.screen(script.now(6.0));
    assert!(!line_with(&screen, "vehicle 3 ").contains("LINK LOST"));
}

#[test]
fn without_a_key_commands_are_refused_on_the_status_line() {
    let mut script = Script::new();
    script.app = App::new(GroundModel::default(), None, false);
    script.fly(VEHICLE, 1);
    assert_eq!(script.key(KeyCode::Char('s')), None);
    assert_eq!(script.app.input, Input::Normal);
    assert!(script.screen(script.now(1.0)).contains("no link key"));
}

#[test]
fn every_tab_draws_in_small_terminals_without_panicking() {
    let mut script = Script::new();
    script.fly(VEHICLE, 2);
    script.fly(3, 1);
    for (width, height) in [(20, 8), (60, 15), (80, 24), (1, 1)] {
        let mut terminal = Terminal::new(TestBackend::new(width, height)).expect("terminal");
        for tab in 0..script.app.tabs().len() {
            script.app.tab = tab;
            terminal
                .draw(|frame| script.app.draw(frame, script.now(2.0)))
                .expect("draw");
        }
    }
}
