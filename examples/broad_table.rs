//! Runs registered filters over the BROAD recordings and prints RMSE tables (degrees).
//!
//! ```sh
//! cargo run --release --example broad_table                         # every filter, defaults
//! cargo run --release --example broad_table -- mahony kp=0.8 ki=0.01 # one filter, overrides
//! ```
//! The data folder is `$ROOTFUSE_BROAD_DIR` or `../shared/broad_csv`.
use rootfuse::attitude::Recording;
use rootfuse::attitude::registry::{FilterKind, FilterSpec};
use rootfuse::eval::metrics::{Alignment, evaluate};
use rootfuse::io::read_dir;
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::env::var_os("ROOTFUSE_BROAD_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/broad_csv"));
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (names, overrides): (Vec<&String>, Vec<&String>) =
        args.iter().partition(|a| !a.contains('='));
    let kinds: Vec<FilterKind> = if names.is_empty() {
        FilterKind::ALL.to_vec()
    } else {
        names
            .iter()
            .map(|n| FilterKind::from_name(n))
            .collect::<Result<_, _>>()?
    };
    let recs: Vec<Recording> = read_dir(&dir)?;
    println!(
        "| filter | dof | precision | {} | mean |",
        recs.iter()
            .map(|r| r.name.as_str())
            .collect::<Vec<_>>()
            .join(" | ")
    );
    println!("|---|---|---|{}---|", "---|".repeat(recs.len()));
    for kind in kinds {
        for dof in [9u8, 6] {
            let mut spec = FilterSpec::new(kind.name())?;
            spec.set_dof(rootfuse::attitude::Dof::from_count(dof).ok_or("dof is 6 or 9")?)?;
            for o in &overrides {
                spec.set(o)?;
            }
            let align = if dof == 9 {
                Alignment::NineD
            } else {
                Alignment::SixD
            };
            for precision in ["f64", "f32"] {
                let mut cells = Vec::new();
                let mut sum = [0.0; 3];
                for rec in &recs {
                    let est = if precision == "f64" {
                        rec.estimate(&mut spec.build::<f64>())
                    } else {
                        rec.estimate(&mut spec.build::<f32>())
                    };
                    let r = evaluate(rec, &est, align)?;
                    sum[0] += r.total;
                    sum[1] += r.heading;
                    sum[2] += r.inclination;
                    cells.push(format!(
                        "{:.2} / {:.2} / {:.2}",
                        r.total, r.heading, r.inclination
                    ));
                }
                let n = recs.len() as f64;
                println!(
                    "| {} | {dof}D | {precision} | {} | {:.2} / {:.2} / {:.2} |",
                    kind.name(),
                    cells.join(" | "),
                    sum[0] / n,
                    sum[1] / n,
                    sum[2] / n
                );
            }
        }
    }
    Ok(())
}
