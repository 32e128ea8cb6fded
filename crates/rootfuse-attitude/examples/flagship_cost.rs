//! Cost per update of the flagship ([`SqrtEskf`], 9D, default parameters) in one precision
//! or lane width: for timing whole processes side by side and for
//! `valgrind --tool=callgrind` instruction counts (docs/flagship_cost.md).
//!
//! ```sh
//! cargo build --release -p rootfuse-attitude --example flagship_cost
//! target/release/examples/flagship_cost MODE [SAMPLES] [PASSES] [JITTER] [FILTER] [DOF] [RATE]
//! ```
//! FILTER is `sqrt-eskf` (the default), `mahony`, `madgwick` or `complementary`, each with its
//! default parameters; DOF is 9 (the default) or 6; RATE the sample rate in Hz (default 286, like
//! BROAD; `rootfuse throughput` runs 100 Hz with 10 % jitter).
//! MODE is `f32`, `f64`, `f32x8`, `f64x4` or `none` (only the input is made). The input is synthetic (at RATE):
//! rests of 4 s between 10 s of rotation about a wandering axis, gravity and a dipping field
//! rotated into the sensor frame, plus a little deterministic noise; every lane runs the same
//! data. It is built before the clock starts, so only `update` is timed. Prints one JSON line:
//! the best ns per channel-update over PASSES passes and a checksum of the final orientation.
//! JITTER (default 0) is the relative spread of the time step: each sample's `dt`, in each lane
//! on its own, is `(1 + JITTER·u)/RATE` with `u` uniform in [−1, 1], as a fleet of real
//! recordings with jittered time stamps gives (a constant `dt` is the cheap case).

use rootfuse_attitude::filters::{
    Complementary, ComplementaryParams, Madgwick, MadgwickParams, Mahony, MahonyParams, SqrtEskf,
    SqrtEskfParams,
};
use rootfuse_attitude::{Dof, ImuSample, Lane, OrientationFilter, Quat, Vec3};
use rootfuse_lane::wide;
use std::time::Instant;

/// A deterministic uniform stream in [−1, 1) (xorshift64 from `seed`).
fn xorshift(mut state: u64) -> impl FnMut() -> f64 {
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0
    }
}

/// `n` samples (sensor frame, SI units) of the motion described in the module docs.
fn motion(n: usize, rate_hz: f64) -> Vec<ImuSample<f64>> {
    let dt = 1.0 / rate_hz;
    let mut uniform = xorshift(0x2545_f491_4f6c_dd1d);
    let mut noise = move |scale: f64| uniform() * scale;
    let mut q = Quat::<f64>::from_euler_zyx(0.3, 0.1, -0.2);
    (0..n)
        .map(|i| {
            let t = i as f64 * dt;
            let moving = t % 14.0 >= 4.0;
            let w = if moving {
                Vec3::new((0.7 * t).sin(), (0.5 * t).cos(), 0.6 * (0.3 * t).sin()) * 1.5
            } else {
                Vec3::zero()
            };
            q = (q * Quat::from_rotation_vector(w * dt)).normalize();
            let acc = q.rotate_inverse(Vec3::new(0.0, 0.0, 9.81));
            let mag = q.rotate_inverse(Vec3::new(0.0, 20.0, -40.0));
            let mut n3 = |s: f64| Vec3::new(noise(s), noise(s), noise(s));
            let bias = Vec3::new(0.01, -0.005, 0.002);
            ImuSample::new(w + bias + n3(0.002), acc + n3(0.05), mag + n3(0.3))
        })
        .collect()
}

