//! The single-channel filter loop a Rust user writes, timed: the reference that
//! `benches/python/bench_peers.py` compares `rootfuse.Filter.update_batch` with (same file,
//! same filter and precision, same outputs collected: orientation, bias, flags and, where the
//! filter has one, the attitude covariance per sample).
//!
//! `cargo run --release --example filter_loop -- FILE.csv FILTER DOF PRECISION REPEATS`
//! prints `{"ns_per_sample": best of REPEATS, "checksum": ...}` as one JSON line.

use rootfuse::attitude::registry::FilterSpec;
use rootfuse::attitude::{Dof, ImuSample, Lane, OrientationFilter, Vec3};
use std::time::Instant;

/// Runs the whole recording once and returns a checksum of the collected outputs.
fn run<T: Lane>(spec: &FilterSpec, rec: &rootfuse::io::Recording) -> f64 {
    let mut f = spec.build::<T>();
    let n = rec.len();
    let (mut quat, mut bias, mut flags) = (
        Vec::with_capacity(4 * n),
        Vec::with_capacity(3 * n),
        Vec::with_capacity(n),
    );
    let mut cov = Vec::with_capacity(9 * n);
    let w = |x: T| -> f64 { x.extract(0).into() };
    for i in 0..n {
        let s = rec.sample(i);
        let c = |v: Vec3<f64>| Vec3::<T>::from_f64([v.x, v.y, v.z]);
        f.update(
            &ImuSample::new(c(s.gyr), c(s.acc), c(s.mag)),
            T::from_f64(rec.dt(i)),
        );
        flags.push(f.flags().bits(0));
        let q = f.quat();
        quat.extend_from_slice(&[w(q.w), w(q.x), w(q.y), w(q.z)]);
        let b = f.bias();
        bias.extend_from_slice(&[w(b.x), w(b.y), w(b.z)]);
        if let Some(p) = f.attitude_covariance() {
            cov.extend(p.m.iter().flatten().map(|&x| w(x)));
        }
    }
    quat.iter().sum::<f64>()
        + cov.iter().sum::<f64>()
        + bias.iter().sum::<f64>()
        + flags.iter().map(|&x| f64::from(x)).sum::<f64>()
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [file, filter, dof, precision, repeats] = args.as_slice() else {
        return Err("usage: filter_loop FILE.csv FILTER DOF PRECISION REPEATS".into());
    };
    let rec = rootfuse::io::read_csv(file).map_err(|e| e.to_string())?;
    let mut spec = FilterSpec::new(filter).map_err(|e| e.to_string())?;
    let dof = dof
        .parse()
        .ok()
        .and_then(Dof::from_count)
        .ok_or("DOF: 6 or 9")?;
    spec.set_dof(dof).map_err(|e| e.to_string())?;
    let repeats: usize = repeats.parse().map_err(|_| "REPEATS: a whole number")?;
    let mut best = f64::INFINITY;
    let mut checksum = 0.0;
    for _ in 0..repeats.max(1) {
        let start = Instant::now();
        checksum = match precision.as_str() {
            "f32" => run::<f32>(&spec, &rec),
            "f64" => run::<f64>(&spec, &rec),
            _ => return Err("PRECISION: f32 or f64".into()),
        };
        best = best.min(start.elapsed().as_secs_f64());
    }
    println!(
        "{{\"ns_per_sample\": {}, \"checksum\": {checksum}}}",
        best * 1e9 / rec.len().max(1) as f64
    );
    Ok(())
}
