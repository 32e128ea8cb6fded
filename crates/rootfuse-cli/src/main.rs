//! The `rootfuse` command line.
//!
//! Exit codes: 0 success; 1 some files failed under `--keep-going` (the others were
//! processed); 2 an error (bad arguments, unreadable or malformed input), reported as one line
//! naming file, line and column where there is one.
use clap::{Parser, Subcommand};

/// `println!` that ends the process quietly when stdout is closed (output piped into `head`),
/// instead of panicking.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if let Err(e) = writeln!(std::io::stdout(), $($arg)*) {
            if e.kind() == std::io::ErrorKind::BrokenPipe {
                std::process::exit(0);
            }
        }
    }};
}
use std::process::ExitCode;

mod calibrate;
mod checks;
mod demo;
mod device_params;
mod engine;
mod eval;
mod filter_args;
mod filters;
mod outputs;
mod plot;
mod run;
mod signal;
mod simulate;
mod stream;
mod stress;
mod throughput;

/// Numerically robust estimation: attitude filters, least squares, SIMD batch processing.
#[derive(Parser)]
#[command(name = "rootfuse", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Calibrates a sensor from recordings (magnetometer hard/soft iron, accelerometer
    /// offset/scale, gyroscope bias) and writes a JSON file that `run --calibration` applies.
    Calibrate(calibrate::CalibrateArgs),
    /// Runs the built-in default job on simulated data and prints accuracy and throughput.
    Demo(demo::DemoArgs),
    /// Runs a filter over IMU files (CSV, Parquet, Arrow) and writes one estimate file per input.
    #[command(after_long_help = RUN_HELP)]
    Run(run::RunArgs),
    /// Writes a seeded fleet of simulated IMUs (with truth) as Parquet or Arrow.
    Simulate(simulate::SimulateArgs),
    /// Scores estimate files against ground truth with the BROAD metrics.
    Eval(eval::EvalArgs),
    /// Lists every filter with its parameters, defaults and units.
    Filters,
    /// Numerical stress scenarios for every recursive least-squares form (f32 and f64).
    Stress(stress::StressArgs),
    /// Channel-updates per second of a filter: scalar, SIMD lanes, and lanes on every core.
    Throughput(throughput::ThroughputArgs),
}

/// What `rootfuse run --help` adds after the options.
const RUN_HELP: &str = "\
Gaps and bad samples: every filter screens each sample. A time step that is not in (0, max_dt] \
(a gap longer than `--max-dt`, default 1 s) or a gyroscope reading that is not finite or \
faster than `max_gyr` (default 35 rad/s, `--param max_gyr=70` for a 4000 °/s sensor) skips \
the whole sample; a non-finite \
accelerometer or magnetometer reading, or one beyond `max_acc` (default 1000 m/s²) or \
`max_mag` (default 1000, for µT; raise it for nT or raw counts), skips that correction. Each skip is counted in the \
`rejected:` summary line and, per sample, in the `--flags` column. After a skipped gap the \
orientation is held, not extrapolated.

Outputs: each estimate is written to a temporary file and renamed into place, so a final \
`<stem>.csv` (`.parquet`, `.arrow`) is always complete. Inputs are streamed: read, filtered and \
written a block of rows at a time, all files side by side, so memory does not grow with their \
length. SIGINT or SIGTERM stops at the end of the block being run, removes the estimates in \
progress and exits with code 130; temporary files left by a killed run are removed by the next run that \
writes the same estimate. Two inputs with the same file name, or an --out folder in which \
an estimate would replace an input, are refused before anything is written.";

/// How a command ended.
pub enum Outcome {
    /// Everything worked.
    Success,
    /// Some inputs failed but the others were processed (`--keep-going`).
    Partial,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Calibrate(args) => calibrate::run(&args).map(|()| Outcome::Success),
        Command::Demo(args) => demo::run(&args).map(|()| Outcome::Success),
        Command::Run(args) => run::run(&args),
        Command::Eval(args) => eval::run(&args).map(|()| Outcome::Success),
        Command::Simulate(args) => simulate::run(&args).map(|()| Outcome::Success),
        Command::Stress(args) => stress::run(&args).map(|()| Outcome::Success),
        Command::Throughput(args) => throughput::run(&args).map(|()| Outcome::Success),
        Command::Filters => {
            filters::print();
            Ok(Outcome::Success)
        }
    };
    match result {
        Ok(Outcome::Success) => ExitCode::SUCCESS,
        Ok(Outcome::Partial) => ExitCode::from(1),
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::from(2)
        }
    }
}
