//! What `rootfuse run` and `rootfuse simulate` may do to files that exist: replace only their
//! own output of the same input (else `--force`), never a symbolic link, leave no temporary
//! file on SIGINT/SIGTERM and no empty `--out` after a failure, and write all the estimates
//! of a run or none.
use std::path::{Path, PathBuf};

mod common;
use common::columns::{fleet_columns, replace, write_parquet};
#[cfg(unix)]
use common::terminate_when;
use common::{Scratch, bin, temporaries};

fn temp_dir(name: &str) -> Scratch {
    common::temp_dir("files", name)
}

/// Runs `rootfuse` with `args` and returns exit code, stdout, stderr.
fn run(args: &[&dyn AsRef<std::ffi::OsStr>]) -> (Option<i32>, String, String) {
    let o = bin()
        .args(args.iter().map(|a| a.as_ref()))
        .output()
        .expect("the binary runs");
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// A small simulated fleet file (2 devices, `seconds` s at 100 Hz).
fn fleet(path: &Path, seconds: &str) {
    let (code, _, stderr) = run(&[
        &"simulate",
        &"--devices",
        &"2",
        &"--seconds",
        &seconds,
        &"--out",
        &path,
    ]);
    assert_eq!(code, Some(0), "{stderr}");
}

/// `run <args> --filter mahony --dof 6`.
fn run_6d(args: &[&dyn AsRef<std::ffi::OsStr>]) -> (Option<i32>, String, String) {
    let mut all: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&"run"];
    all.extend_from_slice(args);
    all.extend_from_slice(&[&"--filter", &"mahony", &"--dof", &"6"]);
    run(&all)
}

