//! Arrow IPC inputs memory-mapped and decoded in place.
//!
//! Arrow's `FileReader` and `StreamReader` read a whole record batch into memory before
//! decoding it, so a file written as one record batch of 1e7 rows took about 1 GB. Here the
//! file is mapped and arrow-ipc's push decoders (`FileDecoder`, `StreamDecoder`) build arrays
//! that point into the mapping (zero-copy for aligned, uncompressed buffers, which is what
//! arrow-rs and pyarrow write). The reader then slices the batch into blocks, and after each
//! block tells the kernel it no longer needs the pages it touched
//! ([`Mapped::release`]), so the resident set stays at a few blocks whatever the batch size.
//!
//! Compressed record batches (LZ4, ZSTD) are still decompressed whole by the decoder: their
//! floor is the decompressed size of the batch.
//!
//! A mapped file must not be truncated by another program while it is read: the kernel then
//! ends the process with SIGBUS on the next access to a page past the new end. Files of a
//! recording being read are not expected to change under the reader.

use arrow::buffer::Buffer;
use arrow::ipc::Block;
use arrow::ipc::reader::{FileDecoder, StreamDecoder};
use arrow::record_batch::RecordBatch;
use memmap2::Mmap;
use std::ptr::NonNull;
use std::sync::Arc;

/// A read-only memory map of a whole input file.
pub(crate) struct Mapped(Arc<Mmap>);

impl Mapped {
    /// Maps `file` for reading.
    pub(crate) fn open(file: &std::fs::File) -> std::io::Result<Self> {
        // SAFETY: the mapping is read-only and shared; its contents change only if another
        // program writes the file while it is read (see the module documentation).
        let map = unsafe { Mmap::map(file)? };
        // Blocks are read front to back: read ahead.
        #[cfg(unix)]
        let _ = map.advise(memmap2::Advice::Sequential);
        Ok(Self(Arc::new(map)))
    }

    /// The whole file as an Arrow buffer that keeps the mapping alive.
    pub(crate) fn buffer(&self) -> Buffer {
        let map: Arc<dyn arrow::alloc::Allocation> = self.0.clone();
        match NonNull::new(self.0.as_ptr().cast_mut()) {
            // SAFETY: `ptr` and `len` are those of the live mapping, which `map` (the owner
            // handed to the buffer) keeps mapped as long as any array points into it.
            Some(ptr) => unsafe { Buffer::from_custom_allocation(ptr, self.0.len(), map) },
            None => Buffer::from_vec(Vec::<u8>::new()),
        }
    }

    /// Drops the mapping's pages from this process's resident set. The pages stay in the
    /// page cache, and a later access (a device column still to be written, the next block)
    /// maps them again from it: without this, every page read stays resident until the
    /// file is closed, and a one-batch file costs its size in memory.
    pub(crate) fn release(&self) {
        #[cfg(unix)]
        // SAFETY: for a shared, read-only file mapping MADV_DONTNEED only unmaps pages; the
        // next access reads the same bytes back from the file (it would zero-fill only a
        // private anonymous mapping, which this is not).
        let _ = unsafe { self.0.unchecked_advise(memmap2::UncheckedAdvice::DontNeed) };
    }
}

/// An Arrow IPC file (the file format) read through its footer.
pub(crate) struct IpcFile {
    buffer: Buffer,
    decoder: FileDecoder,
    batches: Vec<Block>,
}

/// The footer of an Arrow IPC file: schema, metadata version, dictionary and record batch
/// blocks.
pub(crate) struct Footer {
    pub(crate) schema: arrow::datatypes::SchemaRef,
    version: arrow::ipc::MetadataVersion,
    dictionaries: Vec<Block>,
    batches: Vec<Block>,
}

impl Footer {
    /// Reads the footer at the end of `buffer` (the whole file).
    pub(crate) fn read(buffer: &Buffer) -> Result<Self, String> {
        // Leading magic and padding (8), footer length (4) and trailing magic (6).
        let len = buffer.len();
        if len < 18 {
            return Err(format!(
                "the file has {len} bytes, too few for the Arrow file format (truncated?)"
            ));
        }
        let trailer: [u8; 10] = buffer[len - 10..]
            .try_into()
            .map_err(|_| "the file's last 10 bytes cannot be read".to_string())?;
        let footer_len =
            arrow::ipc::reader::read_footer_length(trailer).map_err(|e| e.to_string())?;
        let start = (len - 10)
            .checked_sub(footer_len)
            .filter(|&s| s >= 8)
            .ok_or_else(|| {
                format!("the footer length {footer_len} exceeds the file ({len} bytes): truncated")
            })?;
        let footer =
            arrow::ipc::root_as_footer(&buffer[start..len - 10]).map_err(|e| e.to_string())?;
        let schema = footer
            .schema()
            .ok_or_else(|| "the footer has no schema".to_string())?;
        let schema = arrow::ipc::convert::try_fb_to_schema(schema).map_err(|e| e.to_string())?;
        Ok(Self {
            schema: Arc::new(schema),
            version: footer.version(),
            dictionaries: footer
                .dictionaries()
                .map(|v| v.iter().copied().collect())
                .unwrap_or_default(),
            batches: footer
                .recordBatches()
                .map(|v| v.iter().copied().collect())
                .unwrap_or_default(),
        })
    }
}

