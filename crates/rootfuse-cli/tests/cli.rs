//! End-to-end tests of the built `rootfuse` binary: run + eval agree with the library, and
//! bad input gives one clear line and exit code 2 (never a panic).
use rootfuse_eval::metrics::{Alignment, evaluate};
use rootfuse_eval::sim::scenario;
use rootfuse_io::{read_csv, read_estimates, write_recording};
use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::{Scratch, bin};
#[cfg(unix)]
use common::{temporaries, terminate_when};

fn temp_dir(name: &str) -> Scratch {
    common::temp_dir("cli", name)
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("the binary runs")
}

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The first `rows` data lines of a CSV file.
fn cut(src: &Path, dst: &Path, rows: usize) {
    let content = std::fs::read_to_string(src).unwrap();
    let head: Vec<&str> = content.lines().take(rows + 1).collect();
    std::fs::write(dst, head.join("\n") + "\n").unwrap();
}

fn broad_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("ROOTFUSE_BROAD_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/broad_csv"));
    if dir.join("index.csv").is_file() {
        Some(dir)
    } else {
        assert!(
            std::env::var_os("CI").is_none(),
            "BROAD data missing at {}",
            dir.display()
        );
        None
    }
}

/// run writes one estimate per input, and eval's numbers equal the library's metrics.
fn run_then_eval(inputs: &[PathBuf], filter: &str, dof: &str) {
    let out = temp_dir(&format!("out-{filter}-{dof}"));
    let mut args = vec![
        "run".to_string(),
        "--filter".into(),
        filter.into(),
        "--dof".into(),
        dof.into(),
    ];
    args.extend([
        "--out".into(),
        out.display().to_string(),
        "--precision".into(),
        "f32".into(),
    ]);
    args.extend(inputs.iter().map(|p| p.display().to_string()));
    let o = bin().args(&args).output().unwrap();
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "run failed: {stderr}");
    assert!(
        stdout.contains("samples") && stdout.contains("rejected"),
        "{stdout}"
    );
    let align = if dof == "6" {
        Alignment::SixD
    } else {
        Alignment::NineD
    };
    for input in inputs {
        let name = input.file_stem().unwrap().to_string_lossy().into_owned();
        let est_path = out.join(format!("{name}.csv"));
        let o = run(&[
            "eval",
            &input.display().to_string(),
            &est_path.display().to_string(),
            "--dof",
            dof,
            "--json",
        ]);
        let (json, stderr) = text(&o);
        assert!(o.status.success(), "eval failed: {stderr}");
        let rec = read_csv(input).unwrap();
        let est = read_estimates(&est_path).unwrap();
        assert_eq!(est.t, rec.t, "estimate times are the input's");
        let lib = evaluate(&rec, &est.quat, align).unwrap();
        let parsed: serde_json::Value = serde_json::from_str(&json).unwrap();
        let field = |key: &str| -> f64 { parsed["files"][0][key].as_f64().unwrap() };
        assert_eq!(field("total"), lib.total, "{json}");
        assert_eq!(field("inclination"), lib.inclination, "{json}");
    }
}

#[test]
fn run_and_eval_on_simulated_files() {
    let dir = temp_dir("sim");
    let mut inputs = Vec::new();
    for (i, name) in ["slow-rotation", "translation"].iter().enumerate() {
        let rec = scenario(name, i as u64, 5.0, 100.0).unwrap();
        let path = dir.join(format!("{name}.csv"));
        write_recording(&path, &rec).unwrap();
        inputs.push(path);
    }
    run_then_eval(&inputs, "ekf", "9");
    run_then_eval(&inputs, "madgwick", "6");
}

#[test]
#[cfg_attr(
    not(broad_data),
    ignore = "BROAD data not found (../shared/broad_csv or $ROOTFUSE_BROAD_DIR)"
)]
fn run_and_eval_on_a_cut_of_broad() {
    let Some(broad) = broad_dir() else { return };
    let dir = temp_dir("broad");
    let cut_file = dir.join("29_cut.csv");
    // The movement phase (use = 1) starts at line 9328; keep 20 s of it.
    cut(
        &broad.join("29_disturbed_stationary_magnet_B.csv"),
        &cut_file,
        15000,
    );
    run_then_eval(&[cut_file], "mahony", "9");
}

