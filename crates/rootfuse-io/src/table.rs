//! The CSV layer under every reader: the encoding checked, the delimiter found from the header
//! (comma, semicolon or tab; a decimal comma where the delimiter is not a comma), rows with
//! their 1-based file lines, cells parsed as numbers with empty cells told apart.

use crate::error::{Place, ReadError};
use std::borrow::ToOwned;
use std::format;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::string::String;
use std::vec::Vec;

/// How a CSV file is written: found from its header line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dialect {
    /// The field delimiter: `,`, `;` or a tab.
    pub delimiter: u8,
    /// Numbers may use a decimal comma (`0,25`): only where the delimiter is not a comma, as
    /// spreadsheets in many locales write with `;` or a tab.
    pub decimal_comma: bool,
}

impl Dialect {
    /// The delimiter a header line uses: whichever of comma, semicolon and tab it has most of
    /// (a comma when it has none, a one-column file).
    pub fn of_header(line: &[u8]) -> Self {
        let count = |c: u8| line.iter().filter(|&&b| b == c).count();
        let (comma, semicolon, tab) = (count(b','), count(b';'), count(b'\t'));
        let delimiter = if semicolon > comma && semicolon >= tab {
            b';'
        } else if tab > comma && tab > semicolon {
            b'\t'
        } else {
            b','
        };
        Self {
            delimiter,
            decimal_comma: delimiter != b',',
        }
    }

    /// The delimiter's name, for messages.
    pub fn delimiter_name(self) -> &'static str {
        match self.delimiter {
            b';' => "semicolon",
            b'\t' => "tab",
            _ => "comma",
        }
    }
}

/// Longest header line read before a file is judged not to be CSV.
const MAX_HEADER: u64 = 1 << 20;

/// A binary format a file's first bytes name, and what to do with such a file: checked before
/// the text encodings, whose NUL-byte test would call any binary file UTF-16.
fn binary_format(head: &[u8]) -> Option<(&'static str, &'static str)> {
    const COLUMNAR: &str = "CSV readers (`rootfuse eval`, `read_csv`) do not read it; `rootfuse run` reads Parquet and Arrow files by their extension (.parquet, .arrow, .arrows, .feather), and Python by `rootfuse.arrow`";
    const COMPRESSED: &str = "decompress it first (e.g. `gunzip`, `zstd -d`, `xz -d`)";
    let formats: [(&[u8], &str, &str); 8] = [
        (b"PAR1", "a Parquet file", COLUMNAR),
        (b"ARROW1", "an Arrow IPC file", COLUMNAR),
        (b"\xFF\xFF\xFF\xFF", "an Arrow IPC stream", COLUMNAR),
        (b"\x1F\x8B", "a gzip-compressed file", COMPRESSED),
        (b"\x28\xB5\x2F\xFD", "a zstd-compressed file", COMPRESSED),
        (b"\xFD7zXZ\x00", "an xz-compressed file", COMPRESSED),
        (
            b"PK\x03\x04",
            "a zip archive (or a spreadsheet workbook)",
            "unzip it, or save the sheet as CSV",
        ),
        (
            b"\x89HDF",
            "an HDF5 file",
            "export the data as CSV, Parquet or Arrow",
        ),
    ];
    formats
        .into_iter()
        .find(|(magic, _, _)| head.starts_with(magic))
        .map(|(_, format, what)| (format, what))
}

/// The encoding a file's first bytes give away, when it is not UTF-8 (which may start with a
/// byte-order mark) or ASCII.
fn foreign_encoding(head: &[u8]) -> Option<&'static str> {
    match head {
        [0xFF, 0xFE, 0, 0, ..] => Some("UTF-32 little-endian"),
        [0, 0, 0xFE, 0xFF, ..] => Some("UTF-32 big-endian"),
        [0xFF, 0xFE, ..] => Some("UTF-16 little-endian"),
        [0xFE, 0xFF, ..] => Some("UTF-16 big-endian"),
        // ASCII in UTF-16 without a byte-order mark: every other byte is zero.
        _ if head.contains(&0) => Some("UTF-16 or UTF-32 (NUL bytes, no byte-order mark)"),
        _ => None,
    }
}

/// A cell as a number.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Cell {
    /// A number (`NaN` and `inf` in any case are numbers: std's grammar).
    Number(f64),
    /// Nothing but white space: a missing value, as pandas writes NaN.
    Empty,
    /// Anything else.
    Text,
}

