//! The smoother on the simulated disturbed-field scenarios with the adopted field's azimuth
//! error in its passes' heading variance (`adopted_field_error_scale`, the default 1) and
//! without it (0): mean smoothed 9D total RMSE over seeds, degrees. The passes' fusion weighs
//! each pass's heading by its variance, so the term decides which pass is trusted where one
//! has turned toward an adopted field (docs/accuracy.md, "The adopted field's azimuth error in
//! the report").
//!
//! ```sh
//! cargo run --release --example smoothed_adopted_field -- --seconds 300 --seeds 5
//! cargo run --release --example smoothed_adopted_field -- mag_home_time=0   # PARAM=VALUE
//! ```
use rootfuse::attitude::filters::{SqrtEskf, SqrtEskfParams};
use rootfuse::attitude::smooth::forward_backward;
use rootfuse::eval::metrics::{Alignment, evaluate};
use rootfuse::eval::sim::scenario;
use rootfuse::lane::wide::f64x2;

#[path = "shared/param_row.rs"]
mod param_row;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = param_row::parse(5, 120.0)?;
    let (base, seeds, seconds) = (&args.params, args.seeds, args.seconds);
    let mut header = Vec::new();
    let mut cells = Vec::new();
    for name in [
        "pendulum-disturbed",
        "vehicle-disturbed",
        "handheld-translation-disturbed",
        "magnetic-disturbance",
    ] {
        let mut sums = [0.0; 2];
        for seed in 0..seeds {
            let rec = scenario(name, seed, seconds, 100.0)?;
            for (sum, scale) in sums.iter_mut().zip([0.0, 1.0]) {
                let p = SqrtEskfParams {
                    adopted_field_error_scale: scale,
                    ..base.clone()
                }
                .for_smoothing();
                let out = forward_backward(&rec, || SqrtEskf::<f64x2>::new(&p), true)
                    .map_err(|e| format!("{name} seed {seed}: {e}"))?;
                *sum += evaluate(&rec, &out.quat, Alignment::NineD)?.total / seeds as f64;
            }
        }
        header.push(format!(
            "{name} ({seeds} seeds, {seconds} s), passes without / with"
        ));
        cells.push(format!("{:.2} / {:.2}", sums[0], sums[1]));
    }
    param_row::print_row(&args.label, &header, &cells);
    Ok(())
}
