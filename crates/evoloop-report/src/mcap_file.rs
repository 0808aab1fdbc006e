//! An MCAP writer whose memory stays flat however long the recording runs.
//!
//! mcap 0.26's `Writer` keeps a `ChunkIndex` (about 350 bytes with its map and string) for every
//! chunk it has written until `finish`, whether or not the summary is to carry them: a realtime
//! run recording 64 KiB chunks grew by about 1 MiB in 3 minutes (the hostile probe's reading).
//! This writer spools each chunk's index record to an unnamed temporary file beside the
//! recording and copies them into the summary at the end, so its memory is the open chunk, its
//! compressed copy and a message index per channel, all reused from chunk to chunk.
//!
//! The layout is the MCAP specification's (<https://mcap.dev/spec>): magic; Header; Schema,
//! Channel and Metadata records; LZ4-compressed Chunks, each followed by its MessageIndex records;
//! DataEnd with the data section's CRC; a summary (schemas, channels, Statistics, ChunkIndexes,
//! MetadataIndexes, SummaryOffsets); Footer with the summary's CRC; magic. `mcap`'s reader is the
//! independent check (tests below and `tests/record_mcap.rs`).

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, BufWriter, Seek, SeekFrom, Write};

/// The file's first and last bytes.
pub(crate) const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";
/// The chunks' compression (LZ4 frames).
pub(crate) const COMPRESSION: &str = "lz4";

/// Record opcodes (also the reader's, `report::recording`).
pub(crate) mod op {
    pub const HEADER: u8 = 0x01;
    pub const FOOTER: u8 = 0x02;
    pub const SCHEMA: u8 = 0x03;
    pub const CHANNEL: u8 = 0x04;
    pub const MESSAGE: u8 = 0x05;
    pub const CHUNK: u8 = 0x06;
    pub const MESSAGE_INDEX: u8 = 0x07;
    pub const CHUNK_INDEX: u8 = 0x08;
    pub const STATISTICS: u8 = 0x0B;
    pub const METADATA: u8 = 0x0C;
    pub const METADATA_INDEX: u8 = 0x0D;
    pub const SUMMARY_OFFSET: u8 = 0x0E;
    pub const DATA_END: u8 = 0x0F;
}

/// A sink that counts its bytes and keeps a running CRC-32 of them (the data section's, then
/// the summary's).
struct Counted<W: Write> {
    inner: W,
    pos: u64,
    crc: crc32fast::Hasher,
}

