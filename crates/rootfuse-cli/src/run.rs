//! `rootfuse run`: filter IMU files (CSV, Parquet, Arrow), write one estimate file per input,
//! streaming (see [`crate::stream`]).
use crate::Outcome;
use crate::checks::{InputChecks, parse_units};
use crate::engine::{Columns, PrecisionArg};
use crate::filter_args::FilterArgs;
use crate::outputs::{Ledger, missing_folders, remove_empty, source_of};
use crate::signal::{exit_interrupted, install_signal_handler, interrupted};
use crate::stream::{Job, Totals, run_columnar, run_csv};
use clap::Args;
use rootfuse_attitude::OrientationFilter;
use rootfuse_attitude::smooth::smooth_spec;
use rootfuse_attitude::units::Units;
use rootfuse_batch::{RejectionTotals, samples_with_missing_imu};
use rootfuse_columnar::Format;
use rootfuse_io::{ImuGaps, read_csv_in, scan_dir, stale_temporaries, write_estimates};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `rootfuse run`.
#[derive(Args)]
pub struct RunArgs {
    /// IMU files: CSV (one recording each), or Parquet / Arrow IPC (file or stream format)
    /// fleets (rows of many devices told apart by a `device` column); or folders of them
    /// (every `*.csv` but `index.csv`, or every `*.parquet` / `*.arrow` / `*.arrows`).
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    #[command(flatten)]
    filter: FilterArgs,
    /// Output folder for `<stem>.<format>` estimate files.
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Format of the estimate files (default: that of the inputs).
    #[arg(long, value_enum)]
    format: Option<FormatArg>,
    /// Arithmetic precision.
    #[arg(long, value_enum, default_value = "f64")]
    precision: PrecisionArg,
    /// Also write the gyro-bias estimate (`bx,by,bz`, rad/s).
    #[arg(long)]
    bias: bool,
    /// Also write the attitude-error covariance (`p_xx,p_xy,p_xz,p_yy,p_yz,p_zz`, rad², earth
    /// frame ENU, `p_zz` = heading), for filters that carry one (`sqrt-eskf`, `ekf`).
    #[arg(long)]
    covariance: bool,
    /// Also write a `flags` column: per sample, the sum of 1 (dt skipped), 2 (gyroscope
    /// skipped), 4 (accelerometer correction skipped), 8 (magnetometer correction skipped),
    /// 16 (a correction gated), and the detector states 32 (at rest) and 64 (magnetic field
    /// disturbed) for filters that detect them (`sqrt-eskf`).
    #[arg(long)]
    flags: bool,
    /// Offline: smooth each file forward-backward (two runs fused by their attitude
    /// covariances, `rootfuse_attitude::smooth`), in f64; for filters that carry a covariance.
    /// Not combined with `--bias`, `--covariance` or `--flags`. Needs a whole recording in
    /// memory (one file at a time, about 2× the CSV file); CSV inputs only.
    #[arg(long)]
    offline: bool,
    /// Skip unreadable files, and in fleets the devices with bad time stamps (reported; a
    /// device's rows are left out from its bad row on), instead of stopping; exit code 1 if
    /// any failed.
    #[arg(long)]
    keep_going: bool,
    /// Units of the inputs, converted on read to the filters' s, rad/s, m/s² and µT: a
    /// comma-separated list of `time=s|ms|us|ns`, `gyro=rad/s|deg/s`, `acc=m/s2|g|mg`,
    /// `mag=uT|nT|G|mG`, or a factor to the filters' unit for raw counts (`acc=0.000598`);
    /// sensors left out are in the filters' units. Each input's data are checked against
    /// these units: a sensor whose readings look like another unit is named with the option
    /// that declares it: a warning, but an error for a gyroscope whose readings fail against
    /// how the gravity direction (or, in 9D, the magnetic field's) turned, unless its unit
    /// is given here (a wrong one makes
    /// every estimate wrong; `gyro=rad/s` says the readings are rad/s after all).
    #[arg(long, value_name = "LIST", value_parser = parse_units, default_value = "")]
    units: Units,
    /// Make every warning about an input an error (exit 2, no estimate written): readings that
    /// look like another unit than declared, and NaN or infinite IMU values (without it such
    /// values, dropped packets, are kept and the filter skips them: the whole sample for the
    /// gyroscope, that correction for the accelerometer or magnetometer, counted in the summary
    /// and in `--flags`). A sensor whose every sample or correction the filter skipped is an
    /// error either way (a file without magnetometer columns is not: under a filter's 9D
    /// default it runs with a note that every magnetometer correction is skipped, and
    /// `--dof 9` makes it an error).
    #[arg(long)]
    strict: bool,
    /// Per-device parameters: a CSV, Parquet or Arrow table with a `device` column (as the
    /// fleet names its devices; a CSV recording is the device named after its file stem),
    /// then one column per parameter (an empty cell keeps the run's value). Listed devices
    /// run with their own parameters over `--param`, `--dof` and `--max-dt` (a column the
    /// command line also sets is noted, not refused); the others with the run's. Devices
    /// that share the structural parameters (`dof`, `max_dt`, `max_gyr`, switches) share
    /// SIMD chunks; each device equals its own scalar run bit for bit.
    #[arg(long, value_name = "FILE")]
    device_params: Option<PathBuf>,
    /// Apply a calibration file written by `rootfuse calibrate` to the raw readings before
    /// filtering (`y_cal = S·(y_raw − h)` per sensor in the file).
    #[arg(long)]
    calibration: Option<PathBuf>,
    /// Replace existing files in `--out` that rootfuse did not write for the same input
    /// (without it such a file is refused before anything is written; rootfuse's own
    /// estimate of the same input, unchanged since, is replaced either way). A symbolic link
    /// is never replaced nor written through.
    #[arg(long)]
    force: bool,
}

