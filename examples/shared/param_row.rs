//! Shared by the flagship's examples that print one markdown table row per parameter set
//! (`flagship_coverage`, `field_layouts`, `smoothed_adopted_field`): their arguments
//! (`PARAM=VALUE` for the flagship's parameters, `--seeds N`, `--seconds S`) and the row.
use rootfuse::attitude::filters::{Params, SqrtEskfParams};

/// The parsed arguments.
pub struct Args {
    /// The defaults with every `PARAM=VALUE` applied.
    pub params: SqrtEskfParams,
    /// The `PARAM=VALUE` arguments as given: the row's label.
    pub label: Vec<String>,
    pub seeds: u64,
    pub seconds: f64,
}

/// The command line's arguments, with `seeds` and `seconds` where they are not given.
pub fn parse(seeds: u64, seconds: f64) -> Result<Args, Box<dyn std::error::Error>> {
    let mut out = Args {
        params: SqrtEskfParams::default(),
        label: Vec::new(),
        seeds,
        seconds,
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--seeds" => out.seeds = args.next().ok_or("--seeds N")?.parse()?,
            "--seconds" => out.seconds = args.next().ok_or("--seconds S")?.parse()?,
            _ => {
                out.params.apply(&a)?;
                out.label.push(a);
            }
        }
    }
    Ok(out)
}

/// Prints the header and the row: the label ("defaults" without one), then the cells.
pub fn print_row(label: &[String], header: &[String], cells: &[String]) {
    println!("| parameters | {} |", header.join(" | "));
    let label = if label.is_empty() {
        "defaults".to_string()
    } else {
        label.join(" ")
    };
    println!("| {label} | {} |", cells.join(" | "));
}
