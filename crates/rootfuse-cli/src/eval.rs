//! `rootfuse eval`: the BROAD metrics of estimate files against ground truth.
use clap::Args;
use rootfuse_eval::metrics::{Alignment, Rmse, evaluate};
use rootfuse_io::{read_csv, read_estimates};
use std::path::{Path, PathBuf};

/// Options of `rootfuse eval`.
#[derive(Args)]
pub struct EvalArgs {
    /// Ground-truth recording (with `qw,qx,qy,qz` and optionally `use`).
    #[arg(conflicts_with = "truth_dir", requires = "est")]
    truth: Option<PathBuf>,
    /// Estimate file (`t,qw,qx,qy,qz`).
    est: Option<PathBuf>,
    /// Folder of ground-truth recordings (matched to estimates by file name).
    #[arg(long, requires = "est_dir")]
    truth_dir: Option<PathBuf>,
    /// Folder of estimate files.
    #[arg(long)]
    est_dir: Option<PathBuf>,
    /// 9: compare as is; 6: remove the constant heading offset first.
    #[arg(long, value_parser = ["6", "9"], default_value = "9")]
    dof: String,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

/// Scores one estimate file against one truth file.
pub fn score(truth: &Path, est: &Path, align: Alignment) -> Result<Rmse, String> {
    let rec = read_csv(truth).map_err(|e| e.to_string())?;
    let est_data = read_estimates(est).map_err(|e| e.to_string())?;
    if est_data.t.len() != rec.len() {
        return Err(format!(
            "{}: {} estimates for {} truth samples in {}",
            est.display(),
            est_data.t.len(),
            rec.len(),
            truth.display()
        ));
    }
    if let Some(i) =
        (0..rec.len()).find(|&i| (est_data.t[i] - rec.t[i]).abs() > 1e-6 * rec.t[i].abs().max(1.0))
    {
        return Err(format!(
            "{}: line {}: time {} does not match the truth's {} ({})",
            est.display(),
            i + 2,
            est_data.t[i],
            rec.t[i],
            truth.display()
        ));
    }
    evaluate(&rec, &est_data.quat, align).map_err(|e| format!("{}: {e}", truth.display()))
}

/// Runs the command.
pub fn run(args: &EvalArgs) -> Result<(), String> {
    let align = if args.dof == "6" {
        Alignment::SixD
    } else {
        Alignment::NineD
    };
    let mut pairs: Vec<(String, PathBuf, PathBuf)> = Vec::new();
    match (&args.truth, &args.est, &args.truth_dir, &args.est_dir) {
        (Some(t), Some(e), None, None) => pairs.push((stem(e), t.clone(), e.clone())),
        (None, None, Some(td), Some(ed)) => {
            let mut names: Vec<PathBuf> = std::fs::read_dir(ed)
                .map_err(|e| format!("{}: cannot read folder: {e}", ed.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == "csv"))
                .collect();
            names.sort();
            for e in names {
                let t = td.join(e.file_name().unwrap_or_default());
                if !t.is_file() {
                    return Err(format!(
                        "{}: no truth file {} for it",
                        e.display(),
                        t.display()
                    ));
                }
                pairs.push((stem(&e), t, e));
            }
            if pairs.is_empty() {
                return Err(format!("{}: no estimate files (*.csv)", ed.display()));
            }
        }
        _ => return Err("give TRUTH EST, or --truth-dir D --est-dir E".into()),
    }
    let mut rows = Vec::new();
    for (name, t, e) in &pairs {
        rows.push((name.clone(), score(t, e, align)?));
    }
    let n = rows.len() as f64;
    let mean = |f: fn(&Rmse) -> f64| rows.iter().map(|(_, r)| f(r)).sum::<f64>() / n;
    let (mt, mh, mi) = (
        mean(|r| r.total),
        mean(|r| r.heading),
        mean(|r| r.inclination),
    );
    if args.json {
        let files: Vec<String> = rows
            .iter()
            .map(|(name, r)| {
                format!(
                    "{{\"name\": {}, \"total\": {}, \"heading\": {}, \"inclination\": {}}}",
                    json_string(name),
                    r.total,
                    r.heading,
                    r.inclination
                )
            })
            .collect();
        out!(
            "{{\"files\": [{}], \"mean\": {{\"total\": {mt}, \"heading\": {mh}, \"inclination\": {mi}}}}}",
            files.join(", ")
        );
    } else {
        out!("| file | total (deg) | heading (deg) | inclination (deg) |");
        out!("|---|---|---|---|");
        for (name, r) in &rows {
            out!(
                "| {name} | {:.3} | {:.3} | {:.3} |",
                r.total,
                r.heading,
                r.inclination
            );
        }
        if rows.len() > 1 {
            out!("| mean | {mt:.3} | {mh:.3} | {mi:.3} |");
        }
    }
    Ok(())
}

fn stem(p: &Path) -> String {
    p.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// A JSON string literal (quotes, backslashes and control characters escaped).
fn json_string(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 => out.push_str(&format!("\\u{:04x}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}
