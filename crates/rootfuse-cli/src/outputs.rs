//! Which existing files an output may replace.
//!
//! rootfuse replaces only a file it wrote itself for the same input: each folder it writes
//! into keeps a ledger, `.rootfuse-outputs.json`, of the files written there, each with its
//! source (the input's canonical path, or `rootfuse simulate`) and the length and
//! modification time the file had when written. A file not in the ledger, written for
//! another input, or changed since (the user copied a recording over an old estimate) is
//! someone else's: replacing it needs `--force`. A symbolic link is never replaced nor
//! written through, `--force` or not: the link would be replaced by a plain file, or the
//! file it points to (an input elsewhere, say) overwritten.
use serde_json::{Map, Value, json};
use std::path::{Path, PathBuf};

/// The ledger's file name in an output folder.
pub const LEDGER: &str = ".rootfuse-outputs.json";

/// The source of `rootfuse simulate` outputs.
pub const SIMULATE: &str = "rootfuse simulate";

/// The files rootfuse wrote in one folder.
pub struct Ledger {
    path: PathBuf,
    files: Map<String, Value>,
}

impl Ledger {
    /// The ledger of `dir` (empty when there is none, or it cannot be read: then no file
    /// counts as rootfuse's, which errs on the side of the user's files).
    pub fn load(dir: &Path) -> Self {
        let path = dir.join(LEDGER);
        let files = std::fs::read(&path)
            .ok()
            .and_then(|b| serde_json::from_slice::<Value>(&b).ok())
            .and_then(|v| v.get("files").and_then(Value::as_object).cloned())
            .unwrap_or_default();
        Self { path, files }
    }

    /// Whether `output` may be written for `source`: absent, or written by rootfuse for
    /// `source` and unchanged since, or any regular file under `force`.
    pub fn check(&self, output: &Path, source: &str, force: bool) -> Result<(), String> {
        let meta = match std::fs::symlink_metadata(output) {
            Ok(m) => m,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
            Err(e) => return Err(format!("{}: cannot inspect: {e}", output.display())),
        };
        if meta.file_type().is_symlink() {
            return Err(format!(
                "{}: is a symbolic link; an output never replaces a link nor writes through it (even with --force): remove the link or choose another output folder",
                output.display()
            ));
        }
        if !meta.is_file() {
            return Err(format!(
                "{}: exists and is not a file; choose another output",
                output.display()
            ));
        }
        if force || self.entry(output) == Some(stamp(source, &meta)) {
            return Ok(());
        }
        Err(format!(
            "{}: exists and was not written by rootfuse for {source}; rootfuse replaces only its own output of the same input: give --force to replace it, or choose another output",
            output.display()
        ))
    }

    fn entry(&self, output: &Path) -> Option<Value> {
        let name = output.file_name()?.to_str()?;
        self.files.get(name).cloned()
    }

    /// Notes `output` (just put in place) as written for `source`, and saves the ledger
    /// (atomically).
    pub fn record(&mut self, output: &Path, source: &str) -> Result<(), String> {
        let meta = std::fs::metadata(output)
            .map_err(|e| format!("{}: cannot inspect: {e}", output.display()))?;
        if let Some(name) = output.file_name().and_then(|n| n.to_str()) {
            self.files.insert(name.to_string(), stamp(source, &meta));
        }
        let text = serde_json::to_string_pretty(&json!({
            "written by": "rootfuse: the files it may replace without --force",
            "files": self.files,
        }))
        .map_err(|e| format!("{}: cannot write: {e}", self.path.display()))?;
        let mut file = rootfuse_io::AtomicFile::create(&self.path).map_err(|e| e.to_string())?;
        std::io::Write::write_all(&mut file, text.as_bytes())
            .map_err(|e| format!("{}: cannot write: {e}", self.path.display()))?;
        file.finish().map_err(|e| e.to_string())
    }
}

/// What the ledger keeps of a file: its source, length and modification time (ns).
fn stamp(source: &str, meta: &std::fs::Metadata) -> Value {
    let modified = meta
        .modified()
        .ok()
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos());
    json!({ "source": source, "bytes": meta.len(), "modified_ns": modified.to_string() })
}

/// The source named for an input: its canonical path (as given when it has none).
pub fn source_of(input: &Path) -> String {
    input
        .canonicalize()
        .unwrap_or_else(|_| input.to_owned())
        .display()
        .to_string()
}

/// The folders `create_dir_all(dir)` would create, deepest first: removed again (when
/// still empty) after a run that failed, so that a failed run leaves no empty `--out`.
pub fn missing_folders(dir: &Path) -> Vec<PathBuf> {
    dir.ancestors()
        .filter(|a| !a.as_os_str().is_empty() && std::fs::symlink_metadata(a).is_err())
        .map(Path::to_path_buf)
        .collect()
}

/// Removes `folders` (from [`missing_folders`]) that are empty, deepest first.
pub fn remove_empty(folders: &[PathBuf]) {
    for f in folders {
        // `remove_dir` refuses a folder with anything in it: only what this run created and
        // left empty goes.
        if std::fs::remove_dir(f).is_err() {
            break;
        }
    }
}
