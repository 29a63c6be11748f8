//! MCAP files read as a stream, record by record, trusting no size the file declares.
//!
//! The format (the MCAP specification, <https://mcap.dev/spec>): 8 magic bytes, then records
//! of a 1-byte opcode, a `u64` length and that many bytes, up to a Footer and the magic again.
//! Messages are either top-level records or inside Chunk records (compressed with zstd or lz4,
//! or not), each with the CRC-32 of its uncompressed records. A Data End record carries the
//! CRC-32 of the data section before it, the Footer that of the summary section.
//!
//! Every length is checked before anything is allocated from it:
//! * a record's length against the bytes left in the file (when its size is known: an
//!   uncompressed file) and against [`MAX_RECORD_BYTES`];
//! * a compressed chunk's declared uncompressed size against [`MAX_DECOMPRESSED_BYTES`], and
//!   its decompression stops after one byte more than it declared;
//! * a record inside a chunk against the bytes left in the chunk;
//! * a string or a schema's data against the bytes left in its record;
//! * schema and channel records kept for the whole file against [`MAX_DEFINITION_BYTES`],
//!   topic and type names against [`MAX_NAME_BYTES`].
//!
//! So memory follows what the file really holds (the largest record, or the largest chunk
//! decompressed, plus one message), never what it claims. CRCs that are not zero (zero means
//! "not computed", per the specification) are checked: a chunk's before any of its messages is
//! handed on, the data section's at the Data End record, the summary's at the Footer.
//!
//! The `mcap` crate is used only for its types ([`mcap::Channel`], [`mcap::Schema`]): its
//! reader allocates buffers of the size a record declares before reading it, decompresses
//! records of a chunk into a buffer sized from their declared lengths and checks chunk CRCs
//! only when asked.

use std::borrow::Cow;
use std::collections::{BTreeMap, HashMap};
use std::io::{self, Read};
use std::sync::Arc;

use crate::bag::{MAX_DECOMPRESSED_BYTES, MAX_DEFINITION_BYTES, MAX_NAME_BYTES, MAX_RECORD_BYTES};

const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

const HEADER: u8 = 0x01;
const FOOTER: u8 = 0x02;
const SCHEMA: u8 = 0x03;
const CHANNEL: u8 = 0x04;
const MESSAGE: u8 = 0x05;
const CHUNK: u8 = 0x06;
const DATA_END: u8 = 0x0F;

/// What a record is, for errors.
fn kind(opcode: u8) -> String {
    match opcode {
        HEADER => "header".into(),
        FOOTER => "footer".into(),
        SCHEMA => "schema".into(),
        CHANNEL => "channel".into(),
        MESSAGE => "message".into(),
        CHUNK => "chunk".into(),
        0x07 => "message index".into(),
        0x08 => "chunk index".into(),
        0x09 => "attachment".into(),
        0x0A => "attachment index".into(),
        0x0B => "statistics".into(),
        0x0C => "metadata".into(),
        0x0D => "metadata index".into(),
        0x0E => "summary offset".into(),
        DATA_END => "data end".into(),
        other => format!("opcode 0x{other:02x}"),
    }
}

/// A problem at a byte of the file: `(offset, what)`. The caller adds the file and the last
/// good message.
type Problem = (u64, String);

/// The bytes of a file, counted and hashed as they are read.
struct Stream<'r> {
    source: &'r mut dyn Read,
    /// Bytes read so far.
    pos: u64,
    /// The size of the file, when known (an uncompressed file).
    len: Option<u64>,
    /// CRC-32 of the data section (magic included), until the Data End record.
    data: Option<crc32fast::Hasher>,
    /// CRC-32 of the summary section, from the Data End record on.
    summary: Option<crc32fast::Hasher>,
}

