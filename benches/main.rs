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
                rootfuse::eval::sim::scenario(name, seed, 10.0, 200.0)
            })
        });
    }
    group.finish();
}

/// The batch engine's unit of work: one chunk of channels (one scalar channel, one
/// `f32x8`/`f64x4` of channels, or two interleaved, `X2<f32x8>`) over 64 samples, for Mahony
/// 6D and the EKF 9D, on the concrete filter type; throughput is in channel-updates, so the
/// lane modes compare directly with the scalar ones.
fn batch_filters(c: &mut Criterion) {
    use rootfuse::attitude::ImuSample;
    use rootfuse::attitude::registry::{FilterSpec, FilterVisitor, RegisteredFilter};
    const STEPS: usize = 64;
    fn data<T: Lane>() -> Vec<(ImuSample<T>, T)> {
        // A slow turn about a tilted axis; gravity and field rotated accordingly.
        let w = Vec3::new(0.2, -0.1, 0.3);
        let mut q = Quat::<f64>::from_euler_zyx(0.5, 0.2, -0.1);
        (0..STEPS)
            .map(|_| {
                q = (q * Quat::from_rotation_vector(w * 0.01)).normalize();
                let acc = q.rotate_inverse(Vec3::new(0.0, 0.0, 9.81));
                let mag = q.rotate_inverse(Vec3::new(0.0, 0.44, -0.9));
                let c = |v: Vec3<f64>| Vec3::<T>::from_f64([v.x, v.y, v.z]);
                (ImuSample::new(c(w), c(acc), c(mag)), T::from_f64(0.01))
            })
            .collect()
    }
    type Group<'a> = criterion::BenchmarkGroup<'a, criterion::measurement::WallTime>;
    struct Bench<'a, 'b> {
        group: &'a mut Group<'b>,
        mode: &'a str,
    }
    impl<T: Lane> FilterVisitor<T> for Bench<'_, '_> {
        type Output = ();
        fn visit<F: RegisteredFilter<T>>(self, spec: &FilterSpec) {
            let input = data::<T>();
            self.group
                .throughput(Throughput::Elements((STEPS * T::LANES) as u64));
            let Some(mut f) = F::from_spec(spec) else {
                return;
            };
            self.group.bench_function(self.mode, |b| {
                b.iter(|| {
                    for (s, dt) in black_box(&input) {
                        f.update(s, *dt);
                    }
                    black_box(f.quat())
                })
            });
        }
    }
    fn bench<T: Lane>(group: &mut Group<'_>, mode: &str, spec: &FilterSpec) {
        spec.visit::<T, _>(Bench { group, mode });
    }
    for (name, dof) in [("mahony", 6u8), ("ekf", 9)] {
        let mut spec = FilterSpec::new(name).unwrap();
        spec.set_dof(rootfuse::attitude::Dof::from_count(dof).expect("6 or 9"))
            .unwrap();
        let mut group = c.benchmark_group(format!("batch/{name}_{dof}d"));
        bench::<f32>(&mut group, "scalar-f32", &spec);
        bench::<f64>(&mut group, "scalar-f64", &spec);
        bench::<wide::f32x8>(&mut group, "lanes-f32x8", &spec);
        bench::<wide::f64x4>(&mut group, "lanes-f64x4", &spec);
        bench::<rootfuse_lane::X2<wide::f32x8>>(&mut group, "lanes-x2-f32x8", &spec);
        group.finish();
    }
}

/// Time per RLS update for every form, n = 3, 4, 7, 8, 16, 64, in f32, f64 and f32x8 lanes
/// (throughput per channel: an `f32x8` update counts 8). White regressors, λ = 0.999, no
/// bounds; the ratios to `conventional` within one group are the comparison.
fn rls_forms(c: &mut Criterion) {
    use rootfuse::lane::{Mat, Vector};
    use rootfuse::lsq::rls::{
        BiermanUd, Conventional, InformationQr, InverseQr, Joseph, Potter, RecursiveLeastSquares,
        RlsConfig,
    };
    const SAMPLES: usize = 64;
    fn bench<T: Lane, F: RecursiveLeastSquares<T, N>, const N: usize>(
        group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
        precision: &str,
        config: RlsConfig,
        label: &str,
    ) {
        // A fixed pseudo-random stream (xorshift), the same for every form.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut uniform = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let input: Vec<(Vector<T, N>, T)> = (0..SAMPLES)
            .map(|_| {
                let h = Vector::<T, N>::from_fn(|_, _| T::from_f64(uniform()));
                let z = T::from_f64(uniform());
                (h, z)
            })
            .collect();
        let x0 = Vector::<T, N>::zeros();
        let p0 = Mat::<T, N, N>::identity().scale(T::from_f64(10.0));
        let mut f = F::new(&x0, &p0, config).unwrap();
        group.throughput(Throughput::Elements((SAMPLES * T::LANES) as u64));
        group.bench_function(format!("{}{label}/{precision}", F::NAME), |b| {
            b.iter(|| {
                for (h, z) in black_box(&input) {
                    f.update(h, *z, T::one());
                }
            })
        });
        black_box(f.estimate());
    }
    macro_rules! sizes {
        ($($n:literal)*) => {$({
            let mut group = c.benchmark_group(format!("rls/n{}", $n));
            group
                .sample_size(10)
                .warm_up_time(std::time::Duration::from_millis(300))
                .measurement_time(std::time::Duration::from_secs(1));
            macro_rules! forms {
                ($t:ty, $p:literal) => {
                    let c = RlsConfig::new(0.999);
                    bench::<$t, Conventional<$t, $n>, $n>(&mut group, $p, c, "");
                    bench::<$t, Joseph<$t, $n>, $n>(&mut group, $p, c, "");
                    bench::<$t, Potter<$t, $n>, $n>(&mut group, $p, c, "");
                    bench::<$t, BiermanUd<$t, $n>, $n>(&mut group, $p, c, "");
                    bench::<$t, InverseQr<$t, $n>, $n>(&mut group, $p, c, "");
                    bench::<$t, InformationQr<$t, $n>, $n>(&mut group, $p, c, "");
                    let plain = c.without_compensation();
                    bench::<$t, InformationQr<$t, $n>, $n>(&mut group, $p, plain, "-plain");
                };
            }
            forms!(f32, "f32");
            forms!(f64, "f64");
            forms!(wide::f32x8, "f32x8");
            group.finish();
        })*};
    }
    sizes!(3 4 7 8 16 64);
}

