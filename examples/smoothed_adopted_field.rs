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
use rootfuse::attitude::filters::{Params, SqrtEskf, SqrtEskfParams};
use rootfuse::attitude::smooth::forward_backward;
use rootfuse::eval::metrics::{Alignment, evaluate};
use rootfuse::eval::sim::scenario;
use rootfuse::lane::wide::f64x2;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (mut seeds, mut seconds) = (5u64, 120.0);
    let mut base = SqrtEskfParams::default();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--seeds" => seeds = args.next().ok_or("--seeds N")?.parse()?,
            "--seconds" => seconds = args.next().ok_or("--seconds S")?.parse()?,
            _ => base.apply(&a)?,
        }
    }
    println!("| scenario ({seeds} seeds, {seconds} s) | passes without | with |");
    println!("|---|---|---|");
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
        println!("| {name} | {:.2} | {:.2} |", sums[0], sums[1]);
    }
    Ok(())
}