impl Stream<'_> {
    fn hash(&mut self, bytes: &[u8]) {
        for hasher in [&mut self.data, &mut self.summary].into_iter().flatten() {
            hasher.update(bytes);
        }
    }

    /// Exactly `n` bytes, read into a buffer that grows with what arrives (not from `n`).
    fn take(&mut self, n: u64) -> io::Result<Vec<u8>> {
        let mut out = Vec::new();
        (&mut *self.source).take(n).read_to_end(&mut out)?;
        self.hash(&out);
        self.pos += out.len() as u64;
        if (out.len() as u64) < n {
            return Err(io::ErrorKind::UnexpectedEof.into());
        }
        Ok(out)
    }

    /// Skips `n` bytes (hashing them) in constant memory.
    fn skip(&mut self, n: u64) -> io::Result<()> {
        let mut buf = vec![0u8; 1 << 16];
        let mut left = n;
        while left > 0 {
            let want = buf.len().min(usize::try_from(left).unwrap_or(usize::MAX));
            let got = match self.source.read(&mut buf[..want]) {
                Ok(0) => return Err(io::ErrorKind::UnexpectedEof.into()),
                Ok(got) => got,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            };
            self.hash(&buf[..got]);
            self.pos += got as u64;
            left -= got as u64;
        }
        Ok(())
    }

    /// The opcode and length that start the next record (not hashed yet: the data section's
    /// CRC ends before the Data End record); `None` at the very end of the file.
    fn head(&mut self) -> io::Result<Option<[u8; 9]>> {
        let mut head = [0u8; 9];
        let mut got = 0;
        while got < head.len() {
            match self.source.read(&mut head[got..]) {
                Ok(0) => break,
                Ok(n) => got += n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        self.pos += got as u64;
        match got {
            0 => Ok(None),
            9 => Ok(Some(head)),
            _ => Err(io::ErrorKind::UnexpectedEof.into()),
        }
    }
}

/// A little-endian reader over one record's bytes that never reads past them.
struct Fields<'a, 'w> {
    data: &'a [u8],
    pos: usize,
    /// "the schema record at byte 120", for errors.
    what: &'w str,
}

impl<'a> Fields<'a, '_> {
    fn bytes(&mut self, n: usize, field: &str) -> Result<&'a [u8], String> {
        let left = self.data.len() - self.pos;
        if n > left {
            return Err(format!(
                "{}: {field} declares {n} bytes, but only {left} remain in the record",
                self.what
            ));
        }
        let out = &self.data[self.pos..self.pos + n];
        self.pos += n;
        Ok(out)
    }

    fn u16(&mut self, field: &str) -> Result<u16, String> {
        Ok(u16::from_le_bytes(
            self.bytes(2, field)?.try_into().expect("2"),
        ))
    }

    fn u32(&mut self, field: &str) -> Result<u32, String> {
        Ok(u32::from_le_bytes(
            self.bytes(4, field)?.try_into().expect("4"),
        ))
    }

    fn u64(&mut self, field: &str) -> Result<u64, String> {
        Ok(u64::from_le_bytes(
            self.bytes(8, field)?.try_into().expect("8"),
        ))
    }

    /// A `u32`-prefixed byte string.
    fn prefixed(&mut self, field: &str) -> Result<&'a [u8], String> {
        let len = self.u32(field)?;
        self.bytes(len as usize, field)
    }

    /// A `u32`-prefixed UTF-8 string of at most `max` bytes.
    fn string(&mut self, field: &str, max: usize) -> Result<String, String> {
        let bytes = self.prefixed(field)?;
        if bytes.len() > max {
            return Err(format!(
                "{}: the {field} has {} bytes, more than the {max} a name may have",
                self.what,
                bytes.len()
            ));
        }
        String::from_utf8(bytes.to_vec())
            .map_err(|_| format!("{}: the {field} is not UTF-8", self.what))
    }

    fn rest(&mut self) -> &'a [u8] {
        let out = &self.data[self.pos..];
        self.pos = self.data.len();
        out
    }
}

/// The schemas and channels of one file, as its records define them.
#[derive(Default)]
struct Definitions {
    schemas: HashMap<u16, Arc<mcap::Schema<'static>>>,
    channels: HashMap<u16, Arc<mcap::Channel<'static>>>,
    /// Bytes of the distinct schema and channel records kept.
    bytes: usize,
}

impl Definitions {
    fn keep(&mut self, n: usize, what: &str) -> Result<(), String> {
        self.bytes = self.bytes.saturating_add(n);
        if self.bytes > MAX_DEFINITION_BYTES {
            return Err(format!(
                "{what}: the schema and channel records of the file exceed \
                 {MAX_DEFINITION_BYTES} bytes"
            ));
        }
        Ok(())
    }

