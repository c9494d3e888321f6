//! Shared by the targets: decode the input whole and in chunks, and require the same
//! frames and the same counters either way. The first byte picks the chunk sizes, so the
//! fuzzer explores chunkings as well as contents.

use skyframe_core::devices::Decoder;

pub fn whole_and_chunked<D, F>(make: impl Fn() -> D, data: &[u8]) -> Vec<F>
where
    D: Decoder<Frame = F>,
    F: PartialEq + core::fmt::Debug,
{
    let Some((&seed, stream)) = data.split_first() else {
        return Vec::new();
    };
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
