//! `rootfuse stress`: numerical stress scenarios for every recursive least-squares form, in
//! f32 and f64, against a double-double reference (the runners of `rootfuse_lsq::stress`).
use crate::plot::TraceSeries;
use clap::Args;
use rootfuse_lsq::stress::{SCENARIOS, StressOptions, StressRow, run_all, run_scenario};

/// Options of `rootfuse stress`.
#[derive(Args)]
pub struct StressArgs {
    /// Only this scenario (default: all).
    #[arg(long, value_parser = SCENARIOS)]
    scenario: Option<String>,
    /// Ten times longer `benign` and `lambda-one` runs (1e7 steps).
    #[arg(long)]
    long: bool,
    /// Multiplies every step count (e.g. 0.01 for a quick look).
    #[arg(long, default_value_t = 1.0)]
    scale: f64,
    /// Print one JSON array instead of a table.
    #[arg(long)]
    json: bool,
    /// Also draw the relative error over the steps of `--scenario` (every form, f32 and f64;
    /// the first parameter value) to this `.png` or `.svg` file.
    #[arg(long, value_name = "FILE", requires = "scenario")]
    plot: Option<std::path::PathBuf>,
}

/// Runs the command.
pub fn run(args: &StressArgs) -> Result<(), String> {
    if !(args.scale > 0.0 && args.scale.is_finite()) {
        return Err(format!("--scale must be positive, got {}", args.scale));
    }
    let options = StressOptions {
        long: args.long,
        scale: args.scale,
    };
    let rows = match &args.scenario {
        Some(name) => {
            run_scenario(name, options).ok_or_else(|| format!("unknown scenario `{name}`"))?
        }
        None => run_all(options),
    };
    if let (Some(path), Some(name)) = (&args.plot, &args.scenario) {
        let first = rows.first().and_then(|r| r.param);
        let series: Vec<TraceSeries> = rows
            .iter()
            .filter(|r| r.param == first)
            .map(|r| TraceSeries {
                form: r.form.to_string(),
                f64: r.precision == "f64",
                points: r.trace.clone(),
            })
            .collect();
        let title = match first {
            Some(p) => format!("stress: {name} ({p:e})"),
            None => format!("stress: {name}"),
        };
        crate::plot::stress_trace(path, &title, &series)?;
    }
    if args.json {
        let objects: Vec<String> = rows.iter().map(json_row).collect();
        out!("[{}]", objects.join(",\n "));
    } else {
        out!(
            "| form | precision | scenario | param | steps | max rel err | PD lost at | NaN at | detected | ns/update |"
        );
        out!("|---|---|---|---|---|---|---|---|---|---|");
        let opt = |v: Option<u64>| v.map_or("-".to_string(), |s| s.to_string());
        for r in &rows {
            out!(
                "| {} | {} | {} | {} | {} | {:.2e} | {} | {} | {} | {:.0} |",
                r.form,
                r.precision,
                r.scenario,
                r.param.map_or("-".to_string(), |p| format!("{p:e}")),
                r.steps,
                r.max_rel_err,
                opt(r.pd_lost_at),
                opt(r.nan_at),
                r.detected,
                r.ns_per_update
            );
        }
    }
    Ok(())
}

/// A JSON number; NaN and infinities (which JSON cannot write) become `null`.
fn number(x: f64) -> String {
    if x.is_finite() {
        format!("{x:e}")
    } else {
        "null".into()
    }
}

fn json_row(r: &StressRow) -> String {
    let step = |v: Option<u64>| v.map_or("null".to_string(), |s| s.to_string());
    format!(
        "{{\"form\": \"{}\", \"precision\": \"{}\", \"scenario\": \"{}\", \"param\": {}, \"steps\": {}, \"max_rel_err\": {}, \"pd_lost_at\": {}, \"nan_at\": {}, \"detected\": {}, \"ns_per_update\": {}}}",
        r.form,
        r.precision,
        r.scenario,
        r.param.map_or("null".to_string(), number),
        r.steps,
        number(r.max_rel_err),
        step(r.pd_lost_at),
        step(r.nan_at),
        r.detected,
        number(r.ns_per_update)
    )
}