    fn schema(&mut self, data: &[u8], what: &str) -> Result<(), String> {
        let mut f = Fields { data, pos: 0, what };
        let id = f.u16("schema id")?;
        let name = f.string("schema name", MAX_NAME_BYTES)?;
        let encoding = f.string("schema encoding", MAX_NAME_BYTES)?;
        let text = f.prefixed("schema data")?;
        if id == 0 {
            return Err(format!("{what}: schema id 0 is reserved (no schema)"));
        }
        let schema = mcap::Schema {
            id,
            name,
            encoding,
            data: text.to_vec().into(),
        };
        match self.schemas.get(&id) {
            Some(known) if **known == schema => Ok(()),
            Some(_) => Err(format!("{what}: schema {id} is defined twice, differently")),
            None => {
                self.keep(data.len(), what)?;
                self.schemas.insert(id, Arc::new(schema));
                Ok(())
            }
        }
    }

    fn channel(&mut self, data: &[u8], what: &str) -> Result<(), String> {
        let mut f = Fields { data, pos: 0, what };
        let id = f.u16("channel id")?;
        let schema_id = f.u16("schema id")?;
        let topic = f.string("topic name", MAX_NAME_BYTES)?;
        let message_encoding = f.string("message encoding", MAX_NAME_BYTES)?;
        let map = f.prefixed("metadata")?;
        let mut metadata = BTreeMap::new();
        let mut m = Fields {
            data: map,
            pos: 0,
            what,
        };
        while m.pos < map.len() {
            let key = m.string("metadata key", usize::MAX)?;
            let value = m.string("metadata value", usize::MAX)?;
            metadata.insert(key, value);
        }
        let schema = match schema_id {
            0 => None,
            s => Some(self.schemas.get(&s).cloned().ok_or_else(|| {
                format!("{what}: channel {id} ({topic}) names schema {s}, which is not defined before it")
            })?),
        };
        let channel = mcap::Channel {
            id,
            topic,
            schema,
            message_encoding,
            metadata,
        };
        match self.channels.get(&id) {
            Some(known) if **known == channel => Ok(()),
            Some(_) => Err(format!(
                "{what}: channel {id} is defined twice, differently"
            )),
            None => {
                self.keep(data.len(), what)?;
                self.channels.insert(id, Arc::new(channel));
                Ok(())
            }
        }
    }
}

/// A message record: `(channel, log time, publish time, data)`.
type Message = (Arc<mcap::Channel<'static>>, u64, u64, Vec<u8>);

fn message(defs: &Definitions, data: &[u8], what: &str) -> Result<Message, String> {
    let mut f = Fields { data, pos: 0, what };
    let channel_id = f.u16("channel id")?;
    let _sequence = f.u32("sequence")?;
    let log_time = f.u64("log time")?;
    let publish_time = f.u64("publish time")?;
    let channel = defs.channels.get(&channel_id).cloned().ok_or_else(|| {
        format!("{what}: the message is on channel {channel_id}, which is not defined before it")
    })?;
    Ok((channel, log_time, publish_time, f.rest().to_vec()))
}

/// The records of a chunk, decompressed and checked against its CRC.
fn chunk_records<'d>(body: &'d [u8], what: &str) -> Result<Cow<'d, [u8]>, String> {
    let mut f = Fields {
        data: body,
        pos: 0,
        what,
    };
    let _start = f.u64("message start time")?;
    let _end = f.u64("message end time")?;
    let declared = f.u64("uncompressed size")?;
    let crc = f.u32("uncompressed CRC")?;
    let compression = f.string("compression", MAX_NAME_BYTES)?;
    let compressed_len = f.u64("compressed size")?;
    let compressed = f.bytes(
        usize::try_from(compressed_len).unwrap_or(usize::MAX),
        "compressed size",
    )?;
    let records: Cow<'_, [u8]> = match compression.as_str() {
        "" => {
            if declared != compressed_len {
                return Err(format!(
                    "{what}: an uncompressed chunk of {compressed_len} bytes declares {declared} \
                     bytes uncompressed"
                ));
            }
            compressed.into()
        }
        "zstd" | "lz4" => {
            if declared > MAX_DECOMPRESSED_BYTES as u64 {
                return Err(format!(
                    "{what}: the chunk declares {declared} bytes uncompressed, more than the \
                     {MAX_DECOMPRESSED_BYTES} a compressed chunk may have"
                ));
            }
            let decoder: Box<dyn Read + '_> = if compression == "zstd" {
                Box::new(
                    zstd::stream::read::Decoder::with_buffer(compressed)
                        .map_err(|e| format!("{what}: zstd: {e}"))?,
                )
            } else {
                Box::new(lz4::Decoder::new(compressed).map_err(|e| format!("{what}: lz4: {e}"))?)
            };
            // One byte more than declared tells a chunk that decompresses to more.
            let mut out = Vec::new();
            decoder
                .take(declared + 1)
                .read_to_end(&mut out)
                .map_err(|e| format!("{what}: {compression}: {e} (the chunk is damaged)"))?;
            if out.len() as u64 > declared {
                return Err(format!(
                    "{what}: the chunk declares {declared} bytes uncompressed, but decompresses \
                     to more"
                ));
            }
            if (out.len() as u64) < declared {
                return Err(format!(
                    "{what}: the chunk declares {declared} bytes uncompressed, but decompresses \
                     to {}",
                    out.len()
                ));
            }
            out.into()
        }
        other => {
            return Err(format!(
                "{what}: chunk compression `{other}` is not supported (zstd and lz4 are)"
            ));
        }
    };
    if crc != 0 {
        let computed = crc32fast::hash(&records);
        if computed != crc {
            return Err(format!(
                "{what}: the CRC of the chunk's records is {computed:08x}, but the chunk says \
                 {crc:08x}: the chunk is damaged"
            ));
        }
    }
    Ok(records)
}