#[test]
fn bad_input_is_one_clear_line_and_exit_code_2() {
    let dir = temp_dir("bad");
    let cases = [
        ("missing.csv", None, "cannot read"),
        (
            "header.csv",
            Some("t,gx,gy,ax,ay,az\n0,0,0,0,0,9.8\n"),
            "missing required column `gz`",
        ),
        (
            "cell.csv",
            Some("t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,9.8\n0.1,0,abc,0,0,0,9.8\n"),
            "line 3, column `gy` (#3)",
        ),
        (
            "time.csv",
            Some("t,gx,gy,gz,ax,ay,az\n0.2,0,0,0,0,0,9.8\n0.1,0,0,0,0,0,9.8\n"),
            "line 3, column `t` (#1)",
        ),
    ];
    for (name, content, expected) in cases {
        let path = dir.join(name);
        if let Some(c) = content {
            std::fs::write(&path, c).unwrap();
        }
        let o = run(&[
            "run",
            &path.display().to_string(),
            "--filter",
            "mahony",
            "--out",
            &dir.join("o").display().to_string(),
        ]);
        let (_, stderr) = text(&o);
        assert_eq!(o.status.code(), Some(2), "{name}: {stderr}");
        assert_eq!(
            stderr.lines().count(),
            1,
            "{name}: one line expected: {stderr}"
        );
        assert!(
            stderr.contains(name) && stderr.contains(expected),
            "{name}: {stderr}"
        );
        assert!(!stderr.contains("panicked"));
    }
    // --keep-going processes the good file and says something failed.
    let good = dir.join("good.csv");
    write_recording(&good, &scenario("static", 1, 1.0, 100.0).unwrap()).unwrap();
    let out = dir.join("kg");
    let o = run(&[
        "run",
        &dir.join("cell.csv").display().to_string(),
        &good.display().to_string(),
        "--filter",
        "ekf",
        "--keep-going",
        "--out",
        &out.display().to_string(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o).1);
    assert!(out.join("good.csv").is_file() && !out.join("cell.csv").exists());
    // Unknown filter and bad parameter.
    let o = run(&["run", &good.display().to_string(), "--filter", "kalman"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).1.contains("unknown filter `kalman`"));
    let o = run(&[
        "run",
        &good.display().to_string(),
        "--filter",
        "mahony",
        "--param",
        "kp=-3",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).1.contains("outside"));
    // Without --filter the flagship runs; an --out that is a file is named as such.
    let flagship = dir.join("flagship");
    let o = run(&[
        "run",
        &good.display().to_string(),
        "--out",
        &flagship.display().to_string(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o).1);
    assert!(flagship.join("good.csv").is_file());
    let o = run(&[
        "run",
        &good.display().to_string(),
        "--out",
        &good.display().to_string(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o).1.contains("--out is a file, not a folder"),
        "{}",
        text(&o).1
    );
}

#[test]
fn filters_lists_the_registry() {
    let o = run(&["filters"]);
    let (stdout, _) = text(&o);
    assert!(o.status.success());
    for name in rootfuse_attitude::registry::FilterKind::NAMES {
        assert!(stdout.contains(&format!("{name}: ")), "{name} missing");
    }
}

#[test]
fn stress_json_has_the_specified_keys() {
    let o = run(&[
        "stress",
        "--scenario",
        "dyer-mcreynolds",
        "--scale",
        "1",
        "--json",
    ]);
    let (json, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    assert!(json.trim_start().starts_with('[') && json.trim_end().ends_with(']'));
    let rows = json.matches("\"form\"").count();
    assert!(
        rows >= 6 * 2 * 13,
        "every form, both precisions, thirteen deltas: {rows} rows"
    );
    for key in [
        "precision",
        "scenario",
        "param",
        "steps",
        "max_rel_err",
        "max_rel_err_received",
        "health_kind",
        "health_worst",
        "pd_lost_at",
        "nan_at",
        "detected",
        "ns_per_update",
    ] {
        assert_eq!(json.matches(&format!("\"{key}\":")).count(), rows, "{key}");
    }
    // The covariance forms in f32 report their own failure at the smallest deltas.
    let parsed: serde_json::Value = serde_json::from_str(&json).expect("valid JSON");
    let flagged = parsed.as_array().expect("an array").iter().any(|r| {
        r["form"] == "conventional"
            && r["precision"] == "f32"
            && r["scenario"] == "dyer-mcreynolds"
            && r["param"] == 1e-8
            && r["detected"] == true
    });
    assert!(flagged, "{json}");
    let o = run(&["stress", "--scenario", "nonsense"]);
    assert_eq!(o.status.code(), Some(2));
}

/// `--bias --covariance --flags` add their columns in that order; the covariance is positive
/// on its diagonal; a filter without a covariance is a one-line error, exit code 2.
#[test]
fn run_writes_optional_columns() {
    let dir = temp_dir("columns");
    let mut rec = scenario("slow-rotation", 3, 4.0, 100.0).unwrap();
    rec.gyr[50] = rootfuse_attitude::Vec3::new(100.0, 0.0, 0.0); // saturated
    let input = dir.join("sim.csv");
    write_recording(&input, &rec).unwrap();
    let out = dir.join("o");
    let (input_s, out_s) = (input.display().to_string(), out.display().to_string());
    let common = ["run", &input_s, "--out", &out_s, "--bias", "--flags"];
    let o = bin()
        .args(common)
        .args(["--filter", "sqrt-eskf", "--covariance"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o).1);
    let written = std::fs::read_to_string(out.join("sim.csv")).unwrap();
    let mut lines = written.lines();
    assert_eq!(
        lines.next().unwrap(),
        "t,qw,qx,qy,qz,bx,by,bz,p_xx,p_xy,p_xz,p_yy,p_yz,p_zz,flags"
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|c| c.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), rec.len());
    for row in &rows {
        assert!(row[8] > 0.0 && row[11] > 0.0 && row[13] > 0.0, "{row:?}");
    }
    // The saturated gyro sample is skipped, flagged 2 (gyroscope).
    assert_eq!(rows[50][14], 2.0);
    assert_eq!(rows.iter().filter(|r| r[14] != 0.0).count(), 1);

    let o = bin()
        .args(common)
        .args(["--filter", "mahony", "--covariance"])
        .output()
        .unwrap();
    let (_, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("carries no covariance"), "{stderr}");
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
}

/// `run --offline` smooths forward-backward: more accurate than the online run on the same
/// simulated file; refused for filters without a covariance and with extra columns.
#[test]
fn run_offline_smooths() {
    let dir = temp_dir("offline");
    let rec = scenario("translation", 4, 30.0, 100.0).unwrap();
    let input = dir.join("sim.csv");
    write_recording(&input, &rec).unwrap();
    let input_s = input.display().to_string();
    let mut err = Vec::new();
    for (sub, extra) in [("online", None), ("offline", Some("--offline"))] {
        let out_s = dir.join(sub).display().to_string();
        let mut args = vec!["run", &input_s, "--out", &out_s, "--filter", "flagship"];
        args.extend(extra);
        let o = run(&args);
        assert!(o.status.success(), "{}", text(&o).1);
        let est = read_estimates(dir.join(sub).join("sim.csv")).unwrap();
        assert_eq!(est.quat.len(), rec.len());
        err.push(evaluate(&rec, &est.quat, Alignment::NineD).unwrap().total);
    }
    assert!(
        err[1] < err[0],
        "offline {:.3}° vs online {:.3}°",
        err[1],
        err[0]
    );
    let out_s = dir.join("x").display().to_string();
    for args in [
        vec![
            "run",
            &input_s,
            "--out",
            &out_s,
            "--filter",
            "mahony",
            "--offline",
        ],
        vec![
            "run",
            &input_s,
            "--out",
            &out_s,
            "--filter",
            "flagship",
            "--offline",
            "--bias",
        ],
    ] {
        let o = run(&args);
        assert_eq!(o.status.code(), Some(2), "{}", text(&o).1);
    }
}

/// The last column (`flags`) of an estimate file, per sample.
fn flags_column(path: &Path) -> Vec<u8> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.rsplit(',').next().unwrap().parse::<f64>().unwrap() as u8)
        .collect()
}

/// `--flags` carries the flagship's detector states: 32 while at rest (most of a long-rest
/// recording), 64 where the field is disturbed; filters without detectors never set them.
#[test]
fn run_flags_carry_rest_and_disturbance() {
    let dir = temp_dir("status");
    let column = |scenario_name: &str, filter: &str| -> Vec<u8> {
        let rec = scenario(scenario_name, 2, 40.0, 100.0).unwrap();
        let input = dir.join(format!("{scenario_name}.csv"));
        write_recording(&input, &rec).unwrap();
        let out = dir.join(filter);
        let (i, o) = (input.display().to_string(), out.display().to_string());
        let r = run(&["run", &i, "--out", &o, "--filter", filter, "--flags"]);
        assert!(r.status.success(), "{}", text(&r).1);
        flags_column(&out.join(format!("{scenario_name}.csv")))
    };
    let rest = column("long-rest", "flagship");
    let at_rest = rest.iter().filter(|&&f| f & 32 != 0).count();
    assert!(
        at_rest * 2 > rest.len(),
        "at rest on {at_rest} of {} samples",
        rest.len()
    );
    let magnet = column("magnetic-disturbance", "flagship");
    assert!(
        magnet.iter().any(|&f| f & 64 != 0),
        "no disturbance flagged"
    );
    let mahony = column("long-rest", "mahony");
    assert!(mahony.iter().all(|&f| f & (32 | 64) == 0));
}

/// Runs `rootfuse` with `args` (paths displayed) and returns exit code, stdout, stderr.
fn run_paths(args: &[&dyn AsRef<std::ffi::OsStr>]) -> (Option<i32>, String, String) {
    let o = bin()
        .args(args.iter().map(|a| a.as_ref()))
        .output()
        .expect("the binary runs");
    let (stdout, stderr) = text(&o);
    (o.status.code(), stdout, stderr)
}

fn simulated(dir: &Path, name: &str, seed: u64) -> PathBuf {
    let path = dir.join(name);
    write_recording(&path, &scenario("slow-rotation", seed, 3.0, 100.0).unwrap()).unwrap();
    path
}

/// Two inputs with the same file name would write the same estimate: refused before any
/// output is written (never the first estimate overwritten with exit code 0).
#[test]
fn run_refuses_two_inputs_with_one_output_name() {
    let dir = temp_dir("dupname");
    std::fs::create_dir_all(dir.join("a/s")).unwrap();
    let (a, b) = (
        simulated(&dir, "a/x.csv", 1),
        simulated(&dir, "a/s/x.csv", 2),
    );
    let out = dir.join("o");
    let (code, _, stderr) = run_paths(&[&"run", &a, &b, &"--filter", &"mahony", &"--out", &out]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("both estimates would be written to") && stderr.contains("x.csv"),
        "{stderr}"
    );
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(!out.join("x.csv").exists());
}

/// `--out` equal to the input folder would replace the input by its estimate: refused, the
/// input is untouched.
#[test]
fn run_refuses_to_overwrite_an_input() {
    let dir = temp_dir("overwrite");
    let input = simulated(&dir, "x.csv", 1);
    let before = std::fs::read(&input).unwrap();
    for out in [dir.to_path_buf(), dir.join(".")] {
        let (code, _, stderr) =
            run_paths(&[&"run", &input, &"--filter", &"mahony", &"--out", &out]);
        assert_eq!(code, Some(2), "{stderr}");
        assert!(stderr.contains("would overwrite this input"), "{stderr}");
    }
    // The folder as input too.
    let dir: &Path = &dir;
    let (code, _, stderr) = run_paths(&[&"run", &dir, &"--filter", &"mahony", &"--out", &dir]);
    assert_eq!(code, Some(2), "{stderr}");
    assert_eq!(std::fs::read(&input).unwrap(), before);
}

/// A header-only file, a 6D file under `--dof 9` and an empty folder are one clear error each
/// (not exit code 0 with nothing said, nor "no input could be read").
#[test]
fn run_refuses_files_it_cannot_use() {
    let dir = temp_dir("unusable");
    let header = dir.join("header.csv");
    std::fs::write(&header, "t,gx,gy,gz,ax,ay,az\n").unwrap();
    let (code, _, stderr) = run_paths(&[
        &"run",
        &header,
        &"--filter",
        &"mahony",
        &"--out",
        &dir.join("o"),
    ]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("header.csv: line 2: no data rows"),
        "{stderr}"
    );

    let mut rec = scenario("slow-rotation", 1, 2.0, 100.0).unwrap();
    rec.mag = None;
    let six = dir.join("six.csv");
    write_recording(&six, &rec).unwrap();
    let out = dir.join("o");
    for dof in [vec!["--dof", "9"], vec!["--param", "dof=9"]] {
        let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> =
            vec![&"run", &six, &"--filter", &"mahony", &"--out", &out];
        let dof_args: Vec<&dyn AsRef<std::ffi::OsStr>> = dof
            .iter()
            .map(|a| a as &dyn AsRef<std::ffi::OsStr>)
            .collect();
        args.extend(dof_args);
        let (code, _, stderr) = run_paths(&args);
        assert_eq!(code, Some(2), "{stderr}");
        assert!(
            stderr.contains("six.csv: no magnetometer columns (mx,my,mz)"),
            "{stderr}"
        );
    }
    // The filter's 9D default on a 6D file runs, and says what happens.
    let out = dir.join("default");
    let (code, stdout, stderr) = run_paths(&[&"run", &six, &"--filter", &"mahony", &"--out", &out]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("note: ") && stderr.contains("--dof 6"),
        "{stderr}"
    );
    assert!(
        stdout.contains(&format!("magnetometer {}", rec.len())),
        "{stdout}"
    );

    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let (code, _, stderr) = run_paths(&[&"run", &empty, &"--filter", &"mahony", &"--out", &out]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("no .csv files in the folder"), "{stderr}");
}

/// A NaN in an IMU column (a dropped packet) is skipped and counted by default: flagged per
/// sample, counted in the summary; `--strict` refuses the file.
#[test]
fn run_skips_and_counts_missing_imu_values() {
    let dir = temp_dir("gaps");
    let clean = dir.join("clean.csv");
    write_recording(&clean, &scenario("slow-rotation", 5, 3.0, 100.0).unwrap()).unwrap();
    let content = std::fs::read_to_string(&clean).unwrap();
    // Data line k is row k-1: the gyroscope x of row 50 and the accelerometer z of row 60.
    let gaps: Vec<String> = content
        .lines()
        .enumerate()
        .map(|(k, line)| {
            let mut cells: Vec<String> = line.split(',').map(str::to_string).collect();
            match k {
                51 => cells[1] = "NaN".into(),
                61 => cells[6] = "nan".into(),
                _ => {}
            }
            cells.join(",")
        })
        .collect();
    let input = dir.join("gaps.csv");
    std::fs::write(&input, gaps.join("\n") + "\n").unwrap();
    let out = dir.join("o");
    let (code, stdout, stderr) = run_paths(&[
        &"run",
        &input,
        &"--filter",
        &"mahony",
        &"--flags",
        &"--out",
        &out,
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stdout.contains("missing IMU values (NaN or infinite): 2 sample(s) in 1 file(s)"),
        "{stdout}"
    );
    assert!(stdout.contains("gyro 1, accelerometer 1"), "{stdout}");
    let est = read_estimates(out.join("gaps.csv")).unwrap();
    assert!(est.quat.iter().all(|q| q.w.is_finite()));
    let flags = flags_column(&out.join("gaps.csv"));
    assert_eq!((flags[50], flags[60]), (2, 4));
    assert_eq!(flags.iter().filter(|&&f| f != 0).count(), 2);

    let (code, _, stderr) = run_paths(&[
        &"run",
        &input,
        &"--filter",
        &"mahony",
        &"--strict",
        &"--out",
        &out,
    ]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("line 52, column `gx` (#2): IMU value NaN is not finite"),
        "{stderr}"
    );
}

/// Messages: a NUL byte is shown escaped, never raw.
#[test]
fn messages_escape_control_characters() {
    let dir = temp_dir("nul");
    let input = dir.join("nul.csv");
    std::fs::write(&input, "t,gx,gy,gz,ax,ay,az,use\n0,0,0,0,0,0,9.8,\u{0}\n").unwrap();
    let out = dir.join("o");
    let (code, _, stderr) = run_paths(&[&"run", &input, &"--filter", &"mahony", &"--out", &out]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("`\\u{0}` is not 0 or 1"), "{stderr}");
    assert!(!stderr.contains('\0'));
}

/// Writes an estimate file with the truth's times and the given quaternions.
fn write_est(path: &Path, t: &[f64], q: impl Fn(usize) -> [String; 4]) {
    let mut s = String::from("t,qw,qx,qy,qz\n");
    for (i, t) in t.iter().enumerate() {
        s.push_str(&format!("{t},{}\n", q(i).join(",")));
    }
    std::fs::write(path, s).unwrap();
}

/// `eval` refuses an estimate that is no orientation (it scored all-zero quaternions as
/// 0.000°), says "not finite" as `run` does, refuses a truth folder not fully covered, and
/// an empty estimate folder names the problem.
#[test]
fn eval_refuses_what_it_cannot_score() {
    let dir = temp_dir("evalbad");
    let truth = simulated(&dir, "x.csv", 3);
    let rec = read_csv(&truth).unwrap();
    let est = dir.join("est.csv");
    let good = |i: usize| {
        let q = rec.truth.as_ref().unwrap()[i];
        [q.w, q.x, q.y, q.z].map(|v| v.to_string())
    };
    let zero = || ["0", "0", "0", "0"].map(str::to_string);
    for (q, expected) in [
        (
            Box::new(|_| zero()) as Box<dyn Fn(usize) -> [String; 4]>,
            "line 2: quaternion `qw,qx,qy,qz` has norm 0",
        ),
        (
            Box::new(|i| if i >= 10 { zero() } else { good(i) }),
            "line 12: quaternion",
        ),
        (
            Box::new(|i| {
                let mut g = good(i);
                g[0] = (2.0 * g[0].parse::<f64>().unwrap()).to_string();
                g
            }),
            "line 2: quaternion",
        ),
        (
            Box::new(|i| {
                let mut g = good(i);
                if i == 4 {
                    g[2] = "NaN".into();
                }
                g
            }),
            "line 6, column `qy` (#4): estimate value NaN is not finite",
        ),
    ] {
        write_est(&est, &rec.t, q);
        let (code, _, stderr) = run_paths(&[&"eval", &truth, &est]);
        assert_eq!(code, Some(2), "{stderr}");
        assert!(stderr.contains(expected), "{expected}: {stderr}");
    }
    // A truth folder with a file that has no estimate: refused (the mean would cover less).
    let (truth_dir, est_dir) = (dir.join("truth"), dir.join("est"));
    std::fs::create_dir_all(&truth_dir).unwrap();
    std::fs::create_dir_all(&est_dir).unwrap();
    let (code, _, stderr) =
        run_paths(&[&"eval", &"--truth-dir", &truth_dir, &"--est-dir", &est_dir]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("no .csv files in the folder"), "{stderr}");
    std::fs::copy(&truth, truth_dir.join("a.csv")).unwrap();
    std::fs::copy(&truth, truth_dir.join("b.csv")).unwrap();
    write_est(&est_dir.join("a.csv"), &rec.t, good);
    let (code, _, stderr) =
        run_paths(&[&"eval", &"--truth-dir", &truth_dir, &"--est-dir", &est_dir]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("b.csv: no estimate"), "{stderr}");
    write_est(&est_dir.join("b.csv"), &rec.t, good);
    let (code, stdout, stderr) =
        run_paths(&[&"eval", &"--truth-dir", &truth_dir, &"--est-dir", &est_dir]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stdout.contains("| mean | 0.000 |"), "{stdout}");
}

/// Stale `<name>.tmp.<pid>` files of a killed run are removed by the next run writing `<name>`.
#[test]
fn run_removes_stale_temporary_files() {
    let dir = temp_dir("stale");
    let input = simulated(&dir, "x.csv", 1);
    let out = dir.join("o");
    std::fs::create_dir_all(&out).unwrap();
    let stale = out.join("x.csv.tmp.4000000");
    let other = out.join("y.csv.tmp.4000000");
    std::fs::write(&stale, "t,qw").unwrap();
    std::fs::write(&other, "t,qw").unwrap();
    let (code, _, stderr) = run_paths(&[&"run", &input, &"--filter", &"mahony", &"--out", &out]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stderr.contains("removed 1 temporary file(s)"), "{stderr}");
    assert!(!stale.exists() && out.join("x.csv").is_file());
    // Not this run's business: another output's temporary file stays.
    assert!(other.exists());
}

/// SIGTERM while the estimates are written: the process exits 130, every final file is
/// complete and no temporary file (`<name>.tmp.<pid>`) is left behind.
#[cfg(unix)]
#[test]
fn signal_during_writing_leaves_no_temporary_file() {
    let dir = temp_dir("signal");
    // Large static files, cheap to make, slow enough to write that the signal lands mid-write.
    let rows = 400_000;
    let mut content = String::from("t,gx,gy,gz,ax,ay,az\n");
    for i in 0..rows {
        content.push_str(&format!("{},0.001,0,0,0,0,9.81\n", i as f64 * 0.01));
    }
    let mut inputs = Vec::new();
    for k in 0..4 {
        let p = dir.join(format!("big{k}.csv"));
        std::fs::write(&p, &content).unwrap();
        inputs.push(p);
    }
    let out = dir.join("o");
    // Wait until a temporary file exists, then signal at once.
    let (code, stderr) = terminate_when(
        bin()
            .arg("run")
            .args(&inputs)
            .args(["--filter", "mahony", "--out"])
            .arg(&out),
        || !temporaries(&out).is_empty(),
        "a temporary file",
    );
    assert_eq!(code, Some(130), "{stderr}");
    assert!(stderr.contains("interrupted"), "{stderr}");
    assert_eq!(temporaries(&out), Vec::<PathBuf>::new());
    let written: Vec<PathBuf> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    // The files stream side by side, so none may be complete yet; those that are, are whole.
    assert!(written.len() < 4, "{written:?}");
    for p in written {
        let lines = std::fs::read_to_string(&p).unwrap().lines().count();
        assert_eq!(lines, rows + 1, "{} is incomplete", p.display());
    }
}

/// `(name, total)` of every file in `eval --json` output.
fn json_totals(json: &str) -> Vec<(String, f64)> {
    let parsed: serde_json::Value = serde_json::from_str(json).unwrap();
    parsed["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| {
            (
                f["name"].as_str().unwrap().to_string(),
                f["total"].as_f64().unwrap(),
            )
        })
        .collect()
}

/// `eval --align` on a simulated motion-capture truth (the simulated truth turned by an
/// earth offset and a sensor-to-body rotation), written as a motion-capture export is
/// (`t,qw,qx,qy,qz,use`, no IMU columns, time in ms, scored with `--units time=ms`): as good
/// as scoring against the truth in the IMU's own frames, and it prints both rotations.
#[test]
fn eval_align_scores_truth_in_other_frames() {
    use rootfuse_attitude::{Quat, Vec3};
    let dir = temp_dir("align");
    let rec = scenario("slow-rotation", 11, 60.0, 100.0).unwrap();
    let own = dir.join("own.csv");
    write_recording(&own, &rec).unwrap();
    let (earth, body) = (
        Quat::from_rotation_vector(Vec3::new(1.2, -0.4, 2.0)),
        Quat::from_rotation_vector(Vec3::new(-0.3, 0.9, 0.2)),
    );
    let mut mocap = String::from("t,qw,qx,qy,qz,use\n");
    for (t, q) in rec.t.iter().zip(rec.truth.as_ref().unwrap()) {
        let q = earth * *q * body.conj();
        let ms = t * 1000.0;
        mocap += &format!("{ms},{},{},{},{},1\n", q.w, q.x, q.y, q.z);
    }
    let mocap_path = dir.join("mocap.csv");
    std::fs::write(&mocap_path, mocap).unwrap();
    let out = dir.join("o");
    let (code, _, stderr) = run_paths(&[&"run", &own, &"--filter", &"flagship", &"--out", &out]);
    assert_eq!(code, Some(0), "{stderr}");
    let est = out.join("own.csv");
    let score = |truth: &Path, align: bool| -> (f64, String) {
        let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&"eval", &truth, &est, &"--json"];
        if align {
            args.push(&"--align");
        }
        if truth == mocap_path {
            args.push(&"--units=time=ms");
        }
        let (code, stdout, stderr) = run_paths(&args);
        assert_eq!(code, Some(0), "{stderr}");
        (json_totals(&stdout)[0].1, stdout)
    };
    let (reference, _) = score(&own, false);
    let (misaligned, _) = score(&mocap_path, false);
    let (aligned, json) = score(&mocap_path, true);
    assert!(misaligned > 30.0, "{misaligned}");
    assert!(
        aligned <= reference + 1e-3,
        "aligned {aligned}° vs {reference}° in the IMU's frames"
    );
    let parsed: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(
        parsed["files"][0]["align"]["earth"]
            .as_array()
            .map(Vec::len),
        Some(4),
        "{json}"
    );
    // Without the truth's time unit, the mismatch names it.
    let (code, _, stderr) = run_paths(&[&"eval", &mocap_path, &est, &"--align"]);
    assert_eq!(code, Some(2));
    assert!(
        stderr.contains("spans 1000.0000 times the estimates'")
            && stderr.contains("looks like ms (--units time=ms"),
        "{stderr}"
    );
    // Time in s declared ms: the hint says so; a truth offset by 10 s gets no unit hint.
    let (code, _, stderr) = run_paths(&[&"eval", &own, &est, &"--units=time=ms"]);
    assert_eq!(code, Some(2));
    assert!(
        stderr.contains("looks like s (leave time out of --units)"),
        "{stderr}"
    );
    let mut shifted = rec.clone();
    shifted.t.iter_mut().for_each(|t| *t += 10.0);
    let shifted_path = dir.join("shifted.csv");
    write_recording(&shifted_path, &shifted).unwrap();
    let (code, _, stderr) = run_paths(&[&"eval", &shifted_path, &est]);
    assert_eq!(code, Some(2));
    assert!(
        stderr.contains("does not match") && !stderr.contains("--units"),
        "{stderr}"
    );
    // The table shows both rotations.
    let (code, stdout, _) = run_paths(&[
        &"eval",
        &mocap_path,
        &est,
        &"--align",
        &"--units",
        &"time=ms",
    ]);
    assert_eq!(code, Some(0));
    assert!(
        stdout.contains("earth offset") && stdout.contains("sensor to body"),
        "{stdout}"
    );
}

