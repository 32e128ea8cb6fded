//! `rootfuse eval`: the BROAD metrics of estimate files against ground truth.
use crate::checks::parse_units;
use clap::Args;
use rootfuse_attitude::Quat;
use rootfuse_attitude::units::{Sensor, Unit, Units};
use rootfuse_eval::alignment::{FrameAlignment, align_frames};
use rootfuse_eval::consistency::{Consistency, UpperTriangle, consistency};
use rootfuse_eval::metrics::{Alignment, Rmse, rmse};
use rootfuse_io::Estimates;
use rootfuse_io::{list_dir, read_estimates, read_truth};
use std::path::{Path, PathBuf};

/// Options of `rootfuse eval`.
#[derive(Args)]
pub struct EvalArgs {
    /// Ground-truth file: `t,qw,qx,qy,qz` and optionally `use` (a recording, or a
    /// motion-capture export without IMU columns).
    #[arg(conflicts_with = "truth_dir", requires = "est")]
    truth: Option<PathBuf>,
    /// Estimate file (`t,qw,qx,qy,qz`).
    est: Option<PathBuf>,
    /// Folder of ground-truth files (matched to estimates by file name).
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
    /// The truth is in other frames (motion capture): first estimate the constant earth-frame
    /// offset (about the vertical only with --dof 6) and the sensor-to-body rotation by robust
    /// least squares, print them, and score the aligned estimate. The truth's vertical is
    /// found from the data (z-up or y-up frames alike) and heading and inclination split
    /// about it. A recording that does not turn about two axes is refused (it cannot tell
    /// the two rotations apart).
    #[arg(long)]
    align: bool,
    /// Also judge the reported attitude covariance (estimate files written by `rootfuse run
    /// --covariance`): per file the mean NEES/k and the share of samples inside the 95 %
    /// ellipsoid, total and inclination, after the first 10 % of each file (1 and 95 % when
    /// honest; `rootfuse_eval::consistency`).
    #[arg(long, conflicts_with = "align")]
    consistency: bool,
    /// With --consistency: a floor for the truth's own error, degrees per axis, added to the
    /// covariance (optical truth is itself off by a fraction of a degree).
    #[arg(
        long,
        value_name = "DEG",
        default_value_t = 0.0,
        requires = "consistency"
    )]
    floor: f64,
    /// The units the truth files are written in, as given to `rootfuse run --units` (only
    /// `time` matters here: the estimates' time is in s, the truth's is converted to match).
    #[arg(long, value_name = "LIST", value_parser = parse_units, default_value = "")]
    units: Units,
}

/// The leading share of each file --consistency leaves out (the filter's start-up).
const CONSISTENCY_SKIP: f64 = 0.1;

/// Fewer counted samples than this make a score that is noted as saying little (one second
/// at 100 Hz).
const MIN_SAMPLES: usize = 100;

/// One scored file.
struct Scored {
    name: String,
    rmse: Rmse,
    alignment: Option<FrameAlignment>,
    consistency: Option<Consistency>,
}

/// The covariance columns of an estimate file, per row, or an error saying how to get them.
fn covariances(est: &Path, data: &Estimates) -> Result<Vec<UpperTriangle>, String> {
    const NAMES: [&str; 6] = ["p_xx", "p_xy", "p_xz", "p_yy", "p_yz", "p_zz"];
    let columns: Vec<&[f64]> = NAMES
        .iter()
        .map(|name| {
            data.column(name).ok_or_else(|| {
                format!(
                    "{}: --consistency needs the covariance columns {} (column `{name}` is missing): write them with `rootfuse run --covariance`",
                    est.display(),
                    NAMES.join(",")
                )
            })
        })
        .collect::<Result<_, _>>()?;
    Ok((0..data.t.len())
        .map(|i| core::array::from_fn(|k| columns[k][i]))
        .collect())
}

