//! Any bytes through the streaming log reader and the printf renderer: no panic, no hang,
//! events in file order.
//!
//! The first input byte picks the chunk size the file is fed in (1..=256 bytes, or the whole
//! window), so record boundaries fall at every position of a chunk.

#![no_main]

use std::cell::RefCell;

use libfuzzer_sys::fuzz_target;
use skyframe_core::logfmt::{
    Event, Format, LogReader, Record, render_byte_array, render_data_block,
};

/// Discards text but makes the renderer produce all of it.
struct Sink(usize);

impl core::fmt::Write for Sink {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        self.0 += s.len();
        Ok(())
    }
}

thread_local! {
    // One reader for all runs (`reset` between them), as the tool reuses one across files:
    // it also exercises `reset`, and saves zeroing 300 KB per run.
    static READER: RefCell<Box<LogReader>> = RefCell::new(Box::new(LogReader::new()));
}

fuzz_target!(|input: &[u8]| {
    READER.with(|reader| run(input, &mut reader.borrow_mut()));
});

fn run(input: &[u8], reader: &mut LogReader) {
    let Some((&chunk_selector, bytes)) = input.split_first() else {
        return;
    };
    let chunk = match chunk_selector {
        0 => usize::MAX,
        n => usize::from(n),
    };

    // The input as a format string too: parsing and rendering a zeroed data block.
    if let Ok(format) = Format::parse_bytes(bytes) {
        let text = core::str::from_utf8(bytes).unwrap_or("");
        let text = text.trim_end_matches('\0');
        let zeros = vec![0u8; format.data_len()];
        render_data_block(&mut Sink(0), text, &format, &zeros).expect("a parsed format renders");
    }

    reader.reset();
    let mut texts: Vec<Option<String>> = vec![None; 256];
    let mut last_offset = 0u64;
    let mut on_event = |event: Event<'_>| {
        let offset = match event {
            Event::Record { offset, .. } => offset,
            Event::Problem(problem) => {
                assert!(problem.resume_offset >= problem.offset);
                problem.offset
            }
        };
        assert!(offset >= last_offset, "events out of file order");
        last_offset = offset;
        match event {
            Event::Record {
                record: Record::FormatDefinition { index, text, .. },
                ..
            } => {
                texts[usize::from(index)] = Some(String::from_utf8_lossy(text).into_owned());
            }
            Event::Record {
                record: Record::DataBlock { index, data, format, .. },
                ..
            } => {
                let text = texts[usize::from(index)].as_deref().expect("defined");
                render_data_block(&mut Sink(0), text, format, data).expect("renders");
            }
            Event::Record {
                record: Record::ByteArray { index, bytes, format, .. },
                ..
            } => {
                let text = texts[usize::from(index)].as_deref().expect("defined");
                render_byte_array(&mut Sink(0), text, format, bytes).expect("renders");
            }
            _ => {}
        }
    };
    let mut rest = bytes;
    loop {
        let space = reader.space();
        let count = space.len().min(rest.len()).min(chunk);
        space[..count].copy_from_slice(&rest[..count]);
        reader.commit(count);
        rest = &rest[count..];
        if rest.is_empty() {
            reader.finish();
        }
        while let Some(event) = reader.next_event() {
            on_event(event);
        }
        if rest.is_empty() {
            break;
        }
    }
    assert!(last_offset <= bytes.len() as u64);
}
