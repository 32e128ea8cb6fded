//! `rootfuse demo`: the built-in default job.
//!
//! Simulates a fleet of IMUs over several scenarios (the seeded simulator: exact truth, a
//! realistic sensor model), runs every registered filter in 9D and 6D through the same engine
//! as `rootfuse run`, adds the BROAD recordings when they are present, and prints an accuracy
//! table and a throughput table. It writes a Markdown report and plots (PNG and SVG: error
//! over time per filter, error per scenario) to the output folder.
use crate::engine::{Precision, run_recordings};
use crate::plot;
use clap::Args;
use rootfuse_attitude::registry::{FilterKind, FilterSpec};
use rootfuse_attitude::{Dof, Recording};
use rootfuse_batch::run_final_states;
use rootfuse_eval::metrics::{Alignment, evaluate, evaluate_series};
use rootfuse_eval::sim::scenario_batch;
use rootfuse_io::list_dir;
use rootfuse_io::read_csv;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

/// Options of `rootfuse demo`.
#[derive(Args)]
pub struct DemoArgs {
    /// Number of simulated IMU channels (spread evenly over the scenarios).
    #[arg(long, default_value_t = 1024)]
    channels: usize,
    /// Length of each simulated recording, s.
    #[arg(long, default_value_t = 20.0)]
    seconds: f64,
    /// Sample rate of the simulated IMUs, Hz.
    #[arg(long, default_value_t = 100.0)]
    rate: f64,
    /// Folder with real recordings (BROAD CSV format); default `../shared/broad_csv` if present.
    #[arg(long)]
    data: Option<PathBuf>,
    /// Output folder for the report and the plots.
    #[arg(long, default_value = "out/demo")]
    out: PathBuf,
}

/// The simulated scenarios of the demo.
const SCENARIOS: [&str; 4] = [
    "slow-rotation",
    "fast-rotation",
    "translation",
    "magnetic-disturbance",
];

/// Accuracy of one filter configuration on one group of recordings.
struct Cell {
    mean_total: f64,
    mean_inclination: f64,
}

/// The BROAD recordings of `--data`, or of `../shared/broad_csv` when it is there; none
/// otherwise.
fn read_broad(args: &DemoArgs) -> Result<Vec<Recording>, String> {
    let broad_dir = args.data.clone().or_else(|| {
        let d = PathBuf::from("../shared/broad_csv");
        d.join("index.csv").is_file().then_some(d)
    });
    Ok(match &broad_dir {
        Some(d) => list_dir(d)
            .map_err(|e| e.to_string())?
            .iter()
            .map(read_csv)
            .collect::<Result<_, _>>()
            .map_err(|e| e.to_string())?,
        None => Vec::new(),
    })
}

/// What the demo reports of every filter, 9D and 6D: accuracy per scenario, total RMSE per
/// real recording, throughput, and the 9D error series of the first fast-rotation channel.
struct Measured {
    accuracy: Vec<(String, Vec<Cell>)>,
    real: Vec<(String, Vec<f64>)>,
    speed: Vec<(String, f64)>,
    series: Vec<(String, Vec<f64>)>,
}

/// Runs every filter over the simulated `fleet` (timed through the lanes, then again for the
/// series) and over `broad`.
fn measure(
    fleet: &[(&str, Vec<Recording>)],
    broad: &[Recording],
    samples_per_filter: usize,
) -> Result<Measured, String> {
    let mut accuracy: Vec<(String, Vec<Cell>)> = Vec::new();
    let mut real: Vec<(String, Vec<f64>)> = Vec::new();
    let mut speed: Vec<(String, f64)> = Vec::new();
    let mut series: Vec<(String, Vec<f64>)> = Vec::new();
    for &kind in FilterKind::ALL {
        for dof in [Dof::Nine, Dof::Six] {
            let mut spec = FilterSpec::new(kind.name()).map_err(|e| e.to_string())?;
            spec.set_dof(dof).map_err(|e| e.to_string())?;
            let align = if dof == Dof::Nine {
                Alignment::NineD
            } else {
                Alignment::SixD
            };
            let label = format!("{} {dof}", kind.name());
            let mut cells = Vec::new();
            let mut filtering = 0.0;
            for (name, recs) in fleet {
                // The engine's speed: the same channels through the lanes with only the final
                // state kept (the series the accuracy needs are collected in a second run,
                // not timed: storing them is the report's cost, not the filters').
                let specs = vec![spec.clone(); recs.len()];
                let t0 = Instant::now();
                run_final_states(&specs, recs, Precision::F32).map_err(|e| e.to_string())?;
                filtering += t0.elapsed().as_secs_f64();
                let outputs = run_recordings(&spec, recs, Precision::F32);
                let (mut total, mut incl) = (0.0, 0.0);
                for (rec, out) in recs.iter().zip(&outputs) {
                    let r = evaluate(rec, &out.quat, align).map_err(|e| e.to_string())?;
                    total += r.total;
                    incl += r.inclination;
                }
                // Gyro-only never observes heading: its 9D error would flatten every other curve.
                if *name == "fast-rotation" && dof == Dof::Nine && kind != FilterKind::Gyro {
                    let s = evaluate_series(&recs[0], &outputs[0].quat, align)
                        .map_err(|e| e.to_string())?;
                    series.push((kind.name().to_string(), s.total));
                }
                let n = recs.len() as f64;
                cells.push(Cell {
                    mean_total: total / n,
                    mean_inclination: incl / n,
                });
            }
            speed.push((label.clone(), samples_per_filter as f64 / filtering));
            accuracy.push((label.clone(), cells));
            if !broad.is_empty() {
                let outputs = run_recordings(&spec, broad, Precision::F32);
                let totals = broad
                    .iter()
                    .zip(&outputs)
                    .map(|(rec, out)| evaluate(rec, &out.quat, align).map(|r| r.total))
                    .collect::<Result<Vec<f64>, _>>()
                    .map_err(|e| e.to_string())?;
                real.push((label, totals));
            }
        }
    }
    Ok(Measured {
        accuracy,
        real,
        speed,
        series,
    })
}