/// `eval --consistency` judges the covariance `run --covariance` wrote: NEES/k and coverage
/// per file in the table and the JSON, a floor that can only raise coverage, and a one-line
/// refusal of an estimate file without covariance columns.
#[test]
fn eval_consistency_reads_the_covariance_columns() {
    let dir = temp_dir("consistency");
    let input = simulated(&dir, "c.csv", 2);
    let (with, without) = (dir.join("with"), dir.join("without"));
    for (out, extra) in [(&with, Some("--covariance")), (&without, None)] {
        let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> =
            vec![&"run", &input, &"--filter", &"flagship", &"--out", out];
        if let Some(e) = &extra {
            args.push(e);
        }
        let (code, _, stderr) = run_paths(&args);
        assert_eq!(code, Some(0), "{stderr}");
    }
    let coverage = |floor: &str| {
        let (code, stdout, stderr) = run_paths(&[
            &"eval",
            &input,
            &with.join("c.csv"),
            &"--consistency",
            &"--floor",
            &floor,
            &"--json",
        ]);
        assert_eq!(code, Some(0), "{stderr}");
        let json: serde_json::Value = serde_json::from_str(&stdout).unwrap();
        let c = &json["files"][0]["consistency"];
        assert!(c["nees_total"].as_f64().unwrap() > 0.0, "{stdout}");
        assert!(c["n_used"].as_u64().unwrap() > 0, "{stdout}");
        c["coverage_total"].as_f64().unwrap()
    };
    let (bare, floored) = (coverage("0"), coverage("5"));
    assert!(
        (0.0..=1.0).contains(&bare) && floored >= bare,
        "{bare} {floored}"
    );
    let (code, stdout, _) = run_paths(&[&"eval", &input, &with.join("c.csv"), &"--consistency"]);
    assert_eq!(code, Some(0));
    assert!(
        stdout.contains("NEES/3") && stdout.contains("inside 95 %"),
        "{stdout}"
    );
    let (code, _, stderr) = run_paths(&[&"eval", &input, &without.join("c.csv"), &"--consistency"]);
    assert_eq!(code, Some(2));
    assert!(
        stderr.contains("needs the covariance columns")
            && stderr.contains("rootfuse run --covariance"),
        "{stderr}"
    );
}

