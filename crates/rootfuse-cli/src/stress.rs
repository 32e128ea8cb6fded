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
    /// Multiplies every step count (e.g. 0.01 for a quick look; at most 100).
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
    if !(args.scale > 0.0 && args.scale <= rootfuse_lsq::stress::MAX_SCALE) {
        return Err(format!(
            "--scale must be positive and at most {} (minutes per scenario), got {}",
            rootfuse_lsq::stress::MAX_SCALE,
            args.scale
        ));
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
        let rows: Vec<serde_json::Value> = rows.iter().map(json_row).collect();
        let text = serde_json::to_string_pretty(&rows).map_err(|e| e.to_string())?;
        out!("{text}");
    } else {
        out!(
            "| form | precision | scenario | param | steps | max rel err (f64 data) | max rel err (received data) | health figure | worst | PD lost at | NaN at | detected | ns/update |"
        );
        out!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
        let opt = |v: Option<u64>| v.map_or("-".to_string(), |s| s.to_string());
        for r in &rows {
            out!(
                "| {} | {} | {} | {} | {} | {:.2e} | {:.2e} | {} | {:.2e} | {} | {} | {} | {:.0} |",
                r.form,
                r.precision,
                r.scenario,
                r.param.map_or("-".to_string(), |p| format!("{p:e}")),
                r.steps,
                r.max_rel_err,
                r.max_rel_err_received,
                r.health_kind,
                r.health_worst,
                opt(r.pd_lost_at),
                opt(r.nan_at),
                r.detected,
                r.ns_per_update
            );
        }
    }
    Ok(())
}

/// One row as a JSON object; NaN and infinities (which JSON cannot write) become `null`
/// (serde_json writes non-finite floats as `null`).
fn json_row(r: &StressRow) -> serde_json::Value {
    serde_json::json!({
        "form": r.form,
        "precision": r.precision,
        "scenario": r.scenario,
        "param": r.param,
        "steps": r.steps,
        "max_rel_err": r.max_rel_err,
        "max_rel_err_received": r.max_rel_err_received,
        "health_kind": r.health_kind,
        "health_worst": r.health_worst,
        "pd_lost_at": r.pd_lost_at,
        "nan_at": r.nan_at,
        "detected": r.detected,
        "ns_per_update": r.ns_per_update,
    })
}