/// The report's tables: accuracy on the simulated fleet and on the real recordings,
/// throughput.
fn tables(
    args: &DemoArgs,
    per: usize,
    broad: &[Recording],
    accuracy: &[(String, Vec<Cell>)],
    real: &[(String, Vec<f64>)],
    speed: &[(String, f64)],
) -> String {
    let mut report = String::new();
    let _ = writeln!(report, "# rootfuse demo\n");
    let _ = writeln!(
        report,
        "{} simulated IMUs, {} s at {} Hz each, every filter in f32 with its default parameters.\n",
        per * SCENARIOS.len(),
        args.seconds,
        args.rate
    );
    let _ = writeln!(
        report,
        "## Accuracy on the simulated fleet (mean RMSE, degrees: total / inclination)\n"
    );
    let _ = writeln!(report, "| filter | {} |", SCENARIOS.join(" | "));
    let _ = writeln!(report, "|---|{}", "---|".repeat(SCENARIOS.len()));
    for (label, cells) in accuracy {
        let row: Vec<String> = cells
            .iter()
            .map(|c| format!("{:.2} / {:.2}", c.mean_total, c.mean_inclination))
            .collect();
        let _ = writeln!(report, "| {label} | {} |", row.join(" | "));
    }
    if !broad.is_empty() {
        let names: Vec<&str> = broad.iter().map(|r| r.name.as_str()).collect();
        let _ = writeln!(
            report,
            "\n## Accuracy on real recordings (total RMSE, degrees)\n"
        );
        let _ = writeln!(report, "| filter | {} | mean |", names.join(" | "));
        let _ = writeln!(report, "|---|{}---|", "---|".repeat(names.len()));
        for (label, totals) in real {
            let mean = totals.iter().sum::<f64>() / totals.len() as f64;
            let row: Vec<String> = totals.iter().map(|t| format!("{t:.2}")).collect();
            let _ = writeln!(report, "| {label} | {} | {mean:.2} |", row.join(" | "));
        }
    }
    let _ = writeln!(
        report,
        "\n## Throughput (f32 lanes on all cores, this machine: the filters reading their \
         input, final state kept; simulation, series and evaluation not timed)\n"
    );
    let _ = writeln!(report, "| filter | channel-updates/s | ns per update |");
    let _ = writeln!(report, "|---|---|---|");
    for (label, rate) in speed {
        let _ = writeln!(report, "| {label} | {rate:.3e} | {:.1} |", 1e9 / rate);
    }
    report
}

/// Runs the demo.
pub fn run(args: &DemoArgs) -> Result<(), String> {
    let positive = |x: f64| x > 0.0 && x.is_finite(); // false for NaN too
    if args.channels < SCENARIOS.len() || !positive(args.seconds) || !positive(args.rate) {
        return Err(format!(
            "--channels must be at least {} and --seconds, --rate positive",
            SCENARIOS.len()
        ));
    }
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("{}: cannot create: {e}", args.out.display()))?;
    let per = args.channels / SCENARIOS.len();
    let start = Instant::now();
    let mut fleet: Vec<(&str, Vec<Recording>)> = Vec::new();
    for (k, name) in SCENARIOS.iter().enumerate() {
        let seeds: Vec<u64> = (0..per as u64).map(|s| s + 1000 * k as u64).collect();
        fleet.push((
            name,
            scenario_batch(name, &seeds, args.seconds, args.rate).map_err(|e| e.to_string())?,
        ));
    }
    let samples_per_filter: usize = fleet.iter().flat_map(|(_, r)| r).map(Recording::len).sum();
    out!(
        "rootfuse demo: {} simulated IMUs ({per} per scenario) x {} s at {} Hz, simulated in {:.2} s",
        per * SCENARIOS.len(),
        args.seconds,
        args.rate,
        start.elapsed().as_secs_f64()
    );

    let broad = read_broad(args)?;

    let Measured {
        accuracy,
        real,
        speed,
        series,
    } = measure(&fleet, &broad, samples_per_filter)?;

    let mut report = tables(args, per, &broad, &accuracy, &real, &speed);
    let fig1 = plot::error_over_time(
        &args.out,
        "error_over_time",
        "fast-rotation, channel 0, 9D",
        args.rate,
        &series,
    )?;
    let per_scenario: Vec<(String, Vec<f64>)> = accuracy
        .iter()
        .filter(|(l, _)| l.ends_with("9D") && !l.starts_with("gyro"))
        .map(|(l, c)| (l.clone(), c.iter().map(|c| c.mean_total).collect()))
        .collect();
    let fig2 =
        plot::error_per_scenario(&args.out, "error_per_scenario", &SCENARIOS, &per_scenario)?;
    let _ = writeln!(
        report,
        "\n## Plots\n\n![error over time]({fig1})\n\n![error per scenario]({fig2})"
    );
    let report_path = args.out.join("report.md");
    std::fs::write(&report_path, &report)
        .map_err(|e| format!("{}: cannot write: {e}", report_path.display()))?;
    out!("{}", report.trim_end());
    out!(
        "\nReport, PNG and SVG plots in {} ({:.1} s in all).",
        args.out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
