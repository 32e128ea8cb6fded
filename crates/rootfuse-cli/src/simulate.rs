//! `rootfuse simulate`: a seeded fleet of simulated IMUs (with truth) as one Parquet or Arrow
//! file, to try fleets at scale.
use crate::outputs::{Ledger, SIMULATE};
use clap::Args;
use rootfuse_columnar::{BLOCK_ROWS, FleetFileWriter, Format};
use rootfuse_eval::sim::{SimSample, SimStream, scenario_stream};
use rootfuse_io::stale_temporaries;
use std::path::PathBuf;

/// Devices simulated together and interleaved time-major in the file (row `k` of each, then
/// row `k + 1`, as [`FleetFileWriter::write_group`] lays recordings out): 32 fill eight
/// `f32x8` chunks per block.
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
    /// Replace an existing `--out` that `rootfuse simulate` did not write (a symbolic link
    /// is never replaced nor written through).
    #[arg(long)]
    force: bool,
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
    let dir = match args.out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => std::path::Path::new("."),
    };
    let mut ledger = Ledger::load(dir);
    ledger.check(&args.out, SIMULATE, args.force)?;
    crate::signal::install_signal_handler()?;
    // What a killed simulate left (SIGKILL, power loss): its temporary files of this output.
    for tmp in stale_temporaries(&args.out) {
        std::fs::remove_file(&tmp)
            .map_err(|e| format!("{}: cannot remove stale temporary file: {e}", tmp.display()))?;
        eprintln!(
            "note: removed {}, left by an interrupted run",
            tmp.display()
        );
    }
    let mut writer = FleetFileWriter::create(&args.out, format).map_err(|e| e.to_string())?;
    for first in (0..args.devices).step_by(GROUP) {
        let streams = (first..(first + GROUP).min(args.devices))
            .map(|d| {
                scenario_stream(
                    &args.scenario,
                    args.seed + d as u64,
                    args.seconds,
                    args.rate,
                )
            })
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| format!("--scenario {}: {e}", args.scenario))?;
        match write_group(&mut writer, first as i64, streams) {
            Ok(true) => {}
            Ok(false) => {
                // Dropping the writer removes its temporary file.
                drop(writer);
                eprintln!("interrupted: {} not written", args.out.display());
                std::process::exit(crate::signal::EXIT_INTERRUPTED);
            }
            Err(e) => return Err(e.to_string()),
        }
    }
    let rows = writer.rows();
    writer.finish().map_err(|e| e.to_string())?;
    ledger.record(&args.out, SIMULATE)?;
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

/// Writes the streams of one group as devices `first_device..`, interleaved time-major in
/// record batches of [`BLOCK_ROWS`] rows (the last one shorter): the same batches as
/// [`FleetFileWriter::write_group`] on the whole recordings, so the file is the same, while
/// only a block of samples is held (the whole recordings took 1.45 GB for 10 devices ×
/// 10000 s at 100 Hz). `Ok(false)`: stopped by SIGINT or SIGTERM.
fn write_group(
    writer: &mut FleetFileWriter,
    first_device: i64,
    mut streams: Vec<SimStream>,
) -> Result<bool, rootfuse_columnar::ColumnarError> {
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .clamp(1, streams.len().max(1));
    let per_thread = streams.len().div_ceil(threads).max(1);
    // Samples per device drawn per round: about a block of rows for the whole group.
    let steps = BLOCK_ROWS.div_ceil(streams.len().max(1));
    let mut device = Vec::with_capacity(BLOCK_ROWS);
    let mut rows = Vec::with_capacity(BLOCK_ROWS);
    loop {
        if crate::signal::interrupted() {
            return Ok(false);
        }
        // The devices' streams are independent: draw a round of each on the cores.
        let drawn: Vec<Vec<SimSample>> = std::thread::scope(|scope| {
            let handles: Vec<_> = streams
                .chunks_mut(per_thread)
                .map(|part| {
                    scope.spawn(move || {
                        part.iter_mut()
                            .map(|s| s.by_ref().take(steps).collect::<Vec<_>>())
                            .collect::<Vec<_>>()
                    })
                })
                .collect();
            handles
                .into_iter()
                // A worker only panics on a bug; hand that panic on unchanged.
                .flat_map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
                .collect()
        });
        if drawn.iter().all(Vec::is_empty) {
            break;
        }
        for k in 0..steps {
            for (i, samples) in drawn.iter().enumerate() {
                let Some(x) = samples.get(k) else { continue };
                device.push(first_device + i as i64);
                rows.push(row(x));
                if rows.len() == BLOCK_ROWS {
                    writer.write_rows(&device, &rows)?;
                    device.clear();
                    rows.clear();
                }
            }
        }
    }
    if !rows.is_empty() {
        writer.write_rows(&device, &rows)?;
    }
    Ok(true)
}

/// A sample as the values of a fleet file row ([`rootfuse_columnar::FLEET_COLUMNS`]).
fn row(x: &SimSample) -> [f64; 14] {
    let mag = x.mag.map_or([f64::NAN; 3], |m| m.to_array());
    let q = x.truth.to_array();
    let [gx, gy, gz] = x.gyr.to_array();
    let [ax, ay, az] = x.acc.to_array();
    [
        x.t, gx, gy, gz, ax, ay, az, mag[0], mag[1], mag[2], q[0], q[1], q[2], q[3],
    ]
}