/// On BROAD (pre-aligned), aligning never makes a good estimate look worse: per trial, the
/// total RMSE after `--align` is at most the one without, 9D and 6D.
#[test]
#[cfg_attr(
    not(broad_data),
    ignore = "BROAD data not found (../shared/broad_csv or $ROOTFUSE_BROAD_DIR)"
)]
fn eval_align_never_hurts_on_broad() {
    let Some(broad) = broad_dir() else { return };
    let dir = temp_dir("align-broad");
    for dof in ["9", "6"] {
        let out = dir.join(dof);
        let (code, _, stderr) = run_paths(&[
            &"run",
            &broad,
            &"--filter",
            &"flagship",
            &"--dof",
            &dof,
            &"--out",
            &out,
        ]);
        assert_eq!(code, Some(0), "{stderr}");
        let score = |align: bool| {
            let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![
                &"eval",
                &"--truth-dir",
                &broad,
                &"--est-dir",
                &out,
                &"--dof",
                &dof,
                &"--json",
            ];
            if align {
                args.push(&"--align");
            }
            let (code, stdout, stderr) = run_paths(&args);
            assert_eq!(code, Some(0), "{stderr}");
            json_totals(&stdout)
        };
        let (plain, aligned) = (score(false), score(true));
        assert_eq!(plain.len(), 14);
        for ((name, p), (_, a)) in plain.iter().zip(&aligned) {
            eprintln!("{dof}D {name}: {p:.4}° -> aligned {a:.4}°");
            assert!(a <= p, "{dof}D {name}: aligned {a}° > {p}°");
        }
    }
}

