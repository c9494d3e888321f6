//! Cross-module tests: damaged files read with exact offsets, the frame log, and the
//! round-trip property (random formats and values → encoder → reader → renderer == the C
//! library's `snprintf`).

use std::string::String;
use std::vec::Vec;

use super::*;
use std::string::ToString;

/// Everything a reader said about a file, as comparable text.
fn read_events(bytes: &[u8]) -> Vec<String> {
    let mut reader = std::boxed::Box::new(LogReader::new());
    let mut out = Vec::new();
    read_slice(&mut reader, bytes, |event| out.push(describe(&event)));
    out
}

fn describe(event: &Event<'_>) -> String {
    use std::format;
    match *event {
        Event::Problem(p) => format!("{}: problem {:?} -> {}", p.offset, p.kind, p.resume_offset),
        Event::Record { offset, record } => match record {
            Record::BeginData { time } => format!("{offset}: begin {time}"),
            Record::EndData { time } => format!("{offset}: end {time}"),
            Record::FormatComment { index, text } => {
                format!(
                    "{offset}: comment {index} {}",
                    String::from_utf8_lossy(text)
                )
            }
            Record::FormatDefinition {
                index,
                text,
                format,
            } => format!(
                "{offset}: format {index} {} valid={}",
                String::from_utf8_lossy(text),
                format.is_some()
            ),
            Record::DataBlock {
                index,
                time,
                data,
                format,
            } => {
                let mut text = String::new();
                render_fields(&mut text, format, data).expect("renders");
                format!("{offset}: data {index} {time} {text}")
            }
            Record::ByteArray {
                index,
                time,
                bytes,
                type_byte,
                ..
            } => {
                format!("{offset}: bytes {index} {time} {bytes:?} 0x{type_byte:02X}")
            }
        },
    }
}

/// Renders each field with its own conversion, `|`-separated (the tests here check framing,
/// not literal text, which the round trip covers).
fn render_fields(out: &mut String, format: &Format, data: &[u8]) -> Result<(), RenderError> {
    let mut offset = 0;
    for (i, field) in format.fields().iter().enumerate() {
        if i > 0 {
            out.push('|');
        }
        let value = Value::decode(field.ty, &data[offset..]).ok_or(RenderError::DataMismatch)?;
        render_field(out, field, value)?;
        offset += field.ty.size();
    }
    Ok(())
}

fn begin(sec: i32, nsec: u32) -> Vec<u8> {
    let mut v = std::vec![0xBD, 0, 0, 0];
    v.extend_from_slice(&sec.to_le_bytes());
    v.extend_from_slice(&nsec.to_le_bytes());
    v
}

fn end(sec: i32, nsec: u32) -> Vec<u8> {
    let mut v = begin(sec, nsec);
    v[0] = 0xED;
    v
}

fn text_record(kind: u8, index: u8, text: &[u8]) -> Vec<u8> {
    let mut v = std::vec![kind, index];
    v.extend_from_slice(&(text.len() as u16).to_le_bytes());
    v.extend_from_slice(text);
    v
}

fn timed(kind: u8, index: u8, sec: i32, nsec: u32, body: &[u8]) -> Vec<u8> {
    let mut v = std::vec![kind, index];
    v.extend_from_slice(&(body.len() as u16).to_le_bytes());
    v.extend_from_slice(&sec.to_le_bytes());
    v.extend_from_slice(&nsec.to_le_bytes());
    v.extend_from_slice(body);
    v
}

/// The spec's example data block, (7, -2, 1.5f, 0.25), built by hand.
fn example_body() -> Vec<u8> {
    let mut b = Vec::new();
    b.extend_from_slice(&7u32.to_le_bytes());
    b.extend_from_slice(&(-2i16).to_le_bytes());
    b.extend_from_slice(&1.5f32.to_le_bytes());
    b.extend_from_slice(&0.25f64.to_le_bytes());
    b
}