/// Scores one estimate file against one truth file, aligning the frames first with
/// `frames`.
fn score(truth: &Path, est: &Path, align: Alignment, args: &EvalArgs) -> Result<Scored, String> {
    let frames = args.align;
    let mut reference = read_truth(truth).map_err(|e| e.to_string())?;
    let seconds = args.units.get(Sensor::Time).factor();
    if seconds != 1.0 {
        reference.t.iter_mut().for_each(|t| *t *= seconds);
    }
    let est_data = read_estimates(est).map_err(|e| e.to_string())?;
    let n = reference.t.len();
    if est_data.t.len() != n {
        return Err(format!(
            "{}: {} estimates for {n} truth samples in {}",
            est.display(),
            est_data.t.len(),
            truth.display()
        ));
    }
    let t = &reference.t;
    if let Some(i) = (0..n).find(|&i| (est_data.t[i] - t[i]).abs() > 1e-6 * t[i].abs().max(1.0)) {
        let hint = time_unit_hint(t, &est_data.t, args.units.get(Sensor::Time));
        return Err(format!(
            "{}: line {}: time {} does not match the truth's {} ({}){hint}",
            est.display(),
            i + 2,
            est_data.t[i],
            t[i],
            truth.display()
        ));
    }
    let use_mask = reference.use_mask.as_deref();
    let consistency = args
        .consistency
        .then(|| -> Result<Consistency, String> {
            let cov = covariances(est, &est_data)?;
            consistency(
                &est_data.quat,
                &cov,
                &reference.quat,
                use_mask,
                align,
                args.floor.to_radians(),
                CONSISTENCY_SKIP,
            )
            .map_err(|e| format!("{}: {e}", truth.display()))
        })
        .transpose()?;
    let alignment = frames
        .then(|| align_frames(&est_data.quat, &reference.quat, use_mask, align))
        .transpose()
        .map_err(|e| format!("{}: --align: {e}", est.display()))?;
    let (truth_q, quat) = match &alignment {
        // Estimate and truth turned z-up together, so that heading and inclination split
        // about the truth's own vertical (a y-up motion-capture frame).
        Some(a) => {
            let level = a.level();
            let truth_q = reference.quat.iter().map(|&r| level * r).collect();
            let quat = est_data.quat.iter().map(|&q| level * a.apply(q)).collect();
            (truth_q, quat)
        }
        None => (reference.quat, est_data.quat),
    };
    let rmse =
        rmse(&quat, &truth_q, use_mask, align).map_err(|e| format!("{}: {e}", truth.display()))?;
    if rmse.n_used < MIN_SAMPLES {
        eprintln!(
            "warning: {}: only {} sample(s) count (use = 1, finite truth): an RMSE over so few says little about accuracy",
            truth.display(),
            rmse.n_used
        );
    }
    Ok(Scored {
        name: stem(est),
        rmse,
        alignment,
        consistency,
    })
}

/// What a time mismatch says about the truth's time unit. `truth` is in seconds as
/// `declared` converted it; estimates are written in s. Where the spans' ratio makes the
/// file's own unit one of s, ms, µs or ns (within 1 %) and not the declared one, that unit
/// is named. Empty otherwise (an offset or a stretch of the time line is no unit).
fn time_unit_hint(truth: &[f64], est: &[f64], declared: Unit) -> String {
    let span = |t: &[f64]| t[t.len() - 1] - t[0];
    let ratio = span(truth) / span(est);
    // The factor from the file's numbers to seconds that would have matched.
    let actual = declared.factor() / ratio;
    let Some((name, factor)) = [("s", 1.0), ("ms", 1e-3), ("us", 1e-6), ("ns", 1e-9)]
        .into_iter()
        .find(|(_, f)| (actual / f - 1.0).abs() < 0.01)
    else {
        return String::new();
    };
    if factor == declared.factor() {
        return String::new();
    }
    let fix = if factor == 1.0 {
        "leave time out of --units".to_string()
    } else {
        format!("--units time={name}, as to `rootfuse run`")
    };
    format!(
        "; the truth's time spans {ratio:.4} times the estimates' (written in s): its time looks like {name} ({fix})"
    )
}

/// Runs the command.
pub fn run(args: &EvalArgs) -> Result<(), String> {
    let align = if args.dof == "6" {
        Alignment::SixD
    } else {
        Alignment::NineD
    };
    let pairs = file_pairs(args)?;
    let mut rows = Vec::new();
    for (name, t, e) in &pairs {
        rows.push(Scored {
            name: name.clone(),
            ..score(t, e, align, args)?
        });
    }
    let n = rows.len() as f64;
    let mean = |f: fn(&Rmse) -> f64| rows.iter().map(|s| f(&s.rmse)).sum::<f64>() / n;
    let (mt, mh, mi) = (
        mean(|r| r.total),
        mean(|r| r.heading),
        mean(|r| r.inclination),
    );
    if args.json {
        print_json(&rows, (mt, mh, mi));
    } else {
        print_tables(&rows, (mt, mh, mi), args);
    }
    Ok(())
}

/// The (name, truth, estimate) files to score: one pair, or every estimate in a folder with
/// its truth file of the same name (every truth file must have an estimate).
fn file_pairs(args: &EvalArgs) -> Result<Vec<(String, PathBuf, PathBuf)>, String> {
    let mut pairs: Vec<(String, PathBuf, PathBuf)> = Vec::new();
    match (&args.truth, &args.est, &args.truth_dir, &args.est_dir) {
        (Some(t), Some(e), None, None) => pairs.push((stem(e), t.clone(), e.clone())),
        (None, None, Some(td), Some(ed)) => {
            let names = list_dir(ed).map_err(|e| e.to_string())?;
            if names.is_empty() {
                return Err(format!("{}: no .csv files in the folder", ed.display()));
            }
            // Every truth file must be scored: a mean over fewer files would not be the
            // dataset's.
            for t in list_dir(td).map_err(|e| e.to_string())? {
                same_name_in(
                    ed,
                    &t,
                    "estimate",
                    " (the mean must cover every truth file; score single files as TRUTH EST)",
                )?;
            }
            for e in names {
                let t = same_name_in(td, &e, "truth file", "")?;
                pairs.push((stem(&e), t, e));
            }
        }
        _ => return Err("give TRUTH EST, or --truth-dir D --est-dir E".into()),
    }
    Ok(pairs)
}

