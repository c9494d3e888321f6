//! Shared by the targets: decode the input whole and in chunks, and require the same
//! frames and the same counters either way. The first byte picks the chunk sizes, so the
//! fuzzer explores chunkings as well as contents.

use skyframe_core::devices::Decoder;
use skyframe_core::devices::framing::{MAX_FRAME_LEN, encode_frame};

pub fn whole_and_chunked<D, F>(make: impl Fn() -> D, seed: u8, stream: &[u8]) -> Vec<F>
where
    D: Decoder<Frame = F>,
    F: PartialEq + core::fmt::Debug,
{
    let mut whole = make();
    let mut expected = Vec::new();
    whole.push(stream, 1, &mut |frame| expected.push(frame));

    let mut chunked = make();
    let mut got = Vec::new();
    let mut rest = stream;
    let mut size = usize::from(seed % 17) + 1;
    while !rest.is_empty() {
        let (chunk, tail) = rest.split_at(size.min(rest.len()));
        chunked.push(chunk, 1, &mut |frame| got.push(frame));
        rest = tail;
        // Vary the chunk size along the stream: 1..=17 bytes, driven by the seed.
        size = (size * 7 + usize::from(seed)) % 17 + 1;
    }
    assert_eq!(got, expected, "chunking changed the frames");
    assert_eq!(
        chunked.stats(),
        whole.stats(),
        "chunking changed the counters"
    );
    expected
}

/// Structure-aware input for the binary decoders: random bytes almost never carry a good
/// CRC, so half the inputs are read as a script instead. Each step takes a control byte:
/// below 0xC0 it wraps the next `payload_len` bytes in a correctly checksummed frame (and
/// below 0x80 also overwrites byte `sequenced_at` with the frame index mod 100, which lets
/// the IMU's slow record complete); otherwise the control byte's low bits say how many raw
/// bytes follow unframed.
#[allow(dead_code)] // Not every target includes binary frames.
pub fn scripted_stream(
    script: &[u8],
    frame_type: u8,
    payload_len: usize,
    sequenced_at: Option<usize>,
) -> Vec<u8> {
    let mut stream = Vec::new();
    let mut rest = script;
    let mut index = 0usize;
    while let Some((&control, tail)) = rest.split_first() {
        if control < 0xC0 {
            let take = payload_len.min(tail.len());
            let (payload, after) = tail.split_at(take);
            let mut payload = payload.to_vec();
            payload.resize(payload_len, 0);
            if let (true, Some(at)) = (control < 0x80, sequenced_at) {
                payload[at] = (index % 100) as u8;
            }
            let mut frame = [0u8; MAX_FRAME_LEN];
            if let Some(len) = encode_frame(frame_type, index as u8, &payload, &mut frame) {
                stream.extend_from_slice(&frame[..len]);
            }
            index += 1;
            rest = after;
        } else {
            let take = usize::from(control & 0x3F).min(tail.len());
            let (raw, after) = tail.split_at(take);
            stream.extend_from_slice(raw);
            rest = after;
        }
    }
    stream
}