/// BD(0) FD(12) FC(32) DB(39) DB(69) ED(99), 111 bytes.
fn whole_file() -> Vec<u8> {
    let mut f = begin(1, 0);
    f.extend(text_record(0xFD, 1, b"%u,%hd,%.3f,%lf\0"));
    f.extend(text_record(0xFC, 1, b"n,t"));
    f.extend(timed(0xDB, 1, 1, 5, &example_body()));
    f.extend(timed(0xDB, 1, 2, 999_999_999, &example_body()));
    f.extend(end(3, 0));
    f
}

#[test]
fn whole_file_reads_cleanly() {
    let f = whole_file();
    assert_eq!(f.len(), 111);
    assert_eq!(
        read_events(&f),
        [
            "0: begin 1.000000000",
            "12: format 1 %u,%hd,%.3f,%lf valid=true",
            "32: comment 1 n,t",
            "39: data 1 1.000000005 7|-2|1.500|0.250000",
            "69: data 1 2.999999999 7|-2|1.500|0.250000",
            "99: end 3.000000000",
        ]
        .map(String::from)
    );
}

#[test]
fn truncated_tail_is_reported_and_the_rest_kept() {
    let mut f = whole_file();
    f.truncate(99); // drop End Data
    f.extend(timed(0xDB, 1, 4, 0, &example_body()));
    f.truncate(99 + 20); // power lost mid-record
    let events = read_events(&f);
    assert_eq!(events.len(), 7, "{events:#?}");
    assert_eq!(events[4], "69: data 1 2.999999999 7|-2|1.500|0.250000");
    assert_eq!(
        events[5..],
        [
            "99: problem Truncated { type_byte: 219, needed: 30, available: 20 } -> 119",
            "119: problem NotClosedCleanly -> 119",
        ]
        .map(String::from)
    );
}

#[test]
fn missing_end_data_is_reported() {
    let mut f = whole_file();
    f.truncate(99);
    let events = read_events(&f);
    assert_eq!(
        events.last().map(String::as_str),
        Some("99: problem NotClosedCleanly -> 99")
    );
    assert_eq!(
        read_events(&[]),
        ["0: problem NotClosedCleanly -> 0"].map(String::from)
    );
}

#[test]
fn garbage_in_the_middle_is_skipped_with_offsets() {
    let f = whole_file();
    let mut g = f[..69].to_vec();
    g.extend_from_slice(&[0x00, 0x11, 0xDB, 0x22, 0xFF, 0xFF, 0x33]);
    g.extend_from_slice(&f[69..]);
    let events = read_events(&g);
    assert_eq!(
        events[4..],
        [
            "69: problem UnknownType { type_byte: 0 } -> 76",
            "76: data 1 2.999999999 7|-2|1.500|0.250000",
            "106: end 3.000000000",
        ]
        .map(String::from)
    );
}

#[test]
fn bad_length_resynchronises_on_the_next_record() {
    let mut f = whole_file();
    // The first data block claims 40 bytes: runs into the next record, not past the end.
    f[41] = 40;
    let events = read_events(&f);
    assert_eq!(
        events[3..],
        [
            "39: problem DataLengthMismatch { index: 1, len: 40, expected: 18 } -> 69",
            "69: data 1 2.999999999 7|-2|1.500|0.250000",
            "99: end 3.000000000",
        ]
        .map(String::from)
    );
    // A length past the end of the file.
    let mut f = whole_file();
    f[71] = 0xFF;
    f[72] = 0xFF;
    let events = read_events(&f);
    assert_eq!(
        events[4..],
        [
            "69: problem LengthPastEnd { type_byte: 219, needed: 65547, available: 42 } -> 99",
            "99: end 3.000000000",
        ]
        .map(String::from)
    );
}

#[test]
fn unknown_types_and_bad_headers() {
    let mut f = whole_file();
    f[69] = 0x42;
    let events = read_events(&f);
    assert_eq!(events[4], "69: problem UnknownType { type_byte: 66 } -> 99");
    let mut f = whole_file();
    f[1] = 7; // Begin Data with an index
    let events = read_events(&f);
    assert_eq!(
        events[0],
        "0: problem BadHeader { type_byte: 189, index: 7, len: 0 } -> 12"
    );
    let mut f = whole_file();
    f[69 + 11] = 0xFF; // tv_nsec ≥ 10⁹
    let events = read_events(&f);
    assert_eq!(
        events[4],
        "69: problem BadTime { type_byte: 219, nsec: 4288334335 } -> 99"
    );
}

