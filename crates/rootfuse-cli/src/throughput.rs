//! `rootfuse throughput`: one filter measured in one run as scalar f32, scalar f64, f32x8
//! lanes, f64x4 lanes and f32x8 lanes on every core (synthetic in-memory data).
use clap::Args;
use rootfuse_attitude::registry::FilterSpec;

/// Options of `rootfuse throughput`.
#[derive(Args)]
pub struct ThroughputArgs {
    /// Filter name (see `rootfuse filters`).
    #[arg(long)]
    filter: String,
    /// Parameter override `key=value` (repeatable).
    #[arg(long = "param", value_name = "KEY=VALUE")]
    params: Vec<String>,
    /// 6: gravity only; 9: with magnetometer.
    #[arg(long, value_parser = ["6", "9"])]
    dof: Option<String>,
    /// Number of channels.
    #[arg(long, default_value_t = 4096)]
    channels: usize,
    /// Samples per channel.
    #[arg(long, default_value_t = 2000)]
    samples: usize,
    /// Print the JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

/// Runs the command.
pub fn run(args: &ThroughputArgs) -> Result<(), String> {
    if args.channels == 0 || args.samples == 0 {
        return Err("--channels and --samples must be at least 1".into());
    }
    let mut spec = FilterSpec::new(&args.filter).map_err(|e| e.to_string())?;
    for p in &args.params {
        spec.set(p).map_err(|e| e.to_string())?;
    }
    if let Some(dof) = &args.dof {
        spec.set_dof(if dof == "6" { 6 } else { 9 })
            .map_err(|e| e.to_string())?;
    }
    let report = rootfuse_batch::throughput(&spec, args.channels, args.samples);
    if args.json {
        out!("{}", report.to_json());
    } else {
        out!(
            "{} on {} channels x {} samples",
            report.filter,
            report.channels,
            report.samples
        );
        out!("| mode | channel-updates/s | ns per update | vs scalar-f32 |");
        out!("|---|---|---|---|");
        for m in &report.results {
            let ratio = report.ratio(m.mode, "scalar-f32").unwrap_or(f64::NAN);
            out!(
                "| {} | {:.3e} | {:.2} | {ratio:.2}x |",
                m.mode,
                m.updates_per_s,
                m.ns_per_update
            );
        }
    }
    Ok(())
}
