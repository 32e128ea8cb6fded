//! Files as people have them: semicolons and tabs, decimal commas, byte-order marks, UTF-16,
//! empty cells as pandas writes them, booleans in `use`, estimates with extra columns, folders
//! with an index or with fleets beside recordings, and files in other units.
use super::csv::{temp_dir, write};
use rootfuse_attitude::units::Units;
use rootfuse_io::{
    CsvBlocks, FolderKind, ImuGaps, ReadError, read_csv, read_csv_in, read_csv_with,
    read_estimates, scan_dir, write_estimates, write_recording, write_recording_with,
};

const COMMA: &str = "t,gx,gy,gz,ax,ay,az,qw,qx,qy,qz,use\n\
                     0,0.5,0,0,0,0,9.75,1,0,0,0,1\n\
                     0.01,0.25,0,0,0,0.125,9.75,,,,,0\n";

#[test]
fn semicolons_tabs_and_decimal_commas_read_as_commas() {
    let dir = temp_dir("dialects");
    let want = read_csv(write(&dir, "comma.csv", COMMA)).unwrap();
    let semicolon = COMMA.replace(',', ";");
    let decimal_comma = semicolon.replace('.', ",");
    let tab = COMMA.replace(',', "\t");
    let crlf = COMMA.replace('\n', "\r\n");
    let bom = format!("\u{feff}{COMMA}");
    for (name, text) in [
        ("semicolon", &semicolon),
        ("decimal_comma", &decimal_comma),
        ("tab", &tab),
        ("crlf", &crlf),
        ("bom", &bom),
    ] {
        let mut got = read_csv(write(&dir, &format!("{name}.csv"), text))
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        got.name = want.name.clone();
        assert_eq!(format!("{got:?}"), format!("{want:?}"), "{name}");
    }
    // A decimal comma is no number where commas separate fields: the cell is named.
    let e = read_csv(write(
        &dir,
        "quoted.csv",
        "t,gx,gy,gz,ax,ay,az\n0,\"0,5\",0,0,0,0,9.8\n",
    ))
    .unwrap_err();
    assert!(
        e.to_string()
            .contains("column `gx` (#2): `0,5` is not a number"),
        "{e}"
    );
}

#[test]
fn utf16_and_utf32_are_refused_by_name() {
    let dir = temp_dir("encodings");
    let utf16le: Vec<u8> = [0xFF, 0xFE]
        .into_iter()
        .chain(COMMA.encode_utf16().flat_map(u16::to_le_bytes))
        .collect();
    let utf16be: Vec<u8> = [0xFE, 0xFF]
        .into_iter()
        .chain(COMMA.encode_utf16().flat_map(u16::to_be_bytes))
        .collect();
    let no_bom: Vec<u8> = COMMA.encode_utf16().flat_map(u16::to_le_bytes).collect();
    for (name, bytes, encoding) in [
        ("le", utf16le, "UTF-16 little-endian"),
        ("be", utf16be, "UTF-16 big-endian"),
        ("nobom", no_bom, "UTF-16 or UTF-32"),
    ] {
        let p = dir.join(format!("{name}.csv"));
        std::fs::write(&p, bytes).unwrap();
        let e = read_csv(&p).unwrap_err();
        assert!(matches!(e, ReadError::Encoding { .. }), "{e}");
        let msg = e.to_string();
        assert!(
            msg.contains(encoding) && msg.contains("save it as UTF-8"),
            "{msg}"
        );
    }
}

/// Lines ending in a carriage return alone (classic Mac OS) are named, with the conversion:
/// the reader took the whole file for its header ("expected 15 fields, found 13"). CRLF,
/// CR CR LF and a file whose last line ends in CR still read.
#[test]
fn carriage_return_line_endings_are_named() {
    let dir = temp_dir("cr");
    let p = dir.join("cr.csv");
    std::fs::write(&p, COMMA.replace('\n', "\r")).unwrap();
    let e = read_csv(&p).unwrap_err();
    assert!(matches!(e, ReadError::CarriageReturns { .. }), "{e}");
    assert!(e.to_string().contains("convert them to LF or CRLF"), "{e}");
    assert!(read_estimates(&p).is_err());
    for (name, text) in [
        ("crlf", COMMA.replace('\n', "\r\n")),
        ("last", format!("{}\r", COMMA.trim_end())),
        // As Python's csv.writer leaves it on Windows without newline="".
        ("crcrlf", COMMA.replace('\n', "\r\r\n")),
    ] {
        let p = dir.join(format!("{name}.csv"));
        std::fs::write(&p, text).unwrap();
        assert_eq!(read_csv(&p).unwrap().len(), 2, "{name}");
    }
}

