//! Folders of recordings: a dataset's `index.csv`, and which files of a folder are read and
//! which are left out, with the reason, so that a run can say both.

use crate::error::ReadError;
use crate::recording::read_csv;
use crate::table::Table;
use rootfuse_attitude::Recording;
use std::format;
use std::path::{Path, PathBuf};
use std::string::String;
use std::vec::Vec;

/// One row of a dataset's `index.csv` (`trial,group,fs_hz,n_samples,n_use,duration_s`).
///
/// Only `trial` is required; the other columns are `None` when absent.
#[derive(Clone, Debug, PartialEq)]
pub struct IndexEntry {
    /// Trial name = file stem of `<trial>.csv`.
    pub trial: String,
    /// Group label (`undisturbed`, `disturbed`).
    pub group: Option<String>,
    /// Sampling rate, Hz.
    pub fs_hz: Option<f64>,
    /// Number of samples (data rows).
    pub n_samples: Option<usize>,
    /// Number of rows with `use = 1`.
    pub n_use: Option<usize>,
    /// Duration, s.
    pub duration_s: Option<f64>,
}

/// Reads a dataset's `index.csv` (header-driven; only `trial` is required).
pub fn read_index(path: impl AsRef<Path>) -> Result<Vec<IndexEntry>, ReadError> {
    let mut table = Table::open(path.as_ref())?;
    let trial = table.find("trial").ok_or_else(|| table.missing("trial"))?;
    let [group, fs, ns, nu, dur] =
        ["group", "fs_hz", "n_samples", "n_use", "duration_s"].map(|c| table.find(c));
    let mut out = Vec::new();
    while let Some(line) = table.next_row()? {
        let float = |c: Option<usize>| c.map(|c| table.number(line, c)).transpose();
        let count = |c: Option<usize>| -> Result<Option<usize>, ReadError> {
            c.map(|c| {
                table
                    .text(c)
                    .parse::<usize>()
                    .map_err(|_| ReadError::NotNumeric {
                        place: table.place(line, c),
                        text: table.shown(c),
                    })
            })
            .transpose()
        };
        out.push(IndexEntry {
            trial: table.text(trial),
            group: group.map(|c| table.text(c)),
            fs_hz: float(fs)?,
            n_samples: count(ns)?,
            n_use: count(nu)?,
            duration_s: float(dur)?,
        });
    }
    Ok(out)
}

/// What a folder holds: CSV recordings, or Parquet/Arrow fleets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FolderKind {
    /// CSV recordings (one device each).
    Csv,
    /// Parquet or Arrow IPC fleet files (`.parquet`, `.pq`, `.arrow`, `.arrows`, `.feather`,
    /// `.ipc`).
    Fleet,
}

/// The files of a folder that a run reads, and the data files it leaves out with the reason.
#[derive(Clone, Debug, PartialEq)]
pub struct FolderListing {
    /// The folder.
    pub dir: PathBuf,
    /// What the files read are.
    pub kind: FolderKind,
    /// The files read, in order.
    pub files: Vec<PathBuf>,
    /// `index.csv` chose the files (its trials, in its order).
    pub indexed: bool,
    /// Data files not read, each with why.
    pub left_out: Vec<(PathBuf, &'static str)>,
}

impl FolderListing {
    /// One line saying what was read and, when anything was left out, what and why; `None`
    /// when every data file of the folder is read.
    pub fn note(&self) -> Option<String> {
        if self.left_out.is_empty() {
            return None;
        }
        let what = match (self.kind, self.indexed) {
            (FolderKind::Csv, true) => "the trials its index.csv lists",
            (FolderKind::Csv, false) => "its CSV recordings",
            (FolderKind::Fleet, _) => "its Parquet/Arrow fleet files",
        };
        let mut reasons: Vec<&'static str> = self.left_out.iter().map(|(_, why)| *why).collect();
        reasons.dedup();
        let groups: Vec<String> = reasons
            .iter()
            .map(|why| {
                let names: Vec<String> = self
                    .left_out
                    .iter()
                    .filter(|(_, w)| w == why)
                    .map(|(p, _)| {
                        p.file_name()
                            .unwrap_or_default()
                            .to_string_lossy()
                            .into_owned()
                    })
                    .collect();
                format!("{} ({why})", shorten(&names))
            })
            .collect();
        Some(format!(
            "{}: read {} file(s), {what}; left out {}: {}",
            self.dir.display(),
            self.files.len(),
            self.left_out.len(),
            groups.join("; ")
        ))
    }
}

/// Up to five names, then how many more.
fn shorten(names: &[String]) -> String {
    const SHOWN: usize = 5;
    let mut s = names
        .iter()
        .take(SHOWN)
        .cloned()
        .collect::<Vec<_>>()
        .join(", ");
    if names.len() > SHOWN {
        s.push_str(&format!(" and {} more", names.len() - SHOWN));
    }
    s
}

fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or_default()
        .to_ascii_lowercase()
}