impl IpcFile {
    /// Prepares the decoder of `buffer` (the whole file, whose footer is `footer`) for the
    /// columns `projection`, and reads the dictionaries.
    pub(crate) fn new(
        buffer: Buffer,
        footer: Footer,
        projection: Vec<usize>,
    ) -> Result<Self, String> {
        let mut decoder =
            FileDecoder::new(footer.schema, footer.version).with_projection(projection);
        for block in &footer.dictionaries {
            let data = block_bytes(&buffer, block)?;
            decoder
                .read_dictionary(block, &data)
                .map_err(|e| e.to_string())?;
        }
        Ok(Self {
            buffer,
            decoder,
            batches: footer.batches,
        })
    }

    /// Number of record batches.
    pub(crate) fn len(&self) -> usize {
        self.batches.len()
    }

    /// Record batch `i` (`None` past the end), its arrays pointing into the mapping.
    pub(crate) fn batch(&self, i: usize) -> Result<Option<RecordBatch>, String> {
        let Some(block) = self.batches.get(i) else {
            return Ok(None);
        };
        let data = block_bytes(&self.buffer, block)?;
        // `block_bytes` checked the metadata length against the file.
        let meta = &data[..block.metaDataLength() as usize];
        check_buffers(&frame(meta)?, block.bodyLength())?;
        match self.decoder.read_record_batch(block, &data) {
            Ok(Some(b)) => Ok(Some(b)),
            Ok(None) => Err("the block holds no record batch".into()),
            Err(e) => Err(e.to_string()),
        }
    }
}

/// The bytes of `block` (message and body), checked against the file's length first: the
/// decoders slice without checking, and a footer may point anywhere.
fn block_bytes(buffer: &Buffer, block: &Block) -> Result<Buffer, String> {
    let start = u64::try_from(block.offset()).ok();
    let len = u64::try_from(block.metaDataLength())
        .ok()
        .zip(u64::try_from(block.bodyLength()).ok())
        .and_then(|(m, b)| m.checked_add(b));
    match (start, len) {
        (Some(s), Some(l))
            if s.checked_add(l)
                .is_some_and(|end| end <= buffer.len() as u64) =>
        {
            Ok(buffer.slice_with_length(s as usize, l as usize))
        }
        _ => Err(format!(
            "the footer places a block at byte {} ({} + {} bytes), outside the file of {} bytes (truncated?)",
            block.offset(),
            block.metaDataLength(),
            block.bodyLength(),
            buffer.len()
        )),
    }
}

/// An Arrow IPC stream decoded from the mapped file, one message at a time.
///
/// The messages are framed here rather than by the decoder, so that each one is checked
/// before it is decoded (the decoder slices a body by the offsets a message declares without
/// checking them, and would panic on a damaged file), and so that the end-of-stream marker
/// is seen (the decoder does not say whether it met one or just ran out of bytes).
pub(crate) struct IpcStream {
    rest: Buffer,
    decoder: StreamDecoder,
    /// Record batches decoded and not yet handed out.
    ready: std::collections::VecDeque<RecordBatch>,
    /// The end-of-stream marker was read.
    done: bool,
}

/// How an IPC stream ends short of its end-of-stream marker.
pub(crate) enum StreamEnd {
    /// Inside a message.
    InsideMessage,
    /// After a whole message, without the marker.
    NoMarker,
}

/// A stream's problem: cut short, or a message that cannot be read.
enum Problem {
    Cut,
    Bad(String),
}

/// The prefix of a message: (metadata length, prefix length); metadata length 0 is the
/// end-of-stream marker. The continuation marker `0xFFFFFFFF` leads since Arrow 0.15; older
/// streams start with the length.
fn prefix(bytes: &[u8]) -> Result<(i32, usize), Problem> {
    let word = |at: usize| -> Option<i32> {
        let b: [u8; 4] = bytes.get(at..at + 4)?.try_into().ok()?;
        Some(i32::from_le_bytes(b))
    };
    match word(0) {
        None => Err(Problem::Cut),
        Some(-1) => word(4).map(|len| (len, 8)).ok_or(Problem::Cut),
        Some(len) => Ok((len, 4)),
    }
}

/// The message whose prefix and metadata are `bytes` (a file block's metadata part).
fn frame(bytes: &[u8]) -> Result<arrow::ipc::Message<'_>, String> {
    match frame_at(bytes, false) {
        Ok(Some((m, _))) => Ok(m),
        Ok(None) => Err("the block holds the end-of-stream marker, not a message".into()),
        Err(Problem::Cut) => Err("the block's message is cut short".into()),
        Err(Problem::Bad(e)) => Err(e),
    }
}