impl<W: Write> Write for Counted<W> {
    fn write(&mut self, b: &[u8]) -> io::Result<usize> {
        let n = self.inner.write(b)?;
        self.crc.update(&b[..n]);
        self.pos += n as u64;
        Ok(n)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

impl<W: Write> Counted<W> {
    /// The CRC so far; the next bytes start a new one.
    fn take_crc(&mut self) -> u32 {
        std::mem::take(&mut self.crc).finalize()
    }
}

/// Little-endian fields into a record body.
trait Put {
    fn u16(&mut self, v: u16);
    fn u32(&mut self, v: u32);
    fn u64(&mut self, v: u64);
    /// A string: u32 length, bytes.
    fn str(&mut self, s: &str);
    /// A string-to-string map: u32 byte length, then key and value strings.
    fn str_map(&mut self, m: &BTreeMap<String, String>);
}

impl Put for Vec<u8> {
    fn u16(&mut self, v: u16) {
        self.extend_from_slice(&v.to_le_bytes());
    }
    fn u32(&mut self, v: u32) {
        self.extend_from_slice(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.extend_from_slice(&v.to_le_bytes());
    }
    fn str(&mut self, s: &str) {
        self.u32(s.len() as u32);
        self.extend_from_slice(s.as_bytes());
    }
    fn str_map(&mut self, m: &BTreeMap<String, String>) {
        let len: usize = m.iter().map(|(k, v)| 8 + k.len() + v.len()).sum();
        self.u32(len as u32);
        for (k, v) in m {
            self.str(k);
            self.str(v);
        }
    }
}

/// Write one record: opcode, body length (u64), body.
fn record(w: &mut impl Write, opcode: u8, body: &[u8]) -> io::Result<()> {
    w.write_all(&[opcode])?;
    w.write_all(&(body.len() as u64).to_le_bytes())?;
    w.write_all(body)
}

/// A schema; its id is its place in `McapWriter::schemas` plus one.
struct Schema {
    name: String,
    encoding: String,
    data: Vec<u8>,
}

/// A channel; its id is its place in `McapWriter::channels` plus one.
struct Channel {
    schema_id: u16,
    topic: String,
    encoding: String,
}

impl Schema {
    fn body(&self, id: u16) -> Vec<u8> {
        let mut b = Vec::new();
        b.u16(id);
        b.str(&self.name);
        b.str(&self.encoding);
        b.u32(self.data.len() as u32);
        b.extend_from_slice(&self.data);
        b
    }
}

impl Channel {
    fn body(&self, id: u16) -> Vec<u8> {
        let mut b = Vec::new();
        b.u16(id);
        b.u16(self.schema_id);
        b.str(&self.topic);
        b.str(&self.encoding);
        b.str_map(&BTreeMap::new());
        b
    }
}

/// The chunk being filled: its records, their time span, and per channel the (log time,
/// offset in the chunk) of each message, for the MessageIndex records written after it.
#[derive(Default)]
struct OpenChunk {
    records: Vec<u8>,
    times: Option<(u64, u64)>,
    index: Vec<Vec<(u64, u64)>>,
    /// The compressed copy, kept for its capacity.
    compressed: Vec<u8>,
}

/// An MCAP file being written; see the module's comment. `finish` completes it; dropped
/// without, the file has its data but no summary (readers call it cut short).
pub struct McapWriter<W: Write> {
    out: Counted<W>,
    chunk: OpenChunk,
    chunk_size: usize,
    /// ChunkIndex records, spooled to an unnamed file until the summary.
    spool: BufWriter<File>,
    schemas: Vec<Schema>,
    channels: Vec<Channel>,
    /// (offset, length, name) of each Metadata record.
    metadata: Vec<(u64, u64, String)>,
    messages: Vec<u64>,
    times: Option<(u64, u64)>,
    chunks: u32,
    body: Vec<u8>,
}

impl<W: Write> McapWriter<W> {
    /// Start a file on `w` (magic and Header), with chunks of about `chunk_size` uncompressed
    /// bytes; `spool_dir` takes the unnamed file of chunk indexes (the recording's own folder:
    /// the same disk, and nothing to clean up after a crash).
    pub fn new(
        w: W,
        profile: &str,
        library: &str,
        chunk_size: usize,
        spool_dir: &std::path::Path,
    ) -> io::Result<Self> {
        let spool = BufWriter::new(tempfile::tempfile_in(spool_dir)?);
        let mut out = Counted {
            inner: w,
            pos: 0,
            crc: crc32fast::Hasher::new(),
        };
        out.write_all(MAGIC)?;
        let mut b = Vec::new();
        b.str(profile);
        b.str(library);
        record(&mut out, op::HEADER, &b)?;
        Ok(Self {
            out,
            chunk: OpenChunk {
                records: Vec::with_capacity(chunk_size + (4 << 10)),
                ..OpenChunk::default()
            },
            chunk_size,
            spool,
            schemas: Vec::new(),
            channels: Vec::new(),
            metadata: Vec::new(),
            messages: Vec::new(),
            times: None,
            chunks: 0,
            body: Vec::new(),
        })
    }

    /// A schema (ids 1..); written at once, outside any chunk.
    pub fn add_schema(&mut self, name: &str, encoding: &str, data: &[u8]) -> io::Result<u16> {
        let id = self.schemas.len() as u16 + 1;
        let s = Schema {
            name: name.into(),
            encoding: encoding.into(),
            data: data.into(),
        };
        record(&mut self.out, op::SCHEMA, &s.body(id))?;
        self.schemas.push(s);
        Ok(id)
    }

    /// A channel (ids 1..) on `schema_id`; written at once, outside any chunk.
    pub fn add_channel(&mut self, schema_id: u16, topic: &str, encoding: &str) -> io::Result<u16> {
        let id = self.channels.len() as u16 + 1;
        let c = Channel {
            schema_id,
            topic: topic.into(),
            encoding: encoding.into(),
        };
        record(&mut self.out, op::CHANNEL, &c.body(id))?;
        self.channels.push(c);
        self.messages.push(0);
        self.chunk.index.push(Vec::new());
        Ok(id)
    }

    /// A Metadata record, outside any chunk (the open one is finished first).
    pub fn write_metadata(&mut self, name: &str, map: &BTreeMap<String, String>) -> io::Result<()> {
        self.finish_chunk()?;
        let mut b = Vec::new();
        b.str(name);
        b.str_map(map);
        let at = self.out.pos;
        record(&mut self.out, op::METADATA, &b)?;
        self.metadata.push((at, self.out.pos - at, name.into()));
        Ok(())
    }

    /// One message on channel `channel` (an id `add_channel` returned). Allocation-free once
    /// the chunk's buffers have grown to their size.
    pub fn write_message(
        &mut self,
        channel: u16,
        sequence: u32,
        log_time: u64,
        publish_time: u64,
        data: &[u8],
    ) -> io::Result<()> {
        let i = usize::from(channel)
            .checked_sub(1)
            .filter(|&i| i < self.channels.len())
            .ok_or_else(|| io::Error::other(format!("no channel {channel}")))?;
        let c = &mut self.chunk;
        c.index[i].push((log_time, c.records.len() as u64));
        c.records.push(op::MESSAGE);
        c.records.u64(2 + 4 + 8 + 8 + data.len() as u64);
        c.records.u16(channel);
        c.records.u32(sequence);
        c.records.u64(log_time);
        c.records.u64(publish_time);
        c.records.extend_from_slice(data);
        c.times = Some(span(c.times, log_time));
        self.times = Some(span(self.times, log_time));
        self.messages[i] += 1;
        if c.records.len() >= self.chunk_size {
            self.finish_chunk()?;
        }
        Ok(())
    }

    /// Compress and write the open chunk, its MessageIndex records after it, and spool its
    /// ChunkIndex. Nothing to do when it is empty.
    fn finish_chunk(&mut self) -> io::Result<()> {
        let c = &mut self.chunk;
        let Some((start, end)) = c.times else {
            return Ok(());
        };
        // No LZ4 block checksums (the chunk's CRC covers the records), as mcap's own writer: the
        // mcap command-line tool's LZ4 reader (Go, pierrec/lz4 #223) rejects frames with them.
        let mut enc = lz4::EncoderBuilder::new()
            .block_checksum(lz4::liblz4::BlockChecksum::NoBlockChecksum)
            .build(std::mem::take(&mut c.compressed))?;
        enc.write_all(&c.records)?;
        let (compressed, done) = enc.finish();
        done?;
        let b = &mut self.body;
        b.clear();
        b.u64(start);
        b.u64(end);
        b.u64(c.records.len() as u64);
        b.u32(crc32fast::hash(&c.records));
        b.str(COMPRESSION);
        b.u64(compressed.len() as u64);
        let chunk_start = self.out.pos;
        self.out.write_all(&[op::CHUNK])?;
        self.out
            .write_all(&((b.len() + compressed.len()) as u64).to_le_bytes())?;
        self.out.write_all(b)?;
        self.out.write_all(&compressed)?;
        let chunk_length = self.out.pos - chunk_start;
        let mut offsets = BTreeMap::new();
        let index_start = self.out.pos;
        for (i, entries) in c.index.iter_mut().enumerate() {
            if entries.is_empty() {
                continue;
            }
            let id = i as u16 + 1;
            offsets.insert(id, self.out.pos);
            b.clear();
            b.u16(id);
            b.u32(16 * entries.len() as u32);
            for &(t, at) in entries.iter() {
                b.u64(t);
                b.u64(at);
            }
            record(&mut self.out, op::MESSAGE_INDEX, b)?;
            entries.clear();
        }
        b.clear();
        b.u64(start);
        b.u64(end);
        b.u64(chunk_start);
        b.u64(chunk_length);
        b.u32(10 * offsets.len() as u32);
        for (id, at) in offsets {
            b.u16(id);
            b.u64(at);
        }
        b.u64(self.out.pos - index_start);
        b.str(COMPRESSION);
        b.u64(compressed.len() as u64);
        b.u64(c.records.len() as u64);
        record(&mut self.spool, op::CHUNK_INDEX, b)?;
        c.compressed = compressed;
        c.compressed.clear();
        c.records.clear();
        c.times = None;
        self.chunks += 1;
        Ok(())
    }

    /// Write the last chunk, DataEnd, the summary and the Footer; return the sink, flushed.
    pub fn finish(mut self) -> io::Result<W> {
        self.finish_chunk()?;
        let data_crc = self.out.take_crc();
        record(&mut self.out, op::DATA_END, &data_crc.to_le_bytes())?;
        let summary_start = self.out.pos;
        let _ = self.out.take_crc();
        let mut groups = Vec::new();
        self.group(&mut groups, op::SCHEMA, |w| {
            for (id, s) in (1..).zip(&w.schemas) {
                record(&mut w.out, op::SCHEMA, &s.body(id))?;
            }
            Ok(())
        })?;
        self.group(&mut groups, op::CHANNEL, |w| {
            for (id, c) in (1..).zip(&w.channels) {
                record(&mut w.out, op::CHANNEL, &c.body(id))?;
            }
            Ok(())
        })?;
        self.group(&mut groups, op::STATISTICS, |w| {
            let b = w.statistics();
            record(&mut w.out, op::STATISTICS, &b)
        })?;
        self.group(&mut groups, op::CHUNK_INDEX, |w| {
            w.spool.flush()?;
            let f = w.spool.get_mut();
            f.seek(SeekFrom::Start(0))?;
            io::copy(f, &mut w.out).map(drop)
        })?;
        self.group(&mut groups, op::METADATA_INDEX, |w| {
            for (at, len, name) in &w.metadata {
                let mut b = Vec::new();
                b.u64(*at);
                b.u64(*len);
                b.str(name);
                record(&mut w.out, op::METADATA_INDEX, &b)?;
            }
            Ok(())
        })?;
        let offsets_start = self.out.pos;
        for (opcode, at, len) in groups {
            let mut b = vec![opcode];
            b.u64(at);
            b.u64(len);
            record(&mut self.out, op::SUMMARY_OFFSET, &b)?;
        }
        // The footer's CRC covers the summary and the footer up to the CRC itself.
        self.out.write_all(&[op::FOOTER])?;
        self.out.write_all(&20u64.to_le_bytes())?;
        self.out.write_all(&summary_start.to_le_bytes())?;
        self.out.write_all(&offsets_start.to_le_bytes())?;
        let summary_crc = self.out.take_crc();
        self.out.write_all(&summary_crc.to_le_bytes())?;
        self.out.write_all(MAGIC)?;
        self.out.flush()?;
        Ok(self.out.inner)
    }

    /// Write a summary group with `write` and note its (opcode, start, length) for the
    /// SummaryOffset records; an empty group is left out.
    fn group(
        &mut self,
        groups: &mut Vec<(u8, u64, u64)>,
        opcode: u8,
        write: impl FnOnce(&mut Self) -> io::Result<()>,
    ) -> io::Result<()> {
        let at = self.out.pos;
        write(self)?;
        if self.out.pos > at {
            groups.push((opcode, at, self.out.pos - at));
        }
        Ok(())
    }

    fn statistics(&self) -> Vec<u8> {
        let (start, end) = self.times.unwrap_or((0, 0));
        let mut b = Vec::new();
        b.u64(self.messages.iter().sum());
        b.u16(self.schemas.len() as u16);
        b.u32(self.channels.len() as u32);
        b.u32(0); // attachments
        b.u32(self.metadata.len() as u32);
        b.u32(self.chunks);
        b.u64(start);
        b.u64(end);
        let counts: Vec<(u16, u64)> = (1..)
            .zip(self.messages.iter().copied())
            .filter(|&(_, n)| n > 0)
            .collect();
        b.u32(10 * counts.len() as u32);
        for (id, n) in counts {
            b.u16(id);
            b.u64(n);
        }
        b
    }
}

/// `times` widened to include `t`.
fn span(times: Option<(u64, u64)>, t: u64) -> (u64, u64) {
    times.map_or((t, t), |(a, b)| (a.min(t), b.max(t)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file of `n` messages on two channels, in small chunks.
    fn file(n: u64, dir: &std::path::Path) -> Vec<u8> {
        let mut w = McapWriter::new(Vec::new(), "", "test", 1000, dir).unwrap();
        let s = w.add_schema("a", "jsonschema", b"{}").unwrap();
        let a = w.add_channel(s, "a", "json").unwrap();
        let b = w.add_channel(s, "b", "json").unwrap();
        let meta = BTreeMap::from([("k".to_string(), "v".to_string())]);
        w.write_metadata("evoloop", &meta).unwrap();
        for i in 0..n {
            let ch = if i % 3 == 0 { b } else { a };
            let text = format!("{{\"i\":{i}}}");
            w.write_message(ch, i as u32, 1000 + i, 2000 + i, text.as_bytes())
                .unwrap();
        }
        w.finish().unwrap()
    }

    /// mcap's own reader (an independent implementation of the specification) reads every
    /// message back in order, the summary's statistics and indexes agree, and the CRCs of the
    /// data section, every chunk and the summary check out.
    #[test]
    fn mcap_reads_back_every_message_with_summary_indexes_and_crcs() {
        let dir = tempfile::tempdir().unwrap();
        let bytes = file(500, dir.path());
        let summary = mcap::read::Summary::read(&bytes).unwrap().unwrap();
        let stats = summary.stats.as_ref().unwrap();
        assert_eq!(stats.message_count, 500);
        assert_eq!(stats.channel_message_counts[&1], 333);
        assert_eq!(stats.channel_message_counts[&2], 167);
        assert_eq!(
            (stats.message_start_time, stats.message_end_time),
            (1000, 1499)
        );
        assert!(stats.chunk_count > 5, "{} chunks", stats.chunk_count);
        assert_eq!(summary.chunk_indexes.len(), stats.chunk_count as usize);
        assert_eq!(summary.channels.len(), 2);
        let m = mcap::read::metadata(&bytes, &summary.metadata_indexes[0]).unwrap();
        assert_eq!(m.metadata["k"], "v");
        let mut i = 0;
        for msg in mcap::MessageStream::new(&bytes).unwrap() {
            let msg = msg.unwrap();
            assert_eq!(msg.log_time, 1000 + i);
            assert_eq!(msg.publish_time, 2000 + i);
            assert_eq!(msg.sequence as u64, i);
            assert_eq!(msg.data.as_ref(), format!("{{\"i\":{i}}}").as_bytes());
            assert_eq!(msg.channel.topic, if i % 3 == 0 { "b" } else { "a" });
            i += 1;
        }
        assert_eq!(i, 500);
        // Through the chunk indexes and message indexes, as a seeking viewer reads.
        let mut seen = 0;
        for ci in &summary.chunk_indexes {
            let idx = summary.read_message_indexes(&bytes, ci).unwrap();
            let entries: usize = idx.values().map(|v| v.len()).sum();
            for (_, entries) in idx {
                for e in entries {
                    let msg = summary.seek_message(&bytes, ci, &e).unwrap();
                    assert_eq!(msg.log_time, e.log_time);
                }
            }
            seen += entries;
        }
        assert_eq!(seen, 500);
        assert_eq!(validated_messages(&bytes), Ok(500));
    }

    /// The messages mcap's linear reader finds with the CRCs of the data section, every chunk
    /// and the summary all checked (it fails on a mismatch).
    fn validated_messages(bytes: &[u8]) -> Result<usize, String> {
        use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
        use std::io::Read;
        let mut reader = LinearReader::new_with_options(
            LinearReaderOptions::default()
                .with_validate_chunk_crcs(true)
                .with_validate_data_section_crc(true)
                .with_validate_summary_section_crc(true),
        );
        let mut cursor = std::io::Cursor::new(bytes);
        let mut n = 0;
        while let Some(event) = reader.next_event() {
            match event.map_err(|e| e.to_string())? {
                LinearReadEvent::ReadRequest(k) => {
                    let got = cursor.read(reader.insert(k)).unwrap();
                    reader.notify_read(got);
                }
                LinearReadEvent::Record { opcode, .. } => n += usize::from(opcode == op::MESSAGE),
            }
        }
        Ok(n)
    }

    /// The validation above can fail: a changed letter that still parses, in the data section
    /// (the metadata's value) and in the summary (its copy of the schema's encoding), is caught
    /// by the data section's and the summary's CRC.
    #[test]
    fn changed_bytes_fail_the_crc_checks() {
        let dir = tempfile::tempdir().unwrap();
        let bytes = file(50, dir.path());
        let find = |what: &[u8], nth: usize| {
            bytes
                .windows(what.len())
                .enumerate()
                .filter(|(_, w)| *w == what)
                .nth(nth)
                .map(|(i, _)| i + what.len() - 1)
                .unwrap()
        };
        for at in [find(b"\x01\0\0\0v", 0), find(b"jsonschema", 1)] {
            let mut bad = bytes.clone();
            bad[at] ^= 0x01;
            let e = validated_messages(&bad).unwrap_err();
            assert!(e.to_lowercase().contains("crc"), "byte {at}: {e}");
        }
    }

    /// An empty recording (a run stopped before its first cycle) is still a whole file.
    #[test]
    fn an_empty_recording_is_a_whole_file() {
        let dir = tempfile::tempdir().unwrap();
        let bytes = file(0, dir.path());
        let summary = mcap::read::Summary::read(&bytes).unwrap().unwrap();
        assert_eq!(summary.stats.unwrap().message_count, 0);
        assert_eq!(mcap::MessageStream::new(&bytes).unwrap().count(), 0);
    }
}
