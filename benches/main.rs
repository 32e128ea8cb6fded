//! The one criterion bench binary. Build with `cargo bench` (the workspace sets
//! `-C target-cpu=native`); compare modes as ratios within one run.
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rootfuse::{Lane, Quat, Vec3};
use std::hint::black_box;

/// One exponential-map gyro step with renormalisation, per channel.
fn gyro_step(c: &mut Criterion) {
    let mut group = c.benchmark_group("quat/gyro_step");
    fn step<T: Lane>(q: Quat<T>, w: Vec3<T>, dt: T) -> Quat<T> {
        (q * Quat::from_rotation_vector(w * dt)).normalize()
    }
    group.throughput(Throughput::Elements(1));
    group.bench_function("scalar-f32", |b| {
        let (mut q, w) = (Quat::<f32>::identity(), Vec3::new(0.1f32, -0.2, 0.3));
        b.iter(|| q = step(black_box(q), black_box(w), 0.005))
    });
    group.bench_function("scalar-f64", |b| {
        let (mut q, w) = (Quat::<f64>::identity(), Vec3::new(0.1f64, -0.2, 0.3));
        b.iter(|| q = step(black_box(q), black_box(w), 0.005))
    });
    group.throughput(Throughput::Elements(8));
    group.bench_function("lanes-f32x8", |b| {
        type V = wide::f32x8;
        let w = Vec3::<V>::new(V::splat(0.1), V::splat(-0.2), V::splat(0.3));
        let mut q = Quat::<V>::identity();
        b.iter(|| q = step(black_box(q), black_box(w), V::splat(0.005)))
    });
    group.throughput(Throughput::Elements(4));
    group.bench_function("lanes-f64x4", |b| {
        type V = wide::f64x4;
        let w = Vec3::<V>::new(V::splat(0.1), V::splat(-0.2), V::splat(0.3));
        let mut q = Quat::<V>::identity();
        b.iter(|| q = step(black_box(q), black_box(w), V::splat(0.005)))
    });
    group.finish();
}

/// The simulator: one channel, 10 s at 200 Hz, per preset.
fn simulator(c: &mut Criterion) {
    let mut group = c.benchmark_group("sim/10s_200Hz");
    group.sample_size(20);
    group.throughput(Throughput::Elements(2000));
    for name in ["static", "slow-rotation", "fast-rotation"] {
        group.bench_function(name, |b| {
            let mut seed = 0;
            b.iter(|| {
                seed += 1;
                rootfuse::attitude::sim::scenario(name, seed, 10.0, 200.0)
            })
        });
    }
    group.finish();
}

criterion_group!(benches, gyro_step, simulator);
criterion_main!(benches);
