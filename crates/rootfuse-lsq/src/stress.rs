//! Numerical stress scenarios for the recursive forms (the runners behind `rootfuse stress`).
//!
//! Every scenario runs every form of [`rls`](crate::rls) in f32 and f64 and compares its
//! estimate with two references, both the same forgetting-factor least-squares problem solved
//! by Givens QR in double-double arithmetic (about 106 bits, an implementation independent of
//! the forms), without covariance bounds:
//! - `max_rel_err`: on the f64 data (what the scenario means);
//! - `max_rel_err_received`: on the data the form actually received, i.e. `h`, `z`, the
//!   weight, `λ` and `P₀` rounded to the form's precision (for f64 rows the same as above).
//!   This is the error of the form itself; the difference between the two is the rounding of
//!   the input, which no form can undo. The `2⁻ᵏ` values of δ make the data exact in f32.
//!
//! The f64 rows therefore measure accuracy, not agreement between two f64 algorithms. Each
//! form is run once alone, timed (`ns_per_update`), recording its estimate and a health
//! figure at checkpoints; then the references replay the data and the checkpoints are
//! compared.
//!
//! Scenario names (the `scenario` field) and what they run:
//! - `dyer-mcreynolds` (Dyer & McReynolds 1969, as in Bierman 1977, ch. V): n = 3,
//!   `x₀ = 0`, `P₀ = I₃`, two measurements `z = hᵀx_true` (no noise) with rows `[1,1,1]` then
//!   `[1,1,1+δ]`, weight `1/δ²` (noise variance `δ²`), λ = 1; `x_true = [1, 1.5, 2]`;
//!   `δ = 10⁻² … 10⁻⁸` and `δ = 2⁻⁷, 2⁻¹⁰, 2⁻¹³, 2⁻¹⁷, 2⁻²⁰, 2⁻²³` (`param` = δ). Up to
//!   `2⁻²⁰` the f32 data are exact (`1 + δ`, `1/δ²`, `z = 4.5 + 2δ` and the whitening
//!   `√w = 2ᵏ` are representable); at `2⁻²³`, `z` rounds.
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
//! Every scenario's regressors, measurements and weights come from a fixed-seed generator
//! (SplitMix64, uniform in `[−1, 1)`), `x_true = [1, 1.5, 2, …]` (`1 + j/2`), `x₀ = 0`.
//!
//! Row fields: `pd_lost_at` is the first checkpoint step where the form's own health showed a
//! non-positive or non-finite pivot or flagged lost definiteness; `nan_at` the first
//! checkpoint with a non-finite estimate; `detected` whether the form reported a failure
//! itself (lost definiteness, or updates refused as numerically unusable).
//!
//! Health figure (`health_kind`, worst value over the checkpoints in `health_worst`),
//! computed in f64 from the state the form stores, so that it can show a failure the form's
//! own cheap pivots cannot:
//! - conventional, Joseph: `lambda_min/lambda_max`, the smallest over the largest eigenvalue of
//!   the stored `P`; `≤ 0` means `P` is indefinite (or singular), small positive values mean
//!   `κ(P)` = its inverse.
//! - Potter, inverse QR: `kappa(S)`, the 2-norm condition number of the stored factor `S`
//!   (`P = S Sᵀ`, so `κ(P) = κ(S)²`); near `1/u` (f32: `1.7·10⁷`) a direction of `S` is lost
//!   in rounding, `∞` means `S` is singular. Potter's own pivots (the diagonal of `S Sᵀ`)
//!   cannot show that.
//! - information QR: `kappa(R)` of the stored `R` (`P⁻¹ = Rᵀ R`), the same meaning.
//! - Bierman U-D: `min_d/max_d`, the smallest over the largest diagonal entry of `D`
//!   (`P = U D Uᵀ`, unit `U`); `≤ 0` means the factored `P` is no longer positive definite.

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
    /// Largest `‖x − x_ref‖ / ‖x_ref‖` over the checkpoints (or at the last step, see above),
    /// `x_ref` solved on the f64 data.
    pub max_rel_err: f64,
    /// The same against the exact solution of the data the form received (rounded to its
    /// precision): the form's own error.
    pub max_rel_err_received: f64,
    /// Which health figure `health_worst` is (see the module documentation).
    pub health_kind: &'static str,
    /// Worst value of the health figure over the checkpoints (largest condition number,
    /// smallest eigenvalue or pivot ratio); NaN if the form could not be built.
    pub health_worst: f64,
    /// First checkpoint step where the form's health showed lost definiteness.
    pub pd_lost_at: Option<u64>,
    /// First checkpoint step with a non-finite estimate.
    pub nan_at: Option<u64>,
    /// Whether the form reported a failure itself.
    pub detected: bool,
    /// Wall time per update of the form alone, nanoseconds.
    pub ns_per_update: f64,
    /// `(step, ‖x − x_ref‖ / ‖x_ref‖)` (f64-data reference) at every checkpoint (infinite where the estimate was
    /// not finite): the error over the run, for plots.
    pub trace: Vec<(u64, f64)>,
}

