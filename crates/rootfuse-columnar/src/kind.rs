//! Which decoder an input needs, told by its first bytes rather than its name: `.arrow` is
//! used for both Arrow IPC formats (pyarrow's `ipc.new_stream` writes the stream format
//! under any name).

use crate::Format;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

/// The magic that opens an Arrow IPC file (the file format; the stream format has none).
const ARROW_FILE_MAGIC: &[u8; 6] = b"ARROW1";
/// The magic that opens a Parquet file.
const PARQUET_MAGIC: &[u8; 4] = b"PAR1";

/// The decoder for a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    Parquet,
    /// Arrow IPC file format: footer with the record batch count, random access.
    IpcFile,
    /// Arrow IPC stream format: messages one after the other, ended by a marker.
    IpcStream,
}

/// Tells `file`'s kind by its magic (Parquet, Arrow IPC file); without either, an Arrow name
/// (`.arrow`, `.arrows`, ...) is read as an IPC stream and anything else as Parquet, whose
/// decoder then names what is wrong. Leaves `file` at its start.
pub(crate) fn detect(path: &Path, file: &mut std::fs::File) -> std::io::Result<Kind> {
    let mut head = Vec::with_capacity(ARROW_FILE_MAGIC.len());
    file.by_ref()
        .take(ARROW_FILE_MAGIC.len() as u64)
        .read_to_end(&mut head)?;
    file.seek(SeekFrom::Start(0))?;
    Ok(if head.starts_with(ARROW_FILE_MAGIC) {
        Kind::IpcFile
    } else if head.starts_with(PARQUET_MAGIC) {
        Kind::Parquet
    } else if Format::of_path(path) == Some(Format::Arrow) {
        Kind::IpcStream
    } else {
        Kind::Parquet
    })
}

/// A reader that notes when it reaches the end of its input. The IPC stream decoder takes
/// an end of file between messages as the end of the stream; a stream written to the end
/// has an end-of-stream marker instead, so reaching the end of the file means the stream
/// was cut off after its last whole message.
pub(crate) struct EndAware<R> {
    inner: R,
    reached_end: bool,
}

impl<R> EndAware<R> {
    pub(crate) fn new(inner: R) -> Self {
        Self {
            inner,
            reached_end: false,
        }
    }

    /// True once a read found no more bytes.
    pub(crate) fn reached_end(&self) -> bool {
        self.reached_end
    }
}

impl<R: Read> Read for EndAware<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        if n == 0 && !buf.is_empty() {
            self.reached_end = true;
        }
        Ok(n)
    }
}