/// `eval --align` on real data where a plain fit misleads: a y-up truth (BROAD 02 turned so
/// that its y axis is up, as many motion-capture systems are) scores as the z-up truth, 6D
/// and 9D; a still stretch (BROAD 27, rows 45319–46588: under 1° of rotation, where a plain
/// fit gives a 147° earth offset) is refused with the rotation it has and the rotation it needs;
/// five samples are scored with a warning.
#[test]
#[cfg_attr(
    not(broad_data),
    ignore = "BROAD data not found (../shared/broad_csv or $ROOTFUSE_BROAD_DIR)"
)]
fn eval_align_on_y_up_still_and_short_truths() {
    use rootfuse_attitude::{Quat, Vec3};
    let Some(broad) = broad_dir() else { return };
    let dir = temp_dir("align-real");
    let rec = read_csv(broad.join("02_undisturbed_slow_rotation_B.csv")).unwrap();
    let z_up = dir.join("z.csv");
    write_recording(&z_up, &rec).unwrap();
    let y_up_turn = Quat::from_axis_angle(Vec3::new(1.0, 0.0, 0.0), -std::f64::consts::FRAC_PI_2);
    let mut turned = rec.clone();
    for q in turned.truth.as_mut().unwrap() {
        *q = y_up_turn * *q;
    }
    let y_up = dir.join("y.csv");
    write_recording(&y_up, &turned).unwrap();
    for dof in ["9", "6"] {
        let out = dir.join(format!("o{dof}"));
        let (code, _, stderr) = run_paths(&[
            &"run",
            &z_up,
            &"--filter",
            &"flagship",
            &"--dof",
            &dof,
            &"--out",
            &out,
        ]);
        assert_eq!(code, Some(0), "{stderr}");
        let est = out.join("z.csv");
        let score = |truth: &Path| {
            let (code, stdout, stderr) =
                run_paths(&[&"eval", &truth, &est, &"--align", &"--dof", &dof, &"--json"]);
            assert_eq!(code, Some(0), "{stderr}");
            let json: serde_json::Value = serde_json::from_str(&stdout).unwrap();
            let vertical = json["files"][0]["align"]["vertical"].clone();
            (json_totals(&stdout)[0].1, vertical)
        };
        let ((z, z_vertical), (y, y_vertical)) = (score(&z_up), score(&y_up));
        assert!((z - y).abs() < 1e-6, "{dof}D: z-up {z}° vs y-up {y}°");
        assert!(z < 1.0, "{dof}D: {z}°");
        assert_eq!(z_vertical, serde_json::json!([0.0, 0.0, 1.0]));
        assert_eq!(y_vertical, serde_json::json!([0.0, 1.0, 0.0]));
    }

    let rec = read_csv(broad.join("27_disturbed_phone_vibration_B.csv")).unwrap();
    let still = dir.join("still.csv");
    write_recording(&still, &rec.slice(45317..46587)).unwrap();
    let out = dir.join("still-out");
    let (code, _, stderr) = run_paths(&[&"run", &still, &"--filter", &"flagship", &"--out", &out]);
    assert_eq!(code, Some(0), "{stderr}");
    for dof in ["9", "6"] {
        let (code, _, stderr) = run_paths(&[
            &"eval",
            &still,
            &out.join("still.csv"),
            &"--align",
            &"--dof",
            &dof,
        ]);
        assert_eq!(code, Some(2), "{stderr}");
        assert!(
            stderr.contains("does not rotate enough") && stderr.contains("at least 5° needed"),
            "{stderr}"
        );
    }

    let five = dir.join("five.csv");
    write_recording(&five, &read_csv(&z_up).unwrap().slice(20000..20005)).unwrap();
    let out = dir.join("five-out");
    let (code, _, stderr) = run_paths(&[&"run", &five, &"--filter", &"flagship", &"--out", &out]);
    assert_eq!(code, Some(0), "{stderr}");
    let (code, _, stderr) = run_paths(&[&"eval", &five, &out.join("five.csv")]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("only 5 sample(s) count") && stderr.contains("says little about accuracy"),
        "{stderr}"
    );
}

