//! `rootfuse demo`: the built-in default job.
//!
//! Today it integrates a fleet of simulated gyroscopes (constant body rates about random axes,
//! whose exact orientation is known in closed form) with the exponential map, in f32 and f64,
//! one channel at a time and eight channels per `f32x8`, and prints the error against the
//! closed form and the throughput of each. It grows with the filters.
use clap::Args;
use rootfuse_attitude::{Quat, Vec3};
use rootfuse_lane::Lane;
use std::hint::black_box;
use std::time::Instant;

/// Options of `rootfuse demo`.
#[derive(Args)]
pub struct DemoArgs {
    /// Number of simulated IMU channels.
    #[arg(long, default_value_t = 1024)]
    channels: usize,
    /// Samples per channel (at 200 Hz).
    #[arg(long, default_value_t = 2000)]
    samples: usize,
}

const DT: f64 = 0.005;

/// A deterministic channel: body rate (rad/s) about a fixed axis.
fn channel_rate(i: usize) -> Vec3<f64> {
    // Golden-angle spiral over the sphere, rates from 0.1 to 6 rad/s.
    let k = i as f64 + 0.5;
    let z = 1.0 - 2.0 * (k / 1024.0).fract();
    let r = (1.0 - z * z).sqrt();
    let phi = k * 2.399_963_229_728_653;
    let rate = 0.1 + 5.9 * ((k * 0.618_033_988_749_895).fract());
    Vec3::new(r * phi.cos(), r * phi.sin(), z) * rate
}

fn integrate<T: Lane>(rate: Vec3<T>, dt: T, samples: usize) -> Quat<T> {
    let mut q = Quat::identity();
    for _ in 0..samples {
        q = (q * Quat::from_rotation_vector(black_box(rate) * dt)).normalize();
    }
    q
}

/// Runs the demo and prints its tables.
pub fn run(args: &DemoArgs) -> Result<(), String> {
    if args.channels == 0 || args.samples == 0 {
        return Err("--channels and --samples must be at least 1".into());
    }
    let (n, s) = (args.channels, args.samples);
    let exact: Vec<Quat<f64>> = (0..n)
        .map(|i| {
            let w = channel_rate(i);
            let angle = w.norm() * DT * s as f64;
            Quat::from_axis_angle(w.try_normalize().0, angle)
        })
        .collect();
    println!(
        "rootfuse demo: {n} gyro channels x {s} samples at {:.0} Hz, exponential-map integration",
        1.0 / DT
    );
    println!();
    println!("| mode        | max error (deg) | channel-updates/s |");
    println!("|-------------|-----------------|-------------------|");

    let t = Instant::now();
    let mut worst = 0.0f64;
    for (i, q_exact) in exact.iter().enumerate() {
        let q = integrate(channel_rate(i), DT, s);
        worst = worst.max(q.angle_to(*q_exact));
    }
    report("scalar f64", worst, n * s, t.elapsed().as_secs_f64());

    let t = Instant::now();
    let mut worst = 0.0f64;
    for (i, q_exact) in exact.iter().enumerate() {
        let w = channel_rate(i);
        let q = integrate(Vec3::new(w.x as f32, w.y as f32, w.z as f32), DT as f32, s);
        worst = worst.max(to_f64(q).angle_to(*q_exact));
    }
    report("scalar f32", worst, n * s, t.elapsed().as_secs_f64());

    type V = rootfuse_lane::wide::f32x8;
    let t = Instant::now();
    let mut worst = 0.0f64;
    for chunk in 0..n.div_ceil(8) {
        let idx = |lane: usize| (chunk * 8 + lane).min(n - 1);
        let rate = Vec3::<V>::from_lanes(|lane| {
            let w = channel_rate(idx(lane));
            Vec3::new(w.x as f32, w.y as f32, w.z as f32)
        });
        let q = integrate(rate, V::splat(DT as f32), s);
        for lane in 0..8 {
            worst = worst.max(to_f64(q.lane(lane)).angle_to(exact[idx(lane)]));
        }
    }
    report(
        "lanes f32x8",
        worst,
        n.div_ceil(8) * 8 * s,
        t.elapsed().as_secs_f64(),
    );
    println!();
    println!("Errors are against the closed-form rotation; lanes equal scalar f32 bit for bit.");
    Ok(())
}

fn to_f64(q: Quat<f32>) -> Quat<f64> {
    Quat::new(q.w as f64, q.x as f64, q.y as f64, q.z as f64)
}

fn report(mode: &str, worst_rad: f64, updates: usize, seconds: f64) {
    println!(
        "| {mode:<11} | {:>15.3e} | {:>17.3e} |",
        worst_rad.to_degrees(),
        updates as f64 / seconds
    );
}