/// A CSV data file (not the dataset's index).
fn is_csv(path: &Path) -> bool {
    extension(path) == "csv" && path.file_name().is_some_and(|n| n != "index.csv")
}

/// A Parquet or Arrow IPC file, by its extension.
pub fn is_fleet_file(path: &Path) -> bool {
    matches!(
        extension(path).as_str(),
        "parquet" | "pq" | "arrow" | "arrows" | "feather" | "ipc"
    )
}

/// Which files of a folder a run reads: the trials listed in its `index.csv` (as
/// `<trial>.csv`, in index order) when there is one, else every `*.csv` but `index.csv`,
/// sorted by name; a folder without CSV files, its Parquet and Arrow files. The data files
/// left out (CSV files the index does not list, fleet files beside CSV recordings) are listed
/// with the reason; other files (README, …) are not data and are not listed.
pub fn scan_dir(dir: impl AsRef<Path>) -> Result<FolderListing, ReadError> {
    let dir = dir.as_ref();
    let mut entries = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| ReadError::io(dir, e))? {
        let path = entry.map_err(|e| ReadError::io(dir, e))?.path();
        if path.is_file() {
            entries.push(path);
        }
    }
    entries.sort();
    let csv: Vec<PathBuf> = entries.iter().filter(|p| is_csv(p)).cloned().collect();
    let fleet: Vec<PathBuf> = entries
        .iter()
        .filter(|p| is_fleet_file(p))
        .cloned()
        .collect();
    let index = dir.join("index.csv");
    let mut listing = FolderListing {
        dir: dir.to_owned(),
        kind: FolderKind::Csv,
        files: csv,
        indexed: false,
        left_out: Vec::new(),
    };
    if index.is_file() {
        listing.indexed = true;
        listing.files = read_index(&index)?
            .into_iter()
            .map(|e| dir.join(format!("{}.csv", e.trial)))
            .collect();
        listing.left_out = entries
            .iter()
            .filter(|p| is_csv(p) && !listing.files.contains(p))
            .map(|p| (p.clone(), "not listed in index.csv"))
            .collect();
    } else if listing.files.is_empty() {
        listing.kind = FolderKind::Fleet;
        listing.files = fleet;
        return Ok(listing);
    }
    listing.left_out.extend(
        fleet
            .into_iter()
            .map(|p| (p, "Parquet/Arrow fleets do not run beside CSV recordings")),
    );
    Ok(listing)
}

/// The CSV recordings of a folder (see [`scan_dir`]; empty for a folder of fleets).
pub fn list_dir(dir: impl AsRef<Path>) -> Result<Vec<PathBuf>, ReadError> {
    let listing = scan_dir(dir)?;
    Ok(match listing.kind {
        FolderKind::Csv => listing.files,
        FolderKind::Fleet => Vec::new(),
    })
}

/// Reads every CSV recording of a folder (see [`list_dir`] for which files), stopping at the
/// first error.
pub fn read_dir(dir: impl AsRef<Path>) -> Result<Vec<Recording>, ReadError> {
    list_dir(dir)?.iter().map(read_csv).collect()
}