fn run<T: Lane>(
    data: &[ImuSample<f64>],
    passes: usize,
    jitter_rate: (f64, f64),
    filter: &str,
    dof: Dof,
) -> (f64, f64) {
    match filter {
        "mahony" => run_filter(data, passes, jitter_rate, || {
            Mahony::<T>::new(&MahonyParams {
                dof,
                ..Default::default()
            })
        }),
        "madgwick" => run_filter(data, passes, jitter_rate, || {
            Madgwick::<T>::new(&MadgwickParams {
                dof,
                ..Default::default()
            })
        }),
        "complementary" => run_filter(data, passes, jitter_rate, || {
            Complementary::<T>::new(&ComplementaryParams {
                dof,
                ..Default::default()
            })
        }),
        _ => run_filter(data, passes, jitter_rate, || {
            SqrtEskf::<T>::new(&SqrtEskfParams {
                dof,
                ..Default::default()
            })
        }),
    }
}

fn run_filter<T: Lane, F: OrientationFilter<T>>(
    data: &[ImuSample<f64>],
    passes: usize,
    (jitter, rate_hz): (f64, f64),
    make: impl Fn() -> F,
) -> (f64, f64) {
    let c = |v: Vec3<f64>| Vec3::<T>::from_f64([v.x, v.y, v.z]);
    let mut uniform = xorshift(0x9e37_79b9_7f4a_7c15);
    let input: Vec<(ImuSample<T>, T)> = data
        .iter()
        .map(|s| {
            let dt =
                T::from_fn(|_| <T::Scalar as Lane>::from_f64((1.0 + jitter * uniform()) / rate_hz));
            (ImuSample::new(c(s.gyr), c(s.acc), c(s.mag)), dt)
        })
        .collect();
    let mut best = f64::INFINITY;
    let mut checksum = 0.0;
    for _ in 0..passes.max(1) {
        let mut f = make();
        let start = Instant::now();
        for (s, dt) in std::hint::black_box(&input) {
            f.update(s, *dt);
        }
        best = best.min(start.elapsed().as_secs_f64());
        let q = f.quat();
        checksum = (0..T::LANES)
            .map(|l| {
                [q.w, q.x, q.y, q.z]
                    .iter()
                    .map(|x| x.extract(l).into())
                    .sum::<f64>()
            })
            .sum();
    }
    (
        best * 1e9 / (input.len() * T::LANES).max(1) as f64,
        checksum,
    )
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: flagship_cost MODE [SAMPLES] [PASSES] [JITTER] [FILTER] [DOF] [RATE]";
    let mode = args.first().ok_or(usage)?;
    let number = |i: usize, default: usize| -> Result<usize, String> {
        args.get(i)
            .map_or(Ok(default), |a| a.parse().map_err(|_| usage.to_string()))
    };
    let (samples, passes) = (number(1, 100_000)?, number(2, 3)?);
    let real = |i: usize, default: f64| -> Result<f64, String> {
        args.get(i)
            .map_or(Ok(default), |a| a.parse().map_err(|_| usage.to_string()))
    };
    let (jitter, rate_hz) = (real(3, 0.0)?, real(6, 286.0)?);
    let filter = args.get(4).map_or("sqrt-eskf", String::as_str);
    if !["sqrt-eskf", "mahony", "madgwick", "complementary"].contains(&filter) {
        return Err(usage.into());
    }
    let dof = match args.get(5).map_or("9", String::as_str) {
        "9" => Dof::Nine,
        "6" => Dof::Six,
        _ => return Err(usage.into()),
    };
    let data = motion(samples, rate_hz);
    let (ns, checksum) = match mode.as_str() {
        "f32" => run::<f32>(&data, passes, (jitter, rate_hz), filter, dof),
        "f64" => run::<f64>(&data, passes, (jitter, rate_hz), filter, dof),
        "f32x8" => run::<wide::f32x8>(&data, passes, (jitter, rate_hz), filter, dof),
        "f64x4" => run::<wide::f64x4>(&data, passes, (jitter, rate_hz), filter, dof),
        // Only the input: the baseline subtracted from instruction counts.
        "none" => (0.0, std::hint::black_box(&data).len() as f64),
        _ => return Err(usage.into()),
    };
    println!(
        "{{\"mode\": \"{mode}\", \"samples\": {samples}, \"jitter\": {jitter}, \"ns_per_channel_update\": {ns:.2}, \"checksum\": {checksum}}}"
    );
    Ok(())
}