/// The largest [`StressOptions::scale`] the command line and Python accept: 100 times the
/// documented lengths (1e8 steps of a long run) is minutes per scenario, and the run cannot
/// be interrupted midway.
pub const MAX_SCALE: f64 = 100.0;

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
            let decimal = (2..=8).map(|e| 10f64.powi(-e));
            let binary = [7, 10, 13, 17, 20, 23].map(|k| 2f64.powi(-k));
            for delta in decimal.chain(binary) {
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
    let exact = reference_run::<N, G>(s, make(), &at, |v| v);
    // What the f32 forms receive: every input rounded to f32 (f64 forms receive the data).
    let exact_f32 = reference_run::<N, G>(s, make(), &at, |v| f64::from(v as f32));
    macro_rules! forms {
        ($t:ty, $p:literal, $received:expr) => {
            rows.push(one_form::<$t, Conventional<$t, N>, N, G>(
                s,
                $p,
                make(),
                &at,
                &exact,
                $received,
            ));
            rows.push(one_form::<$t, Joseph<$t, N>, N, G>(
                s,
                $p,
                make(),
                &at,
                &exact,
                $received,
            ));
            rows.push(one_form::<$t, Potter<$t, N>, N, G>(
                s,
                $p,
                make(),
                &at,
                &exact,
                $received,
            ));
            rows.push(one_form::<$t, BiermanUd<$t, N>, N, G>(
                s,
                $p,
                make(),
                &at,
                &exact,
                $received,
            ));
            rows.push(one_form::<$t, InverseQr<$t, N>, N, G>(
                s,
                $p,
                make(),
                &at,
                &exact,
                $received,
            ));
            rows.push(one_form::<$t, InformationQr<$t, N>, N, G>(
                s,
                $p,
                make(),
                &at,
                &exact,
                $received,
            ));
        };
    }
    forms!(f32, "f32", &exact_f32);
    forms!(f64, "f64", &exact);
}

/// The true parameters every scenario measures.
fn x_true<const N: usize>() -> [f64; N] {
    core::array::from_fn(|j| 1.0 + j as f64 * 0.5)
}

fn prior<T: Lane, const N: usize>(s: &Scenario) -> (Vector<T, N>, Mat<T, N, N>) {
    (Vector::zeros(), Mat::identity().scale(T::from_f64(s.p0)))
}

