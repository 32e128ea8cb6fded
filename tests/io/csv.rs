//! The CSV reader and writer (every error kind names file, line and column), the BROAD
//! metrics on hand-made cases, and the four real BROAD trials.
use rootfuse_attitude::{Quat, Recording, Vec3};
use rootfuse_eval::metrics::{Alignment, MetricsError, error_series, evaluate, rmse, sample_error};
use rootfuse_io::{
    ImuGaps, ReadError, WriteError, list_dir, read_csv, read_csv_with, read_dir, read_estimates,
    read_index, stale_temporaries, temporary_path, write_estimates, write_recording,
};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// A fresh, empty folder under the system temp dir, unique per call (tests run in parallel),
/// removed with everything in it when the guard is dropped (at the end of the test).
pub(super) struct TempDir(PathBuf);

impl std::ops::Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for TempDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

pub(super) fn temp_dir(tag: &str) -> TempDir {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let k = COUNTER.fetch_add(1, Ordering::Relaxed);
    let dir =
        std::env::temp_dir().join(format!("rootfuse-data-io-{}-{tag}-{k}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    TempDir(dir)
}

pub(super) fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

const HEADER: &str = "t,gx,gy,gz,ax,ay,az,mx,my,mz,qw,qx,qy,qz,use";

/// Reads `body` (after the standard header) and returns the error message.
fn read_err(tag: &str, text: &str) -> (ReadError, String, PathBuf) {
    let dir = temp_dir(tag);
    let p = write(&dir, &format!("{tag}.csv"), text);
    let e = read_csv(&p).expect_err("must fail");
    let msg = e.to_string();
    assert!(
        msg.contains(&p.display().to_string()),
        "message must name the file: {msg}"
    );
    (e, msg, p)
}

#[test]
fn reads_full_file() {
    let dir = temp_dir("full");
    let text = format!(
        "{HEADER}\n0,0.1,0.2,0.3,0,0,9.81,20,0,-40,1,0,0,0,0\n0.01,-1e-3,2.5E+1,0,1,2,3,4,5,6,0.5,0.5,0.5,0.5,1\n"
    );
    let p = write(&dir, "trial_a.csv", &text);
    let r = read_csv(&p).unwrap();
    assert_eq!(r.name, "trial_a");
    assert_eq!(r.t, vec![0.0, 0.01]);
    assert_eq!(r.gyr[1], Vec3::new(-1e-3, 25.0, 0.0));
    assert_eq!(r.acc[0], Vec3::new(0.0, 0.0, 9.81));
    assert_eq!(r.mag.as_ref().unwrap()[1], Vec3::new(4.0, 5.0, 6.0));
    assert_eq!(r.truth.as_ref().unwrap()[1], Quat::new(0.5, 0.5, 0.5, 0.5));
    assert_eq!(r.use_mask, Some(vec![false, true]));
}

#[test]
fn reads_reordered_extra_columns_6d_and_nan_truth() {
    let dir = temp_dir("reorder");
    // Columns shuffled, an extra column (`temp`) and whitespace; no magnetometer (6D);
    // truth NaN on one row and partly NaN on another (unknown as a whole).
    let text = "use, az ,temp,qz,ay,qy,ax,qx,gz,qw,gy,t,gx\n\
                1,9.8,25.0,0,0.1,0,0.2,0,0.03,1,0.02,0.000,0.01\n\
                0,9.7,25.1,NaN,0.1,NaN,0.2,NaN,0.03,NaN,0.02,0.005,0.01\n\
                1,9.6,25.2,0.1,0.1,nan,0.2,0,0.03,1,0.02,0.010,0.01\n\
                \n";
    let p = write(&dir, "six.csv", text);
    let r = read_csv(&p).unwrap();
    assert_eq!(r.len(), 3);
    assert!(r.mag.is_none(), "6D file");
    assert_eq!(r.gyr[0], Vec3::new(0.01, 0.02, 0.03));
    assert_eq!(r.acc[2], Vec3::new(0.2, 0.1, 9.6));
    let truth = r.truth.as_ref().unwrap();
    assert_eq!(truth[0], Quat::new(1.0, 0.0, 0.0, 0.0));
    for q in &truth[1..] {
        assert!(q.w.is_nan() && q.x.is_nan() && q.y.is_nan() && q.z.is_nan());
    }
    assert_eq!(r.use_mask, Some(vec![true, false, true]));
    // The 6D sample carries NaN magnetometer for the filters.
    assert!(r.sample(0).mag.x.is_nan());
}

#[test]
fn byte_order_mark_and_crlf_are_accepted() {
    let dir = temp_dir("bom");
    let p = write(
        &dir,
        "bom.csv",
        "\u{feff}t,gx,gy,gz,ax,ay,az\r\n0,1,2,3,4,5,6\r\n",
    );
    let r = read_csv(&p).unwrap();
    assert_eq!(r.gyr[0], Vec3::new(1.0, 2.0, 3.0));
    assert_eq!(r.acc[0], Vec3::new(4.0, 5.0, 6.0));
}

#[test]
fn minimal_file_without_truth_or_use() {
    let dir = temp_dir("minimal");
    let p = write(
        &dir,
        "m.csv",
        "t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,1\n1,0,0,0,0,0,1\n",
    );
    let r = read_csv(&p).unwrap();
    assert_eq!(r.len(), 2);
    assert!(r.mag.is_none() && r.truth.is_none() && r.use_mask.is_none());
}

#[test]
fn error_missing_file() {
    let p = temp_dir("missing").join("nope.csv");
    let e = read_csv(&p).unwrap_err();
    assert!(matches!(e, ReadError::Io { .. }));
    assert!(e.to_string().contains("nope.csv"), "{e}");
}

#[test]
fn error_empty_file() {
    let (e, msg, _) = read_err("empty", "");
    assert!(matches!(e, ReadError::Empty { .. }), "{msg}");
    assert!(msg.contains("line 1"), "{msg}");
}

#[test]
fn error_missing_required_column() {
    let (e, msg, _) = read_err("nogz", "t,gx,gy,ax,ay,az\n0,0,0,0,0,1\n");
    assert!(
        matches!(e, ReadError::MissingColumn { column: "gz", .. }),
        "{msg}"
    );
    assert!(msg.contains("line 1") && msg.contains("`gz`"), "{msg}");
}

#[test]
fn error_partial_groups() {
    let (e, msg, _) = read_err("partmag", "t,gx,gy,gz,ax,ay,az,mx,my\n0,0,0,0,0,0,1,1,1\n");
    assert!(
        matches!(e, ReadError::MissingColumn { column: "mz", .. }),
        "{msg}"
    );
    let (e, msg, _) = read_err(
        "partq",
        "t,gx,gy,gz,ax,ay,az,qw,qx,qz\n0,0,0,0,0,0,1,1,0,0\n",
    );
    assert!(
        matches!(e, ReadError::MissingColumn { column: "qy", .. }),
        "{msg}"
    );
}

/// The line and 1-based column index of an error's place.
fn at(place: &rootfuse_io::Place) -> (u64, Option<usize>) {
    (place.line, place.column.as_ref().map(|c| c.1))
}

#[test]
fn error_duplicate_column() {
    let (e, msg, _) = read_err("dup", "t,gx,gy,gz,ax,ay,az,gx\n0,0,0,0,0,0,1,0\n");
    assert!(
        matches!(e, ReadError::DuplicateColumn { ref place } if at(place) == (1, Some(8))),
        "{msg}"
    );
    assert!(msg.contains("line 1, column `gx` (#8)"), "{msg}");
}

#[test]
fn error_non_numeric_cell() {
    let text =
        format!("{HEADER}\n0,0,0,0,0,0,9.8,1,2,3,1,0,0,0,1\n0.1,0,0,0,0,abc,9.8,1,2,3,1,0,0,0,1\n");
    let (e, msg, _) = read_err("nonnum", &text);
    assert!(
        matches!(
            e,
            ReadError::NotNumeric { ref place, .. } if at(place) == (3, Some(6))
        ),
        "{msg}"
    );
    assert!(
        msg.contains("line 3, column `ay` (#6)") && msg.contains("`abc`"),
        "{msg}"
    );
}

#[test]
fn error_field_count() {
    let text =
        format!("{HEADER}\n0,0,0,0,0,0,9.8,1,2,3,1,0,0,0,1\n0.1,0,0,0,0,0,9.8,1,2,3,1,0,0,1\n");
    let (e, msg, _) = read_err("fields", &text);
    assert!(
        matches!(
            e,
            ReadError::FieldCount { ref place, expected: 15, found: 14 } if place.line == 3
        ),
        "{msg}"
    );
    assert!(msg.contains("line 3"), "{msg}");
}

#[test]
fn error_non_finite_time() {
    let text = "gx,gy,gz,ax,ay,az,t\n0,0,0,0,0,1,0\n0,0,0,0,0,1,inf\n";
    let (e, msg, _) = read_err("tinf", text);
    assert!(
        matches!(
            e,
            ReadError::NonFiniteTime { ref place, .. } if at(place) == (3, Some(7))
        ),
        "{msg}"
    );
    assert!(msg.contains("line 3, column `t` (#7)"), "{msg}");
    let (e, _, _) = read_err("tnan", "t,gx,gy,gz,ax,ay,az\nNaN,0,0,0,0,0,1\n");
    assert!(matches!(e, ReadError::NonFiniteTime { ref place, .. } if place.line == 2));
}

#[test]
fn error_non_monotonic_time() {
    let text = "t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,1\n0.01,0,0,0,0,0,1\n0.01,0,0,0,0,0,1\n";
    let (e, msg, _) = read_err("tmono", text);
    assert!(
        matches!(
            e,
            ReadError::NonMonotonicTime { ref place, .. } if at(place) == (4, Some(1))
        ),
        "{msg}"
    );
    assert!(msg.contains("line 4, column `t` (#1)"), "{msg}");
    let text = "t,gx,gy,gz,ax,ay,az\n0.02,0,0,0,0,0,1\n0.01,0,0,0,0,0,1\n";
    let (e, _, _) = read_err("tback", text);
    assert!(matches!(e, ReadError::NonMonotonicTime { ref place, .. } if place.line == 3));
}

#[test]
fn error_nan_in_imu_columns() {
    let text =
        format!("{HEADER}\n0,0,0,0,0,0,9.8,1,2,3,1,0,0,0,1\n0.1,0,0,0,0,0,9.8,1,NaN,3,1,0,0,0,1\n");
    let (e, msg, _) = read_err("imunan", &text);
    assert!(
        matches!(
            e,
            ReadError::NonFiniteImu { ref place, .. } if at(place) == (3, Some(9))
        ),
        "{msg}"
    );
    assert!(msg.contains("line 3, column `my` (#9)"), "{msg}");
    let text = "t,gx,gy,gz,ax,ay,az\n0,-inf,0,0,0,0,1\n";
    let (e, msg, _) = read_err("imuinf", text);
    assert!(
        matches!(
            e,
            ReadError::NonFiniteImu { ref place, .. } if at(place) == (2, Some(2))
        ),
        "{msg}"
    );
}

#[test]
fn error_infinite_truth() {
    let text = format!("{HEADER}\n0,0,0,0,0,0,9.8,1,2,3,1,0,inf,0,1\n");
    let (e, msg, _) = read_err("qinf", &text);
    assert!(
        matches!(
            e,
            ReadError::InfiniteTruth { ref place, .. } if at(place) == (2, Some(13))
        ),
        "{msg}"
    );
    assert!(msg.contains("line 2, column `qy` (#13)"), "{msg}");
}

#[test]
fn error_use_not_binary() {
    for bad in ["2", "0.5", "yes"] {
        let text = format!("{HEADER}\n0,0,0,0,0,0,9.8,1,2,3,1,0,0,0,{bad}\n");
        let (e, msg, _) = read_err("use", &text);
        assert!(
            matches!(
                e,
                ReadError::BadUse { ref place, .. } if at(place) == (2, Some(15))
            ),
            "{msg}"
        );
        assert!(msg.contains("line 2, column `use` (#15)"), "{msg}");
    }
}

#[test]
fn lists_and_reads_folders() {
    // Without an index: every *.csv except index.csv, sorted; README and others skipped.
    let dir = temp_dir("folder");
    let row = "t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,1\n";
    write(&dir, "b.csv", row);
    write(&dir, "a.csv", row);
    write(&dir, "README.md", "# hi\n");
    write(&dir, "notes.txt", "x");
    let names: Vec<_> = list_dir(&dir)
        .unwrap()
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["a.csv", "b.csv"]);
    let recs = read_dir(&dir).unwrap();
    assert_eq!(recs.len(), 2);
    assert_eq!(recs[0].name, "a");

    // With an index: its trials in its order.
    write(
        &dir,
        "index.csv",
        "trial,group,fs_hz,n_samples,n_use,duration_s\nb,g,100,1,0,0.01\n",
    );
    let listed = list_dir(&dir).unwrap();
    assert_eq!(listed, vec![dir.join("b.csv")]);
    let idx = read_index(dir.join("index.csv")).unwrap();
    assert_eq!(idx[0].n_samples, Some(1));
    assert_eq!(idx[0].fs_hz, Some(100.0));
    assert_eq!(idx[0].group.as_deref(), Some("g"));

    // A listed trial whose file is missing is an error naming that file.
    write(&dir, "index.csv", "trial\nb\nmissing_trial\n");
    let e = read_dir(&dir).unwrap_err();
    assert!(e.to_string().contains("missing_trial.csv"), "{e}");
}

#[test]
fn writes_estimates_atomically_and_exactly() {
    let dir = temp_dir("write");
    let p = dir.join("est.csv");
    let t = [0.0, 0.1, 0.2];
    let q = [
        Quat::new(1.0, 0.0, 0.0, 0.0),
        Quat::new(0.1f64.sqrt(), 0.3, -0.2, 0.77f64.sqrt()),
        Quat::new(0.0, 0.0, 1.0, 0.0),
    ];
    let flag = [f64::NAN, 1e-300, 2.5];
    write_estimates(&p, &t, &q, &[("flag", &flag)]).unwrap();
    let text = std::fs::read_to_string(&p).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t,qw,qx,qy,qz,flag"));
    let row: Vec<f64> = lines
        .next()
        .unwrap()
        .split(',')
        .map(|s| s.parse().unwrap())
        .collect();
    assert_eq!(row[..5], [0.0, 1.0, 0.0, 0.0, 0.0]);
    assert!(row[5].is_nan());
    let row: Vec<f64> = lines
        .next()
        .unwrap()
        .split(',')
        .map(|s| s.parse().unwrap())
        .collect();
    // Shortest round-trip formatting: the same bits come back.
    assert_eq!(row[1].to_bits(), 0.1f64.sqrt().to_bits());
    assert_eq!(row[4].to_bits(), 0.77f64.sqrt().to_bits());
    assert_eq!(row[5], 1e-300);
    assert!(text.lines().nth(1).unwrap().ends_with(",NaN"));
    // Only the target is left behind (no temporary file).
    let files: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert_eq!(files.len(), 1);

    // Overwrites in place.
    write_estimates(&p, &t[..1], &q[..1], &[]).unwrap();
    assert_eq!(
        std::fs::read_to_string(&p).unwrap(),
        "t,qw,qx,qy,qz\n0,1,0,0,0\n"
    );

    // Errors: length mismatch and bad names, each naming the file.
    let e = write_estimates(&p, &t, &q[..2], &[]).unwrap_err();
    assert!(
        matches!(
            e,
            WriteError::Length {
                expected: 3,
                found: 2,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("est.csv"));
    for bad in ["", "qw", "a,b", "x\n"] {
        let e = write_estimates(&p, &t, &q, &[(bad, &flag)]).unwrap_err();
        assert!(matches!(e, WriteError::BadColumnName { .. }), "{e}");
    }
    let e = write_estimates(dir.join("no/such/dir.csv"), &t, &q, &[]).unwrap_err();
    assert!(matches!(e, WriteError::Io { .. }), "{e}");

    // What read_estimates would refuse is not written: the pair agrees.
    let nan = [q[0], Quat::new(f64::NAN, 0.0, 0.0, 0.0), q[2]];
    let zero = [q[0], q[1], Quat::new(0.0, 0.0, 0.0, 0.0)];
    for (t, q, row) in [
        (&[0.0, 0.1, 0.1], &q, 2),
        (&[0.0, f64::INFINITY, 0.2], &q, 1),
        (&t, &nan, 1),
        (&t, &zero, 2),
    ] {
        let e = write_estimates(&p, t, q, &[]).unwrap_err();
        assert!(
            matches!(e, WriteError::Unreadable { row: r, .. } if r == row),
            "{e}"
        );
    }
    assert_eq!(
        read_estimates(&p).unwrap().t,
        [0.0],
        "the file is unchanged"
    );
}

#[test]
fn recording_round_trip_through_csv() {
    // A simulated recording with magnetometer, truth and mask written and read back is equal
    // bit for bit (shortest round-trip number formatting).
    let mut rec = rootfuse_eval::sim::scenario("irregular-dt", 3, 2.0, 100.0).unwrap();
    rec.use_mask.as_mut().unwrap()[5] = false;
    rec.truth.as_mut().unwrap()[7] = Quat::new(f64::NAN, f64::NAN, f64::NAN, f64::NAN);
    let dir = temp_dir("roundtrip");
    let p = dir.join(format!("{}.csv", rec.name));
    write_recording(&p, &rec).unwrap();
    let back = read_csv(&p).unwrap();
    assert_eq!(back.name, rec.name);
    assert_eq!(back.t, rec.t);
    assert_eq!(back.gyr, rec.gyr);
    assert_eq!(back.acc, rec.acc);
    assert_eq!(back.mag, rec.mag);
    assert_eq!(back.use_mask, rec.use_mask);
    let (a, b) = (back.truth.clone().unwrap(), rec.truth.clone().unwrap());
    for (x, y) in a.iter().zip(&b) {
        assert!(x == y || (x.w.is_nan() && y.w.is_nan()));
    }
    // And a 6D recording without truth.
    let six = Recording {
        mag: None,
        truth: None,
        use_mask: None,
        ..back.clone()
    };
    write_recording(&p, &six).unwrap();
    assert_eq!(read_csv(&p).unwrap(), six);
}

// ---------------------------------------------------------------- metrics

const DEG: f64 = std::f64::consts::PI / 180.0;

fn qz(a: f64) -> Quat<f64> {
    Quat::from_heading(a)
}
fn qx(a: f64) -> Quat<f64> {
    Quat::from_axis_angle(Vec3::new(1.0, 0.0, 0.0), a)
}

/// A few varied reference orientations.
fn references(n: usize) -> Vec<Quat<f64>> {
    (0..n)
        .map(|i| {
            let s = i as f64;
            Quat::from_euler_zyx(0.7 * s - 2.0, 0.3 * (0.5 * s).sin(), 0.9 * (0.3 * s).cos())
        })
        .collect()
}

#[test]
fn metric_pure_heading_error() {
    for &a in &[0.0, 1e-9, 0.01, 5.0 * DEG, 90.0 * DEG, 179.0 * DEG] {
        for r in references(20) {
            let e = sample_error(qz(a) * r, r);
            assert!((e.total - a).abs() < 1e-12, "{a}: {e:?}");
            assert!((e.heading - a).abs() < 1e-12, "{a}: {e:?}");
            assert!(e.inclination.abs() < 1e-12, "{a}: {e:?}");
        }
    }
}

#[test]
fn metric_pure_inclination_error() {
    for &b in &[1e-9, 0.02, 10.0 * DEG, 120.0 * DEG] {
        for r in references(20) {
            // About earth-x and about a tilted horizontal axis: both pure inclination.
            for e_q in [qx(b), qz(0.4) * qx(b) * qz(-0.4)] {
                let e = sample_error(e_q * r, r);
                assert!((e.total - b).abs() < 1e-12, "{b}: {e:?}");
                assert!((e.inclination - b).abs() < 1e-12, "{b}: {e:?}");
                assert!(e.heading.abs() < 1e-12, "{b}: {e:?}");
            }
        }
    }
}

#[test]
fn metric_sign_invariance() {
    for r in references(20) {
        let est = qz(0.3) * qx(0.2) * r;
        let base = sample_error(est, r);
        for (a, b) in [(-est, r), (est, -r), (-est, -r)] {
            let e = sample_error(a, b);
            assert!((e.total - base.total).abs() < 1e-14);
            assert!((e.heading - base.heading).abs() < 1e-14);
            assert!((e.inclination - base.inclination).abs() < 1e-14);
        }
    }
    // And the RMSE including the 6D offset (circular mean of angles 2π apart).
    let refs = references(50);
    let est: Vec<_> = refs
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let q = qz(0.5) * *r;
            if i % 2 == 0 { -q } else { q }
        })
        .collect();
    let six = rmse(&est, &refs, None, Alignment::SixD).unwrap();
    assert!(six.total < 1e-10, "{six:?}");
    assert!((six.heading_offset - 0.5 / DEG).abs() < 1e-9);
}

#[test]
fn metric_mixture_matches_closed_form() {
    // e = qz(α)·qx(β): heading α, inclination β, total 2·acos(cos(α/2)·cos(β/2)).
    for &(a, b) in &[(0.1, 0.2), (1.0, 0.05), (2.5, 1.2), (0.0, 3.0)] {
        for r in references(10) {
            let e = sample_error(qz(a) * qx(b) * r, r);
            let total = 2.0 * ((a / 2.0).cos() * (b / 2.0).cos()).acos();
            assert!((e.heading - a).abs() < 1e-12, "{e:?}");
            assert!((e.inclination - b).abs() < 1e-12, "{e:?}");
            assert!((e.total - total).abs() < 1e-12, "{e:?}");
        }
    }
    // Against the literal README formulas on arbitrary pairs (acos is only accurate away from
    // zero, so a modest tolerance).
    let refs = references(40);
    for (i, r) in refs.iter().enumerate() {
        let est = refs[(i * 7 + 3) % refs.len()];
        let e = est * r.conj();
        let lit_total = 2.0 * e.w.abs().min(1.0).acos();
        let lit_head = 2.0 * (e.z / e.w).abs().atan();
        let lit_incl = 2.0 * (e.w * e.w + e.z * e.z).sqrt().min(1.0).acos();
        let m = sample_error(est, *r);
        assert!((m.total - lit_total).abs() < 1e-7);
        assert!((m.heading - lit_head).abs() < 1e-7);
        assert!((m.inclination - lit_incl).abs() < 1e-7);
    }
}

#[test]
fn metric_six_d_removes_constant_heading_offset() {
    let refs = references(200);
    let off = 37.0 * DEG;
    let est: Vec<_> = refs.iter().map(|r| qz(off) * *r).collect();
    let nine = rmse(&est, &refs, None, Alignment::NineD).unwrap();
    assert!((nine.heading - 37.0).abs() < 1e-9 && (nine.total - 37.0).abs() < 1e-9);
    assert!(nine.inclination < 1e-9 && nine.heading_offset == 0.0);
    let six = rmse(&est, &refs, None, Alignment::SixD).unwrap();
    assert!(six.total < 1e-9 && six.heading < 1e-9, "{six:?}");
    assert!((six.heading_offset - 37.0).abs() < 1e-9);

    // Offset plus an inclination error: the offset goes, the inclination stays.
    let est: Vec<_> = refs.iter().map(|r| qz(off) * qx(2.0 * DEG) * *r).collect();
    let six = rmse(&est, &refs, None, Alignment::SixD).unwrap();
    let nine = rmse(&est, &refs, None, Alignment::NineD).unwrap();
    assert!(
        (six.inclination - 2.0).abs() < 1e-9 && six.heading < 1e-9,
        "{six:?}"
    );
    assert!((nine.inclination - six.inclination).abs() < 1e-12);

    // Offset near ±180°: the circular mean does not average +179° and −179° to 0.
    let est: Vec<_> = refs
        .iter()
        .enumerate()
        .map(|(i, r)| qz(if i % 2 == 0 { 179.0 } else { -179.0 } * DEG) * *r)
        .collect();
    let six = rmse(&est, &refs, None, Alignment::SixD).unwrap();
    assert!((six.heading - 1.0).abs() < 1e-9, "{six:?}");
}

#[test]
fn metric_rmse_mask_nan_and_errors() {
    let refs = references(6);
    // Heading errors 1°, 2°, 3°, ... on samples 0..6.
    let est: Vec<_> = refs
        .iter()
        .enumerate()
        .map(|(i, r)| qz((i + 1) as f64 * DEG) * *r)
        .collect();
    let mut truth = refs.clone();
    truth[4] = Quat::new(f64::NAN, f64::NAN, f64::NAN, f64::NAN);
    let mask = [true, false, true, true, true, true];
    let m = rmse(&est, &truth, Some(&mask), Alignment::NineD).unwrap();
    // Counted: samples 0, 2, 3, 5 → errors 1, 3, 4, 6 degrees.
    assert_eq!(m.n_used, 4);
    let expect = ((1.0 + 9.0 + 16.0 + 36.0) / 4.0_f64).sqrt();
    assert!((m.total - expect).abs() < 1e-9 && (m.heading - expect).abs() < 1e-9);
    let s = error_series(&est, &truth, Some(&mask), Alignment::NineD).unwrap();
    assert!(s.total[4].is_nan() && !s.used[4] && !s.used[1]);
    assert!(
        (s.heading[1] - 2.0).abs() < 1e-9,
        "uncounted samples still have errors"
    );

    // A non-finite, zero or unnormalised estimate on a counted sample is refused, naming
    // the row (never silently skipped, scored as perfect or normalised); on a sample that
    // does not count (row 1) it is not looked at.
    for q in [
        Quat::new(f64::NAN, 0.0, 0.0, 0.0),
        Quat::new(0.0, 0.0, 0.0, 0.0),
        Quat::from_array(est[2].to_array().map(|c| 2.0 * c)),
    ] {
        for mode in [Alignment::NineD, Alignment::SixD] {
            let mut bad = est.clone();
            bad[2] = q;
            assert!(matches!(
                rmse(&bad, &truth, Some(&mask), mode),
                Err(MetricsError::NotAnOrientation { row: 2, .. })
            ));
            let mut uncounted = est.clone();
            uncounted[1] = q;
            assert!(rmse(&uncounted, &truth, Some(&mask), mode).is_ok());
        }
    }

    assert!(matches!(
        rmse(&est[..3], &truth, None, Alignment::NineD),
        Err(MetricsError::Length { .. })
    ));
    assert_eq!(
        rmse(&est, &truth, Some(&[false; 6]), Alignment::NineD),
        Err(MetricsError::NoUsableSamples)
    );
    let rec = Recording {
        t: (0..6).map(f64::from).collect(),
        ..Recording::default()
    };
    assert_eq!(
        evaluate(&rec, &est, Alignment::NineD),
        Err(MetricsError::NoTruth)
    );
}

#[test]
fn metric_tiny_errors_are_resolved() {
    // acos(|e_w|) cannot see 1e-9 rad (cos(5e-10) rounds to 1); the atan2 form does.
    let r = references(1)[0];
    let e = sample_error(qx(1e-9) * r, r);
    assert!((e.total - 1e-9).abs() < 1e-15, "{e:?}");
}

// ---------------------------------------------------------------- the real BROAD trials

#[test]
#[cfg_attr(
    not(broad_data),
    ignore = "BROAD data not found (../shared/broad_csv or $ROOTFUSE_BROAD_DIR)"
)]
fn reads_broad_trials_matching_index() {
    let Some(dir) = crate::common::broad_dir() else {
        return;
    };
    let index = read_index(dir.join("index.csv")).unwrap();
    // The index lists exactly the trial files of the folder, however many it holds.
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.ends_with(".csv") && n != "index.csv")
        .collect();
    files.sort();
    let mut listed: Vec<String> = index.iter().map(|e| format!("{}.csv", e.trial)).collect();
    listed.sort();
    assert_eq!(listed, files);
    assert!(index.len() >= 4, "{} trials", index.len());
    for entry in &index {
        let path = dir.join(format!("{}.csv", entry.trial));
        let start = std::time::Instant::now();
        let rec = read_csv(&path).unwrap();
        let elapsed = start.elapsed();
        let n_use = rec
            .use_mask
            .as_ref()
            .unwrap()
            .iter()
            .filter(|&&u| u)
            .count();
        eprintln!(
            "{}: {} samples, {} use, read in {:.0} ms",
            entry.trial,
            rec.len(),
            n_use,
            elapsed.as_secs_f64() * 1e3
        );
        assert_eq!(Some(rec.len()), entry.n_samples, "{}", entry.trial);
        assert_eq!(Some(n_use), entry.n_use, "{}", entry.trial);
        assert!(rec.mag.is_some());
        let fs = entry.fs_hz.unwrap();
        let dur = rec.t[rec.len() - 1] - rec.t[0];
        assert!((dur - (rec.len() - 1) as f64 / fs).abs() < 1e-5, "{dur}");
        // use = 1 only where the truth is known, and the truth is unit where known.
        let truth = rec.truth.as_ref().unwrap();
        let mask = rec.use_mask.as_ref().unwrap();
        for (q, &u) in truth.iter().zip(mask) {
            if u {
                assert!((q.norm() - 1.0).abs() < 1e-6);
            }
        }
        // Metrics sanity on real data: the truth scores zero; a 5° heading offset is 5° in
        // 9D and vanishes in 6D.
        let z = evaluate(&rec, truth, Alignment::NineD).unwrap();
        assert_eq!(z.n_used, n_use);
        assert!(z.total < 1e-6, "{z:?}");
        let shifted: Vec<_> = truth.iter().map(|q| qz(5.0 * DEG) * *q).collect();
        let nine = evaluate(&rec, &shifted, Alignment::NineD).unwrap();
        let six = evaluate(&rec, &shifted, Alignment::SixD).unwrap();
        assert!((nine.heading - 5.0).abs() < 1e-6 && six.total < 1e-6);
    }
}

