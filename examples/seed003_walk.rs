//! `heading-pipeline`: heading and position error over 10-minute simulated walks, MEMS only vs with
//! beacons, printed as Markdown tables (one row per seed, then the means).
//!
//! ```sh
//! cargo run --release --example seed003_walk            # seeds 0..10, 6D and 9D
//! cargo run --release --example seed003_walk -- 20      # seeds 0..20
//! ```
use rootfuse::beacon::sim::{WalkConfig, run_walk};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seeds: u64 = std::env::args().nth(1).map_or(Ok(10), |s| s.parse())?;
    for (dof, fixes) in [(6u8, true), (9, true), (6, false)] {
        println!(
            "\n### {dof}D pipeline, beacon heading fusion{}\n",
            if fixes {
                " + beacon position fixes"
            } else {
                " only (no position fixes)"
            }
        );
        println!(
            "| seed | final ψ err MEMS (°) | final ψ err beacons (°) | RMS ψ MEMS (°) | RMS ψ beacons (°) | max pos err MEMS (m) | max pos err beacons (m) | final pos err beacons (m) | headings fused/refused | weak/fix decisions |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|");
        let mut sums = [0.0f64; 6];
        let mut worst_pos = 0.0f64;
        for seed in 0..seeds {
            let cfg = WalkConfig {
                seed,
                dof: rootfuse::attitude::Dof::from_count(dof).expect("6 or 9"),
                position_fixes: fixes,
                ..WalkConfig::default()
            };
            let r = run_walk(&cfg)?;
            let d = f64::to_degrees;
            println!(
                "| {seed} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {}/{} | {}/{} |",
                d(r.final_mems),
                d(r.final_beacon),
                d(r.rms_mems),
                d(r.rms_beacon),
                r.max_pos_mems,
                r.max_pos_beacon,
                r.final_pos_beacon,
                r.headings[0],
                r.headings[1],
                r.decisions[0],
                r.decisions[1]
            );
            let v = [
                d(r.final_mems).abs(),
                d(r.final_beacon).abs(),
                d(r.rms_mems),
                d(r.rms_beacon),
                r.max_pos_mems,
                r.max_pos_beacon,
            ];
            for (s, x) in sums.iter_mut().zip(v) {
                *s += x;
            }
            worst_pos = worst_pos.max(r.max_pos_beacon);
            eprintln!(
                "seed {seed}: beacon heading rms (weak, fixes) {:.1}° {:.1}°, fixes {:.2} m over {}",
                d(r.beacon_heading_rms[0]),
                d(r.beacon_heading_rms[1]),
                r.fix_rms.0,
                r.fix_rms.1
            );
            if seed == 0 {
                eprintln!("models (medium, strong) [A, n]: {:?}", r.models);
            }
        }
        let n = seeds as f64;
        println!(
            "| mean | {:.1} (abs) | {:.1} (abs) | {:.1} | {:.1} | {:.1} | {:.1} (worst {worst_pos:.1}) | | | |",
            sums[0] / n,
            sums[1] / n,
            sums[2] / n,
            sums[3] / n,
            sums[4] / n,
            sums[5] / n
        );
    }
    Ok(())
}