/// The double-double reference estimates at the checkpoints (bounds removed), on the data
/// (`h`, `z`, weight, λ and `P₀`) passed through `round`: the identity for the f64 data,
/// rounding to f32 for what the f32 forms receive.
fn reference_run<const N: usize, G>(
    s: &Scenario,
    mut samples: G,
    at: &[u64],
    round: fn(f64) -> f64,
) -> Vec<[f64; N]>
where
    G: FnMut(u64, &[f64; N]) -> Sample<N>,
{
    let mut f = DdInformationQr::<N>::new(round(s.p0), round(s.config.lambda));
    let x_true = x_true::<N>();
    let mut out = Vec::with_capacity(at.len());
    let mut start = 0;
    for &stop in at {
        for k in start..stop {
            let (h, z, w) = samples(k, &x_true);
            f.update(&h.map(round), round(z), round(w));
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
    received: &[[f64; N]],
) -> StressRow
where
    T: Lane<Scalar = T, Mask = bool> + Into<f64>,
    F: RecursiveLeastSquares<T, N> + HealthFigure,
    G: FnMut(u64, &[f64; N]) -> Sample<N>,
{
    let mut row = StressRow {
        form: F::NAME,
        precision,
        scenario: s.name,
        param: s.param,
        steps: s.steps,
        max_rel_err: f64::NAN,
        max_rel_err_received: f64::NAN,
        health_kind: F::KIND,
        health_worst: f64::NAN,
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
    let mut health_worst = if F::WORST_IS_LARGEST {
        0.0
    } else {
        f64::INFINITY
    };
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
        let figure = f.figure();
        // NaN (a broken state) is the worst value.
        health_worst = if figure.is_nan() || health_worst.is_nan() {
            f64::NAN
        } else if F::WORST_IS_LARGEST {
            health_worst.max(figure)
        } else {
            health_worst.min(figure)
        };
    }
    row.ns_per_update = elapsed * 1e9 / s.steps as f64;
    let health = f.health();
    row.detected = health.lost_definiteness || health.rejected_numerical.as_ref()[0] > 0;
    row.health_worst = health_worst;
    let rel = |x: &[f64; N], x_ref: &[f64; N]| {
        let num: f64 = x.iter().zip(x_ref).map(|(a, b)| (a - b) * (a - b)).sum();
        let den: f64 = x_ref.iter().map(|b| b * b).sum();
        (num / den).sqrt()
    };
    let mut worst = 0.0f64;
    let mut worst_received = 0.0f64;
    for (((&k, (x, pd)), x_ref), x_rec) in at.iter().zip(&snapshots).zip(reference).zip(received) {
        if !pd && row.pd_lost_at.is_none() {
            row.pd_lost_at = Some(k);
        }
        if x.iter().any(|v| !v.is_finite()) {
            row.nan_at.get_or_insert(k);
            worst = f64::INFINITY;
            worst_received = f64::INFINITY;
            row.trace.push((k, f64::INFINITY));
            continue;
        }
        let err = rel(x, x_ref);
        row.trace.push((k, err));
        worst = worst.max(err);
        let last_received = rel(x, x_rec);
        worst_received = if s.final_only {
            last_received
        } else {
            worst_received.max(last_received)
        };
    }
    // Scenarios that measure recovery judge the last step only (the trace keeps the rest).
    row.max_rel_err = match row.trace.last() {
        Some(&(_, last)) if s.final_only => last,
        _ => worst,
    };
    row.max_rel_err_received = worst_received;
    row
}

/// The health figure of a form (see the module documentation), from its stored state in f64.
trait HealthFigure {
    /// Its name in the `health_kind` field.
    const KIND: &'static str;
    /// Whether larger values are worse (condition numbers) or smaller (eigenvalues, pivots).
    const WORST_IS_LARGEST: bool;
    fn figure(&self) -> f64;
}

fn to_faer<T: Lane<Scalar = T> + Into<f64>, const N: usize>(a: &Mat<T, N, N>) -> faer::Mat<f64> {
    faer::Mat::from_fn(N, N, |i, j| a.m[i][j].into())
}

/// `λ_min/λ_max` of a symmetric matrix (NaN if not finite or the solver fails).
fn eigen_ratio<T: Lane<Scalar = T> + Into<f64>, const N: usize>(p: &Mat<T, N, N>) -> f64 {
    let m = to_faer(p);
    if !m.is_all_finite() {
        return f64::NAN;
    }
    match m.self_adjoint_eigenvalues(faer::Side::Lower) {
        Ok(ev) => ev[0] / ev[N - 1],
        Err(_) => f64::NAN,
    }
}

/// `σ_max/σ_min` of a factor (`∞` if singular, NaN if not finite or the solver fails).
fn condition<T: Lane<Scalar = T> + Into<f64>, const N: usize>(a: &Mat<T, N, N>) -> f64 {
    let m = to_faer(a);
    if !m.is_all_finite() {
        return f64::NAN;
    }
    match m.singular_values() {
        Ok(sv) => sv[0] / sv[N - 1],
        Err(_) => f64::NAN,
    }
}

macro_rules! health_figure {
    ($form:ident, $kind:literal, $largest:literal, |$f:ident| $body:expr) => {
        impl<T: Lane<Scalar = T, Mask = bool> + Into<f64>, const N: usize> HealthFigure
            for $form<T, N>
        {
            const KIND: &'static str = $kind;
            const WORST_IS_LARGEST: bool = $largest;
            fn figure(&self) -> f64 {
                let $f = self;
                $body
            }
        }
    };
}
health_figure!(Conventional, "lambda_min/lambda_max", false, |f| {
    eigen_ratio(&f.covariance())
});
health_figure!(Joseph, "lambda_min/lambda_max", false, |f| eigen_ratio(
    &f.covariance()
));
health_figure!(Potter, "kappa(S)", true, |f| condition(f.factor()));
health_figure!(InverseQr, "kappa(S)", true, |f| condition(f.factor()));
health_figure!(InformationQr, "kappa(R)", true, |f| condition(f.factor()));
health_figure!(BiermanUd, "min_d/max_d", false, |f| {
    let d: [f64; N] = core::array::from_fn(|j| f.d()[j].into());
    let lo = d.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = d.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    // f64::min/max skip NaN; a NaN pivot is a broken state.
    if d.iter().any(|v| v.is_nan()) {
        f64::NAN
    } else {
        lo / hi
    }
});