/// `run good.parquet --format csv --out .` beside the user's own `good.csv` does not replace
/// it silently: it is refused before anything is written; `--force` replaces it; a rerun
/// replaces rootfuse's own estimate of the same input without `--force`, but not one written
/// for another input of the same name, nor one the user changed since.
#[test]
fn run_replaces_only_its_own_output_of_the_same_input() {
    let dir = temp_dir("own");
    let good = dir.join("good.parquet");
    fleet(&good, "1");
    let user = dir.join("good.csv");
    std::fs::write(&user, "t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,9.81\n").unwrap();
    let before = std::fs::read(&user).unwrap();
    let dir_path: &Path = &dir;
    let (code, _, stderr) = run_6d(&[&good, &"--format", &"csv", &"--out", &dir_path]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("good.csv: exists and was not written by rootfuse")
            && stderr.contains("--force"),
        "{stderr}"
    );
    assert_eq!(
        std::fs::read(&user).unwrap(),
        before,
        "the user's file is kept"
    );
    let (code, _, stderr) = run_6d(&[&good, &"--format", &"csv", &"--out", &dir_path, &"--force"]);
    assert_eq!(code, Some(0), "{stderr}");
    assert_ne!(std::fs::read(&user).unwrap(), before);
    // Its own estimate of the same input: replaced without --force.
    let (code, _, stderr) = run_6d(&[&good, &"--format", &"csv", &"--out", &dir_path]);
    assert_eq!(code, Some(0), "{stderr}");
    // Another input of the same name: refused.
    std::fs::create_dir_all(dir.join("other")).unwrap();
    let other = dir.join("other/good.parquet");
    fleet(&other, "2");
    let (code, _, stderr) = run_6d(&[&other, &"--format", &"csv", &"--out", &dir_path]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("was not written by rootfuse for"),
        "{stderr}"
    );
    // The estimate changed by the user since: theirs now.
    std::fs::write(&user, "mine\n").unwrap();
    let (code, _, stderr) = run_6d(&[&good, &"--format", &"csv", &"--out", &dir_path]);
    assert_eq!(code, Some(2), "{stderr}");
    assert_eq!(std::fs::read_to_string(&user).unwrap(), "mine\n");
    // simulate follows the same rule for its --out.
    let (code, _, stderr) = run(&[
        &"simulate",
        &"--devices",
        &"1",
        &"--seconds",
        &"1",
        &"--out",
        &dir.join("good.csv.parquet"),
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    std::fs::write(dir.join("mine.parquet"), b"mine").unwrap();
    let (code, _, stderr) = run(&[
        &"simulate",
        &"--devices",
        &"1",
        &"--seconds",
        &"1",
        &"--out",
        &dir.join("mine.parquet"),
    ]);
    assert_eq!(code, Some(2), "{stderr}");
    assert_eq!(std::fs::read(dir.join("mine.parquet")).unwrap(), b"mine");
}

/// A symbolic link in `--out` where an estimate goes (here: the input itself, linked into
/// the output folder) is not replaced by the estimate: it is refused, with `--force` too;
/// the link and its target are untouched.
#[cfg(unix)]
#[test]
fn run_never_replaces_a_symbolic_link() {
    let dir = temp_dir("symlink");
    std::fs::create_dir_all(dir.join("data")).unwrap();
    std::fs::create_dir_all(dir.join("out")).unwrap();
    let target = dir.join("data/x.parquet");
    fleet(&target, "1");
    let link = dir.join("out/x.parquet");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let before = std::fs::read(&target).unwrap();
    let out = dir.join("out");
    for force in [false, true] {
        let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&link, &"--out", &out];
        if force {
            args.push(&"--force");
        }
        let (code, _, stderr) = run_6d(&args);
        assert_eq!(code, Some(2), "--force {force}: {stderr}");
        assert!(stderr.contains("is a symbolic link"), "{stderr}");
        assert!(
            std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(std::fs::read(&target).unwrap(), before);
    }
}

/// `simulate` stopped by SIGTERM (or SIGINT) leaves no `<out>.tmp.<pid>` (hundreds of MB at
/// scale): it removes its temporary file and exits 130,
/// and a later `simulate` removes the stale temporary files of its output that a killed one
/// left.
#[cfg(unix)]
#[test]
fn simulate_leaves_no_temporary_file() {
    let dir = temp_dir("simulate-signal");
    let out = dir.join("s.parquet");
    let (code, stderr) = terminate_when(
        bin()
            .args(["simulate", "--devices", "8", "--seconds", "20000", "--out"])
            .arg(&out),
        || !temporaries(&dir).is_empty(),
        "a temporary file",
    );
    assert_eq!(code, Some(130), "{stderr}");
    assert_eq!(temporaries(&dir), Vec::<PathBuf>::new());
    assert!(!out.exists());
    // What SIGKILL would leave: removed by the next simulate of that output, and only that.
    let stale = dir.join("s.parquet.tmp.4000000");
    let others = dir.join("t.parquet.tmp.4000000");
    std::fs::write(&stale, b"partial").unwrap();
    std::fs::write(&others, b"partial").unwrap();
    fleet(&out, "1");
    assert!(!stale.exists());
    assert!(others.exists());
}

/// A run that fails leaves no empty `--out` folder of its own: the folder it created is
/// removed again (only if it is empty and this run created it).
#[test]
fn failed_run_leaves_no_new_out_folder() {
    let dir = temp_dir("no-out");
    let bad = dir.join("bad.parquet");
    std::fs::write(&bad, b"PAR1 not a parquet file PAR1").unwrap();
    let out = dir.join("new/out");
    let (code, _, stderr) = run_6d(&[&bad, &"--out", &out]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(!out.exists() && !dir.join("new").exists(), "{stderr}");
    // A folder that was there before stays.
    let kept = dir.join("kept");
    std::fs::create_dir_all(&kept).unwrap();
    let (code, _, _) = run_6d(&[&bad, &"--out", &kept]);
    assert_eq!(code, Some(2));
    assert!(kept.is_dir());
}

/// One rule for a run of several inputs where a later one is bad: without `--keep-going` the
/// run writes all its estimates or none (exit 2), Parquet and CSV alike; with `--keep-going`
/// both write the good ones (exit 1).
#[test]
fn a_bad_input_means_no_estimate_without_keep_going() {
    let dir = temp_dir("all-or-none");
    let good = dir.join("good.parquet");
    fleet(&good, "1");
    let bytes = std::fs::read(&good).unwrap();
    let trunc = dir.join("trunc.parquet");
    std::fs::write(&trunc, &bytes[..bytes.len() / 2]).unwrap();
    // CSV: a good recording, and one whose time goes back after the good one has ended.
    let good_csv = dir.join("good.csv");
    let bad_csv = dir.join("bad.csv");
    let mut text = String::from("t,gx,gy,gz,ax,ay,az\n");
    for i in 0..100 {
        text.push_str(&format!("{},0.01,0,0,0,0,9.81\n", f64::from(i) * 0.01));
    }
    std::fs::write(&good_csv, &text).unwrap();
    for i in 100..2000 {
        let t = if i == 1500 { 0.5 } else { f64::from(i) * 0.01 };
        text.push_str(&format!("{t},0.01,0,0,0,0,9.81\n"));
    }
    std::fs::write(&bad_csv, &text).unwrap();
    for (inputs, name) in [
        ([&good, &trunc], "good.parquet"),
        ([&good_csv, &bad_csv], "good.csv"),
    ] {
        let out = dir.join(format!("o-{name}"));
        let (code, _, stderr) = run_6d(&[inputs[0], inputs[1], &"--out", &out]);
        assert_eq!(code, Some(2), "{name}: {stderr}");
        assert!(
            !out.join(name).exists(),
            "{name}: the good estimate was written"
        );
        assert_eq!(temporaries(&out), Vec::<PathBuf>::new());
        let (code, _, stderr) = run_6d(&[inputs[0], inputs[1], &"--out", &out, &"--keep-going"]);
        assert_eq!(code, Some(1), "{name}: {stderr}");
        assert!(out.join(name).is_file(), "{name}: {stderr}");
    }
}

/// SIGTERM during the second of two fleet files: the run exits 130 without writing any
/// estimate, the first file's included (as docs/cli.md says).
#[cfg(unix)]
#[test]
fn signal_writes_no_estimate() {
    let dir = temp_dir("run-signal");
    // The files of a run are one fleet: the first file's devices must be others than the
    // simulated 0..20 (else the second file would restart their time).
    let first = dir.join("a.parquet");
    let others: Vec<i64> = (0..200).map(|r| 100 + r % 2).collect();
    let device = std::sync::Arc::new(arrow::array::Int64Array::from(others));
    write_parquet(&first, replace(fleet_columns(200), "device", device), 64);
    let second = dir.join("b.parquet");
    let (code, _, stderr) = run(&[
        &"simulate",
        &"--devices",
        &"20",
        &"--seconds",
        &"300",
        &"--out",
        &second,
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    let out = dir.join("o");
    let (code, stderr) = terminate_when(
        bin()
            .arg("run")
            .args([&first, &second])
            .args(["--filter", "mahony", "--dof", "6", "--out"])
            .arg(&out),
        || {
            temporaries(&out)
                .iter()
                .any(|p| p.to_string_lossy().contains("b.parquet.tmp."))
        },
        "the second file's temporary file",
    );
    assert_eq!(code, Some(130), "{stderr}");
    assert!(stderr.contains("no estimate written"), "{stderr}");
    assert_eq!(temporaries(&out), Vec::<PathBuf>::new());
    assert!(!out.join("a.parquet").exists());
    assert!(!out.join("b.parquet").exists());
}