/// `run --help` documents the 1 s gap limit and what a signal does (the limit appeared
/// nowhere before).
#[test]
fn run_help_documents_gaps_and_signals() {
    let (code, stdout, _) = run_paths(&[&"run", &"--help"]);
    assert_eq!(code, Some(0));
    for expected in [
        "--max-dt",
        "max_dt",
        "max_gyr",
        "--strict",
        "SIGTERM",
        "exits with code 130",
    ] {
        assert!(stdout.contains(expected), "{expected}: {stdout}");
    }
}

/// Whole-number parameters refuse fractions instead of rounding them, and `--dof` cannot
/// silently beat a `--param dof` (none of `dof=7` as 6D, `window=2.5` as 3,
/// `--dof 9 --param dof=6` as 9D runs).
#[test]
fn parameters_refuse_fractions_and_contradictions() {
    let dir = temp_dir("kinds");
    let input = simulated(&dir, "x.csv", 1);
    let out = dir.join("out");
    for (args, expected) in [
        (vec!["--filter", "mahony", "--param", "dof=7"], "6 or 9"),
        (
            vec!["--filter", "ecf-ekf", "--param", "window=2.5"],
            "whole number",
        ),
        (
            vec!["--filter", "gyro", "--param", "init_from_acc=0.5"],
            "0 or 1",
        ),
        (
            vec!["--filter", "mahony", "--dof", "9", "--param", "dof=6"],
            "`dof` is given twice: by --dof 9 and by --param dof=6; give it once",
        ),
        (vec!["--filter", "mahony", "--max-dt", "0"], "--max-dt"),
    ] {
        let mut all: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&"run", &input, &"--out", &out];
        all.extend(args.iter().map(|a| a as &dyn AsRef<std::ffi::OsStr>));
        let (code, _, stderr) = run_paths(&all);
        assert_eq!(code, Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(expected), "{args:?}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{args:?}: one line: {stderr}");
    }
}