/// Runs the command.
pub fn run(args: &RunArgs) -> Result<Outcome, String> {
    let spec = args.filter.spec()?;
    check_filter_options(args, &spec)?;
    if args.out.exists() && !args.out.is_dir() {
        return Err(format!(
            "{}: --out is a file, not a folder: give the folder the estimates go to",
            args.out.display()
        ));
    }
    let files = input_files(&args.inputs)?;
    let (format, columnar) = output_format(args, &files)?;
    let outputs_of_files = output_paths(&files, &args.out, format)?;
    let mut ledger = Ledger::load(&args.out);
    for (file, out) in files.iter().zip(&outputs_of_files) {
        ledger.check(out, &source_of(file), args.force)?;
    }
    install_signal_handler()?;
    let gaps = if args.strict {
        ImuGaps::Refuse
    } else {
        ImuGaps::Keep
    };
    let created = missing_folders(&args.out);
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("{}: cannot create: {e}", args.out.display()))?;
    let start = Instant::now();
    let result = (|| -> Result<Totals, String> {
        remove_stale(&outputs_of_files, &args.out)?;
        let calibration = args
            .calibration
            .as_deref()
            .map(crate::calibrate::read_calibration)
            .transpose()?;
        if let Some(set) = &calibration {
            set.check_units(&args.units)?;
        }
        let device_specs = args
            .device_params
            .as_deref()
            .map(|p| crate::device_params::DeviceSpecs::read(p, &spec, &args.filter.assignments()))
            .transpose()?;
        if device_specs.is_some() && args.offline {
            return Err("--device-params runs fleets and CSV recordings online; --offline smooths each file with the run's parameters".into());
        }
        for note in device_specs.iter().flat_map(|d| d.overrides()) {
            eprintln!("{note}");
        }
        let job = Job {
            device_specs: device_specs.as_ref(),
            spec: &spec,
            precision: args.precision.into(),
            columns: Columns {
                bias: args.bias,
                covariance: args.covariance,
                flags: args.flags,
            },
            format,
            gaps,
            units: args.units,
            strict: args.strict,
            keep_going: args.keep_going,
            nine_d: spec.uses_magnetometer(),
            // `--dof 9` or `--param dof=9` asked for the magnetometer; the filters' default
            // did not.
            dof_explicit: args.filter.dof_explicit(),
            calibration: calibration.as_ref(),
        };
        let mut staged = Vec::new();
        let totals = if args.offline {
            let mut written = Vec::new();
            let totals = smooth_files(&job, &files, &outputs_of_files, &mut written);
            for (file, out) in written {
                ledger.record(&out, &source_of(&file))?;
            }
            totals?
        } else if columnar {
            run_columnar(&job, &files, &outputs_of_files, &mut staged)?
        } else {
            run_csv(&job, &files, &outputs_of_files, &mut staged)?
        };
        // Every input ran (or, under --keep-going, failed and was reported): only now do the
        // estimates take their final names, so that a failed run writes none of them.
        for (file, staged) in staged {
            let out = staged.path().to_owned();
            staged.commit().map_err(|e| e.to_string())?;
            ledger.record(&out, &source_of(&file))?;
        }
        Ok(totals)
    })();
    let totals = match result {
        Ok(t) => t,
        Err(e) => {
            remove_empty(&created);
            return Err(e);
        }
    };
    Ok(report(args, &totals, start.elapsed().as_secs_f64()))
}