#[test]
fn data_before_its_format_and_invalid_formats() {
    let mut f = begin(0, 0);
    f.extend(timed(0xDB, 2, 0, 0, &[1, 2, 3, 4])); // 12
    f.extend(text_record(0xFD, 2, b"%s")); // 28
    f.extend(timed(0xDB, 2, 0, 0, &[1, 2, 3, 4])); // 34
    f.extend(text_record(0xFD, 2, b"%hhx")); // 50
    f.extend(timed(0xDA, 2, 0, 7, &[1, 2])); // 58
    f.extend(timed(0xDB, 2, 0, 0, &[9])); // 72
    f.extend(end(1, 0)); // 85
    assert_eq!(
        read_events(&f),
        [
            "0: begin 0.000000000",
            "12: problem UndefinedFormat { index: 2 } -> 28",
            "28: format 2 %s valid=false",
            "28: problem InvalidFormat { index: 2, error: UnsupportedConversion { at: 0, specifier: 115 } } -> 34",
            "34: problem DataOfInvalidFormat { index: 2 } -> 50",
            "50: format 2 %hhx valid=true",
            "58: bytes 2 0.000000007 [1, 2] 0xDA",
            "72: data 2 0.000000000 9",
            "85: end 1.000000000",
        ]
        .map(String::from)
    );
}

#[test]
fn byte_array_of_a_wide_format_is_skipped() {
    let mut f = text_record(0xFD, 3, b"%hx");
    f.extend(timed(0xBA, 3, 0, 0, &[1, 2]));
    f.extend(end(0, 0));
    assert_eq!(
        read_events(&f)[1],
        "7: problem NotByteArrayFormat { index: 3 } -> 21"
    );
}

#[test]
fn reading_byte_by_byte_gives_the_same_events() {
    let mut f = whole_file();
    f.insert(40, 0x99);
    let whole = read_events(&f);
    let mut reader = std::boxed::Box::new(LogReader::new());
    let mut events = Vec::new();
    for &b in &f {
        reader.space()[0] = b;
        reader.commit(1);
        while let Some(e) = reader.next_event() {
            events.push(describe(&e));
        }
    }
    reader.finish();
    while let Some(e) = reader.next_event() {
        events.push(describe(&e));
    }
    assert_eq!(events, whole);
}

#[test]
fn frame_log_round_trip() {
    use crate::executive::FrameRecord;
    use crate::schedule::{OverrunPolicy, TaskSlot};
    let slot = |name| TaskSlot {
        name,
        period_ns: 1,
        offset_ns: 0,
        budget_ns: 1,
        on_overrun: OverrunPolicy::Log,
    };
    let log = FrameRecordFormat::new(&[slot("imu"), slot("gps")]).expect("builds");
    assert_eq!(
        log.columns(),
        "frame,release_ns,start_latency_ns,work_ns,overhead_ns,missed_before,ran_mask,\
         over_budget_mask,over_frame_mask,skipped_mask,reset_mask,flags,exec_ns_imu,exec_ns_gps"
    );
    assert!(FrameRecordFormat::new(&[slot("a,b")]).is_err());
    let mut record = FrameRecord::empty();
    record.frame = 42;
    record.release_ns = 420_000_000;
    record.work_ns = 900;
    record.ran = 0b11;
    record.flags = 3;
    record.exec_ns[0] = 300;
    record.exec_ns[1] = 500;
    let mut buf = [0u8; 512];
    let mut len = log.encode_declaration(&mut buf, 5).expect("declares");
    len += encode_frame_record(&mut buf[len..], 5, 420_001_000, &log, &record).expect("encodes");
    len += encode_end_data(&mut buf[len..], 1).expect("ends");
    let mut reader = std::boxed::Box::new(LogReader::new());
    let mut text = String::new();
    let mut decoded = None;
    let mut names = Vec::new();
    read_slice(&mut reader, &buf[..len], |event| match event {
        Event::Record {
            record: Record::DataBlock {
                format, data, time, ..
            },
            ..
        } => {
            text = std::format!("{time},");
            render_data_block(&mut text, log.format_text(), format, data).expect("renders");
            decoded = decode_frame_record(format, data);
        }
        Event::Record {
            record: Record::FormatComment { text, .. },
            ..
        } => {
            let columns = std::str::from_utf8(text).expect("utf-8");
            names = frame_record_task_names(columns)
                .expect("a frame log")
                .map(String::from)
                .collect();
        }
        _ => {}
    });
    assert_eq!(
        text,
        "0.420001000,42,420000000,0,900,0,0,3,0,0,0,0,3,300,500"
    );
    assert_eq!(decoded, Some(record));
    assert_eq!(names, ["imu", "gps"]);
    assert!(frame_record_task_names("frame,release_ns").is_none());
    assert!(frame_record_task_names(&std::format!("{},x", log.columns())).is_none());
    let other = Format::parse("%llu,%llu").expect("valid");
    assert_eq!(decode_frame_record(&other, &[0; 16]), None);
}

