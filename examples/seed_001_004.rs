//! Two patent methods against their references on simulated scenarios: roll/pitch/yaw RMSE
//! (degrees, f64, 9D and 6D, from 2 s on; 6D heading aligned at 2 s) per filter, averaged
//! over seeds 1..=N at 100 Hz. `conv` runs the wrong-start motion of tests/filters.rs.
//!
//! ```sh
//! cargo run --release --example seed_001_004 -- [seconds] [seeds] filter[:k=v,...] ...
//! ```
//! The BROAD numbers come from `examples/broad_table.rs`.
use rootfuse::attitude::registry::FilterSpec;
use rootfuse::attitude::{ImuSample, OrientationFilter, Quat, Recording};
use rootfuse::eval::metrics::euler_rmse;
use rootfuse::eval::sim;

/// The wrong-start convergence motion of tests/filters.rs: worst error over the last 10 s.
fn conv(name: &str, dof: u8) -> f64 {
    use rootfuse::attitude::Vec3;
    let g = 9.81;
    let dip = 64f64.to_radians();
    let field = Vec3::new(0.0, dip.cos(), -dip.sin()) * 50.0;
    let mut q = Quat::from_euler_zyx(0.3, -0.2, 0.1);
    let wrong = Quat::<f64>::from_euler_zyx(1.0, 0.6, -0.7);
    let (first, _) = FilterSpec::new(name.split_once(':').map_or(name, |x| x.0))
        .map(|s| (s, 0))
        .unwrap();
    let mut spec = first;
    if let Some((_, o)) = name.split_once(':') {
        for o in o.split(',') {
            spec.set(o).unwrap();
        }
    }
    spec.set_dof(rootfuse::attitude::Dof::from_count(dof).expect("6 or 9"))
        .unwrap();
    let mut f = spec.build::<f64>();
    f.update(
        &ImuSample::new(
            Vec3::zero(),
            wrong.rotate_inverse(Vec3::new(0.0, 0.0, g)),
            wrong.rotate_inverse(field),
        ),
        0.01,
    );
    let mut worst: f64 = 0.0;
    for k in 0..4000 {
        let t = k as f64 * 0.01;
        let w = match ((t / 2.0) as usize) % 4 {
            0 => Vec3::new(0.0, 0.0, 0.0),
            1 => Vec3::new(0.4, -0.2, 0.3),
            2 => Vec3::new(-0.3, 0.5, -0.6),
            _ => Vec3::new(0.1, 0.1, 0.8),
        };
        q = (q * Quat::from_rotation_vector(w * 0.01)).normalize();
        f.update(
            &ImuSample::new(
                w,
                q.rotate_inverse(Vec3::new(0.0, 0.0, g)),
                q.rotate_inverse(field),
            ),
            0.01,
        );
        if k >= 3000 {
            let e = f.quat() * q.conj();
            let err = if dof == 9 {
                f.quat().angle_to(q)
            } else {
                2.0 * (e.w * e.w + e.z * e.z).sqrt().min(1.0).acos()
            };
            worst = worst.max(err.to_degrees());
        }
    }
    worst
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().is_some_and(|a| a == "conv") {
        for f in &args[1..] {
            println!("{f}: 6D {:.3}°, 9D {:.3}°", conv(f, 6), conv(f, 9));
        }
        return Ok(());
    }
    let seconds: f64 = args.first().map_or(Ok(60.0), |a| a.parse())?;
    let seeds: u64 = args.get(1).map_or(Ok(4), |a| a.parse())?;
    let filters = &args[2.min(args.len())..];
    println!("| scenario | dof | filter | roll | pitch | yaw |");
    println!("|---|---|---|---|---|---|");
    for scenario in ["static", "slow-rotation", "fast-rotation", "translation"] {
        let recs: Vec<Recording> = (1..=seeds)
            .map(|seed| sim::scenario(scenario, seed, seconds, 100.0))
            .collect::<Result<_, _>>()?;
        for dof in [9u8, 6] {
            for f in filters {
                let (name, overrides) = f.split_once(':').unwrap_or((f, ""));
                let mut spec = FilterSpec::new(name)?;
                spec.set_dof(rootfuse::attitude::Dof::from_count(dof).ok_or("dof is 6 or 9")?)?;
                for o in overrides.split(',').filter(|o| !o.is_empty()) {
                    spec.set(o)?;
                }
                let mut mean = [0.0; 3];
                for rec in &recs {
                    let r = euler_rmse(rec, &rec.estimate(&mut spec.build::<f64>()), 2.0, dof == 6);
                    for (m, x) in mean.iter_mut().zip(r) {
                        *m += x / recs.len() as f64;
                    }
                }
                println!(
                    "| {scenario} | {dof}D | {f} | {:.3} | {:.3} | {:.3} |",
                    mean[0], mean[1], mean[2]
                );
            }
        }
    }
    Ok(())
}
