//! `rootfuse run`: filter IMU CSV files, write one estimate file per input.
use crate::Outcome;
use crate::engine::{Columns, PrecisionArg, run_recordings_with};
use crate::filter_args::FilterArgs;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use rootfuse_attitude::registry::FilterSpec;
use rootfuse_attitude::smooth::forward_backward;
use rootfuse_attitude::{OrientationFilter, Recording};
use rootfuse_batch::{ChannelOutput, RejectionTotals};
use rootfuse_io::{ImuGaps, list_dir, read_csv_with, stale_temporaries, write_estimates};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, MutexGuard, PoisonError};
use std::time::Instant;

/// Held while an estimate file is being written. The SIGINT/SIGTERM handler takes it before it
/// exits, so the write in progress is finished and renamed into place (or removed on error)
/// and no new one starts: a signal never leaves a temporary file behind.
static WRITING: Mutex<()> = Mutex::new(());

/// Set by the signal handler before it waits for [`WRITING`], so that the main thread, should
/// it take the lock first for its next file, exits instead of starting that write.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Exit code after SIGINT or SIGTERM (128 + SIGINT, as shells report an interrupt).
const EXIT_INTERRUPTED: i32 = 130;

/// Options of `rootfuse run`.
#[derive(Args)]
pub struct RunArgs {
    /// IMU CSV files, or folders of them (every `*.csv` but `index.csv`).
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    #[command(flatten)]
    filter: FilterArgs,
    /// Output folder for `<stem>.csv` estimate files.
    #[arg(long, default_value = "out")]
    out: PathBuf,
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
    /// Not combined with `--bias`, `--covariance` or `--flags`.
    #[arg(long)]
    offline: bool,
    /// Skip unreadable files (reported) instead of stopping; exit code 1 if any failed.
    #[arg(long)]
    keep_going: bool,
    /// Refuse a file with a NaN or infinite IMU value. Without it such values (dropped
    /// packets) are kept and the filter skips them: the whole sample for the gyroscope, that
    /// correction for the accelerometer or magnetometer, counted in the summary and in
    /// `--flags`.
    #[arg(long)]
    strict: bool,
    /// Apply a calibration file written by `rootfuse calibrate` to the raw readings before
    /// filtering (`y_cal = S·(y_raw − h)` per sensor in the file).
    #[arg(long)]
    calibration: Option<PathBuf>,
}

