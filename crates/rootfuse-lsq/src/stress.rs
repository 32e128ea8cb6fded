//! Numerical stress scenarios for the recursive forms (the runners behind `rootfuse stress`).
//!
//! Every scenario runs every form of [`rls`](crate::rls) in f32 and f64 and compares its
//! estimate with a reference: the same forgetting-factor least-squares problem solved by
//! Givens QR in double-double arithmetic (about 106 bits, an implementation independent of
//! the forms), on the same data, without covariance bounds. So the f64 rows measure accuracy,
//! not agreement between two f64 algorithms. Each form is run twice: once alone, timed (`ns_per_update`), recording
//! its estimate and health at checkpoints; then the reference replays the data and the
//! checkpoints are compared.
//!
//! Scenario names (the `scenario` field) and what they run:
//! - `dyer-mcreynolds`: `P₀ = I₃`, rows `[1,1,1]` and `[1,1,1+δ]`, noise variance `δ²`,
//!   `δ = 10⁻² … 10⁻⁸` (`param` = δ), λ = 1.
//! - `benign`: n = 8, λ = 1 − 10⁻³ with white regressors, and λ = 1 − 10⁻⁴ with AR(1)
//!   regressors (coefficient 0.9) (`param` = λ), 10⁶ steps (10⁷ with `long`).
//! - `non-persistent`: n = 8, λ = 0.999, only a rank-2 subspace excited for 4·10⁵ steps, then
//!   full excitation for 10⁵ steps, bounds `[10⁻⁶, 10³]` on; `max_rel_err` is taken at the
//!   last step (after recovery).
//! - `windup`: n = 8, λ = 0.999, 6 of 8 regressors exactly zero for 4·10⁵ steps, then full
//!   excitation for 10⁵ steps; `param` = 1 with bounds `[10⁻⁶, 10³]`, 0 without.
//!   `max_rel_err` at the last step.
//! - `lambda-one`: n = 8, λ = 1, white regressors, 10⁶ steps (10⁷ with `long`).
//! - `hilbert`: monomial regressors `[1, t, …, t^{n−1}]`, `t` uniform in `[0, 1]`,
//!   n = 4, 6, 8 (`param` = n), λ = 1, 10⁴ steps.
//!
//! Row fields: `pd_lost_at` is the first checkpoint step where the form's own health showed a
//! non-positive or non-finite pivot or flagged lost definiteness; `nan_at` the first
//! checkpoint with a non-finite estimate; `detected` whether the form reported a failure
//! itself (lost definiteness, or updates refused as numerically unusable).

use crate::rls::{
    BiermanUd, Conventional, InformationQr, InverseQr, Joseph, Potter, RecursiveLeastSquares,
    RlsConfig,
};
use rootfuse_lane::{Lane, Mat, Vector};
mod reference;
use reference::DdInformationQr;
use std::time::Instant;
use std::vec::Vec;

/// Every scenario name, in the order [`run_all`] runs them.
pub const SCENARIOS: [&str; 6] = [
    "dyer-mcreynolds",
    "benign",
    "non-persistent",
    "windup",
    "lambda-one",
    "hilbert",
];

/// One result row: one form, one precision, one scenario and parameter.
#[derive(Clone, Debug, PartialEq)]
pub struct StressRow {
    /// Form name (`RecursiveLeastSquares::NAME`).
    pub form: &'static str,
    /// `"f32"` or `"f64"`.
    pub precision: &'static str,
    /// Scenario name (one of [`SCENARIOS`]).
    pub scenario: &'static str,
    /// Scenario parameter (δ, λ, n or a 0/1 switch; see the module documentation).
    pub param: Option<f64>,
    /// Updates run.
    pub steps: u64,
    /// Largest `‖x − x_ref‖ / ‖x_ref‖` over the checkpoints (or at the last step, see above).
    pub max_rel_err: f64,
    /// First checkpoint step where the form's health showed lost definiteness.
    pub pd_lost_at: Option<u64>,
    /// First checkpoint step with a non-finite estimate.
    pub nan_at: Option<u64>,
    /// Whether the form reported a failure itself.
    pub detected: bool,
    /// Wall time per update of the form alone, nanoseconds.
    pub ns_per_update: f64,
    /// `(step, ‖x − x_ref‖ / ‖x_ref‖)` at every checkpoint (infinite where the estimate was
    /// not finite): the error over the run, for plots.
    pub trace: Vec<(u64, f64)>,
}