#[test]
fn shipped_table_has_a_frame_log_format() {
    let log = FrameRecordFormat::new(crate::schedule::SHIPPED.tasks).expect("builds");
    assert_eq!(log.task_count(), crate::schedule::SHIPPED.tasks.len());
}

/// The oracle: the bytes the C library prints for one conversion specification and its value.
#[allow(unsafe_code)] // FFI to the C library is the point of an independent oracle.
fn c_printf(spec: &str, value: Value) -> Vec<u8> {
    let long = spec.contains('l') && !spec.contains("ll");
    let spec = std::ffi::CString::new(spec).expect("no NUL");
    let mut buf = std::vec![0u8; 16384];
    let cap = buf.len();
    let p = buf.as_mut_ptr().cast::<libc::c_char>();
    // SAFETY: `buf` has `cap` bytes; each specification has exactly one conversion whose
    // C type matches the promoted argument passed with it.
    let n = unsafe {
        match value {
            Value::I8(v) => libc::snprintf(p, cap, spec.as_ptr(), libc::c_int::from(v)),
            Value::U8(v) => libc::snprintf(p, cap, spec.as_ptr(), libc::c_int::from(v)),
            Value::I16(v) => libc::snprintf(p, cap, spec.as_ptr(), libc::c_int::from(v)),
            Value::U16(v) => libc::snprintf(p, cap, spec.as_ptr(), libc::c_int::from(v)),
            // The log's `l` is 32 bits (the thesis's platform); C's long here is 64.
            Value::I32(v) if long => libc::snprintf(p, cap, spec.as_ptr(), libc::c_long::from(v)),
            Value::U32(v) if long => libc::snprintf(p, cap, spec.as_ptr(), libc::c_ulong::from(v)),
            Value::I32(v) => libc::snprintf(p, cap, spec.as_ptr(), v),
            Value::U32(v) => libc::snprintf(p, cap, spec.as_ptr(), v),
            Value::I64(v) => libc::snprintf(p, cap, spec.as_ptr(), v),
            Value::U64(v) => libc::snprintf(p, cap, spec.as_ptr(), v),
            Value::F32(v) => libc::snprintf(p, cap, spec.as_ptr(), f64::from(v)),
            Value::F64(v) => libc::snprintf(p, cap, spec.as_ptr(), v),
        }
    };
    let n = usize::try_from(n).expect("snprintf succeeded");
    assert!(n < cap);
    buf.truncate(n);
    buf
}

/// Rendered bytes, exactly as C would print them.
struct Bytes(Vec<u8>);

impl core::fmt::Write for Bytes {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        self.0.extend_from_slice(s.as_bytes());
        Ok(())
    }
}