/// Binary files given to the CSV reader are named for what they are (their NUL bytes once
/// made them "UTF-16"), with what to do instead.
#[test]
fn binary_formats_are_refused_by_name() {
    let dir = temp_dir("binary");
    for (name, head, format, advice) in [
        (
            "fleet.parquet",
            &b"PAR1\x15\x04\x15\x00"[..],
            "a Parquet file",
            "rootfuse run",
        ),
        (
            "fleet.arrow",
            b"ARROW1\x00\x00",
            "an Arrow IPC file",
            "rootfuse.arrow",
        ),
        (
            "fleet.arrows",
            b"\xFF\xFF\xFF\xFF\x10\x00",
            "an Arrow IPC stream",
            "rootfuse run",
        ),
        ("rec.csv.gz", b"\x1F\x8B\x08\x00\x00", "gzip", "gunzip"),
        ("rec.csv.zst", b"\x28\xB5\x2F\xFD\x00", "zstd", "zstd -d"),
        (
            "rec.xlsx",
            b"PK\x03\x04\x14\x00",
            "zip archive",
            "save the sheet as CSV",
        ),
    ] {
        let p = dir.join(name);
        std::fs::write(&p, head).unwrap();
        let e = read_csv(&p).unwrap_err();
        assert!(matches!(e, ReadError::NotText { .. }), "{e}");
        let msg = e.to_string();
        assert!(
            msg.contains(format)
                && msg.contains(advice)
                && msg.contains(name)
                && !msg.contains("UTF"),
            "{msg}"
        );
    }
}

/// A CSV with a `device` column holds several devices' rows, which one recording cannot: the
/// time error says so.
#[test]
fn a_csv_fleet_is_named_in_the_time_error() {
    let dir = temp_dir("csv-fleet");
    let text =
        "device,t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,0,9.8\n0,0.01,0,0,0,0,0,9.8\n1,0,0,0,0,0,0,9.8\n";
    let e = read_csv(write(&dir, "fleet.csv", text)).unwrap_err();
    let msg = e.to_string();
    assert!(
        matches!(e, ReadError::NonMonotonicTime { .. })
            && msg.contains("line 4")
            && msg.contains("Parquet or Arrow"),
        "{msg}"
    );
    let single = "t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,9.8\n0,0,0,0,0,0,9.8\n";
    let msg = read_csv(write(&dir, "one.csv", single))
        .unwrap_err()
        .to_string();
    assert!(!msg.contains("device"), "{msg}");
}

#[test]
fn empty_cells_are_missing_values() {
    let dir = temp_dir("empty");
    // Truth cells left empty (pandas writes NaN so): unknown truth, the row is read.
    let rec = read_csv(write(&dir, "truth.csv", COMMA)).unwrap();
    assert!(rec.truth.as_ref().unwrap()[1].w.is_nan());
    assert_eq!(rec.use_mask.as_deref(), Some(&[true, false][..]));
    // An empty IMU cell is a missing value: refused by default, NaN when kept.
    let text = "t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,9.8\n0.01,,0,0,0,0,9.8\n";
    let p = write(&dir, "imu.csv", text);
    let e = read_csv(&p).unwrap_err();
    assert!(
        e.to_string()
            .ends_with("line 3, column `gx` (#2): IMU value (empty cell) is missing"),
        "{e}"
    );
    assert!(read_csv_with(&p, ImuGaps::Keep).unwrap().gyr[1].x.is_nan());
    // An empty time is refused either way.
    let p = write(&dir, "t.csv", "t,gx,gy,gz,ax,ay,az\n,0,0,0,0,0,9.8\n");
    let e = read_csv_with(&p, ImuGaps::Keep).unwrap_err();
    assert!(matches!(e, ReadError::NonFiniteTime { .. }), "{e}");
}

#[test]
fn use_reads_what_pandas_writes() {
    let dir = temp_dir("use");
    let text = "t,gx,gy,gz,ax,ay,az,use\n0,0,0,0,0,0,9.8,True\n0.1,0,0,0,0,0,9.8,false\n\
                0.2,0,0,0,0,0,9.8,1.0\n0.3,0,0,0,0,0,9.8,0.0\n0.4,0,0,0,0,0,9.8,\n";
    let rec = read_csv(write(&dir, "use.csv", text)).unwrap();
    assert_eq!(
        rec.use_mask.as_deref(),
        Some(&[true, false, true, false, false][..])
    );
}

#[test]
fn a_missing_column_lists_what_the_header_has() {
    let dir = temp_dir("missing");
    let text = "time;gyro_x;gyro_y;gyro_z;acc_x;acc_y;acc_z\n0;0;0;0;0;0;9,8\n";
    let e = read_csv(write(&dir, "names.csv", text)).unwrap_err();
    assert_eq!(
        e.to_string().rsplit_once(".csv: ").unwrap().1,
        "line 1: missing required column `t` (the header has `time`, `gyro_x`, `gyro_y`, \
         `gyro_z`, `acc_x`, `acc_y`, `acc_z` (semicolon-separated))"
    );
}

