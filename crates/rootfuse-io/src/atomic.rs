//! Files that appear complete or not at all: written under a temporary name beside the
//! target, then renamed into place.

use crate::error::WriteError;
use crate::format::{check_name, push_all};
use std::borrow::ToOwned;
use std::format;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::string::{String, ToString};
use std::vec::Vec;

/// A file being written to [`temporary_path`] and renamed to its final path by
/// [`finish`](Self::finish) (after its data reached the disk). Dropped unfinished (an error,
/// a panic), it removes the temporary file: the final path keeps its previous content or
/// stays absent.
///
/// ```
/// use std::io::Write;
/// let dir = std::env::temp_dir().join(format!("rootfuse-atomic-doc-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// let path = dir.join("a.txt");
/// let mut f = rootfuse_io::AtomicFile::create(&path).unwrap();
/// f.write_all(b"hello").unwrap();
/// assert!(!path.exists()); // not before `finish`
/// f.finish().unwrap();
/// assert_eq!(std::fs::read(&path).unwrap(), b"hello");
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
#[derive(Debug)]
pub struct AtomicFile {
    path: PathBuf,
    tmp: PathBuf,
    writer: Option<std::io::BufWriter<std::fs::File>>,
}

impl AtomicFile {
    /// Creates the temporary file of `path` (this process's [`temporary_path`]).
    pub fn create(path: impl AsRef<Path>) -> Result<Self, WriteError> {
        let path = path.as_ref().to_owned();
        let tmp = temporary_path(&path, std::process::id());
        let file = std::fs::File::create(&tmp).map_err(|source| WriteError::Io {
            file: path.clone(),
            source,
        })?;
        Ok(Self {
            path,
            tmp,
            writer: Some(std::io::BufWriter::with_capacity(1 << 16, file)),
        })
    }

    /// The final path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Flushes, syncs the data to disk and renames the file into place.
    pub fn finish(self) -> Result<(), WriteError> {
        self.close()?.commit()
    }

    /// Flushes and syncs the data to disk, without the rename: the complete file waits under
    /// its temporary name until [`Staged::commit`], so that a run of many files can put them
    /// all in place at its end, or none when one fails (a dropped [`Staged`] removes it).
    pub fn close(mut self) -> Result<Staged, WriteError> {
        let result = (|| -> Result<(), std::io::Error> {
            let Some(w) = self.writer.take() else {
                return Ok(());
            };
            let file = w.into_inner().map_err(|e| e.into_error())?;
            // Data on disk before the rename makes it visible: no empty file after a crash.
            file.sync_all()
        })();
        match result {
            Ok(()) => Ok(Staged {
                path: std::mem::take(&mut self.path),
                tmp: Some(std::mem::take(&mut self.tmp)),
            }),
            Err(source) => {
                let _ = std::fs::remove_file(&self.tmp);
                Err(WriteError::Io {
                    file: self.path.clone(),
                    source,
                })
            }
        }
    }

    fn writer(&mut self) -> std::io::Result<&mut std::io::BufWriter<std::fs::File>> {
        self.writer
            .as_mut()
            .ok_or_else(|| std::io::Error::other("file already finished"))
    }
}

impl std::io::Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.writer()?.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.writer()?.flush()
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.writer.take().is_some() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// A complete file under its temporary name ([`AtomicFile::close`]), renamed into place by
/// [`commit`](Self::commit); dropped uncommitted (an error elsewhere in the run, a signal),
/// it is removed and the final path keeps its previous content or stays absent.
#[derive(Debug)]
pub struct Staged {
    path: PathBuf,
    tmp: Option<PathBuf>,
}

impl Staged {
    /// Nothing staged for `path` (an output kept in memory): committing it does nothing.
    pub fn nothing(path: impl Into<PathBuf>) -> Self {
        Self {
            path: path.into(),
            tmp: None,
        }
    }

