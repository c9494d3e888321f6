//! A text log and the conversion of the equivalent binary log are identical
//! (`log-format.md`): the same records go into a binary stream and a text stream; the binary
//! one goes through `skyframe-log to-csv`; the CSV files must match byte for byte.

use skyframe_core::logfmt::printf::Value;
use skyframe_core::logfmt::record::{
    LogFormat, encode_begin_data, encode_byte_array, encode_data_block, encode_end_data,
};
use skyframe_shell::logwriter::{LogWriter, StreamMode, WriterConfig};
use skyframe_tests::{scratch, to_csv};

#[test]
fn text_log_equals_the_conversion_of_the_binary_log() {
    let dir = scratch("text-logs");
    let mut writer = LogWriter::new(WriterConfig::new(dir.join("flight")));
    let mut binary_stream = writer.stream_as("twin_bin", 1 << 20, StreamMode::Binary);
    let mut text_stream = writer.stream_as("twin_txt", 1 << 20, StreamMode::Text);
    let handle = writer.start().expect("writer");

    let mut records: Vec<Vec<u8>> = Vec::new();
    let mut buf = [0u8; 1024];
    let push = |n: usize, buf: &[u8], records: &mut Vec<Vec<u8>>| records.push(buf[..n].to_vec());
    let imu = LogFormat::new(
        "%hhu,%.4f,%.4f,%e,%g,%+08.3lf,%hhu",
        "counter,p_rad_s,q_rad_s,r_rad_s,fx_m_s2,alt_m,status",
    );
    let n = imu.encode_declaration(&mut buf, 1).expect("declares");
    push(n, &buf, &mut records);
    let n = encode_begin_data(&mut buf, 1_795_000_000_000_000_000).expect("begin");
    push(n, &buf, &mut records);
    let parsed = imu.parse().expect("format");
    for i in 0..200u32 {
        let values = [
            Value::U8(i as u8),
            Value::F32(0.001 * i as f32),
            Value::F32(-1.5e-3 * i as f32),
            Value::F32(1e-7 * i as f32),
            Value::F32(123456.0 / (i + 1) as f32),
            Value::F64(-99.125 + f64::from(i)),
            Value::U8((i % 3) as u8),
        ];
        let n = encode_data_block(
            &mut buf,
            1,
            1_795_000_000_000_000_000 + u64::from(i) * 10_000_000,
            &parsed,
            &values,
        )
        .expect("encodes");
        push(n, &buf, &mut records);
    }
    // A redefinition: new header lines from here on, in both.
    let raw = LogFormat::new("%hhx", "raw_hex");
    let n = raw.encode_declaration(&mut buf, 2).expect("declares");
    push(n, &buf, &mut records);
    let n = encode_byte_array(
        &mut buf,
        2,
        1_795_000_002_000_000_000,
        &[0x00, 0x7f, 0x80, 0xff],
    )
    .expect("array");
    push(n, &buf, &mut records);
    let again = LogFormat::new("%u;%c", "count,letter");
    let n = again.encode_declaration(&mut buf, 1).expect("declares");
    push(n, &buf, &mut records);
    let parsed = again.parse().expect("format");
    for (i, c) in [b'a', b',', 0xe9].into_iter().enumerate() {
        let n = encode_data_block(
            &mut buf,
            1,
            1_795_000_003_000_000_000 + i as u64,
            &parsed,
            &[Value::U32(i as u32), Value::U8(c)],
        )
        .expect("encodes");
        push(n, &buf, &mut records);
    }
    let n = encode_end_data(&mut buf, 1_795_000_004_000_000_000).expect("end");
    push(n, &buf, &mut records);

    for r in &records {
        assert!(binary_stream.push_record(r));
        assert!(text_stream.push_record(r));
    }
    handle.finish();

    let converted = to_csv(&[dir.join("flight/twin_bin.bin")], &dir.join("converted"));
    for index in [1, 2] {
        let from_binary =
            std::fs::read(converted.join(format!("twin_bin.{index}.csv"))).expect("converted csv");
        let direct =
            std::fs::read(dir.join(format!("flight/twin_txt.{index}.csv"))).expect("text csv");
        assert_eq!(
            String::from_utf8_lossy(&direct),
            String::from_utf8_lossy(&from_binary),
            "format {index}"
        );
        assert_eq!(direct, from_binary, "byte for byte, format {index}");
    }
    assert!(
        !dir.join("flight/twin_txt.bin").exists(),
        "a text stream writes no binary"
    );
}