/// A CSV file read row by row after its header.
pub(crate) struct Table<R: Read> {
    rdr: csv::Reader<BufReader<R>>,
    /// The current row (after [`next_row`](Self::next_row)).
    pub record: csv::ByteRecord,
    /// The file, for messages.
    pub file: PathBuf,
    /// The header's column names, trimmed.
    pub header: Vec<String>,
    /// How the file is written.
    pub dialect: Dialect,
}

impl Table<std::fs::File> {
    /// Opens a file and reads its header.
    pub fn open(path: &Path) -> Result<Self, ReadError> {
        let file = std::fs::File::open(path).map_err(|e| ReadError::io(path, e))?;
        Self::new(file, path)
    }
}

impl<R: Read> Table<R> {
    /// Reads the header from `reader`; `file` names it in messages.
    pub fn new(reader: R, file: &Path) -> Result<Self, ReadError> {
        // The csv reader buffers too; a large buffer keeps a 9 MB file to a few reads.
        let mut buffered = BufReader::with_capacity(1 << 16, reader);
        let mut line = Vec::new();
        (&mut buffered)
            .take(MAX_HEADER)
            .read_until(b'\n', &mut line)
            .map_err(|e| ReadError::io(file, e))?;
        if let Some((format, what_to_do)) = binary_format(&line) {
            return Err(ReadError::NotText {
                place: Place::file(file),
                format,
                what_to_do,
            });
        }
        if let Some(encoding) = foreign_encoding(&line) {
            return Err(ReadError::Encoding {
                place: Place::file(file),
                encoding,
            });
        }
        // No newline in the header read, yet a carriage return before its end: lines end in CR
        // alone, and the "header" holds the whole file (or its first MiB). A CR before a
        // newline (`\r\r\n` as some writers leave it) or in a quoted field of a header that
        // ends in a newline is no such file.
        let trailing_crs = line.iter().rev().take_while(|&&b| b == b'\r').count();
        let body = &line[..line.len() - trailing_crs];
        if !line.ends_with(b"\n") && body.contains(&b'\r') {
            return Err(ReadError::CarriageReturns {
                place: Place::line(file, 1),
            });
        }
        // Spreadsheet programs like to start UTF-8 files with a byte-order mark.
        let line = line.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&line);
        if line.iter().all(u8::is_ascii_whitespace) {
            return Err(ReadError::Empty {
                place: Place::line(file, 1),
            });
        }
        let dialect = Dialect::of_header(line);
        let mut fields = csv::ByteRecord::new();
        csv::ReaderBuilder::new()
            .has_headers(false)
            .delimiter(dialect.delimiter)
            .from_reader(line)
            .read_byte_record(&mut fields)
            .map_err(|e| csv_error(file, e, 0))?;
        let header = fields
            .iter()
            .map(|f| String::from_utf8_lossy(trim(f)).into_owned())
            .collect();
        let rdr = csv::ReaderBuilder::new()
            .has_headers(false)
            // Field counts are checked here so that the error can name the line.
            .flexible(true)
            .delimiter(dialect.delimiter)
            .buffer_capacity(1 << 16)
            .from_reader(buffered);
        Ok(Self {
            rdr,
            record: csv::ByteRecord::new(),
            file: file.to_owned(),
            header,
            dialect,
        })
    }

    /// The 0-based field of the column named `name`.
    pub fn find(&self, name: &str) -> Option<usize> {
        self.header.iter().position(|h| h == name)
    }

    /// The error of a missing column, listing what the header has.
    pub fn missing(&self, column: &'static str) -> ReadError {
        ReadError::MissingColumn {
            place: Place::line(&self.file, 1),
            column,
            found: format!(
                "{} ({}-separated)",
                column_list(self.header.iter()),
                self.dialect.delimiter_name()
            ),
        }
    }

    /// Reads the next data row into [`record`](Self::record) and returns its 1-based line, or
    /// `None` at the end. A blank line (an editor's trailing newline) is not a row; a row whose
    /// field count differs from the header's is an error naming its line.
    pub fn next_row(&mut self) -> Result<Option<u64>, ReadError> {
        while self
            .rdr
            .read_byte_record(&mut self.record)
            .map_err(|e| csv_error(&self.file, e, 1))?
        {
            // The header line was read before the csv reader started.
            let line = self.record.position().map_or(0, |p| p.line() + 1);
            if self.record.len() == 1 && trim(&self.record[0]).is_empty() {
                continue;
            }
            if self.record.len() != self.header.len() {
                return Err(ReadError::FieldCount {
                    place: Place::line(&self.file, line),
                    expected: self.header.len(),
                    found: self.record.len(),
                });
            }
            return Ok(Some(line));
        }
        Ok(None)
    }

    /// Field `field` of the current row as a number.
    pub fn cell(&self, field: usize) -> Cell {
        let text = trim(&self.record[field]);
        if text.is_empty() {
            return Cell::Empty;
        }
        let Ok(s) = std::str::from_utf8(text) else {
            return Cell::Text;
        };
        if let Ok(v) = s.parse::<f64>() {
            return Cell::Number(v);
        }
        if self.dialect.decimal_comma
            && s.bytes().filter(|&b| b == b',').count() == 1
            && let Ok(v) = s.replacen(',', ".", 1).parse::<f64>()
        {
            return Cell::Number(v);
        }
        Cell::Text
    }

    /// Field `field` of the current row as written (trimmed, lossy UTF-8, control characters
    /// escaped), for messages.
    pub fn shown(&self, field: usize) -> String {
        let mut out = String::new();
        for c in String::from_utf8_lossy(trim(&self.record[field])).chars() {
            if c.is_control() {
                out.extend(c.escape_default());
            } else {
                out.push(c);
            }
        }
        out
    }

    /// Field `field` of the current row, trimmed.
    pub fn text(&self, field: usize) -> String {
        String::from_utf8_lossy(trim(&self.record[field])).into_owned()
    }

    /// The place of field `field` on `line`.
    pub fn place(&self, line: u64, field: usize) -> Place {
        Place::cell(&self.file, line, &self.header[field], field)
    }

    /// Field `field` as a number, NaN when the cell is empty (a missing value), or the error
    /// naming the cell.
    pub fn value(&self, line: u64, field: usize) -> Result<f64, ReadError> {
        match self.cell(field) {
            Cell::Empty => Ok(f64::NAN),
            _ => self.number(line, field),
        }
    }

    /// Field `field` as a number, or the error naming the cell (an empty cell is not one).
    pub fn number(&self, line: u64, field: usize) -> Result<f64, ReadError> {
        match self.cell(field) {
            Cell::Number(v) => Ok(v),
            Cell::Empty | Cell::Text => Err(ReadError::NotNumeric {
                place: self.place(line, field),
                text: self.shown(field),
            }),
        }
    }
}