/// A parameter given twice, by its own option and by `--param` or by two `--param`, is one
/// error naming both, in every command that takes them (`run`, `throughput`): one value used
/// to win silently. So is `--dof` for `gyro`, which has no 6D/9D choice and ignored it.
#[test]
fn parameters_given_twice_or_where_unused_are_refused() {
    let dir = temp_dir("twice");
    let input = simulated(&dir, "x.csv", 1);
    let out = dir.join("out");
    let with_dof = "complementary, mahony, madgwick, ekf, sqrt-eskf, ecf-ekf, \
        complementary-reconstruction, lsq-fusion, heading-pipeline";
    let cases: [(&[&str], String); 5] = [
        (
            &["--filter", "mahony", "--max-dt", "2", "--param", "max_dt=3"],
            "`max_dt` is given twice: by --max-dt 2 and by --param max_dt=3; give it once".into(),
        ),
        (
            &["--filter", "mahony", "--param", "kp=1", "--param", "kp=2"],
            "`kp` is given twice: by --param kp=1 and by --param kp=2; give it once".into(),
        ),
        (
            &["--filter", "mahony", "--param", "kp=1", "--param", "kp=1"],
            "`kp` is given twice: by --param kp=1 and by --param kp=1; give it once".into(),
        ),
        (
            &["--filter", "mahony", "--dof", "6", "--param", "dof=6"],
            "`dof` is given twice: by --dof 6 and by --param dof=6; give it once".into(),
        ),
        (
            &["--filter", "gyro", "--dof", "6"],
            format!(
                "--dof 6: filter `gyro` has no 6D/9D choice (no `dof` parameter); leave dof out, or choose a filter that has one: {with_dof}"
            ),
        ),
    ];
    for (args, expected) in &cases {
        let expected = format!("error: {expected}\n");
        let mut run: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&"run", &input, &"--out", &out];
        run.extend(args.iter().map(|a| a as &dyn AsRef<std::ffi::OsStr>));
        let (code, _, stderr) = run_paths(&run);
        assert_eq!(
            (code, stderr.as_str()),
            (Some(2), expected.as_str()),
            "run {args:?}"
        );
        let mut throughput: Vec<&dyn AsRef<std::ffi::OsStr>> =
            vec![&"throughput", &"--channels", &"8", &"--samples", &"10"];
        throughput.extend(args.iter().map(|a| a as &dyn AsRef<std::ffi::OsStr>));
        let (code, _, stderr) = run_paths(&throughput);
        assert_eq!(
            (code, stderr.as_str()),
            (Some(2), expected.as_str()),
            "throughput {args:?}"
        );
    }
    assert!(!out.exists(), "nothing written");
    // Each once is fine, and gyro runs without a dof.
    for args in [
        &[
            "--filter", "mahony", "--max-dt", "2", "--param", "kp=1", "--dof", "6",
        ][..],
        &["--filter", "gyro"],
    ] {
        let mut run: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&"run", &input, &"--out", &out];
        run.extend(args.iter().map(|a| a as &dyn AsRef<std::ffi::OsStr>));
        let (code, _, stderr) = run_paths(&run);
        assert_eq!(code, Some(0), "{args:?}: {stderr}");
    }
}

/// The gap limit is settable: a 2 s gap is skipped by default (flag 1 at that sample) and
/// bridged with `--max-dt 3`.
#[test]
fn max_dt_sets_the_gap_limit() {
    let dir = temp_dir("maxdt");
    let mut rec = scenario("slow-rotation", 2, 4.0, 100.0).unwrap();
    let gap_at = 150;
    for t in &mut rec.t[gap_at..] {
        *t += 2.0;
    }
    let input = dir.join("gap.csv");
    write_recording(&input, &rec).unwrap();
    for (max_dt, skipped) in [(None, true), (Some("3"), false)] {
        let out = dir.join(format!("out-{skipped}"));
        let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![
            &"run",
            &input,
            &"--out",
            &out,
            &"--filter",
            &"mahony",
            &"--flags",
        ];
        if let Some(v) = &max_dt {
            args.extend([&"--max-dt" as &dyn AsRef<std::ffi::OsStr>, v]);
        }
        let (code, _, stderr) = run_paths(&args);
        assert_eq!(code, Some(0), "{stderr}");
        let flags = flags_column(&out.join("gap.csv"));
        assert_eq!(flags[gap_at] & 1 == 1, skipped, "max_dt {max_dt:?}");
        assert!(
            flags
                .iter()
                .enumerate()
                .all(|(k, f)| k == gap_at || f & 1 == 0)
        );
    }
}