/// The scores as one JSON document: per file, and the mean `(total, heading, inclination)`.
fn print_json(rows: &[Scored], (mt, mh, mi): (f64, f64, f64)) {
    let files: Vec<serde_json::Value> = rows
        .iter()
        .map(|s| {
            let r = &s.rmse;
            let mut file = serde_json::json!({
                "name": s.name,
                "total": r.total,
                "heading": r.heading,
                "inclination": r.inclination,
            });
            if let Some(a) = &s.alignment {
                file["align"] = alignment_json(a);
            }
            if let Some(c) = &s.consistency {
                file["consistency"] = serde_json::json!({
                    "nees_total": c.nees_total,
                    "coverage_total": c.coverage_total,
                    "nees_inclination": c.nees_inclination,
                    "coverage_inclination": c.coverage_inclination,
                    "n_used": c.n_used,
                    "n_invalid": c.n_invalid,
                });
            }
            file
        })
        .collect();
    let json = serde_json::json!({
        "files": files,
        "mean": { "total": mt, "heading": mh, "inclination": mi },
    });
    out!("{json}");
}

/// The scores as Markdown tables: RMSE per file and mean, then the covariance's consistency
/// and the alignment where asked for.
fn print_tables(rows: &[Scored], (mt, mh, mi): (f64, f64, f64), args: &EvalArgs) {
    out!("| file | total (deg) | heading (deg) | inclination (deg) |");
    out!("|---|---|---|---|");
    for s in rows {
        let r = &s.rmse;
        out!(
            "| {} | {:.3} | {:.3} | {:.3} |",
            s.name,
            r.total,
            r.heading,
            r.inclination
        );
    }
    if rows.len() > 1 {
        out!("| mean | {mt:.3} | {mh:.3} | {mi:.3} |");
    }
    if args.consistency {
        out!(
            "\ncovariance (after the first {:.0} % of each file, floor {}°): 1 and 95 % when honest",
            CONSISTENCY_SKIP * 100.0,
            args.floor
        );
        out!("| file | NEES/3 | inside 95 % | inclination NEES/2 | inside 95 % |");
        out!("|---|---|---|---|---|");
        for s in rows {
            if let Some(c) = &s.consistency {
                out!(
                    "| {} | {:.2} | {:.1} % | {:.2} | {:.1} % |",
                    s.name,
                    c.nees_total,
                    100.0 * c.coverage_total,
                    c.nees_inclination,
                    100.0 * c.coverage_inclination
                );
            }
        }
    }
    if args.align {
        out!("\naligned (estimate in the truth's frames = earth ⊗ q ⊗ sensor_to_body*):");
        out!(
            "| file | truth vertical | earth offset (deg, about axis) | sensor to body (deg, about axis) | outliers | median error (deg) |"
        );
        out!("|---|---|---|---|---|---|");
        for s in rows {
            if let Some(a) = &s.alignment {
                let v = a.vertical;
                out!(
                    "| {} | [{:.3}, {:.3}, {:.3}] | {} | {} | {} of {} | {:.3} |",
                    s.name,
                    v.x,
                    v.y,
                    v.z,
                    axis_angle(a.earth),
                    axis_angle(a.sensor_to_body),
                    a.n_downweighted,
                    a.n_used,
                    a.median_error_deg
                );
            }
        }
    }
}

/// `angle° about [x, y, z]` of a rotation.
fn axis_angle(q: Quat<f64>) -> String {
    let v = q.to_rotation_vector();
    let angle = v.norm();
    if angle == 0.0 {
        return "0".into();
    }
    let a = v * (1.0 / angle);
    format!(
        "{:.4} about [{:.4}, {:.4}, {:.4}]",
        angle.to_degrees(),
        a.x,
        a.y,
        a.z
    )
}

/// The alignment as a JSON object: both rotations as `[w, x, y, z]`.
fn alignment_json(a: &FrameAlignment) -> serde_json::Value {
    serde_json::json!({
        "earth": a.earth.to_array(),
        "sensor_to_body": a.sensor_to_body.to_array(),
        "n_used": a.n_used,
        "n_downweighted": a.n_downweighted,
        "median_error": a.median_error_deg,
        "vertical": a.vertical.to_array(),
        "excitation": a.excitation_deg,
    })
}

/// The file of `dir` with the name of `file` (its counterpart), or an error saying that `file`
/// has no `what` there, with the reason `why`.
fn same_name_in(dir: &Path, file: &Path, what: &str, why: &str) -> Result<PathBuf, String> {
    let counterpart = dir.join(file.file_name().unwrap_or_default());
    if counterpart.is_file() {
        Ok(counterpart)
    } else {
        Err(format!(
            "{}: no {what} {} for it{why}",
            file.display(),
            counterpart.display()
        ))
    }
}

fn stem(p: &Path) -> String {
    p.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}