/// A csv-crate error as a read error; `offset` lines precede what the csv reader saw.
fn csv_error(file: &Path, e: csv::Error, offset: u64) -> ReadError {
    let line = e.position().map_or(0, |p| p.line() + offset);
    let message = e.to_string();
    match e.into_kind() {
        csv::ErrorKind::Io(source) => ReadError::io(file, source),
        csv::ErrorKind::Utf8 { err, .. } => ReadError::Csv {
            place: Place::line(file, line),
            message: format!("invalid UTF-8 ({err})"),
        },
        csv::ErrorKind::UnequalLengths {
            expected_len, len, ..
        } => ReadError::FieldCount {
            place: Place::line(file, line),
            expected: expected_len as usize,
            found: len as usize,
        },
        _ => ReadError::Csv {
            place: Place::line(file, line),
            message,
        },
    }
}

/// ASCII whitespace trimmed from both ends (files written by hand or by `%8.3f`).
pub(crate) fn trim(f: &[u8]) -> &[u8] {
    f.trim_ascii()
}

/// The file stem of `path`, as a recording's name.
pub(crate) fn stem(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// The columns a file has, for a message about one it lacks: the first 12 by name, then how
/// many in all (`no columns` for none).
///
/// ```
/// let names = ["t", "gx"].map(String::from);
/// assert_eq!(rootfuse_io::column_list(names.iter()), "`t`, `gx`");
/// ```
pub fn column_list<'a>(names: impl ExactSizeIterator<Item = &'a String>) -> String {
    const SHOWN: usize = 12;
    let all = names.len();
    let mut shown: Vec<String> = names.take(SHOWN).map(|h| format!("`{h}`")).collect();
    if all > SHOWN {
        shown.push(format!("… {all} in all"));
    }
    if shown.is_empty() {
        "no columns".into()
    } else {
        shown.join(", ")
    }
}