impl ByteWrite for Bytes {
    fn write_byte(&mut self, byte: u8) -> core::fmt::Result {
        self.0.push(byte);
        Ok(())
    }
}

#[test]
fn percent_c_prints_the_raw_byte_or_its_latin1_stand_in() {
    let format = Format::parse("[%-3c]").expect("valid");
    let mut raw = Bytes(Vec::new());
    render_data_block_bytes(&mut raw, "[%-3c]", &format, &[0xE9]).expect("renders");
    assert_eq!(raw.0, b"[\xE9  ]");
    assert_eq!(raw.0, c_printf("[%-3c]", Value::U8(0xE9)));
    let mut text = String::new();
    render_data_block(&mut text, "[%-3c]", &format, &[0xE9]).expect("renders");
    assert_eq!(text, "[\u{e9}  ]");
}

mod round_trip {
    use super::*;
    use proptest::prelude::*;

    /// A conversion spec (as text) and a value of its field type.
    #[derive(Clone, Debug)]
    struct Piece {
        literal: String,
        spec: String,
        value: Value,
    }

    fn value_for(ty: FieldType) -> BoxedStrategy<Value> {
        match ty {
            FieldType::I8 => any::<i8>().prop_map(Value::I8).boxed(),
            FieldType::U8 => any::<u8>().prop_map(Value::U8).boxed(),
            FieldType::I16 => any::<i16>().prop_map(Value::I16).boxed(),
            FieldType::U16 => any::<u16>().prop_map(Value::U16).boxed(),
            FieldType::I32 => any::<i32>().prop_map(Value::I32).boxed(),
            FieldType::U32 => any::<u32>().prop_map(Value::U32).boxed(),
            FieldType::I64 => any::<i64>().prop_map(Value::I64).boxed(),
            FieldType::U64 => any::<u64>().prop_map(Value::U64).boxed(),
            FieldType::F32 => prop_oneof![
                proptest::num::f32::ANY.prop_map(Value::F32),
                (-1e7f32..1e7).prop_map(Value::F32),
                prop::sample::select(std::vec![
                    0.5f32, 2.5, -0.0, 0.125, 1e-5, 9.999_999, 999_999.5, 100.0
                ])
                .prop_map(Value::F32),
            ]
            .boxed(),
            FieldType::F64 => prop_oneof![
                proptest::num::f64::ANY.prop_map(Value::F64),
                (-1e7f64..1e7).prop_map(Value::F64),
                prop::sample::select(std::vec![
                    0.5f64, 2.5, -0.0, 0.125, 1e-5, 0.00001, 999999.5, 9.9999995, 1e15, 5e-324
                ])
                .prop_map(Value::F64),
            ]
            .boxed(),
        }
    }

    /// Every (length + specifier) of the spec's table with its field type.
    const CONVERSIONS: &[(&str, FieldType)] = &[
        ("hhd", FieldType::I8),
        ("hhi", FieldType::I8),
        ("hhu", FieldType::U8),
        ("hhx", FieldType::U8),
        ("hhX", FieldType::U8),
        ("hho", FieldType::U8),
        ("c", FieldType::U8),
        ("hd", FieldType::I16),
        ("hi", FieldType::I16),
        ("hu", FieldType::U16),
        ("hx", FieldType::U16),
        ("hX", FieldType::U16),
        ("ho", FieldType::U16),
        ("d", FieldType::I32),
        ("ld", FieldType::I32),
        ("i", FieldType::I32),
        ("u", FieldType::U32),
        ("lu", FieldType::U32),
        ("x", FieldType::U32),
        ("X", FieldType::U32),
        ("lo", FieldType::U32),
        ("lld", FieldType::I64),
        ("lli", FieldType::I64),
        ("llu", FieldType::U64),
        ("llx", FieldType::U64),
        ("llX", FieldType::U64),
        ("llo", FieldType::U64),
        ("f", FieldType::F32),
        ("F", FieldType::F32),
        ("e", FieldType::F32),
        ("E", FieldType::F32),
        ("g", FieldType::F32),
        ("G", FieldType::F32),
        ("lf", FieldType::F64),
        ("lF", FieldType::F64),
        ("le", FieldType::F64),
        ("lE", FieldType::F64),
        ("lg", FieldType::F64),
        ("lG", FieldType::F64),
    ];