/// The message at the start of `bytes` and its whole length (prefix, metadata and, when
/// `with_body`, its body, which must be there too); `None` for the end-of-stream marker.
fn frame_at(
    bytes: &[u8],
    with_body: bool,
) -> Result<Option<(arrow::ipc::Message<'_>, usize)>, Problem> {
    let (len, prefix_len) = prefix(bytes)?;
    if len == 0 {
        return Ok(None);
    }
    let len = usize::try_from(len)
        .map_err(|_| Problem::Bad(format!("a message declares a negative length {len}")))?;
    let meta_len = prefix_len + len;
    let meta = bytes.get(prefix_len..meta_len).ok_or(Problem::Cut)?;
    let message = arrow::ipc::root_as_message(meta)
        .map_err(|e| Problem::Bad(format!("a message cannot be read: {e}")))?;
    let body = u64::try_from(message.bodyLength()).map_err(|_| {
        Problem::Bad(format!(
            "a message declares a negative body length {}",
            message.bodyLength()
        ))
    })?;
    let total = if with_body {
        (meta_len as u64).saturating_add(body)
    } else {
        meta_len as u64
    };
    if total > bytes.len() as u64 {
        return Err(Problem::Cut);
    }
    Ok(Some((message, total as usize)))
}

/// Refuses a record batch (or dictionary) message whose buffers lie outside its body of
/// `body_len` bytes.
fn check_buffers(message: &arrow::ipc::Message<'_>, body_len: i64) -> Result<(), String> {
    let batch = match message.header_type() {
        arrow::ipc::MessageHeader::RecordBatch => message.header_as_record_batch(),
        arrow::ipc::MessageHeader::DictionaryBatch => {
            message.header_as_dictionary_batch().and_then(|d| d.data())
        }
        _ => None,
    };
    let Some(buffers) = batch.and_then(|b| b.buffers()) else {
        return Ok(());
    };
    for (i, b) in buffers.iter().enumerate() {
        let inside = b.offset() >= 0
            && b.length() >= 0
            && b.offset()
                .checked_add(b.length())
                .is_some_and(|end| end <= body_len);
        if !inside {
            return Err(format!(
                "buffer {i} of a message ({} bytes at {}) lies outside its body of {body_len} bytes",
                b.length(),
                b.offset()
            ));
        }
    }
    Ok(())
}

impl IpcStream {
    /// Reads the schema at the start of `buffer` (the whole file).
    pub(crate) fn open(buffer: Buffer) -> Result<(Self, arrow::datatypes::SchemaRef), String> {
        // The first message is the schema. The decoder reads it too, but says so only once a
        // message follows: read it here for the caller.
        let schema = match frame_at(&buffer, true) {
            Err(Problem::Cut) | Ok(None) => {
                return Err(
                    "the file ends before the stream's schema is complete (empty or truncated)"
                        .into(),
                );
            }
            Err(Problem::Bad(e)) => return Err(e),
            Ok(Some((message, _))) => {
                let fb = message
                    .header_as_schema()
                    .ok_or("the stream does not start with a schema")?;
                Arc::new(arrow::ipc::convert::try_fb_to_schema(fb).map_err(|e| e.to_string())?)
            }
        };
        let stream = Self {
            rest: buffer,
            decoder: StreamDecoder::new(),
            ready: Default::default(),
            done: false,
        };
        Ok((stream, schema))
    }

    /// Checks the next message (or the end-of-stream marker) and hands it to the decoder.
    fn feed(&mut self) -> Result<(), Problem> {
        let (total, end) = match frame_at(&self.rest, true)? {
            Some((message, total)) => {
                check_buffers(&message, message.bodyLength()).map_err(Problem::Bad)?;
                (total, false)
            }
            None => (prefix(&self.rest)?.1, true),
        };
        let mut message = self.rest.slice_with_length(0, total);
        self.rest.advance(total);
        // A message without a body (a schema, a batch of empty buffers) is decoded only when
        // the next bytes come, so one message may give the batch before it too.
        while !message.is_empty() {
            let batch = self
                .decoder
                .decode(&mut message)
                .map_err(|e| Problem::Bad(e.to_string()))?;
            self.ready.extend(batch);
        }
        self.done = end;
        Ok(())
    }

    /// The next record batch, `Ok(None)` after the end-of-stream marker.
    pub(crate) fn next(&mut self) -> Result<Option<RecordBatch>, Result<StreamEnd, String>> {
        loop {
            if let Some(b) = self.ready.pop_front() {
                return Ok(Some(b));
            }
            if self.done {
                return Ok(None);
            }
            if self.rest.is_empty() {
                return Err(Ok(StreamEnd::NoMarker));
            }
            match self.feed() {
                Ok(()) => {}
                Err(Problem::Cut) => return Err(Ok(StreamEnd::InsideMessage)),
                Err(Problem::Bad(e)) => return Err(Err(e)),
            }
        }
    }
}