#[test]
fn estimates_keep_every_column() {
    let dir = temp_dir("estimates");
    let p = write(
        &dir,
        "est.csv",
        "t,qw,qx,qy,qz,bx,flags\n0,1,0,0,0,0.001,0\n0.01,1,0,0,0,,33\n",
    );
    let est = read_estimates(&p).unwrap();
    assert_eq!(est.extra.len(), 2);
    assert_eq!(est.column("flags"), Some(&[0.0, 33.0][..]));
    assert!(est.column("bx").unwrap()[1].is_nan());
    let p = write(&dir, "bad.csv", "t,qw,qx,qy,qz,note\n0,1,0,0,0,hello\n");
    let e = read_estimates(&p).unwrap_err();
    assert!(
        e.to_string()
            .contains("column `note` (#6): `hello` is not a number"),
        "{e}"
    );
}

#[test]
fn folders_say_what_they_leave_out() {
    let dir = temp_dir("folders");
    write(&dir, "a.csv", COMMA);
    write(&dir, "b.csv", COMMA);
    write(&dir, "fleet.parquet", "not read");
    write(&dir, "README.md", "not data");
    let listing = scan_dir(&dir).unwrap();
    assert_eq!(listing.kind, FolderKind::Csv);
    assert_eq!(listing.files.len(), 2);
    let note = listing.note().unwrap();
    assert!(
        note.ends_with(
            "read 2 file(s), its CSV recordings; left out 1: fleet.parquet (Parquet/Arrow fleets do not run beside CSV recordings)"
        ),
        "{note}"
    );
    write(&dir, "index.csv", "trial\nb\n");
    let note = scan_dir(&dir).unwrap().note().unwrap();
    assert!(
        note.contains("read 1 file(s), the trials its index.csv lists; left out 2: a.csv (not listed in index.csv); fleet.parquet"),
        "{note}"
    );
    // Every data file read: nothing to say.
    let only = temp_dir("folders-only");
    write(&only, "a.csv", COMMA);
    assert_eq!(scan_dir(&only).unwrap().note(), None);
}

#[test]
fn units_are_converted_as_read() {
    let dir = temp_dir("units");
    let text = "t,gx,gy,gz,ax,ay,az,mx,my,mz\n0,180,0,0,0,0,1,20000,0,-40000\n\
                10,-90,0,0,0,0.5,1,20000,0,-40000\n";
    let p = write(&dir, "units.csv", text);
    let units: Units = "time=ms,gyro=deg/s,acc=g,mag=nT".parse().unwrap();
    let rec = read_csv_in(&p, ImuGaps::Refuse, units).unwrap();
    assert_eq!(rec.t, [0.0, 0.01]);
    assert_eq!(rec.gyr[0].x, std::f64::consts::PI);
    assert_eq!(rec.gyr[1].x, -std::f64::consts::FRAC_PI_2);
    assert_eq!((rec.acc[1].y, rec.acc[1].z), (0.5 * 9.80665, 9.80665));
    assert_eq!(rec.mag.as_ref().unwrap()[0].z, -40.0);
    // Block by block, the same.
    let mut blocks = CsvBlocks::open(&p, ImuGaps::Refuse)
        .unwrap()
        .with_units(units);
    let mut part = blocks.empty_recording();
    blocks.read_into(&mut part, 1).unwrap();
    blocks.read_into(&mut part, 1).unwrap();
    assert_eq!(part.t, rec.t);
    assert_eq!(part.acc, rec.acc);
}

#[test]
fn what_is_written_reads_back() {
    let dir = temp_dir("readback");
    let mut rec = rootfuse_eval::sim::scenario("slow-rotation", 1, 1.0, 50.0).unwrap();
    rec.gyr[3].y = f64::NAN;
    let p = dir.join("gaps.csv");
    let e = write_recording(&p, &rec).unwrap_err();
    assert!(
        e.to_string()
            .contains("row 3 (line 5), column `gy`: gyroscope value NaN is not finite"),
        "{e}"
    );
    write_recording_with(&p, &rec, ImuGaps::Keep).unwrap();
    assert!(read_csv_with(&p, ImuGaps::Keep).unwrap().gyr[3].y.is_nan());
    rec.gyr[3].y = 0.0;
    rec.t[10] = rec.t[9];
    let e = write_recording(&p, &rec).unwrap_err();
    assert!(
        e.to_string().contains("row 10 (line 12), column `t`: time"),
        "{e}"
    );
    let q = rootfuse_attitude::Quat::new(1.0, 0.0, 0.0, 0.0);
    let e = write_estimates(&p, &[0.0, 0.0], &[q, q], &[]).unwrap_err();
    assert!(
        e.to_string()
            .contains("row 1 (line 3), column `t`: time 0 does not increase"),
        "{e}"
    );
}
