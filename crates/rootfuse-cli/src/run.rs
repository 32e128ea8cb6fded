//! `rootfuse run`: filter IMU CSV files, write one estimate file per input.
use crate::Outcome;
use crate::engine::{PrecisionArg, run_recordings};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use rootfuse_attitude::Recording;
use rootfuse_attitude::io::{list_dir, read_csv, write_estimates};
use rootfuse_attitude::registry::FilterSpec;
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
        spec.set_dof(if dof == "6" { 6 } else { 9 })
            .map_err(|e| e.to_string())?;
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
    let outputs = run_recordings(&spec, &recs, args.precision.into());
    let seconds = start.elapsed().as_secs_f64();
    spinner.finish_and_clear();

    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("{}: cannot create: {e}", args.out.display()))?;
    let mut totals = [0u64; 5];
    let mut samples = 0usize;
    for (rec, out) in recs.iter().zip(&outputs) {
        let path = args.out.join(format!("{}.csv", rec.name));
        let columns: [Vec<f64>; 3] = [
            out.bias.iter().map(|b| b.x).collect(),
            out.bias.iter().map(|b| b.y).collect(),
            out.bias.iter().map(|b| b.z).collect(),
        ];
        let extra: Vec<(&str, &[f64])> = if args.bias {
            vec![
                ("bx", &columns[0]),
                ("by", &columns[1]),
                ("bz", &columns[2]),
            ]
        } else {
            Vec::new()
        };
        write_estimates(&path, &rec.t, &out.quat, &extra).map_err(|e| e.to_string())?;
        let r = out.rejections;
        for (t, v) in totals.iter_mut().zip([r.dt, r.gyr, r.acc, r.mag, r.gated]) {
            *t += v;
        }
        samples += rec.len();
    }
    out!(
        "{} file(s), {samples} samples, {:.3e} samples/s ({:?}), estimates in {}",
        recs.len(),
        samples as f64 / seconds.max(1e-9),
        args.precision,
        args.out.display()
    );
    out!(
        "rejected: dt {}, gyro {}, accelerometer {}, magnetometer {}, gated {}",
        totals[0],
        totals[1],
        totals[2],
        totals[3],
        totals[4]
    );
    if failed > 0 {
        eprintln!("{failed} file(s) failed");
        Ok(Outcome::Partial)
    } else {
        Ok(Outcome::Success)
    }
}
