//! Helpers shared by the CLI's end-to-end test files.
use std::path::{Path, PathBuf};
use std::process::Command;

pub mod columns;

/// The built `rootfuse` binary.
pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_rootfuse"))
}

/// A scratch directory of one test, removed when the test ends (passed or failed): recordings
/// and estimates of whole BROAD trials must not pile up in the system's temp folder.
pub struct Scratch(PathBuf);

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A fresh scratch directory `<temp>/rootfuse-<group>-<name>-<pid>`.
pub fn temp_dir(group: &str, name: &str) -> Scratch {
    let dir = std::env::temp_dir().join(format!("rootfuse-{group}-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    Scratch(dir)
}