    fn piece() -> impl Strategy<Value = Piece> {
        let literal = prop_oneof![
            3 => "[a-zA-Z0-9 ,;:=_.\\-]{0,4}",
            1 => Just(String::from("%%")),
            1 => Just(String::from(",")),
        ];
        let flags = prop::collection::vec(
            prop::sample::select(std::vec!['-', '+', ' ', '#', '0']),
            0..4,
        );
        let width = prop::option::of(0u16..25);
        let precision = prop::option::weighted(0.5, prop_oneof![0u16..20, 20u16..80]);
        let conversion = prop::sample::select(CONVERSIONS);
        (literal, flags, width, precision, conversion).prop_flat_map(
            |(literal, flags, width, precision, (conversion, ty))| {
                let mut spec = String::from("%");
                spec.extend(flags);
                if let Some(w) = width {
                    // "%0" is a flag, not a width.
                    if w > 0 {
                        spec.push_str(&w.to_string());
                    }
                }
                if let Some(p) = precision {
                    spec.push('.');
                    spec.push_str(&p.to_string());
                }
                spec.push_str(conversion);
                value_for(ty).prop_map(move |value| Piece {
                    literal: literal.clone(),
                    spec: spec.clone(),
                    value,
                })
            },
        )
    }

    fn cases() -> u32 {
        std::env::var("PROPTEST_CASES")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(2000)
    }