/// Run-length options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StressOptions {
    /// Ten times longer `benign` and `lambda-one` runs.
    pub long: bool,
    /// Multiplies every step count (`1.0` = the documented lengths; smaller for quick checks).
    pub scale: f64,
}

impl Default for StressOptions {
    fn default() -> Self {
        Self {
            long: false,
            scale: 1.0,
        }
    }
}

/// Runs one scenario by name; `None` for an unknown name.
pub fn run_scenario(name: &str, options: StressOptions) -> Option<Vec<StressRow>> {
    let mut rows = Vec::new();
    let scaled = |n: f64| ((n * options.scale).round() as u64).max(1);
    let long = if options.long { 10.0 } else { 1.0 };
    match name {
        "dyer-mcreynolds" => {
            for e in 2..=8 {
                let delta = 10f64.powi(-e);
                let s = Scenario {
                    name: "dyer-mcreynolds",
                    param: Some(delta),
                    steps: 2,
                    config: RlsConfig::new(1.0),
                    p0: 1.0,
                    final_only: false,
                    checkpoints: 2,
                };
                all_forms::<3, _>(&s, &mut rows, || {
                    move |k, x: &[f64; 3]| {
                        let h = [1.0, 1.0, if k == 0 { 1.0 } else { 1.0 + delta }];
                        (h, dot(&h, x), 1.0 / (delta * delta))
                    }
                });
            }
        }
        "benign" => {
            for (lambda, ar) in [(0.999, false), (0.9999, true)] {
                let s = Scenario {
                    name: "benign",
                    param: Some(lambda),
                    steps: scaled(1e6 * long),
                    config: RlsConfig::new(lambda),
                    p0: 100.0,
                    final_only: false,
                    checkpoints: 100,
                };
                let coef = if ar { 0.9 } else { 0.0 };
                all_forms::<8, _>(&s, &mut rows, || ar_regressors(coef, 1));
            }
        }
        "non-persistent" | "windup" => {
            let windup = name == "windup";
            let switches: &[bool] = if windup { &[true, false] } else { &[true] };
            for &bounded in switches {
                let mut config = RlsConfig::new(0.999);
                if bounded {
                    config = config.with_bounds(1e-6, 1e3);
                }
                let quiet = scaled(4e5);
                let s = Scenario {
                    name: if windup { "windup" } else { "non-persistent" },
                    param: windup.then_some(if bounded { 1.0 } else { 0.0 }),
                    steps: quiet + scaled(1e5),
                    config,
                    p0: 1.0,
                    final_only: true,
                    checkpoints: 100,
                };
                all_forms::<8, _>(&s, &mut rows, || {
                    let mut full = ar_regressors(0.0, 2);
                    let mut rng = Rng(3);
                    move |k, x: &[f64; 8]| {
                        let (mut h, _, w) = full(k, x);
                        if k < quiet {
                            if windup {
                                h[2..].fill(0.0);
                            } else {
                                let (a, b) = (rng.uniform(), rng.uniform());
                                h = core::array::from_fn(|j| {
                                    a * (j as f64 + 1.0) - b * (j % 3) as f64
                                });
                            }
                        }
                        let z = dot(&h, x) + 1e-3 * rng.uniform();
                        (h, z, w)
                    }
                });
            }
        }
        "lambda-one" => {
            let s = Scenario {
                name: "lambda-one",
                param: None,
                steps: scaled(1e6 * long),
                config: RlsConfig::new(1.0),
                p0: 100.0,
                final_only: false,
                checkpoints: 100,
            };
            all_forms::<8, _>(&s, &mut rows, || ar_regressors(0.0, 4));
        }
        "hilbert" => {
            hilbert::<4>(scaled(1e4), &mut rows);
            hilbert::<6>(scaled(1e4), &mut rows);
            hilbert::<8>(scaled(1e4), &mut rows);
        }
        _ => return None,
    }
    Some(rows)
}

