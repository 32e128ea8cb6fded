//! The Parquet / Arrow IPC fleet reader on arbitrary bytes.

use rootfuse_attitude::registry::FilterSpec;
use rootfuse_batch::{Columns, FleetRunner, OnError, Precision};
use rootfuse_columnar::{Devices, FleetReader, ImuGaps};
use std::path::PathBuf;

/// A file of this thread's own (the reader takes a path), rewritten for every input.
fn scratch(ext: &str) -> PathBuf {
    let id = format!("{:?}", std::thread::current().id());
    let id: String = id.chars().filter(char::is_ascii_digit).collect();
    std::env::temp_dir().join(format!(
        "rootfuse-fuzz-columnar-{}-{id}.{ext}",
        std::process::id()
    ))
}

/// Fuzz target `columnar_reader`: [`FleetReader`] on arbitrary bytes, as Parquet when the
/// input starts with `PAR1` and under an Arrow name otherwise (read as an IPC file after the
/// magic `ARROW1`, as an IPC stream without it); every block read goes through
/// a [`FleetRunner`] (Mahony, 6D).
///
/// Invariants: no panic; every block has one device and one time stamp per row, and as many
/// sensor rows; an error's message names the file; the runner's estimates are unit
/// quaternions for the rows it kept.
pub fn columnar_reader(data: &[u8]) {
    let ext = if data.starts_with(b"PAR1") {
        "parquet"
    } else {
        "arrow"
    };
    let path = scratch(ext);
    if std::fs::write(&path, data).is_err() {
        return;
    }
    let shown = path.display().to_string();
    let check_error = |e: &dyn std::fmt::Display| {
        let msg = e.to_string();
        assert!(msg.starts_with(&shown), "message without the file: {msg}");
    };
    // Unreachable: "mahony" is a registered filter name, and 6 is a value every `dof`
    // parameter accepts (the registry's own tests check both).
    let mut spec = FilterSpec::new("mahony").unwrap_or_else(|_| unreachable!("a registered name"));
    if spec.set_dof(rootfuse_attitude::Dof::Six).is_err() {
        unreachable!("mahony has a dof parameter");
    }
    let mut runner = FleetRunner::new(&spec, Precision::F64, Columns::default());
    let mut devices = Devices::default();
    match FleetReader::open(&path, ImuGaps::Keep) {
        Err(e) => check_error(&e),
        Ok(mut reader) => loop {
            match reader.next_chunk(&mut devices) {
                Err(e) => {
                    check_error(&e);
                    break;
                }
                Ok(None) => break,
                Ok(Some(chunk)) => {
                    let b = &chunk.block;
                    let n = b.len();
                    assert!(n > 0, "empty block");
                    assert!(b.device.len() == n && b.gyr.len() == n && b.acc.len() == n);
                    assert!(b.mag.as_ref().is_none_or(|m| m.len() == n));
                    assert!(b.device.iter().all(|&d| (d as usize) < devices.len()));
                    // Unreachable: with `OnError::DropDevice` a bad device is dropped and
                    // counted, `step` returns an error only under `OnError::Stop`.
                    let est = runner
                        .step(b, None, OnError::DropDevice)
                        .unwrap_or_else(|_| unreachable!("DropDevice never fails"));
                    for r in (0..n).filter(|&r| est.kept[r]) {
                        let q = est.quat[r].to_array();
                        let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
                        assert!((norm - 1.0).abs() < 1e-6, "row {r}: quaternion norm {norm}");
                    }
                }
            }
        },
    }
    let _ = std::fs::remove_file(&path);
}
