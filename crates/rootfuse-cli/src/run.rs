//! `rootfuse run`: filter IMU CSV files, write one estimate file per input.
use crate::Outcome;
use crate::engine::{Columns, PrecisionArg, run_recordings_with};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use rootfuse_attitude::registry::FilterSpec;
use rootfuse_attitude::smooth::forward_backward;
use rootfuse_attitude::{Dof, OrientationFilter, Recording};
use rootfuse_batch::{ChannelOutput, RejectionTotals};
use rootfuse_io::{list_dir, read_csv, write_estimates};
use std::path::PathBuf;
use std::time::Instant;

/// Options of `rootfuse run`.
#[derive(Args)]
pub struct RunArgs {
    /// IMU CSV files, or folders of them (every `*.csv` but `index.csv`).
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Filter name (see `rootfuse filters`).
    #[arg(long)]
    filter: String,
    /// Parameter override `key=value` (repeatable).
    #[arg(long = "param", value_name = "KEY=VALUE")]
    params: Vec<String>,
    /// 6: gravity only; 9: with magnetometer (filters with a `dof` parameter).
    #[arg(long, value_parser = ["6", "9"])]
    dof: Option<String>,
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
}

/// Runs the command.
pub fn run(args: &RunArgs) -> Result<Outcome, String> {
    let mut spec = FilterSpec::new(&args.filter).map_err(|e| e.to_string())?;
    for p in &args.params {
        spec.set(p).map_err(|e| e.to_string())?;
    }
    if let Some(dof) = &args.dof {
        spec.set_dof(if dof == "6" { Dof::Six } else { Dof::Nine })
            .map_err(|e| e.to_string())?;
    }
    if args.covariance && spec.build::<f64>().attitude_covariance().is_none() {
        return Err(format!(
            "--covariance: filter `{}` carries no covariance (sqrt-eskf and ekf do)",
            args.filter
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
                args.filter
            ));
        }
    }
    let mut files = Vec::new();
    for input in &args.inputs {
        if input.is_dir() {
            files.extend(list_dir(input).map_err(|e| e.to_string())?);
        } else {
            files.push(input.clone());
        }
    }
    let bar = ProgressBar::new(files.len() as u64).with_style(
        ProgressStyle::with_template("{msg:>10} [{bar:30}] {pos}/{len} {wide_msg}")
            .map_err(|e| e.to_string())?
            .progress_chars("=> "),
    );
    bar.set_message("reading");
    let mut recs: Vec<Recording> = Vec::new();
    let mut failed = 0usize;
    for file in &files {
        match read_csv(file) {
            Ok(rec) => recs.push(rec),
            Err(e) if args.keep_going => {
                bar.suspend(|| eprintln!("error: {e}"));
                failed += 1;
            }
            Err(e) => return Err(e.to_string()),
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    if recs.is_empty() {
        return Err("no input could be read".into());
    }
    let spinner = ProgressBar::new_spinner().with_message(format!(
        "running {} on {} channel(s)",
        args.filter,
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
    let mut totals = [0u64; 6];
    let mut samples = 0usize;
    for (rec, out) in recs.iter().zip(&outputs) {
        let path = args.out.join(format!("{}.csv", rec.name));
        let series = extra_columns(out);
        let extra: Vec<(&str, &[f64])> = series
            .iter()
            .map(|(name, values)| (*name, values.as_slice()))
            .collect();
        write_estimates(&path, &rec.t, &out.quat, &extra).map_err(|e| e.to_string())?;
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
    if failed > 0 {
        eprintln!("{failed} file(s) failed");
        Ok(Outcome::Partial)
    } else {
        Ok(Outcome::Success)
    }
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