/// `--covariance` and `--offline` need a filter with a covariance; `--offline` writes
/// orientations only.
fn check_filter_options(
    args: &RunArgs,
    spec: &rootfuse_attitude::registry::FilterSpec,
) -> Result<(), String> {
    if args.covariance && spec.build::<f64>().attitude_covariance().is_none() {
        return Err(format!(
            "--covariance: filter `{}` carries no covariance (sqrt-eskf and ekf do)",
            args.filter.filter
        ));
    }
    if args.offline {
        if args.bias || args.covariance || args.flags {
            return Err(
                "--offline writes orientations only (no --bias, --covariance, --flags)".into(),
            );
        }
        if spec.build::<f64>().attitude_covariance().is_none() {
            return Err(format!(
                "--offline: filter `{}` carries no covariance to weight the two passes (sqrt-eskf and ekf do)",
                args.filter.filter
            ));
        }
    }
    Ok(())
}

/// The format of the estimates and whether the inputs are columnar fleets (Parquet/Arrow):
/// CSV and fleets are not mixed in one run, and `--offline` reads and writes CSV only.
fn output_format(args: &RunArgs, files: &[PathBuf]) -> Result<(Format, bool), String> {
    let columnar = files
        .iter()
        .any(|f| Format::of_path(f).is_some_and(|x| x != Format::Csv));
    if columnar
        && files
            .iter()
            .any(|f| Format::of_path(f) == Some(Format::Csv))
    {
        return Err(
            "give CSV recordings or Parquet/Arrow fleets in one run, not both (their devices are told apart differently)"
                .into(),
        );
    }
    if args.offline && args.format.is_some_and(|f| f != FormatArg::Csv) {
        return Err("--offline writes CSV estimates".into());
    }
    if columnar && args.offline {
        return Err("--offline reads CSV recordings (it needs each recording whole in memory); write a fleet's devices to CSV files to smooth them".into());
    }
    let format = match args.format {
        Some(f) => f.into(),
        None if columnar => files
            .first()
            .and_then(|f| Format::of_path(f))
            .unwrap_or(Format::Parquet),
        None => Format::Csv,
    };
    Ok((format, columnar))
}

/// The closing lines of a run (files, samples, speed, rejections, missing values, failures)
/// and its outcome.
fn report(args: &RunArgs, totals: &Totals, seconds: f64) -> Outcome {
    let samples = totals.samples;
    let devices = if totals.devices > 0 {
        format!(", {} device(s)", totals.devices)
    } else {
        String::new()
    };
    out!(
        "{} file(s){devices}, {samples} samples, {:.3e} samples/s ({}), estimates in {}",
        totals.files,
        samples as f64 / seconds.max(1e-9),
        if args.offline {
            "f64, offline".to_string()
        } else {
            format!("{:?}", args.precision)
        },
        args.out.display()
    );
    let r = &totals.rejections;
    out!(
        "rejected: dt {}, gyro {}, accelerometer {}, magnetometer {}, gated {}, magnetic disturbance {}",
        r.dt,
        r.gyr,
        r.acc,
        r.mag,
        r.gated,
        r.mag_disturbed
    );
    if totals.missing_imu > 0 {
        out!(
            "missing IMU values (NaN or infinite): {} sample(s) in {} file(s), skipped by the filter and counted above (--strict refuses such files)",
            totals.missing_imu,
            totals.files_with_missing_imu
        );
    }
    if totals.failed_files > 0 || totals.failed_devices > 0 {
        eprintln!(
            "{} file(s) failed, {} device(s) failed",
            totals.failed_files, totals.failed_devices
        );
        Outcome::Partial
    } else {
        Outcome::Success
    }
}

/// `--format` on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum FormatArg {
    /// CSV.
    Csv,
    /// Apache Parquet.
    Parquet,
    /// Arrow IPC (file format).
    Arrow,
}

impl From<FormatArg> for Format {
    fn from(f: FormatArg) -> Self {
        match f {
            FormatArg::Csv => Format::Csv,
            FormatArg::Parquet => Format::Parquet,
            FormatArg::Arrow => Format::Arrow,
        }
    }
}

/// The input files: files as given, folders expanded to their CSV recordings (the trials of
/// their `index.csv`, or every `.csv` but `index.csv`) or, when there are none, their Parquet
/// and Arrow files (`rootfuse_io::scan_dir`); a note names the data files a folder leaves out
/// and why.
fn input_files(inputs: &[PathBuf]) -> Result<Vec<PathBuf>, String> {
    let mut files = Vec::new();
    for input in inputs {
        if !input.is_dir() {
            files.push(input.clone());
            continue;
        }
        let listing = scan_dir(input).map_err(|e| e.to_string())?;
        if listing.files.is_empty() {
            return Err(format!(
                "{}: no .csv files in the folder (nor .parquet or .arrow)",
                input.display()
            ));
        }
        if let Some(note) = listing.note() {
            eprintln!("note: {note}");
        }
        files.extend(listing.files);
    }
    Ok(files)
}

