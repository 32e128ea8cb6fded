//! `rootfuse simulate`: a seeded fleet of simulated IMUs (with truth) as one Parquet or Arrow
//! file, to try fleets at scale.
use clap::Args;
use rootfuse_columnar::{FleetFileWriter, Format};
use rootfuse_eval::sim::scenario_batch;
use std::path::PathBuf;

/// Devices simulated together and interleaved time-major in the file (see
/// [`FleetFileWriter::write_group`]): 32 fill eight `f32x8` chunks per block, and the
/// simulator holds only these recordings at a time (about 7 MB each for 10 min at 100 Hz).
const GROUP: usize = 32;

/// Options of `rootfuse simulate`.
#[derive(Args)]
pub struct SimulateArgs {
    /// Number of devices (device `d` is simulated with seed `seed + d`).
    #[arg(long)]
    devices: usize,
    /// Length of each recording, s.
    #[arg(long)]
    seconds: f64,
    /// Sampling rate, Hz.
    #[arg(long, default_value_t = 100.0)]
    rate: f64,
    /// Simulator preset (see `rootfuse demo --help`; e.g. `static`, `slow-rotation`).
    #[arg(long, default_value = "slow-rotation")]
    scenario: String,
    /// First seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output file, `.parquet` or `.arrow` (written atomically).
    #[arg(long)]
    out: PathBuf,
}

/// Runs the command.
pub fn run(args: &SimulateArgs) -> Result<(), String> {
    let format = Format::of_path(&args.out)
        .filter(|f| *f != Format::Csv)
        .ok_or_else(|| {
            format!(
                "{}: the fleet file must end in .parquet or .arrow",
                args.out.display()
            )
        })?;
    if args.devices == 0 {
        return Err("--devices must be at least 1".into());
    }
    let mut writer = FleetFileWriter::create(&args.out, format).map_err(|e| e.to_string())?;
    for first in (0..args.devices).step_by(GROUP) {
        let seeds: Vec<u64> = (first..(first + GROUP).min(args.devices))
            .map(|d| args.seed + d as u64)
            .collect();
        let recs = scenario_batch(&args.scenario, &seeds, args.seconds, args.rate)
            .map_err(|e| format!("--scenario {}: {e}", args.scenario))?;
        writer
            .write_group(first as i64, &recs)
            .map_err(|e| e.to_string())?;
    }
    let rows = writer.rows();
    writer.finish().map_err(|e| e.to_string())?;
    out!(
        "{} device(s), {rows} rows ({} s at {} Hz, scenario {}, seeds {}..{}) in {}",
        args.devices,
        args.seconds,
        args.rate,
        args.scenario,
        args.seed,
        args.seed + args.devices as u64,
        args.out.display()
    );
    Ok(())
}