/// Runs the command.
pub fn run(args: &RunArgs) -> Result<Outcome, String> {
    let spec = args.filter.spec()?;
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
    let mut files = Vec::new();
    for input in &args.inputs {
        if input.is_dir() {
            let listed = list_dir(input).map_err(|e| e.to_string())?;
            if listed.is_empty() {
                return Err(format!("{}: no .csv files in the folder", input.display()));
            }
            files.extend(listed);
        } else {
            files.push(input.clone());
        }
    }
    let outputs_of_files = output_paths(&files, &args.out)?;
    install_signal_handler()?;
    let nine_d = spec.uses_magnetometer();
    // `--dof 9` or `--param dof=9` asked for the magnetometer; the filters' default did not.
    let dof_explicit = args.filter.dof_explicit();
    let gaps = if args.strict {
        ImuGaps::Refuse
    } else {
        ImuGaps::Keep
    };
    let bar = ProgressBar::new(files.len() as u64).with_style(
        ProgressStyle::with_template("{msg:>10} [{bar:30}] {pos}/{len} {wide_msg}")
            .map_err(|e| e.to_string())?
            .progress_chars("=> "),
    );
    bar.set_message("reading");
    let calibration = args
        .calibration
        .as_deref()
        .map(crate::calibrate::read_calibration)
        .transpose()?;
    let mut recs: Vec<Recording> = Vec::new();
    let mut out_paths: Vec<&Path> = Vec::new();
    let mut failed = 0usize;
    for (file, out_path) in files.iter().zip(&outputs_of_files) {
        let checked = read_csv_with(file, gaps)
            .map_err(|e| e.to_string())
            .and_then(|rec| check_recording(file, rec, nine_d, dof_explicit));
        match checked {
            Ok((mut rec, note)) => {
                if let Some(cal) = &calibration {
                    crate::calibrate::apply_calibration(&mut rec, cal);
                }
                if let Some(note) = note {
                    bar.suspend(|| eprintln!("note: {note}"));
                }
                recs.push(rec);
                out_paths.push(out_path);
            }
            Err(e) if args.keep_going => {
                bar.suspend(|| eprintln!("error: {e}"));
                failed += 1;
            }
            Err(e) => return Err(e),
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    if recs.is_empty() {
        return Err("no input could be read".into());
    }
    let spinner = ProgressBar::new_spinner().with_message(format!(
        "running {} on {} channel(s)",
        args.filter.filter,
        recs.len()
    ));
    spinner.enable_steady_tick(std::time::Duration::from_millis(120));
    let start = Instant::now();
    let columns = Columns {
        bias: args.bias,
        covariance: args.covariance,
        flags: args.flags,
    };
    let outputs = if args.offline {
        smooth_recordings(&spec, &recs)?
    } else {
        run_recordings_with(&spec, &recs, args.precision.into(), columns)
    };
    let seconds = start.elapsed().as_secs_f64();
    spinner.finish_and_clear();

    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("{}: cannot create: {e}", args.out.display()))?;
    let mut stale = 0usize;
    for path in &out_paths {
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
            args.out.display()
        );
    }
    let mut totals = [0u64; 6];
    let mut samples = 0usize;
    let (mut gap_samples, mut gap_files) = (0usize, 0usize);
    for ((rec, out), path) in recs.iter().zip(&outputs).zip(&out_paths) {
        let series = extra_columns(out);
        let extra: Vec<(&str, &[f64])> = series
            .iter()
            .map(|(name, values)| (*name, values.as_slice()))
            .collect();
        {
            let _writing = lock_for_writing();
            write_estimates(path, &rec.t, &out.quat, &extra).map_err(|e| e.to_string())?;
        }
        let gaps = samples_with_missing_imu(rec);
        gap_samples += gaps;
        gap_files += usize::from(gaps > 0);
        let r = out.rejections;
        for (t, v) in totals
            .iter_mut()
            .zip([r.dt, r.gyr, r.acc, r.mag, r.gated, r.mag_disturbed])
        {
            *t += v;
        }
        samples += rec.len();
    }
    out!(
        "{} file(s), {samples} samples, {:.3e} samples/s ({}), estimates in {}",
        recs.len(),
        samples as f64 / seconds.max(1e-9),
        if args.offline {
            "f64, offline".to_string()
        } else {
            format!("{:?}", args.precision)
        },
        args.out.display()
    );
    out!(
        "rejected: dt {}, gyro {}, accelerometer {}, magnetometer {}, gated {}, magnetic disturbance {}",
        totals[0],
        totals[1],
        totals[2],
        totals[3],
        totals[4],
        totals[5]
    );
    if gap_samples > 0 {
        out!(
            "missing IMU values (NaN or infinite): {gap_samples} sample(s) in {gap_files} file(s), skipped by the filter and counted above (--strict refuses such files)"
        );
    }
    if failed > 0 {
        eprintln!("{failed} file(s) failed");
        Ok(Outcome::Partial)
    } else {
        Ok(Outcome::Success)
    }
}