// ---------------------------------------------------------------- no panics on any input

mod no_panic {
    use proptest::prelude::*;
    use rootfuse_attitude::Quat;
    use rootfuse_eval::metrics::{Alignment, rmse, sample_error};
    use rootfuse_io::read_csv_from;

    /// Cells that are valid, invalid, special or structural, so that random rows reach every
    /// branch of the reader.
    fn cell() -> impl Strategy<Value = String> {
        prop_oneof![
            4 => (-1e3..1e3f64).prop_map(|v| v.to_string()),
            1 => prop::sample::select(vec![
                "NaN", "inf", "-inf", "", "0", "1", "2", "x", "1e400", "\"1\"", " 3 ", "1,2",
                "\u{feff}", "\n", "\r\n",
            ])
            .prop_map(String::from),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn reader_never_panics_on_bytes(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
            let mut text = b"t,gx,gy,gz,ax,ay,az,mx,my,mz,qw,qx,qy,qz,use\n".to_vec();
            text.extend(bytes);
            let _ = read_csv_from(text.as_slice(), "fuzz.csv", "fuzz");
        }

        #[test]
        fn reader_never_panics_on_rows(
            header in prop::collection::vec(prop::sample::select(vec![
                "t", "gx", "gy", "gz", "ax", "ay", "az", "mx", "my", "mz", "qw", "qx", "qy",
                "qz", "use", "extra",
            ]), 0..18),
            rows in prop::collection::vec(prop::collection::vec(cell(), 0..18), 0..6),
        ) {
            let mut text = header.join(",");
            for r in rows {
                text.push('\n');
                text.push_str(&r.join(","));
            }
            if let Ok(rec) = read_csv_from(text.as_bytes(), "fuzz.csv", "fuzz") {
                prop_assert!(rec.t.windows(2).all(|w| w[1] > w[0]));
                prop_assert!(rec.gyr.iter().all(|g| g.x.is_finite() && g.y.is_finite()));
            }
        }

        #[test]
        fn metrics_never_panic(
            q in prop::collection::vec(prop::array::uniform4(prop_oneof![
                8 => -1.0..1.0f64,
                1 => prop::sample::select(vec![f64::NAN, f64::INFINITY, 0.0, 1e300]),
            ]), 1..20),
            six in any::<bool>(),
        ) {
            let est: Vec<_> = q.iter().map(|a| Quat::new(a[0], a[1], a[2], a[3])).collect();
            let truth: Vec<_> = est.iter().rev().copied().collect();
            for (a, b) in est.iter().zip(&truth) {
                let e = sample_error(*a, *b);
                prop_assert!(e.total.is_nan() || (0.0..=std::f64::consts::PI).contains(&e.total));
            }
            let mode = if six { Alignment::SixD } else { Alignment::NineD };
            let _ = rmse(&est, &truth, None, mode);
        }
    }
}

/// `ImuGaps::Keep` keeps a non-finite IMU value for the filters to skip and count; the
/// default refuses it (`error_nan_in_imu_columns`). Time and truth rules are unchanged.
#[test]
fn imu_gaps_are_kept_on_request() {
    let dir = temp_dir("gaps");
    let text = format!(
        "{HEADER}\n0,0,0,0,0,0,9.8,1,2,3,1,0,0,0,1\n0.1,NaN,0,0,0,0,inf,1,NaN,3,1,0,0,0,1\n"
    );
    let p = write(&dir, "gaps.csv", &text);
    assert!(matches!(
        read_csv(&p),
        Err(ReadError::NonFiniteImu { ref place, .. }) if at(place) == (3, Some(2))
    ));
    let rec = read_csv_with(&p, ImuGaps::Keep).unwrap();
    assert!(rec.gyr[1].x.is_nan() && rec.acc[1].z == f64::INFINITY);
    assert!(rec.mag.as_ref().unwrap()[1].y.is_nan());
    let bad_time = write(&dir, "t.csv", "t,gx,gy,gz,ax,ay,az\nNaN,0,0,0,0,0,1\n");
    assert!(matches!(
        read_csv_with(&bad_time, ImuGaps::Keep),
        Err(ReadError::NonFiniteTime { ref place, .. }) if place.line == 2
    ));
}

/// A quaternion far from unit norm is no orientation: refused in truth (NaN = unknown stays
/// allowed) and in estimates, naming the line; slightly rounded ones are accepted.
#[test]
fn quaternions_far_from_unit_norm_are_refused() {
    let text =
        format!("{HEADER}\n0,0,0,0,0,0,9.8,1,2,3,1,0,0,0,1\n0.1,0,0,0,0,0,9.8,1,2,3,0,0,0,0,1\n");
    let (e, msg, _) = read_err("qzero", &text);
    assert!(
        matches!(e, ReadError::NotUnitQuaternion { ref place, .. } if place.line == 3),
        "{msg}"
    );
    assert!(
        msg.contains("line 3: quaternion `qw,qx,qy,qz` has norm 0"),
        "{msg}"
    );
    let dir = temp_dir("estnorm");
    let est = write(
        &dir,
        "e.csv",
        "t,qw,qx,qy,qz\n0,1,0,0,0\n1,0.7071,0.7071,0,0\n2,2,0,0,0\n",
    );
    let e = read_estimates(&est).unwrap_err();
    assert!(
        matches!(e, ReadError::NotUnitQuaternion { ref place, .. } if place.line == 4),
        "{e}"
    );
    let est = write(&dir, "n.csv", "t,qw,qx,qy,qz\n0,1,0,0,0\n1,NaN,0,0,0\n");
    let e = read_estimates(&est).unwrap_err();
    assert!(
        e.to_string()
            .contains("line 3, column `qw` (#2): estimate value NaN is not finite"),
        "{e}"
    );
}

/// A control character in a cell is shown escaped in the message.
#[test]
fn messages_escape_control_characters() {
    let text = "t,gx,gy,gz,ax,ay,az,use\n0,0,0,0,0,0,9.8,\u{0}\n";
    let (e, msg, _) = read_err("nul", text);
    assert!(
        matches!(e, ReadError::BadUse { ref place, .. } if place.line == 2),
        "{msg}"
    );
    assert!(
        msg.contains("`\\u{0}` is not 0 or 1") && !msg.contains('\0'),
        "{msg}"
    );
    let (_, msg, _) = read_err("bel", "t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,9\u{7}\n");
    assert!(msg.contains("`9\\u{7}` is not a number"), "{msg}");
}

/// Temporary files of other processes' writes to a path are found; ours and other names not.
#[test]
fn stale_temporaries_of_a_path() {
    let dir = temp_dir("stale");
    let target = dir.join("x.csv");
    let stale = temporary_path(&target, 4_000_000);
    for p in [
        &stale,
        &temporary_path(&target, std::process::id()),
        &temporary_path(&dir.join("y.csv"), 4_000_000),
        &dir.join("x.csv.tmp.12a"),
    ] {
        std::fs::write(p, "").unwrap();
    }
    assert_eq!(stale_temporaries(&target), vec![stale]);
}
