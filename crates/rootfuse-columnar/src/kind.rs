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
