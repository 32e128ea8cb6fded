//! `rootfuse simulate` and `rootfuse run` on Parquet and Arrow fleets: results equal the
//! library's per device bit for bit; bad input gives one line naming file, row group, row and
//! column, exit code 2 and no output file; `--keep-going` completes the rest (exit code 1).
use arrow::array::{ArrayRef, AsArray, Float32Array, Float64Array, RecordBatch, StringArray};
use arrow::datatypes::{Float64Type, Int64Type};
use arrow::record_batch::RecordBatchWriter;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use rootfuse_attitude::registry::FilterSpec;
use rootfuse_batch::{Precision, run_recordings};
use rootfuse_eval::sim::scenario;
use std::path::{Path, PathBuf};
use std::sync::Arc;

mod common;
use common::columns::{fleet_columns, floats, replace, write_parquet};
use common::{Scratch, bin};

fn temp_dir(name: &str) -> Scratch {
    common::temp_dir("fleet", name)
}

fn run(args: &[&dyn AsRef<std::ffi::OsStr>]) -> (Option<i32>, String, String) {
    let o = bin().args(args).output().unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// `rootfuse run INPUT --filter mahony --dof 6 --out OUT`.
fn run_6d(input: &Path, out: &Path) -> (Option<i32>, String, String) {
    run_6d_with(input, out, &[])
}

/// [`run_6d`] with `extra` arguments after the others.
fn run_6d_with(input: &Path, out: &Path, extra: &[&str]) -> (Option<i32>, String, String) {
    let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![
        &"run",
        &input,
        &"--filter",
        &"mahony",
        &"--dof",
        &"6",
        &"--out",
        &out,
    ];
    for e in extra {
        args.push(e);
    }
    run(&args)
}

/// Every file in `dir` (none may be a temporary file).
fn files_in(dir: &Path) -> Vec<PathBuf> {
    // The ledger of the files rootfuse wrote (`.rootfuse-outputs.json`) is not an output.
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|d| {
            d.map(|e| e.unwrap().path())
                .filter(|p| !p.ends_with(".rootfuse-outputs.json"))
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// `(device, t, [qw, qx, qy, qz])` rows of a Parquet estimate file.
fn read_parquet_estimates(path: &Path) -> Vec<(i64, f64, [f64; 4])> {
    let file = std::fs::File::open(path).unwrap();
    let reader = ParquetRecordBatchReaderBuilder::try_new(file)
        .unwrap()
        .build()
        .unwrap();
    let mut rows = Vec::new();
    for batch in reader {
        let b = batch.unwrap();
        let f = |n: &str| {
            b.column_by_name(n)
                .unwrap()
                .as_primitive::<Float64Type>()
                .clone()
        };
        let d = b
            .column_by_name("device")
            .unwrap()
            .as_primitive::<Int64Type>()
            .clone();
        let (t, w, x, y, z) = (f("t"), f("qw"), f("qx"), f("qy"), f("qz"));
        for r in 0..b.num_rows() {
            rows.push((
                d.value(r),
                t.value(r),
                [w.value(r), x.value(r), y.value(r), z.value(r)],
            ));
        }
    }
    rows
}

/// The simulator's devices (seeds 0..n, slow-rotation) run through the library directly:
/// per device, `(t, quaternion)` of every sample.
fn library_estimates(n: u64, seconds: f64, precision: Precision) -> Vec<Vec<(f64, [f64; 4])>> {
    let spec = FilterSpec::new("sqrt-eskf").unwrap();
    let recs: Vec<_> = (0..n)
        .map(|s| scenario("slow-rotation", s, seconds, 100.0).unwrap())
        .collect();
    run_recordings(&spec, &recs, precision)
        .into_iter()
        .zip(&recs)
        .map(|(o, rec)| {
            rec.t
                .iter()
                .zip(&o.quat)
                .map(|(&t, q)| (t, q.to_array()))
                .collect()
        })
        .collect()
}

/// A simulated fleet run from Parquet equals the library per device, bit for bit, in f64
/// and f32; the Arrow IPC input and output give the same numbers.
#[test]
fn simulated_fleet_equals_the_library_per_device() {
    let dir = temp_dir("equal");
    let fleet = dir.join("fleet.parquet");
    let (code, stdout, stderr) = run(&[
        &"simulate",
        &"--devices",
        &"5",
        &"--seconds",
        &"3",
        &"--rate",
        &"100",
        &"--out",
        &fleet,
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stdout.contains("5 device(s), 1500 rows"), "{stdout}");
    for (precision, name) in [(Precision::F64, "f64"), (Precision::F32, "f32")] {
        let out = dir.join(format!("o-{name}"));
        let (code, stdout, stderr) = run(&[
            &"run",
            &fleet,
            &"--filter",
            &"flagship",
            &"--precision",
            &name,
            &"--out",
            &out,
        ]);
        assert_eq!(code, Some(0), "{stderr}");
        assert!(
            stdout.contains("1 file(s), 5 device(s), 1500 samples"),
            "{stdout}"
        );
        let rows = read_parquet_estimates(&out.join("fleet.parquet"));
        assert_eq!(rows.len(), 1500);
        let expected = library_estimates(5, 3.0, precision);
        let mut next = [0usize; 5];
        for (d, t, q) in rows {
            let k = next[d as usize];
            next[d as usize] += 1;
            let (te, e) = expected[d as usize][k];
            assert_eq!(t.to_bits(), te.to_bits(), "device {d} row {k}");
            assert_eq!(
                q.map(f64::to_bits),
                e.map(f64::to_bits),
                "device {d} row {k} ({name})"
            );
        }
        assert_eq!(next, [300; 5]);
    }
    // Arrow IPC in and out: the same numbers.
    let arrow_fleet = dir.join("fleet.arrow");
    let (code, _, stderr) = run(&[
        &"simulate",
        &"--devices",
        &"5",
        &"--seconds",
        &"3",
        &"--out",
        &arrow_fleet,
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    let out = dir.join("o-arrow");
    let (code, _, stderr) = run(&[
        &"run",
        &arrow_fleet,
        &"--filter",
        &"flagship",
        &"--format",
        &"parquet",
        &"--out",
        &out,
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(
        read_parquet_estimates(&out.join("fleet.parquet")),
        read_parquet_estimates(&dir.join("o-f64/fleet.parquet"))
    );
}

/// A CSV recording streamed in blocks gives the same estimate file as the library's whole
/// run, without reading the file whole first.
#[test]
fn csv_streaming_equals_the_library() {
    let dir = temp_dir("csv");
    // Longer than one block (65 536 rows over the files), with files of different lengths.
    let recs = [
        scenario("slow-rotation", 1, 700.0, 100.0).unwrap(),
        scenario("static", 2, 30.0, 200.0).unwrap(),
    ];
    let mut inputs = Vec::new();
    for (k, rec) in recs.iter().enumerate() {
        let p = dir.join(format!("r{k}.csv"));
        rootfuse_io::write_recording(&p, rec).unwrap();
        inputs.push(p);
    }
    let out = dir.join("o");
    let (code, _, stderr) = run(&[
        &"run",
        &inputs[0],
        &inputs[1],
        &"--filter",
        &"mahony",
        &"--out",
        &out,
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    let spec = FilterSpec::new("mahony").unwrap();
    let expected = run_recordings(&spec, &recs, Precision::F64);
    for (k, e) in expected.iter().enumerate() {
        let est = rootfuse_io::read_estimates(out.join(format!("r{k}.csv"))).unwrap();
        assert_eq!(est.quat, e.quat, "file {k}");
    }
}

/// Runs one bad file: exit code 2, the message contains every `expected` part, and the
/// output folder holds no file at all (nothing half-written).
fn refused(dir: &Path, input: &Path, extra: &[&str], expected: &[&str]) {
    let out = dir.join("o");
    let (code, _, stderr) = run_6d_with(input, &out, extra);
    assert_eq!(code, Some(2), "{}: {stderr}", input.display());
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    for part in expected {
        assert!(stderr.contains(part), "`{part}` not in: {stderr}");
    }
    assert_eq!(files_in(&out), Vec::<PathBuf>::new(), "{stderr}");
}

#[test]
fn bad_fleet_files_are_refused_with_their_place() {
    let dir = temp_dir("bad");
    let rows = 40;
    let name = |n: &str| dir.join(n);

    let p = name("missing.parquet");
    let mut cols = fleet_columns(rows);
    cols.retain(|(n, _)| *n != "gy");
    write_parquet(&p, cols, 16);
    refused(
        &dir,
        &p,
        &[],
        &["missing.parquet: missing required column `gy` (the file has `device`, `t`, `gx`, `gz`"],
    );

    let p = name("mistyped.parquet");
    let text: ArrayRef = Arc::new(StringArray::from(vec!["0.01"; rows]));
    write_parquet(&p, replace(fleet_columns(rows), "t", text), 16);
    refused(
        &dir,
        &p,
        &[],
        &[
            "mistyped.parquet: column `t` has type Utf8, expected a number (float, integer) or a timestamp",
        ],
    );

    let p = name("device-float.parquet");
    write_parquet(
        &p,
        replace(fleet_columns(rows), "device", floats(&vec![1.5; rows])),
        16,
    );
    refused(
        &dir,
        &p,
        &[],
        &["column `device` has type Float64, expected an integer or string"],
    );

    // Device 1's time goes back at file row 27 (row group 1 of 16-row groups).
    let p = name("backwards.parquet");
    let mut t: Vec<f64> = (0..rows).map(|r| (r / 2) as f64 * 0.01).collect();
    t[27] = 0.05;
    write_parquet(&p, replace(fleet_columns(rows), "t", floats(&t)), 16);
    refused(
        &dir,
        &p,
        &[],
        &[
            "backwards.parquet: row group 1, row 27, column `t` (device 1): time 0.05 does not increase",
        ],
    );

    let p = name("null-time.parquet");
    let mut t: Vec<Option<f64>> = (0..rows).map(|r| Some((r / 2) as f64 * 0.01)).collect();
    t[35] = None;
    write_parquet(
        &p,
        replace(fleet_columns(rows), "t", Arc::new(Float64Array::from(t))),
        16,
    );
    refused(
        &dir,
        &p,
        &[],
        &["null-time.parquet: row group 2, row 35, column `t`: time is null"],
    );

    // A NaN IMU row is a dropped packet: kept and counted, refused with --strict.
    let p = name("nan.parquet");
    let mut gx = vec![0.0; rows];
    gx[20] = f64::NAN;
    write_parquet(&p, replace(fleet_columns(rows), "gx", floats(&gx)), 16);
    refused(
        &dir,
        &p,
        &["--strict"],
        &["nan.parquet: row group 1, row 20, column `gx`: IMU value NaN is not finite"],
    );
    let out = dir.join("nan-kept");
    let (code, stdout, stderr) = run_6d(&p, &out);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stdout.contains("missing IMU values (NaN or infinite): 1 sample(s)"),
        "{stdout}"
    );
    assert!(stdout.contains("gyro 1"), "{stdout}");

    // float32 columns are read as well.
    let p = name("f32.parquet");
    let t32: ArrayRef = Arc::new(Float32Array::from(
        (0..rows).map(|r| (r / 2) as f32 * 0.01).collect::<Vec<_>>(),
    ));
    write_parquet(&p, replace(fleet_columns(rows), "t", t32), 16);
    let (code, stdout, stderr) = run_6d(&p, &dir.join("f32"));
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stdout.contains(&format!("{rows} samples")), "{stdout}");

    // Truncated and corrupt files.
    let good = name("good.parquet");
    write_parquet(&good, fleet_columns(rows), 16);
    let bytes = std::fs::read(&good).unwrap();
    let p = name("truncated.parquet");
    std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    refused(
        &dir,
        &p,
        &[],
        &["truncated.parquet: not a readable Parquet file"],
    );
    let p = name("corrupt.parquet");
    let mut bad = bytes.clone();
    // The data pages start right after the 4-byte magic: scramble the first column chunk.
    for b in &mut bad[4..60] {
        *b ^= 0x5a;
    }
    std::fs::write(&p, &bad).unwrap();
    refused(
        &dir,
        &p,
        &[],
        &["corrupt.parquet: row group 0: not a readable Parquet file"],
    );
    let p = name("garbage.arrow");
    std::fs::write(&p, b"ARROW1\0\0not really").unwrap();
    refused(
        &dir,
        &p,
        &[],
        &["garbage.arrow: not a readable Arrow IPC file"],
    );
}

/// An Arrow record batch without rows is skipped with a note; the file completes.
#[test]
fn empty_record_batch_is_skipped_and_noted() {
    let dir = temp_dir("empty");
    let p = dir.join("gaps.arrow");
    let batch = RecordBatch::try_from_iter(fleet_columns(20)).unwrap();
    let mut w = arrow::ipc::writer::FileWriter::try_new(
        std::fs::File::create(&p).unwrap(),
        &batch.schema(),
    )
    .unwrap();
    w.write(&batch.slice(0, 10)).unwrap();
    w.write(&batch.slice(10, 0)).unwrap();
    w.write(&batch.slice(10, 10)).unwrap();
    w.finish().unwrap();
    let out = dir.join("o");
    let (code, stdout, stderr) = run_6d(&p, &out);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("gaps.arrow: 1 record batch(es) without rows skipped: [1]"),
        "{stderr}"
    );
    assert!(stdout.contains("20 samples"), "{stdout}");
    assert!(out.join("gaps.arrow").is_file());
}

/// An Arrow IPC stream (`.arrows`, or `.arrow` as pyarrow's stream writer leaves it) runs
/// like the same rows in an IPC file; a stream cut after its last whole record batch (the
/// end-of-stream marker lost) is refused naming the file, exit code 2, nothing written.
#[test]
fn arrow_ipc_stream_runs_like_the_ipc_file() {
    let dir = temp_dir("stream");
    let batch = RecordBatch::try_from_iter(fleet_columns(40)).unwrap();
    let parts = [batch.slice(0, 25), batch.slice(25, 15)];
    fn write_all(mut w: impl RecordBatchWriter, parts: &[RecordBatch]) {
        for b in parts {
            w.write(b).unwrap();
        }
        w.close().unwrap();
    }
    let file = dir.join("file.arrow");
    let create = |path: &Path| std::fs::File::create(path).unwrap();
    write_all(
        arrow::ipc::writer::FileWriter::try_new(create(&file), &batch.schema()).unwrap(),
        &parts,
    );
    let estimates = |input: &Path, out: &str| {
        let out = dir.join(out);
        let (code, stdout, stderr) = run_6d_with(input, &out, &["--format", "parquet"]);
        assert_eq!(code, Some(0), "{}: {stderr}", input.display());
        assert!(stdout.contains("40 samples"), "{stdout}");
        let stem = input.file_stem().unwrap().to_string_lossy().into_owned();
        read_parquet_estimates(&out.join(format!("{stem}.parquet")))
    };
    let expected = estimates(&file, "o-file");
    assert_eq!(expected.len(), 40);
    for name in ["stream.arrows", "stream-named.arrow"] {
        let stream = dir.join(name);
        write_all(
            arrow::ipc::writer::StreamWriter::try_new(create(&stream), &batch.schema()).unwrap(),
            &parts,
        );
        assert_eq!(estimates(&stream, &format!("o-{name}")), expected, "{name}");
    }
    let bytes = std::fs::read(dir.join("stream.arrows")).unwrap();
    let cut = dir.join("cut.arrows");
    std::fs::write(&cut, &bytes[..bytes.len() - 8]).unwrap();
    refused(
        &dir,
        &cut,
        &[],
        &[
            "cut.arrows: record batch 2: not a readable Arrow IPC stream file",
            "end-of-stream marker",
        ],
    );
}

/// `--keep-going`: a device whose time goes back is left out from that row on, a corrupt
/// file is skipped; the other devices and files complete, exit code 1.
#[test]
fn keep_going_completes_the_other_devices_and_files() {
    let dir = temp_dir("keep");
    let rows = 40;
    let mut t: Vec<f64> = (0..rows).map(|r| (r / 2) as f64 * 0.01).collect();
    t[27] = 0.05;
    let a = dir.join("a.parquet");
    write_parquet(&a, replace(fleet_columns(rows), "t", floats(&t)), 16);
    let b = dir.join("b.parquet");
    std::fs::write(&b, b"PAR1 not a parquet file PAR1").unwrap();
    let out = dir.join("o");
    let (code, stdout, stderr) = run(&[
        &"run",
        &a,
        &b,
        &"--filter",
        &"mahony",
        &"--dof",
        &"6",
        &"--keep-going",
        &"--out",
        &out,
    ]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("row 27, column `t` (device 1)"), "{stderr}");
    assert!(stderr.contains("b.parquet"), "{stderr}");
    assert!(
        stdout.contains("1 file(s), 2 device(s), 33 samples"),
        "{stdout}"
    );
    assert_eq!(files_in(&out), vec![out.join("a.parquet")]);
    let rows = read_parquet_estimates(&out.join("a.parquet"));
    assert_eq!(rows.iter().filter(|r| r.0 == 0).count(), 20);
    assert_eq!(rows.iter().filter(|r| r.0 == 1).count(), 13);
}

/// `--device-params`: each listed device runs with its own parameters (one of them a
/// structural one, so it gets a chunk of its own) and equals the library's run of it with
/// those parameters bit for bit; the others run with the run's; the run says how many did
/// and lists the table's devices without rows; a bad cell names file, line and column.
#[test]
fn device_params_run_each_device_with_its_own() {
    let dir = temp_dir("device_params");
    let fleet = dir.join("fleet.parquet");
    let (code, _, stderr) = run(&[
        &"simulate",
        &"--devices",
        &"5",
        &"--seconds",
        &"2",
        &"--out",
        &fleet,
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    let params = dir.join("params.csv");
    std::fs::write(
        &params,
        "device,gyr_noise,max_dt\n0,0.02,\n3,,0.5\n99,0.01,\n",
    )
    .unwrap();
    let with_params = |params: &Path, out: &Path| {
        run(&[
            &"run",
            &fleet,
            &"--filter",
            &"flagship",
            &"--device-params",
            &params,
            &"--out",
            &out,
        ])
    };
    let out = dir.join("out");
    let (code, _, stderr) = with_params(&params, &out);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("2 device(s) with parameters of their own, 3 device(s) not in it"),
        "{stderr}"
    );
    assert!(
        stderr.contains("1 device(s) of the table had no rows: 99"),
        "{stderr}"
    );
    let rows = read_parquet_estimates(&out.join("fleet.parquet"));
    for d in 0..5u64 {
        let mut spec = FilterSpec::new("sqrt-eskf").unwrap();
        match d {
            0 => spec.set("gyr_noise=0.02").unwrap(),
            3 => spec.set("max_dt=0.5").unwrap(),
            _ => {}
        }
        let rec = scenario("slow-rotation", d, 2.0, 100.0).unwrap();
        let want = &run_recordings(&spec, &[rec], Precision::F64)[0].quat;
        let got: Vec<[f64; 4]> = rows
            .iter()
            .filter(|r| r.0 == d as i64)
            .map(|r| r.2)
            .collect();
        assert_eq!(got.len(), want.len(), "device {d}");
        for (k, (g, w)) in got.iter().zip(want).enumerate() {
            let same = g
                .iter()
                .zip(w.to_array())
                .all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(same, "device {d}, sample {k}: {g:?} vs {w:?}");
        }
    }
    let bad = dir.join("bad.csv");
    std::fs::write(&bad, "device,gyr_noise\n0,0.02\n1,fast\n").unwrap();
    let (code, _, stderr) = with_params(&bad, &dir.join("out2"));
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("bad.csv: line 3, column `gyr_noise`: expected a number"),
        "{stderr}"
    );
    let unknown = dir.join("unknown.csv");
    std::fs::write(&unknown, "device,kp\n0,1.0\n").unwrap();
    let (code, _, stderr) = with_params(&unknown, &dir.join("out3"));
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("unknown.csv: line 2, column `kp`"),
        "{stderr}"
    );
}

/// Device `d` of the estimates equals the library's run of the simulated device with `spec`
/// bit for bit.
fn assert_device_runs(rows: &[(i64, f64, [f64; 4])], d: u64, seconds: f64, spec: &FilterSpec) {
    let rec = scenario("slow-rotation", d, seconds, 100.0).unwrap();
    let want = &run_recordings(spec, &[rec], Precision::F64)[0].quat;
    let got: Vec<[f64; 4]> = rows
        .iter()
        .filter(|r| r.0 == d as i64)
        .map(|r| r.2)
        .collect();
    assert_eq!(got.len(), want.len(), "device {d}");
    for (k, (g, w)) in got.iter().zip(want).enumerate() {
        let same = g
            .iter()
            .zip(w.to_array())
            .all(|(a, b)| a.to_bits() == b.to_bits());
        assert!(same, "device {d}, sample {k}: {g:?} vs {w:?}");
    }
}

/// A `--device-params` column that the command line also sets is the documented precedence,
/// said aloud: the table's value for its devices, the command line's for the others. A
/// table with one parameter in two columns is refused (the last column does not win).
#[test]
fn device_params_over_the_command_line_is_said_aloud() {
    let dir = temp_dir("device_params_over");
    let fleet = dir.join("fleet.parquet");
    let (code, _, stderr) = run(&[
        &"simulate",
        &"--devices",
        &"2",
        &"--seconds",
        &"1",
        &"--out",
        &fleet,
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    let with_table = |table: &Path, out: &Path| {
        run(&[
            &"run",
            &fleet,
            &"--filter",
            &"flagship",
            &"--param",
            &"gyr_noise=0.03",
            &"--device-params",
            &table,
            &"--out",
            &out,
        ])
    };
    let table = dir.join("params.csv");
    std::fs::write(&table, "device,gyr_noise\n0,0.02\n").unwrap();
    let out = dir.join("out");
    let (code, _, stderr) = with_table(&table, &out);
    assert_eq!(code, Some(0), "{stderr}");
    let note = format!(
        "note: --device-params {}: column `gyr_noise` is set over --param gyr_noise=0.03 for the 1 device(s) with a value in it; the others run with --param gyr_noise=0.03\n",
        table.display()
    );
    assert!(stderr.starts_with(&note), "{stderr}");
    let rows = read_parquet_estimates(&out.join("fleet.parquet"));
    for (d, noise) in [(0, "0.02"), (1, "0.03")] {
        let mut spec = FilterSpec::new("sqrt-eskf").unwrap();
        spec.set(&format!("gyr_noise={noise}")).unwrap();
        assert_device_runs(&rows, d, 1.0, &spec);
    }

    let twice = dir.join("twice.csv");
    std::fs::write(&twice, "device,gyr_noise,gyr_noise\n0,0.02,0.01\n").unwrap();
    let (code, _, stderr) = with_table(&twice, &dir.join("out2"));
    assert_eq!(code, Some(2), "{stderr}");
    assert_eq!(
        stderr,
        format!(
            "error: {}: column `gyr_noise`: the table has this column twice; give each parameter one column\n",
            twice.display()
        )
    );
}