/// The flagship (`SqrtEskf`, 9D, defaults) per channel-update in every precision and lane
/// width, beside VQF (the `vqf-rs` port, f64) on the same recording: BROAD trial 02 when the
/// data is there (`$ROOTFUSE_BROAD_DIR` or `../shared/broad_csv`), else 60 s of the simulator's
/// fast rotation at 286 Hz. Each iteration runs the next 2000 samples (wrapping around) on a
/// filter that keeps running; throughput is in channel-updates, so the rows compare directly.
fn flagship(c: &mut Criterion) {
    use rootfuse::attitude::filters::{SqrtEskf, SqrtEskfParams};
    use rootfuse::attitude::{ImuSample, OrientationFilter};
    const STEPS: usize = 2000;
    let dir = std::env::var_os("ROOTFUSE_BROAD_DIR")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::path::PathBuf::from("../shared/broad_csv"));
    let rec = rootfuse::io::read_csv(dir.join("02_undisturbed_slow_rotation_B.csv"))
        .map(|r| (r, "BROAD 02"))
        .unwrap_or_else(|_| {
            let r = rootfuse::eval::sim::scenario("fast-rotation", 1, 60.0, 286.0)
                .expect("a known scenario");
            (r, "simulated fast rotation")
        });
    let (rec, source) = rec;
    eprintln!("flagship group: {source}, {} samples", rec.len());
    let raw: Vec<(ImuSample<f64>, f64)> =
        (0..rec.len()).map(|i| (rec.sample(i), rec.dt(i))).collect();
    let mut group = c.benchmark_group("flagship/9d");
    fn ours<T: Lane>(group: &mut Group<'_>, mode: &str, raw: &[(ImuSample<f64>, f64)]) {
        let c = |v: Vec3<f64>| Vec3::<T>::from_f64([v.x, v.y, v.z]);
        let input: Vec<(ImuSample<T>, T)> = raw
            .iter()
            .map(|(s, dt)| {
                (
                    ImuSample::new(c(s.gyr), c(s.acc), c(s.mag)),
                    T::from_f64(*dt),
                )
            })
            .collect();
        let mut f = SqrtEskf::<T>::new(&SqrtEskfParams::default());
        let mut at = 0;
        group.throughput(Throughput::Elements((STEPS * T::LANES) as u64));
        group.bench_function(mode, |b| {
            b.iter(|| {
                for _ in 0..STEPS {
                    let (s, dt) = &input[at];
                    f.update(black_box(s), *dt);
                    at = (at + 1) % input.len();
                }
                black_box(f.quat())
            })
        });
    }
    type Group<'a> = criterion::BenchmarkGroup<'a, criterion::measurement::WallTime>;
    ours::<f32>(&mut group, "ours-scalar-f32", &raw);
    ours::<f64>(&mut group, "ours-scalar-f64", &raw);
    ours::<wide::f32x8>(&mut group, "ours-lanes-f32x8", &raw);
    ours::<wide::f64x4>(&mut group, "ours-lanes-f64x4", &raw);
    group.throughput(Throughput::Elements(STEPS as u64));
    let ts = raw.get(1).map_or(0.0035, |r| r.1);
    let mut vqf = vqf_rs::VQF::new(ts, None, None, None);
    let mut at = 0;
    group.bench_function("vqf-rs-f64", |b| {
        b.iter(|| {
            for _ in 0..STEPS {
                let (s, _) = &raw[at];
                let a = |v: Vec3<f64>| [v.x, v.y, v.z];
                vqf.update(a(black_box(s).gyr), a(s.acc), Some(a(s.mag)));
                at = (at + 1) % raw.len();
            }
            black_box(vqf.quat_9d())
        })
    });
    group.finish();
}

criterion_group!(
    benches,
    gyro_step,
    simulator,
    batch_filters,
    rls_forms,
    flagship
);
criterion_main!(benches);
