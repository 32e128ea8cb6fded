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

mod demo;
mod engine;
mod eval;
mod filters;
mod plot;
mod run;
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
    /// Runs the built-in default job on simulated data and prints accuracy and throughput.
    Demo(demo::DemoArgs),
    /// Runs a filter over IMU CSV files and writes one estimate file per input.
    Run(run::RunArgs),
    /// Scores estimate files against ground truth with the BROAD metrics.
    Eval(eval::EvalArgs),
    /// Lists every filter with its parameters, defaults and units.
    Filters,
    /// Numerical stress scenarios for every recursive least-squares form (f32 and f64).
    Stress(stress::StressArgs),
    /// Channel-updates per second of a filter: scalar, SIMD lanes, and lanes on every core.
    Throughput(throughput::ThroughputArgs),
}

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
        Command::Demo(args) => demo::run(&args).map(|()| Outcome::Success),
        Command::Run(args) => run::run(&args),
        Command::Eval(args) => eval::run(&args).map(|()| Outcome::Success),
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
