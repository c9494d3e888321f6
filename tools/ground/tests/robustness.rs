//! Nothing a datagram carries makes the ground panic: not garbage, not damaged datagrams
//! with a good CRC, not well-formed data with extreme values (NaN, ±∞, 1e308 degrees)
//! drawn on every tab.

use proptest::prelude::*;
use ratatui::Terminal;
use ratatui::backend::TestBackend;
use ratatui::crossterm::event::{KeyCode, KeyEvent, KeyModifiers};
use skyframe_core::link::frame::{Envelope, MAX_DATAGRAM_LEN, crc32, encode_datagram};
use skyframe_core::link::messages::{Message, TaskData, TaskFormat, Telemetry, Value};
use skyframe_core::logfmt::Time;
use skyframe_ground::fake_vehicle::{TASKS, sample_task_status};
use skyframe_ground::model::GroundModel;
use skyframe_ground::net::{Received, decode};
use skyframe_ground::ui::App;
use std::net::SocketAddr;
use std::time::Instant;

fn from() -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], 47201))
}

fn encode(sequence: u32, telemetry: Telemetry) -> Vec<u8> {
    let envelope = Envelope {
        vehicle_id: 1,
        sender_id: 0,
        run_id: 1,
        sequence,
        t_ns: u64::from(sequence),
    };
    let mut out = [0u8; MAX_DATAGRAM_LEN];
    let len = encode_datagram(&envelope, &Message::Telemetry(telemetry), None, &mut out)
        .expect("encodes");
    out[..len].to_vec()
}

fn draw_every_tab(app: &mut App) {
    let mut terminal = Terminal::new(TestBackend::new(100, 30)).expect("terminal");
    for _ in 0..app.tabs().len() {
        terminal
            .draw(|frame| app.draw(frame, Instant::now()))
            .expect("draw");
        app.handle_key(KeyEvent::new(KeyCode::Tab, KeyModifiers::NONE));
    }
}

fn extreme() -> impl Strategy<Value = Value> {
    prop_oneof![
        Just(Value::F32(f32::NAN)),
        Just(Value::F32(f32::INFINITY)),
        Just(Value::F64(f64::NEG_INFINITY)),
        Just(Value::F64(1e308)),
        Just(Value::F64(-1e308)),
        Just(Value::U32(u32::MAX)),
        Just(Value::I32(i32::MIN)),
        Just(Value::Bool(true)),
        any::<f64>().prop_map(Value::F64),
        any::<f32>().prop_map(Value::F32),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn arbitrary_bytes_are_refused_or_applied(bytes in proptest::collection::vec(any::<u8>(), 0..1600)) {
        let mut app = App::new(GroundModel::default(), None, true);
        let received = Received { from: from(), incoming: decode(&bytes, None) };
        app.apply(&received, Instant::now());
        draw_every_tab(&mut app);
    }

    #[test]
    fn damaged_datagrams_with_a_fixed_crc_never_panic(
        flips in proptest::collection::vec((0usize..400, any::<u8>()), 1..6),
    ) {
        let columns = TASKS[4].1[0].1;
        let format = TaskFormat {
            task_index: 4,
            format_index: 1,
            columns: heapless::Vec::from_slice(columns.as_bytes()).expect("fits"),
        };
        let mut datagram = encode(1, Telemetry::TaskFormat(format));
        let body = datagram.len() - 4;
        for (at, byte) in flips {
            let at = at % body;
            datagram[at] ^= byte;
        }
        let crc = crc32(&datagram[..body]).to_le_bytes();
        datagram[body..].copy_from_slice(&crc);
        let mut app = App::new(GroundModel::default(), None, true);
        app.apply(&Received { from: from(), incoming: decode(&datagram, None) }, Instant::now());
        draw_every_tab(&mut app);
    }

    #[test]
    fn extreme_values_on_every_tab_never_panic(
        values in proptest::collection::vec(extreme(), 0..20),
        task_index in 0u8..5,
        format_index in 1u8..3,
    ) {
        let mut app = App::new(GroundModel::default(), None, true);
        let mut sequence = 0;
        let mut send = |app: &mut App, telemetry: Telemetry| {
            sequence += 1;
            let incoming = decode(&encode(sequence, telemetry), None);
            app.apply(&Received { from: from(), incoming }, Instant::now());
        };
        for (index, (_, formats)) in TASKS.iter().enumerate() {
            send(&mut app, Telemetry::TaskStatus(sample_task_status(index as u8, 0, 0)));
            for &(format, columns) in formats.iter() {
                let columns = heapless::Vec::from_slice(columns.as_bytes()).expect("fits");
                send(&mut app, Telemetry::TaskFormat(TaskFormat {
                    task_index: index as u8,
                    format_index: format,
                    columns,
                }));
            }
        }
        for _ in 0..3 {
            let data = TaskData {
                task_index,
                format_index,
                time: Time::default(),
                values: values.iter().copied().collect(),
            };
            send(&mut app, Telemetry::TaskData(data));
        }
        draw_every_tab(&mut app);
    }
}
