//! Instruction counts per update of the recursive forms, for `valgrind --tool=callgrind`
//! (repeatable where wall time on a shared machine is not):
//!
//! ```text
//! cargo build --release -p rootfuse-lsq --features std --example rls_instructions
//! valgrind --tool=callgrind --toggle-collect='*run_updates*' \
//!     target/release/examples/rls_instructions FORM PRECISION
//! ```
//!
//! `FORM` is `conventional` or `information-qr` (`information-qr-plain` without compensation),
//! `PRECISION` `f32`, `f64` or `f32x8`; n = 8, λ = 0.999, 10⁴ updates of white regressors (uniform in
//! `[−1, 1)`, weight 1). Divide the collected instruction count by 10⁴.
use rootfuse_lane::wide::f32x8;
use rootfuse_lane::{Lane, Mat, Vector};
use rootfuse_lsq::rls::{Conventional, InformationQr, RecursiveLeastSquares, RlsConfig};

const N: usize = 8;
const UPDATES: usize = 10_000;

type Sample<T> = (Vector<T, N>, T);

fn data<T: Lane>() -> Vec<Sample<T>> {
    // Knuth's MMIX linear congruential generator, top 53 bits: uniform in [−1, 1).
    let mut state = 1u64;
    let mut uniform = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    (0..UPDATES)
        .map(|_| {
            let h: [f64; N] = core::array::from_fn(|_| uniform());
            let z: f64 = h
                .iter()
                .enumerate()
                .map(|(j, v)| v * (1.0 + j as f64))
                .sum();
            (
                Vector::from_fn(|i, _| T::from_f64(h[i])),
                T::from_f64(z + 1e-3 * uniform()),
            )
        })
        .collect()
}

#[inline(never)]
fn run_updates<T: Lane, F: RecursiveLeastSquares<T, N>>(f: &mut F, samples: &[Sample<T>]) {
    for (h, z) in samples {
        f.update(h, *z, T::one());
    }
}

fn run<T: Lane, F: RecursiveLeastSquares<T, N>>(config: RlsConfig) {
    let samples = data::<T>();
    let p0 = Mat::<T, N, N>::identity().scale(T::from_f64(100.0));
    let mut f = F::new(&Vector::zeros(), &p0, config).expect("valid prior");
    run_updates(&mut f, &samples);
    // Keep the result observable.
    std::hint::black_box(f.estimate());
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (form, precision) = match args.as_slice() {
        [_, form, precision] => (form.as_str(), precision.as_str()),
        _ => {
            eprintln!("usage: rls_instructions FORM PRECISION");
            std::process::exit(2);
        }
    };
    let config = RlsConfig::new(0.999);
    let plain = config.without_compensation();
    macro_rules! by_precision {
        ($t:ty) => {
            match form {
                "conventional" => run::<$t, Conventional<$t, N>>(config),
                "information-qr" => run::<$t, InformationQr<$t, N>>(config),
                "information-qr-plain" => run::<$t, InformationQr<$t, N>>(plain),
                _ => {
                    eprintln!("unknown form {form}");
                    std::process::exit(2);
                }
            }
        };
    }
    match precision {
        "f32" => by_precision!(f32),
        "f64" => by_precision!(f64),
        "f32x8" => by_precision!(f32x8),
        _ => {
            eprintln!("unknown precision {precision}");
            std::process::exit(2);
        }
    }
}