/// Runs every scenario.
pub fn run_all(options: StressOptions) -> Vec<StressRow> {
    SCENARIOS
        .iter()
        .flat_map(|name| run_scenario(name, options).unwrap_or_default())
        .collect()
}

fn hilbert<const N: usize>(steps: u64, rows: &mut Vec<StressRow>) {
    let s = Scenario {
        name: "hilbert",
        param: Some(N as f64),
        steps,
        config: RlsConfig::new(1.0),
        p0: 1e4,
        final_only: false,
        checkpoints: 100,
    };
    all_forms::<N, _>(&s, rows, || {
        let mut rng = Rng(5);
        move |_, x: &[f64; N]| {
            let t = 0.5 * (rng.uniform() + 1.0);
            let mut h = [1.0; N];
            for j in 1..N {
                h[j] = h[j - 1] * t;
            }
            (h, dot(&h, x) + 1e-4 * rng.uniform(), 1.0)
        }
    });
}

/// One scenario's fixed settings.
struct Scenario {
    name: &'static str,
    param: Option<f64>,
    steps: u64,
    config: RlsConfig,
    /// `P₀ = p0·I`, `x₀ = 0`.
    p0: f64,
    /// Compare only the last step (scenarios whose middle is deliberately unidentifiable).
    final_only: bool,
    checkpoints: u64,
}

/// Regressors: AR(1) with coefficient `coef` per component (0 = white, uniform in [−1, 1]),
/// weight 1, `z = hᵀx + noise`.
fn ar_regressors<const N: usize>(
    coef: f64,
    seed: u64,
) -> impl FnMut(u64, &[f64; N]) -> ([f64; N], f64, f64) {
    let mut rng = Rng(seed);
    let mut h = [0.0; N];
    let innovation = (1.0 - coef * coef).sqrt();
    move |_, x| {
        for v in h.iter_mut() {
            *v = coef * *v + innovation * rng.uniform();
        }
        (h, dot(&h, x) + 1e-3 * rng.uniform(), 1.0)
    }
}

fn dot<const N: usize>(a: &[f64; N], b: &[f64; N]) -> f64 {
    a.iter().zip(b).map(|(p, q)| p * q).sum()
}