    proptest! {
        // PROPTEST_CASES raises the count for a longer campaign.
        #![proptest_config(ProptestConfig::with_cases(cases()))]

        #[test]
        fn encode_read_render_equals_c_printf(
            pieces in prop::collection::vec(piece(), 0..8),
            tail in "[a-z,]{0,3}",
            index in 1u8..=255,
            t_ns in 0u64..(i32::MAX as u64 * 1_000_000_000),
        ) {
            let mut format_text = String::new();
            let mut expected = Vec::new();
            for piece in &pieces {
                format_text.push_str(&piece.literal);
                format_text.push_str(&piece.spec);
                expected.extend_from_slice(piece.literal.replace("%%", "%").as_bytes());
                expected.extend_from_slice(&c_printf(&piece.spec, piece.value));
            }
            format_text.push_str(&tail);
            expected.extend_from_slice(tail.as_bytes());
            let columns: Vec<String> = (0..pieces.len()).map(|i| std::format!("c{i}")).collect();
            let columns = columns.join(",");

            let format = Format::parse(&format_text).expect("generated formats are valid");
            let values: Vec<Value> = pieces.iter().map(|p| p.value).collect();
            let mut file = std::vec![0u8; 4096];
            let mut len = encode_begin_data(&mut file, t_ns).expect("begin");
            len += encode_format_definition(&mut file[len..], index, &format_text).expect("def");
            len += encode_format_comment(&mut file[len..], index, &columns).expect("comment");
            len += encode_data_block(&mut file[len..], index, t_ns, &format, &values).expect("data");
            len += encode_end_data(&mut file[len..], t_ns).expect("end");

            let mut reader = std::boxed::Box::new(LogReader::new());
            let mut lines = Vec::new();
            read_slice(&mut reader, &file[..len], |event| match event {
                Event::Record { record: Record::DataBlock { format, data, time, .. }, .. } => {
                    let mut text = Bytes(std::format!("{time},").into_bytes());
                    render_data_block_bytes(&mut text, &format_text, format, data)
                        .expect("renders");
                    lines.push(text.0);
                }
                Event::Problem(p) => lines.push(std::format!("problem {p:?}").into_bytes()),
                _ => {}
            });
            let time = Time::from_ns(t_ns).expect("in range");
            let mut line = std::format!("{time},").into_bytes();
            line.extend_from_slice(&expected);
            prop_assert_eq!(lines, std::vec![line], "format {:?}", format_text);
        }

        /// `%f`'s integer-arithmetic path (`printf::fixed_digits`) where it is hardest:
        /// dyadic values k/2ⁿ land exactly on rounding ties at many precisions, and the
        /// range edges (2⁶³, precision 17/18, tiny and subnormal values) switch paths.
        #[test]
        fn fixed_point_ties_and_edges_equal_c_printf(
            k in -100_000_000i64..100_000_000,
            n in 0i32..70,
            scale in prop::sample::select(std::vec![1.0f64, 1e-300, 2f64.powi(62), 2f64.powi(63), 5e-324]),
            precision in 0u16..20,
            flags in prop::sample::select(std::vec!["", "#", "+", "08", "-12", " "]),
            single in any::<bool>(),
        ) {
            let value = k as f64 / 2f64.powi(n) * scale;
            let (spec, value) = if single {
                (std::format!("%{flags}.{precision}f"), Value::F32(value as f32))
            } else {
                (std::format!("%{flags}.{precision}lf"), Value::F64(value))
            };
            let format = Format::parse(&spec).expect("valid");
            let mut data = [0u8; 8];
            let len = value.encode(&mut data).expect("fits");
            let mut out = Bytes(Vec::new());
            render_data_block_bytes(&mut out, &spec, &format, &data[..len]).expect("renders");
            let expected = c_printf(&spec, value);
            prop_assert_eq!(
                String::from_utf8_lossy(&out.0),
                String::from_utf8_lossy(&expected),
                "{} of {:?}", spec, value
            );
        }

        #[test]
        fn byte_arrays_equal_c_printf(
            spec in prop::sample::select(std::vec!["%hhx", "%02hhX", "%c", "%hhd", "%#hho", "<%-4hhu>"]),
            bytes in prop::collection::vec(any::<u8>(), 0..40),
        ) {
            let format = Format::parse(spec).expect("valid");
            let mut out = Bytes(Vec::new());
            render_byte_array_bytes(&mut out, spec, &format, &bytes).expect("renders");
            let expected: Vec<Vec<u8>> = bytes
                .iter()
                .map(|&b| {
                    let value = if spec.contains('d') { Value::I8(b as i8) } else { Value::U8(b) };
                    c_printf(spec, value)
                })
                .collect();
            prop_assert_eq!(out.0, expected.join(&b","[..]));
        }

        #[test]
        fn reader_survives_any_bytes(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
            let mut reader = std::boxed::Box::new(LogReader::new());
            let mut last_offset = 0u64;
            read_slice(&mut reader, &bytes, |event| {
                let offset = match event {
                    Event::Record { offset, .. } => offset,
                    Event::Problem(p) => p.offset,
                };
                assert!(offset >= last_offset, "events in file order");
                assert!(offset <= bytes.len() as u64);
                last_offset = offset;
            });
        }

        #[test]
        fn damage_never_hides_later_good_records(
            first in any::<u8>().prop_filter("not a record type", |b| {
                ![0xBD, 0xED, 0xFC, 0xFD, 0xDB, 0xBA, 0xDA].contains(b)
            }),
            rest in prop::collection::vec(any::<u8>(), 0..64),
            at in 0usize..7,
        ) {
            // Garbage between two whole records: the records after it are still read. (Garbage
            // that starts like a well-formed header is read as a record: no reader can tell.)
            let mut garbage = std::vec![first];
            garbage.extend_from_slice(&rest);
            let f = whole_file();
            let cuts = [0usize, 12, 32, 39, 69, 99, 111];
            let cut = cuts[at];
            let mut g = f[..cut].to_vec();
            g.extend_from_slice(&garbage);
            g.extend_from_slice(&f[cut..]);
            let events = read_events(&g);
            prop_assert!(events.iter().any(|e| e.ends_with("end 3.000000000")), "{:#?}", events);
            if cut <= 69 {
                prop_assert!(events.iter().any(|e| e.ends_with("data 1 2.999999999 7|-2|1.500|0.250000")), "{:#?}", events);
            }
        }
    }
}