/// The schema, channel and message records of a chunk's (decompressed, checked) records.
fn read_chunk<E>(
    defs: &mut Definitions,
    records: &[u8],
    at: u64,
    chunk: &str,
    each: &mut dyn FnMut(Message) -> Result<(), E>,
) -> Result<(), Result<E, Problem>> {
    let mut pos = 0usize;
    while pos < records.len() {
        let left = records.len() - pos;
        if left < 9 {
            return Err(Err((
                at,
                format!("{chunk}: {left} bytes at its end are too few for a record"),
            )));
        }
        let opcode = records[pos];
        let length = u64::from_le_bytes(records[pos + 1..pos + 9].try_into().expect("8"));
        let what = format!(
            "{chunk}: the {} record at byte {pos} of its records",
            kind(opcode)
        );
        let rest = (left - 9) as u64;
        if length > rest {
            return Err(Err((
                at,
                format!("{what} declares {length} bytes, but only {rest} remain in the chunk"),
            )));
        }
        let body = &records[pos + 9..pos + 9 + length as usize];
        pos += 9 + length as usize;
        match opcode {
            SCHEMA => defs.schema(body, &what).map_err(|p| Err((at, p)))?,
            CHANNEL => defs.channel(body, &what).map_err(|p| Err((at, p)))?,
            MESSAGE => each(message(defs, body, &what).map_err(|p| Err((at, p)))?).map_err(Ok)?,
            // Other records do not belong in a chunk; the specification says to skip what a
            // reader does not know.
            _ => {}
        }
    }
    Ok(())
}

