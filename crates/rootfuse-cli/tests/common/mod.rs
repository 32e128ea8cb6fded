//! Helpers shared by the CLI's end-to-end test files.
use std::path::{Path, PathBuf};
use std::process::Command;

pub mod columns;

/// Temporary files (`*.tmp.<pid>`) in `dir`.
// Not every test file that includes this module uses it.
#[allow(dead_code)]
pub fn temporaries(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir)
        .map(|d| {
            d.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.to_string_lossy().contains(".tmp."))
                .collect()
        })
        .unwrap_or_default()
}

/// Runs `cmd` (stdout discarded), sends it SIGTERM as soon as `ready()` holds, and returns its
/// exit code and stderr. The run must still be going when `ready()` first holds (else it
/// finished before `what` was seen), within 120 s.
#[cfg(unix)]
#[allow(dead_code)]
pub fn terminate_when(
    cmd: &mut Command,
    ready: impl Fn() -> bool,
    what: &str,
) -> (Option<i32>, String) {
    use std::process::Stdio;
    let mut child = cmd
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while !ready() {
        assert!(
            child.try_wait().unwrap().is_none(),
            "finished before {what} was seen"
        );
        assert!(start.elapsed().as_secs() < 120, "{what}: not seen");
        std::thread::sleep(std::time::Duration::from_micros(200));
    }
    let killed = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let output = child.wait_with_output().unwrap();
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

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
