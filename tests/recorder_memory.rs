//! The recorder's memory does not grow with the recording (issue 42, item 5): bytes kept by the
//! MCAP writer while it writes 2 000 chunks, measured by the counting allocator's live-byte
//! figure, for evoloop's writer (`report::mcap_file`) and, as the measurement's own check, for
//! mcap 0.26's `Writer`, which keeps each chunk's index until it closes the file.

use evoloop::report::mcap_file::McapWriter;
use evoloop::rt::alloc_count::{self, Counting, LIVE};
use std::sync::atomic::Ordering;

#[global_allocator]
static A: Counting = Counting;

/// A message of a two-mass cycle's size (JSON, ~300 B), so that a 64 KiB chunk holds ~200.
fn message(i: u64) -> Vec<u8> {
    format!(
        "{{\"seq\":{i},\"t\":{},\"y\":[{},{}],\"pad\":\"{}\"}}",
        i,
        i * 3,
        i * 7,
        "x".repeat(240)
    )
    .into_bytes()
}

/// Live bytes kept across writing `chunks` more chunks (after 100 to warm up), by `write`.
fn kept(mut write: impl FnMut(u64)) -> i64 {
    let per_chunk = 220;
    for i in 0..100 * per_chunk {
        write(i);
    }
    alloc_count::arm();
    let before = LIVE.load(Ordering::Relaxed);
    for i in 100 * per_chunk..2100 * per_chunk {
        write(i);
    }
    let after = LIVE.load(Ordering::Relaxed);
    alloc_count::disarm();
    after - before
}

#[test]
fn evoloops_writer_keeps_nothing_per_chunk_and_mcaps_does() {
    let dir = tempfile::tempdir().unwrap();
    let file = std::io::BufWriter::new(std::fs::File::create(dir.path().join("a.mcap")).unwrap());
    let mut w = McapWriter::new(file, "", "test", 64 << 10, dir.path()).unwrap();
    let s = w.add_schema("s", "jsonschema", b"{}").unwrap();
    let ch = w.add_channel(s, "state", "json").unwrap();
    let ours = kept(|i| w.write_message(ch, i as u32, i, i, &message(i)).unwrap());
    let summary = {
        w.finish().unwrap();
        let bytes = std::fs::read(dir.path().join("a.mcap")).unwrap();
        mcap::read::Summary::read(&bytes).unwrap().unwrap()
    };
    assert!(
        summary.chunk_indexes.len() > 2000,
        "{} chunks",
        summary.chunk_indexes.len()
    );

    let file = std::io::BufWriter::new(std::fs::File::create(dir.path().join("b.mcap")).unwrap());
    let mut m = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Lz4))
        .chunk_size(Some(64 << 10))
        .create(file)
        .unwrap();
    let s = m.add_schema("s", "jsonschema", b"{}").unwrap();
    let ch = m
        .add_channel(s, "state", "json", &Default::default())
        .unwrap();
    let theirs = kept(|i| {
        let h = mcap::records::MessageHeader {
            channel_id: ch,
            sequence: i as u32,
            log_time: i,
            publish_time: i,
        };
        m.write_to_known_channel(&h, &message(i)).unwrap()
    });
    m.finish().unwrap();
    eprintln!("bytes kept over 2 000 chunks: evoloop's writer {ours}, mcap's {theirs}");
    // mcap's keeps its chunk indexes: a few hundred bytes per chunk.
    assert!(theirs > 100 * 2000, "mcap's writer kept {theirs} bytes");
    // Ours: nothing that grows (a few KiB of buffer capacity at most).
    assert!(ours.abs() < 16 << 10, "evoloop's writer kept {ours} bytes");
}
