//! End-to-end tests of the built `rootfuse` binary: run + eval agree with the library, and
//! bad input gives one clear line and exit code 2 (never a panic).
use rootfuse_attitude::io::{read_csv, read_estimates, write_recording};
use rootfuse_attitude::metrics::{Alignment, evaluate};
use rootfuse_attitude::sim::scenario;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_rootfuse"))
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rootfuse-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
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
        let field = |key: &str| -> f64 {
            let start = json.find(&format!("\"{key}\": ")).unwrap() + key.len() + 4;
            json[start..]
                .split([',', '}'])
                .next()
                .unwrap()
                .trim()
                .parse()
                .unwrap()
        };
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
        let written = std::fs::read_to_string(out.join(format!("{scenario_name}.csv"))).unwrap();
        written
            .lines()
            .skip(1)
            .map(|l| l.rsplit(',').next().unwrap().parse::<f64>().unwrap() as u8)
            .collect()
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