/// SplitMix64: reproducible data without a dependency.
struct Rng(u64);
impl Rng {
    /// Uniform in `[-1, 1)`.
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// One sample: regressor, measurement, weight.
type Sample<const N: usize> = ([f64; N], f64, f64);

/// Runs every form in f32 and f64. `make` builds a fresh generator of the scenario's samples,
/// so every form (and the reference) sees the same sequence without storing it whole.
fn all_forms<const N: usize, G>(s: &Scenario, rows: &mut Vec<StressRow>, make: impl Fn() -> G)
where
    G: FnMut(u64, &[f64; N]) -> Sample<N>,
{
    let every = (s.steps / s.checkpoints).max(1);
    let at: Vec<u64> = (1..=s.steps)
        .filter(|k| k % every == 0 || *k == s.steps)
        .collect();
    let reference = reference_run::<N, G>(s, make(), &at);
    macro_rules! forms {
        ($t:ty, $p:literal) => {
            rows.push(one_form::<$t, Conventional<$t, N>, N, G>(
                s,
                $p,
                make(),
                &at,
                &reference,
            ));
            rows.push(one_form::<$t, Joseph<$t, N>, N, G>(
                s,
                $p,
                make(),
                &at,
                &reference,
            ));
            rows.push(one_form::<$t, Potter<$t, N>, N, G>(
                s,
                $p,
                make(),
                &at,
                &reference,
            ));
            rows.push(one_form::<$t, BiermanUd<$t, N>, N, G>(
                s,
                $p,
                make(),
                &at,
                &reference,
            ));
            rows.push(one_form::<$t, InverseQr<$t, N>, N, G>(
                s,
                $p,
                make(),
                &at,
                &reference,
            ));
            rows.push(one_form::<$t, InformationQr<$t, N>, N, G>(
                s,
                $p,
                make(),
                &at,
                &reference,
            ));
        };
    }
    forms!(f32, "f32");
    forms!(f64, "f64");
}

/// The true parameters every scenario measures.
fn x_true<const N: usize>() -> [f64; N] {
    core::array::from_fn(|j| 1.0 + j as f64 * 0.5)
}

fn prior<T: Lane, const N: usize>(s: &Scenario) -> (Vector<T, N>, Mat<T, N, N>) {
    (Vector::zeros(), Mat::identity().scale(T::from_f64(s.p0)))
}

/// The double-double reference estimates at the checkpoints (bounds removed).
fn reference_run<const N: usize, G>(s: &Scenario, mut samples: G, at: &[u64]) -> Vec<[f64; N]>
where
    G: FnMut(u64, &[f64; N]) -> Sample<N>,
{
    let mut f = DdInformationQr::<N>::new(s.p0, s.config.lambda);
    let x_true = x_true::<N>();
    let mut out = Vec::with_capacity(at.len());
    let mut start = 0;
    for &stop in at {
        for k in start..stop {
            let (h, z, w) = samples(k, &x_true);
            f.update(&h, z, w);
        }
        start = stop;
        out.push(f.estimate());
    }
    out
}

fn one_form<T, F, const N: usize, G>(
    s: &Scenario,
    precision: &'static str,
    mut samples: G,
    at: &[u64],
    reference: &[[f64; N]],
) -> StressRow
where
    T: Lane<Scalar = T, Mask = bool> + Into<f64>,
    F: RecursiveLeastSquares<T, N>,
    G: FnMut(u64, &[f64; N]) -> Sample<N>,
{
    let mut row = StressRow {
        form: F::NAME,
        precision,
        scenario: s.name,
        param: s.param,
        steps: s.steps,
        max_rel_err: f64::NAN,
        pd_lost_at: None,
        nan_at: None,
        detected: false,
        ns_per_update: f64::NAN,
        trace: Vec::with_capacity(at.len()),
    };
    let (x0, p0) = prior::<T, N>(s);
    let Ok(mut f) = F::new(&x0, &p0, s.config) else {
        row.detected = true;
        return row;
    };
    let x_true = x_true::<N>();
    let mut chunk: Vec<(Vector<T, N>, T, T)> = Vec::new();
    let mut snapshots: Vec<([f64; N], bool)> = Vec::with_capacity(at.len());
    let mut elapsed = 0.0;
    let mut start = 0;
    for &stop in at {
        // Generate and convert outside the timed loop.
        chunk.clear();
        chunk.extend((start..stop).map(|k| {
            let (h, z, w) = samples(k, &x_true);
            (
                Vector::from_fn(|i, _| T::from_f64(h[i])),
                T::from_f64(z),
                T::from_f64(w),
            )
        }));
        start = stop;
        let t0 = Instant::now();
        for (h, z, w) in &chunk {
            f.update(h, *z, *w);
        }
        elapsed += t0.elapsed().as_secs_f64();
        let x = f.estimate();
        let health = f.health();
        let lo: f64 = health.min_pivot.into();
        let hi: f64 = health.max_pivot.into();
        let pd = lo > 0.0 && hi.is_finite() && !health.lost_definiteness;
        snapshots.push((core::array::from_fn(|j| x[j].into()), pd));
    }
    row.ns_per_update = elapsed * 1e9 / s.steps as f64;
    let health = f.health();
    row.detected = health.lost_definiteness || health.rejected_numerical.as_ref()[0] > 0;
    let mut worst = 0.0f64;
    for ((&k, (x, pd)), x_ref) in at.iter().zip(&snapshots).zip(reference) {
        if !pd && row.pd_lost_at.is_none() {
            row.pd_lost_at = Some(k);
        }
        if x.iter().any(|v| !v.is_finite()) {
            row.nan_at.get_or_insert(k);
            worst = f64::INFINITY;
            row.trace.push((k, f64::INFINITY));
            continue;
        }
        let num: f64 = x.iter().zip(x_ref).map(|(a, b)| (a - b) * (a - b)).sum();
        let den: f64 = x_ref.iter().map(|b| b * b).sum();
        let err = (num / den).sqrt();
        row.trace.push((k, err));
        worst = worst.max(err);
    }
    // Scenarios that measure recovery judge the last step only (the trace keeps the rest).
    row.max_rel_err = match row.trace.last() {
        Some(&(_, last)) if s.final_only => last,
        _ => worst,
    };
    row
}