/// Reads every message of an MCAP stream in file order, calling `each` with it.
///
/// `len` is the size of the stream if known (an uncompressed file): a record longer than what
/// remains is refused before it is read. A problem is returned as `Err(Err((offset, what)))`;
/// an error of `each` as `Err(Ok(e))`.
pub(crate) fn read_messages<E>(
    source: &mut dyn Read,
    len: Option<u64>,
    each: &mut dyn FnMut(Message) -> Result<(), E>,
) -> Result<(), Result<E, Problem>> {
    let mut s = Stream {
        source,
        pos: 0,
        len,
        data: Some(crc32fast::Hasher::new()),
        summary: None,
    };
    let problem = |at: u64, what: String| Err((at, what));
    let truncated = |e: io::Error| -> String {
        if e.kind() == io::ErrorKind::UnexpectedEof {
            TRUNCATED.into()
        } else {
            e.to_string()
        }
    };
    match s.take(8) {
        Ok(magic) if magic == MAGIC => {}
        Ok(_) => return Err(problem(0, NOT_MCAP.into())),
        Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => {
            return Err(problem(0, NOT_MCAP.into()));
        }
        Err(e) => return Err(problem(0, e.to_string())),
    }
    let mut defs = Definitions::default();
    loop {
        let at = s.pos;
        let Some(head) = s.head().map_err(|e| problem(at, truncated(e)))? else {
            return Err(problem(
                at,
                format!("the file ends without a footer: {TRUNCATED}"),
            ));
        };
        let opcode = head[0];
        let length = u64::from_le_bytes(head[1..].try_into().expect("8"));
        let what = format!("the {} record at byte {at}", kind(opcode));
        if let Some(total) = s.len {
            let remaining = total.saturating_sub(s.pos);
            if length > remaining {
                return Err(problem(
                    at,
                    format!(
                        "{what} declares {length} bytes, but only {remaining} remain in the \
                         file: it is truncated or damaged"
                    ),
                ));
            }
        }
        // A file whose size is known holds what its records declare; a decompressed stream
        // may not, so its records are held to the limit of what decompression may produce.
        let cap = if s.len.is_some() {
            MAX_RECORD_BYTES
        } else {
            MAX_DECOMPRESSED_BYTES
        };
        if length > cap as u64 {
            return Err(problem(
                at,
                format!("{what} declares {length} bytes, more than the {cap} a record may have"),
            ));
        }
        if opcode == DATA_END {
            let computed = s.data.take().map(crc32fast::Hasher::finalize);
            s.hash(&head);
            let body = s.take(length).map_err(|e| problem(at, truncated(e)))?;
            let mut f = Fields {
                data: &body,
                pos: 0,
                what: &what,
            };
            let saved = f.u32("data section CRC").map_err(|p| problem(at, p))?;
            if let Some(computed) = computed
                && saved != 0
                && computed != saved
            {
                return Err(problem(
                    at,
                    format!(
                        "{what}: the CRC of the data section is {computed:08x}, but the file \
                         says {saved:08x}: the file is damaged"
                    ),
                ));
            }
            s.summary = Some(crc32fast::Hasher::new());
            continue;
        }
        s.hash(&head);
        match opcode {
            FOOTER => {
                // The summary's CRC runs up to the footer's CRC field (its opcode and length are
                // hashed already).
                let summary = s.summary.take();
                let body = s.take(length).map_err(|e| problem(at, truncated(e)))?;
                let mut f = Fields {
                    data: &body,
                    pos: 0,
                    what: &what,
                };
                let _summary_start = f.u64("summary start").map_err(|p| problem(at, p))?;
                let _offsets = f.u64("summary offset start").map_err(|p| problem(at, p))?;
                let saved = f.u32("summary CRC").map_err(|p| problem(at, p))?;
                if let Some(mut hasher) = summary
                    && saved != 0
                {
                    hasher.update(&body[..16]);
                    let computed = hasher.finalize();
                    if computed != saved {
                        return Err(problem(
                            at,
                            format!(
                                "{what}: the CRC of the summary section is {computed:08x}, but \
                                 the footer says {saved:08x}: the file is damaged"
                            ),
                        ));
                    }
                }
                let end = s.pos;
                match s.take(8) {
                    Ok(magic) if magic == MAGIC => return Ok(()),
                    Ok(_) => {
                        return Err(problem(end, "no MCAP magic bytes after the footer".into()));
                    }
                    Err(e) => return Err(problem(end, truncated(e))),
                }
            }
            // The summary section repeats the schemas and channels: skipped, but hashed.
            SCHEMA | CHANNEL | MESSAGE | CHUNK if s.summary.is_none() => {
                let body = s.take(length).map_err(|e| problem(at, truncated(e)))?;
                match opcode {
                    SCHEMA => defs.schema(&body, &what).map_err(|p| problem(at, p))?,
                    CHANNEL => defs.channel(&body, &what).map_err(|p| problem(at, p))?,
                    MESSAGE => {
                        each(message(&defs, &body, &what).map_err(|p| problem(at, p))?)
                            .map_err(Ok)?;
                    }
                    _ => match chunk_records(&body, &what).map_err(|p| problem(at, p))? {
                        Cow::Borrowed(records) => read_chunk(&mut defs, records, at, &what, each)?,
                        Cow::Owned(records) => {
                            drop(body);
                            read_chunk(&mut defs, &records, at, &what, each)?;
                        }
                    },
                }
            }
            _ => s.skip(length).map_err(|e| problem(at, truncated(e)))?,
        }
    }
}

const TRUNCATED: &str = "the file ends in the middle of a record: it is truncated (was the \
     recorder killed? `ros2 bag reindex` or `mcap recover` can save what is intact)";

const NOT_MCAP: &str = "not an MCAP file (no MCAP magic bytes at its start)";
