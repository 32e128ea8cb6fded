//! `rootfuse throughput`: one filter measured in one run as scalar f32, scalar f64, f32x8
//! lanes, f64x4 lanes and f32x8 lanes on every core (synthetic in-memory data).
use crate::filter_args::FilterArgs;
use clap::Args;
use rootfuse_attitude::registry::FilterSpec;

/// Options of `rootfuse throughput`.
#[derive(Args)]
pub struct ThroughputArgs {
    #[command(flatten)]
    filter: FilterArgs,
    /// Number of channels.
    #[arg(long, default_value_t = 4096)]
    channels: usize,
    /// Samples per channel.
    #[arg(long, default_value_t = 2000)]
    samples: usize,
    /// Print the JSON object instead of a table.
    #[arg(long)]
    json: bool,
    /// Instead: f32x8 lanes on one core against the number of channels (8 to 1e6), chunk
    /// by chunk and tick by tick (`--samples` is ignored; each point runs about
    /// `--sweep-seconds`).
    #[arg(long)]
    sweep: bool,
    /// Seconds per sweep point and order (about; best of 3 runs).
    #[arg(long, default_value_t = 0.5)]
    sweep_seconds: f64,
    /// With `--sweep`: also draw it to this PNG (or SVG) file.
    #[arg(long, value_name = "PATH")]
    plot: Option<std::path::PathBuf>,
}

/// The channel counts of `--sweep`.
const SWEEP_CHANNELS: [usize; 7] = [8, 64, 512, 4096, 32768, 262144, 1_000_000];

/// Data cache sizes of CPU 0 from sysfs, `(name, bytes)`, e.g. `("L1d", 49152)`; empty where
/// sysfs does not say.
fn caches() -> Vec<(String, usize)> {
    let base = std::path::Path::new("/sys/devices/system/cpu/cpu0/cache");
    let read = |dir: &std::path::Path, f: &str| std::fs::read_to_string(dir.join(f)).ok();
    let mut out = Vec::new();
    for i in 0..8 {
        let dir = base.join(format!("index{i}"));
        let (Some(level), Some(kind), Some(size)) =
            (read(&dir, "level"), read(&dir, "type"), read(&dir, "size"))
        else {
            continue;
        };
        let kind = kind.trim();
        if kind == "Instruction" {
            continue;
        }
        let size = size.trim();
        let bytes = match size.strip_suffix('K') {
            Some(k) => k.parse::<usize>().ok().map(|k| k * 1024),
            None => size
                .strip_suffix('M')
                .and_then(|m| m.parse::<usize>().ok())
                .map(|m| m << 20),
        };
        if let Some(bytes) = bytes {
            let suffix = if kind == "Data" { "d" } else { "" };
            out.push((format!("L{}{suffix}", level.trim()), bytes));
        }
    }
    out
}

fn run_sweep(args: &ThroughputArgs, spec: &FilterSpec) -> Result<(), String> {
    if !(args.sweep_seconds > 0.0 && args.sweep_seconds.is_finite()) {
        return Err("--sweep-seconds must be positive".into());
    }
    let points = rootfuse_batch::sweep(spec, &SWEEP_CHANNELS, args.sweep_seconds);
    let caches = caches();
    let per_channel = points
        .last()
        .map_or(0.0, |p| p.state_bytes as f64 / p.channels as f64);
    if args.json {
        let json = serde_json::json!({ "filter": spec.kind().name(), "sweep": points });
        out!("{json}");
    } else {
        let names: Vec<String> = caches
            .iter()
            .map(|(n, b)| format!("{n} {} KiB", b / 1024))
            .collect();
        out!(
            "{} in f32x8 lanes on one core; state {per_channel:.0} B per channel; caches: {}",
            spec.kind().name(),
            names.join(", ")
        );
        out!("| channels | samples | state | chunk by chunk /s | tick by tick /s |");
        out!("|---|---|---|---|---|");
        for p in &points {
            out!(
                "| {} | {} | {:.1} KiB | {:.3e} | {:.3e} |",
                p.channels,
                p.samples,
                p.state_bytes as f64 / 1024.0,
                p.chunk_major,
                p.tick
            );
        }
    }
    if let Some(path) = &args.plot {
        let line =
            |label: &str, f: fn(&rootfuse_batch::SweepPoint) -> f64| crate::plot::SweepLine {
                label: label.into(),
                points: points.iter().map(|p| (p.channels as f64, f(p))).collect(),
            };
        let lines = [
            line("chunk by chunk (offline)", |p| p.chunk_major),
            line("tick by tick (streaming)", |p| p.tick),
        ];
        // Where the channels' state fills each cache: bytes / bytes per channel.
        let marks: Vec<(String, f64)> = caches
            .iter()
            .filter(|_| per_channel > 0.0)
            .map(|(n, b)| (format!("state = {n}"), *b as f64 / per_channel))
            .collect();
        let title = format!(
            "{} {}D, f32x8 lanes, one core: throughput vs channels",
            spec.kind().name(),
            if spec.uses_magnetometer() { 9 } else { 6 }
        );
        crate::plot::throughput_sweep(path, &title, &lines, &marks)?;
    }
    Ok(())
}

/// Runs the command.
pub fn run(args: &ThroughputArgs) -> Result<(), String> {
    if args.channels == 0 || args.samples == 0 {
        return Err("--channels and --samples must be at least 1".into());
    }
    let spec = args.filter.spec()?;
    if args.sweep {
        return run_sweep(args, &spec);
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