/// `calibrate gyro` on a turntable (a steady 0.5 rad/s turn, no rest) says why it found no
/// rest phase: the blocks were steady but turning faster than a bias can be, and how long
/// the longest still stretch was against the length needed (not just "0 rest phases").
#[test]
fn calibrate_gyro_says_why_there_is_no_rest() {
    use rootfuse_attitude::{Recording, Vec3};
    let dir = temp_dir("turntable");
    let n = 3000;
    let t: Vec<f64> = (0..n).map(|i| i as f64 * 0.01).collect();
    let rec = Recording {
        name: "turn".into(),
        gyr: vec![Vec3::new(0.0, 0.0, 0.5); n],
        acc: vec![Vec3::new(0.0, 0.0, 9.81); n],
        mag: Some(
            t.iter()
                .map(|&s| Vec3::new(20.0 * (0.5 * s).cos(), -20.0 * (0.5 * s).sin(), -45.0))
                .collect(),
        ),
        t,
        truth: None,
        use_mask: None,
    };
    let file = dir.join("turn.csv");
    write_recording(&file, &rec).unwrap();
    let cal = dir.join("cal.json");
    let o = run(&[
        "calibrate",
        "gyro",
        file.to_str().unwrap(),
        "--out",
        cal.to_str().unwrap(),
    ]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    for part in [
        "no rest phase found",
        "120 were steady but turning at 0.500 rad/s or more",
        "a turntable is not rest",
        "the longest still stretch lasted 0.00 s, 1 s needed",
    ] {
        assert!(err.contains(part), "{part}: {err}");
    }
    assert!(!cal.exists(), "nothing written");
}

/// `calibrate mag` on a recording with 30 % hard iron writes a JSON calibration close to the
/// truth; `calibrate gyro` adds its section to the same file; `run --calibration` applies it;
/// a malformed calibration file is one clear error, exit 2.
#[test]
fn calibrate_writes_what_run_applies() {
    let dir = temp_dir("calibrate");
    let mut sim =
        rootfuse_eval::sim::scenario_simulation("slow-rotation", 3, 120.0, 100.0).unwrap();
    sim.sensor.mag.as_mut().unwrap().hard_iron = rootfuse_attitude::Vec3::new(12.0, -7.0, 6.0);
    let rec = sim.run().unwrap().recording;
    let file = dir.join("rec.csv");
    write_recording(&file, &rec).unwrap();
    let cal = dir.join("cal.json");
    let f = file.to_str().unwrap();
    let c = cal.to_str().unwrap();
    let o = run(&["calibrate", "mag", f, "--norm", "50", "--out", c]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{out}\n{err}");
    assert!(out.contains("model full"), "{out}");
    let o = run(&["calibrate", "gyro", f, "--out", c]);
    assert!(o.status.success(), "{:?}", text(&o));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&cal).unwrap()).unwrap();
    let h: Vec<f64> = json["mag"]["offset"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert!(
        (h[0] - 12.0).abs() < 0.25 && (h[1] + 7.0).abs() < 0.25 && (h[2] - 6.0).abs() < 0.25,
        "{h:?}"
    );
    assert_eq!(json["mag"]["model"], "full");
    assert_eq!(json["mag"]["units"], "uT");
    assert!(json["gyro"]["offset"].is_array() && json["gyro"]["norm"].is_null());
    let out_dir = dir.join("out");
    let o_dir = out_dir.to_str().unwrap();
    let run_calibrated = || {
        run(&[
            "run",
            f,
            "--filter",
            "sqrt-eskf",
            "--calibration",
            c,
            "--out",
            o_dir,
        ])
    };
    let o = run_calibrated();
    assert!(o.status.success(), "{:?}", text(&o));
    // The same readings written in nT: calibrated with the run's --units, the offset is the
    // µT one (the calibration applies to converted readings); a run that reads them in
    // another unit than the calibration saw is refused.
    let mut in_nt = rec.clone();
    for m in in_nt.mag.as_mut().unwrap() {
        *m = *m * 1000.0;
    }
    let file_nt = dir.join("rec_nt.csv");
    write_recording(&file_nt, &in_nt).unwrap();
    let cal_nt = dir.join("cal_nt.json");
    let (f_nt, c_nt) = (file_nt.to_str().unwrap(), cal_nt.to_str().unwrap());
    let o = run(&[
        "calibrate",
        "mag",
        f_nt,
        "--norm",
        "50",
        "--units",
        "mag=nT",
        "--out",
        c_nt,
    ]);
    assert!(o.status.success(), "{:?}", text(&o));
    let json_nt: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&cal_nt).unwrap()).unwrap();
    assert_eq!(json_nt["mag"]["units"], "nT");
    let h_nt = json_nt["mag"]["offset"][0].as_f64().unwrap();
    assert!(
        (h_nt - h[0]).abs() < 1e-6 * h[0].abs(),
        "{h_nt} µT vs {} µT",
        h[0]
    );
    let run_nt = |cal: &str, units: &str| {
        run(&[
            "run",
            f_nt,
            "--units",
            units,
            "--calibration",
            cal,
            "--out",
            o_dir,
            "--force",
        ])
    };
    let o = run_nt(c_nt, "mag=nT");
    assert!(o.status.success(), "{:?}", text(&o));
    // The same unit as a factor is the same unit.
    let o = run_nt(c_nt, "mag=0.001");
    assert!(o.status.success(), "{:?}", text(&o));
    let o = run_nt(c, "mag=nT");
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        err.contains("fitted on readings in uT, and this run reads them in nT")
            && err.contains("run with --units mag=uT"),
        "{err}"
    );
    // Time in ms is named, as `run` names it (it found thousands of "rest phases" quietly).
    let mut in_ms = rec.clone();
    in_ms.t.iter_mut().for_each(|t| *t *= 1000.0);
    let file_ms = dir.join("rec_ms.csv");
    write_recording(&file_ms, &in_ms).unwrap();
    let cal_ms = dir.join("cal_ms.json");
    let o = run(&[
        "calibrate",
        "gyro",
        file_ms.to_str().unwrap(),
        "--out",
        cal_ms.to_str().unwrap(),
    ]);
    let (_, err) = text(&o);
    assert!(err.contains("run with --units time=ms"), "{err}");
    // Motion that covers a cap of the sphere of directions: refused, unless allowed.
    let cap = rootfuse_eval::sim::scenario("handheld-translation", 1, 30.0, 100.0).unwrap();
    let file_cap = dir.join("cap.csv");
    write_recording(&file_cap, &cap).unwrap();
    let f_cap = file_cap.to_str().unwrap();
    let cal_cap = dir.join("cap.json");
    let c_cap = cal_cap.to_str().unwrap();
    let o = run(&["calibrate", "mag", f_cap, "--out", c_cap]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        err.contains("% of the sphere of directions, at least 40 % needed"),
        "{err}"
    );
    assert!(!cal_cap.exists(), "nothing written");
    let o = run(&[
        "calibrate",
        "mag",
        f_cap,
        "--min-coverage",
        "0",
        "--out",
        c_cap,
    ]);
    assert!(o.status.success(), "{:?}", text(&o));
    // A broken calibration file: refused before anything runs.
    std::fs::write(
        &cal,
        r#"{"format": "rootfuse-calibration", "mag": {"offset": [1, 2]}}"#,
    )
    .unwrap();
    let o = run_calibrated();
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2));
    assert!(err.contains("mag.offset"), "{err}");
    // Too little motion for a magnetometer calibration: a clear refusal.
    let still = rootfuse_eval::sim::scenario("static", 4, 20.0, 100.0).unwrap();
    write_recording(&file, &still).unwrap();
    let o = run(&["calibrate", "mag", f, "--out", c]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2));
    assert!(err.contains("constant reading"), "{err}");
}