/// Removes the temporary files that a killed run left beside the outputs.
fn remove_stale(outputs: &[PathBuf], out: &Path) -> Result<(), String> {
    let mut stale = 0usize;
    for path in outputs {
        for tmp in stale_temporaries(path) {
            std::fs::remove_file(&tmp).map_err(|e| {
                format!("{}: cannot remove stale temporary file: {e}", tmp.display())
            })?;
            stale += 1;
        }
    }
    if stale > 0 {
        eprintln!(
            "note: removed {stale} temporary file(s) left in {} by an interrupted run",
            out.display()
        );
    }
    Ok(())
}

/// Where each input's estimate goes (`OUT/<stem>.csv`), refusing a plan that would lose data:
/// two inputs with the same file name (the second estimate would overwrite the first), or an
/// estimate written over one of the inputs (`--out` is an input folder).
fn output_paths(files: &[PathBuf], out: &Path, format: Format) -> Result<Vec<PathBuf>, String> {
    let canonical_inputs: HashSet<PathBuf> =
        files.iter().filter_map(|f| f.canonicalize().ok()).collect();
    // A folder that does not exist yet holds no input.
    let canonical_out = out.canonicalize().ok();
    let mut first_with_name: HashMap<String, &PathBuf> = HashMap::new();
    let mut paths = Vec::with_capacity(files.len());
    for file in files {
        let name = format!(
            "{}.{}",
            file.file_stem().unwrap_or_default().to_string_lossy(),
            format.extension()
        );
        let path = out.join(&name);
        if let Some(first) = first_with_name.insert(name, file) {
            return Err(format!(
                "{} and {}: both estimates would be written to {}; give inputs with distinct file names",
                first.display(),
                file.display(),
                path.display()
            ));
        }
        if let Some(dir) = &canonical_out
            && canonical_inputs.contains(&dir.join(path.file_name().unwrap_or_default()))
        {
            return Err(format!(
                "{}: the estimate of {} would overwrite this input; choose another --out",
                path.display(),
                file.display()
            ));
        }
        paths.push(path);
    }
    Ok(paths)
}

/// `--offline`: one CSV recording at a time, read whole, smoothed forward-backward (f64)
/// and written, so memory holds one recording (with both passes), not all of them.
///
/// Unlike the streaming runs, each estimate is put in place as soon as it is smoothed (the
/// input and output pairs are pushed to `written`): a later failure keeps the earlier ones.
fn smooth_files(
    job: &Job,
    files: &[PathBuf],
    outs: &[PathBuf],
    written: &mut Vec<(PathBuf, PathBuf)>,
) -> Result<Totals, String> {
    let mut totals = Totals::default();
    let mut checks = InputChecks::new(job.units, job.strict);
    for (d, (file, out)) in files.iter().zip(outs).enumerate() {
        let result = (|| -> Result<(), String> {
            let mut rec = read_csv_in(file, job.gaps, job.units).map_err(|e| e.to_string())?;
            checks.observe_recording(d as u32, &rec);
            if let Some(cal) = job.calibration {
                crate::calibrate::apply_calibration(&mut rec, cal);
            }
            if rec.is_empty() {
                return Err(format!(
                    "{}: line 2: no data rows (the file has only a header)",
                    file.display()
                ));
            }
            crate::stream::check_mag(job, file, rec.mag.is_some())?;
            let smoothed = smooth_spec(&rec, job.spec, job.nine_d)
                .map_err(|e| format!("{}: {e}", rec.name))?;
            if interrupted() {
                exit_interrupted();
            }
            let r = RejectionTotals::of_lane(&smoothed.rejections, 0);
            let nine_d = job.nine_d && rec.mag.is_some();
            let verdict = checks.judge(&file.display().to_string(), d as u32, r, nine_d);
            for w in &verdict.warnings {
                eprintln!("warning: {w}");
            }
            if let Some(e) = verdict.error {
                return Err(e);
            }
            write_estimates(out, &rec.t, &smoothed.quat, &[]).map_err(|e| e.to_string())?;
            written.push((file.clone(), out.clone()));
            totals.rejections += r;
            totals.missing(samples_with_missing_imu(&rec.gyr, &rec.acc, rec.mag.as_deref()) as u64);
            totals.samples += rec.len() as u64;
            Ok(())
        })();
        match result {
            Ok(()) => totals.files += 1,
            Err(e) => totals.fail(e, job.keep_going)?,
        }
    }
    if totals.files == 0 {
        return Err("no input could be read".into());
    }
    Ok(totals)
}