    /// The final path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Renames the file into place.
    pub fn commit(mut self) -> Result<(), WriteError> {
        let Some(tmp) = self.tmp.take() else {
            return Ok(());
        };
        std::fs::rename(&tmp, &self.path).map_err(|source| {
            let _ = std::fs::remove_file(&tmp);
            WriteError::Io {
                file: self.path.clone(),
                source,
            }
        })
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if let Some(tmp) = self.tmp.take() {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// Estimates written as CSV row by row (streaming), atomically: the format of
/// [`write_estimates`](crate::write_estimates) (`t,qw,qx,qy,qz`, then extra columns, numbers in
/// shortest round-trip form), optionally led by a text column such as `device`.
#[derive(Debug)]
pub struct CsvEstimateWriter {
    file: AtomicFile,
    row: String,
    columns: usize,
    label: bool,
}

impl CsvEstimateWriter {
    /// Creates the file and writes the header: `label` (if any) then `names` (the numeric
    /// columns, in the order rows give them).
    pub fn create(
        path: impl AsRef<Path>,
        label: Option<&str>,
        names: &[&str],
    ) -> Result<Self, WriteError> {
        let path = path.as_ref();
        let mut taken: Vec<&str> = Vec::new();
        for name in label.iter().chain(names) {
            check_name(path, name, &taken)?;
            taken.push(name);
        }
        let mut file = AtomicFile::create(path)?;
        let header = taken.join(",") + "\n";
        file.write_all(header.as_bytes())
            .map_err(|source| WriteError::Io {
                file: path.to_owned(),
                source,
            })?;
        Ok(Self {
            file,
            row: String::with_capacity(256),
            columns: names.len(),
            label: label.is_some(),
        })
    }

    /// Writes one row: the label (quoted if it needs to be; ignored without a label column)
    /// and one value per numeric column.
    pub fn write_row(&mut self, label: &str, values: &[f64]) -> Result<(), WriteError> {
        if values.len() != self.columns {
            return Err(WriteError::Length {
                file: self.file.path().to_owned(),
                column: "row".into(),
                expected: self.columns,
                found: values.len(),
            });
        }
        self.row.clear();
        if self.label {
            self.row.push(',');
            if label.contains([',', '"', '\n', '\r']) {
                self.row.push('"');
                self.row.push_str(&label.replace('"', "\"\""));
                self.row.push('"');
            } else {
                self.row.push_str(label);
            }
        }
        push_all(&mut self.row, values);
        self.row.push('\n');
        // Every field was written with a leading comma.
        let bytes = &self.row.as_bytes()[1..];
        self.file.write_all(bytes).map_err(|source| WriteError::Io {
            file: self.file.path().to_owned(),
            source,
        })
    }

    /// Renames the file into place (see [`AtomicFile::finish`]).
    pub fn finish(self) -> Result<(), WriteError> {
        self.file.finish()
    }

    /// Completes the file without putting it in place ([`AtomicFile::close`]).
    pub fn close(self) -> Result<Staged, WriteError> {
        self.file.close()
    }
}

/// The temporary file that process `pid` writes before renaming it to `path`:
/// `<path>.tmp.<pid>`, beside it (a rename is atomic only within one file system).
pub fn temporary_path(path: &Path, pid: u32) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_owned();
    name.push(format!(".tmp.{pid}"));
    path.with_file_name(name)
}

/// Temporary files of writes to `path` by other processes (`<path>.tmp.<pid>`, see
/// [`temporary_path`]) that exist now: what a process killed while writing `path` left
/// behind. The final `path` of such a write is either the previous complete file or absent.
pub fn stale_temporaries(path: &Path) -> Vec<PathBuf> {
    let (Some(dir), Some(name)) = (path.parent(), path.file_name()) else {
        return Vec::new();
    };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let prefix = format!("{}.tmp.", name.to_string_lossy());
    let ours = std::process::id().to_string();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .and_then(|n| n.strip_prefix(&prefix))
                .is_some_and(|pid| {
                    !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()) && pid != ours
                })
        })
        .collect()
}
