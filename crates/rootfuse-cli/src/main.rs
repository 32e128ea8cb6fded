//! The `rootfuse` command line.
use clap::{Parser, Subcommand};
use std::process::ExitCode;

mod demo;

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
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Demo(args) => demo::run(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::from(2)
        }
    }
}