/// Where each input's estimate goes (`OUT/<stem>.csv`), refusing a plan that would lose data:
/// two inputs with the same file name (the second estimate would overwrite the first), or an
/// estimate written over one of the inputs (`--out` is an input folder).
fn output_paths(files: &[PathBuf], out: &Path) -> Result<Vec<PathBuf>, String> {
    let canonical_inputs: HashSet<PathBuf> =
        files.iter().filter_map(|f| f.canonicalize().ok()).collect();
    // A folder that does not exist yet holds no input.
    let canonical_out = out.canonicalize().ok();
    let mut first_with_name: HashMap<String, &PathBuf> = HashMap::new();
    let mut paths = Vec::with_capacity(files.len());
    for file in files {
        let name = format!(
            "{}.csv",
            file.file_stem().unwrap_or_default().to_string_lossy()
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

/// On SIGINT or SIGTERM: wait for the file being written (if any), then exit with
/// [`EXIT_INTERRUPTED`]; estimates already written are complete, none is half written.
fn install_signal_handler() -> Result<(), String> {
    ctrlc::set_handler(|| {
        INTERRUPTED.store(true, Ordering::SeqCst);
        let _writing = WRITING.lock().unwrap_or_else(PoisonError::into_inner);
        exit_interrupted();
    })
    .map_err(|e| format!("cannot install the signal handler: {e}"))
}

/// Takes [`WRITING`] for one file, or exits if a signal came.
fn lock_for_writing() -> MutexGuard<'static, ()> {
    let writing = WRITING.lock().unwrap_or_else(PoisonError::into_inner);
    if INTERRUPTED.load(Ordering::SeqCst) {
        exit_interrupted();
    }
    writing
}

/// Ends the process after a signal. Called only while holding [`WRITING`]: no write is in
/// progress, no temporary file exists, and no other thread can call it at the same time.
fn exit_interrupted() -> ! {
    eprintln!("interrupted: the estimate files written so far are complete");
    std::process::exit(EXIT_INTERRUPTED);
}

/// Refuses a recording the run cannot use: one with no data rows, or without magnetometer
/// columns when 9D was asked for explicitly. When 9D is only the filter's default, a note
/// (returned) says that every magnetometer correction will be skipped.
fn check_recording(
    file: &Path,
    rec: Recording,
    nine_d: bool,
    dof_explicit: bool,
) -> Result<(Recording, Option<String>), String> {
    if rec.is_empty() {
        return Err(format!(
            "{}: line 2: no data rows (the file has only a header)",
            file.display()
        ));
    }
    if nine_d && rec.mag.is_none() {
        let message = format!(
            "{}: no magnetometer columns (mx,my,mz) for 9D operation; use --dof 6",
            file.display()
        );
        if dof_explicit {
            return Err(message);
        }
        return Ok((
            rec,
            Some(format!(
                "{message} (the filter's default is 9D: every magnetometer correction is skipped)"
            )),
        ));
    }
    Ok((rec, None))
}

/// Samples with a NaN or infinite gyroscope, accelerometer or magnetometer value.
fn samples_with_missing_imu(rec: &Recording) -> usize {
    let finite =
        |v: &rootfuse_attitude::Vec3<f64>| v.x.is_finite() && v.y.is_finite() && v.z.is_finite();
    (0..rec.len())
        .filter(|&i| {
            !finite(&rec.gyr[i])
                || !finite(&rec.acc[i])
                || rec.mag.as_ref().is_some_and(|m| !finite(&m[i]))
        })
        .count()
}

/// Forward-backward smoothing of every recording (f64), with the forward pass's rejection
/// counts.
fn smooth_recordings(spec: &FilterSpec, recs: &[Recording]) -> Result<Vec<ChannelOutput>, String> {
    let nine_d = spec.uses_magnetometer();
    recs.iter()
        .map(|rec| {
            let smoothed = forward_backward(rec, || spec.build::<f64>(), nine_d)
                .map_err(|e| format!("{}: {e}", rec.name))?;
            let r = &smoothed.rejections;
            Ok(ChannelOutput {
                quat: smoothed.quat,
                rejections: RejectionTotals::of_lane(r, 0),
                ..ChannelOutput::default()
            })
        })
        .collect()
}

/// The optional output columns that were collected, by name, in file order.
fn extra_columns(out: &ChannelOutput) -> Vec<(&'static str, Vec<f64>)> {
    let mut series = Vec::new();
    if !out.bias.is_empty() {
        series.push(("bx", out.bias.iter().map(|b| b.x).collect()));
        series.push(("by", out.bias.iter().map(|b| b.y).collect()));
        series.push(("bz", out.bias.iter().map(|b| b.z).collect()));
    }
    if !out.covariance.is_empty() {
        let names = ["p_xx", "p_xy", "p_xz", "p_yy", "p_yz", "p_zz"];
        for (k, name) in names.into_iter().enumerate() {
            series.push((name, out.covariance.iter().map(|p| p[k]).collect()));
        }
    }
    if !out.flags.is_empty() {
        series.push(("flags", out.flags.iter().map(|&f| f64::from(f)).collect()));
    }
    series
}
