//! Every recursive least-squares form on arbitrary regressors, measurements, weights and λ.

use crate::Bytes;
use rootfuse_lane::{Lane, Mat, Vector};
use rootfuse_lsq::rls::{
    BiermanUd, Conventional, CovarianceBounds, Health, InformationQr, InverseQr, Joseph, Potter,
    RecursiveLeastSquares, RlsConfig, RlsError,
};

/// Most operations one input runs.
const MAX_OPS: usize = 200;

/// Fuzz target `rls_forms`: one RLS form (byte 0 picks form, size `n ∈ {1, 2, 4}` and `f32` or
/// `f64`), an arbitrary configuration and prior, then arbitrary scalar updates, two-row vector
/// updates and (Bierman U-D) process-noise time updates.
///
/// Invariants: no panic; construction fails exactly when the configuration or the prior is
/// invalid; after every operation the estimate and the covariance are finite and the
/// covariance exactly symmetric; a sample with non-finite `h`, `‖h‖²`, `z` or weight, or a
/// weight `≤ 0`, is not applied, leaves the state bit for bit and counts one
/// `rejected_input`; every scalar update counts exactly one of accepted / rejected input /
/// rejected numerically; for the factored forms every pivot of the factor is positive and
/// finite and `> 0` for moderate data (the represented covariance is positive definite; see
/// `run` for the range), `≥ 0` for any data (semidefinite: a variance may underflow) and the
/// formed covariance has a non-negative diagonal; with covariance
/// bounds, `P ⪯ p_max·I` up to a relative `10·n·u` for the factored forms (times the pivot
/// ratio for the formed `P`), and for the conventional, Joseph and Potter forms up to the
/// per-update bound of `CovarianceBounds` (per row `4u·(‖P‖/λ_s + α·L)`, Potter
/// `4u·(√(L·‖P‖/λ_s) + √α·L)` plus `(Σ_rows 4u·√(‖P‖/λ_s))²`, `L = max(p_max, ‖P‖)`,
/// measured on the `P` before the update, plus the forgetting's contraction of a previous excess), carried from update to
/// update.
pub fn rls_forms(data: &[u8]) {
    let mut input = Bytes::new(data);
    let sel = input.u8();
    let form = (sel >> 3) % 6;
    match (sel & 1 == 1, (sel >> 1) % 3) {
        (true, 0) => by_form::<f32, 1>(form, &mut input, true),
        (true, 1) => by_form::<f32, 2>(form, &mut input, true),
        (true, _) => by_form::<f32, 4>(form, &mut input, true),
        (false, 0) => by_form::<f64, 1>(form, &mut input, false),
        (false, 1) => by_form::<f64, 2>(form, &mut input, false),
        (false, _) => by_form::<f64, 4>(form, &mut input, false),
    }
}

type Extra<T, F, const N: usize> = fn(&mut F, &Vector<T, N>) -> <T as Lane>::Mask;

fn by_form<T: Lane<Scalar = T, Mask = bool> + Into<f64>, const N: usize>(
    form: u8,
    input: &mut Bytes,
    single: bool,
) {
    match form {
        0 => run::<T, Conventional<T, N>, N>(input, single, false, None),
        1 => run::<T, Joseph<T, N>, N>(input, single, false, None),
        2 => run::<T, Potter<T, N>, N>(input, single, true, None),
        3 => {
            let tu: Extra<T, BiermanUd<T, N>, N> = |f, q| f.time_update(q);
            run::<T, BiermanUd<T, N>, N>(input, single, true, Some(tu))
        }
        4 => run::<T, InverseQr<T, N>, N>(input, single, true, None),
        _ => run::<T, InformationQr<T, N>, N>(input, single, true, None),
    }
}

/// The configuration: λ mostly in `[0.745, 1]`, sometimes any value; bounds on a flag.
fn config_from(input: &mut Bytes, single: bool) -> RlsConfig {
    let b = input.u8();
    let lambda = if b.is_multiple_of(4) {
        input.value(single)
    } else {
        1.0 - f64::from(input.u8()) * 1e-3
    };
    let config = RlsConfig::new(lambda);
    if b & 4 != 0 {
        let lo = input.u8();
        let hi = input.u8();
        let p_min = if lo % 16 == 15 {
            input.value(single)
        } else {
            10f64.powi(-i32::from(lo % 16)) * f64::from(lo >> 7)
        };
        let p_max = if hi % 16 == 15 {
            f64::INFINITY
        } else {
            10f64.powi(i32::from(hi % 16) - 4)
        };
        config.with_bounds(p_min, p_max)
    } else {
        config
    }
}

/// Records `w·‖h‖²` of a row the forms accept as input (finite, `w > 0`); a NaN product
/// (`0·∞` cannot occur for accepted rows, but `∞` can) counts as unbounded.
fn note_row(rows: &mut Vec<f64>, h2: f64, w: f64) {
    if h2.is_finite() && w.is_finite() && w > 0.0 {
        let wh2 = w * h2;
        rows.push(if wh2.is_nan() { f64::INFINITY } else { wh2 });
    }
}

fn bits<T: Lane<Scalar = T> + Into<f64>, const R: usize, const C: usize>(
    m: &Mat<T, R, C>,
) -> Vec<u64> {
    m.m.iter()
        .flatten()
        .map(|&v| Into::<f64>::into(v).to_bits())
        .collect()
}

/// A filter from the input's prior (`x₀`, an isotropic `P₀`) and `config`, with the checks of
/// construction: an invalid configuration or prior is refused, a valid moderate one accepted.
/// Returns the filter and `P₀`'s variance, or None when construction was (rightly) refused.
fn prior<T, F, const N: usize>(input: &mut Bytes, single: bool, config: RlsConfig) -> Option<(F, T)>
where
    T: Lane<Scalar = T, Mask = bool> + Into<f64>,
    F: RecursiveLeastSquares<T, N>,
{
    let x0 = Vector::<T, N>::from_fn(|_, _| T::from_f64(input.value(single)));
    let pb = input.u8();
    let p0 = match (pb % 4, config.bounds) {
        (0, _) => input.value(single),
        (1, Some(b)) => b.p_max,
        _ => 10f64.powi(i32::from(pb >> 4) - 6),
    };
    let p0 = T::from_f64(p0);
    let name = F::NAME;
    let config_ok = config.lambda > 0.0
        && config.lambda <= 1.0
        && config.bounds.is_none_or(|b| {
            b.p_min >= 0.0
                && b.p_min.is_finite()
                && b.p_max > b.p_min
                && N as f64 * b.p_min < b.p_max
        });
    match F::with_isotropic_prior(&x0, p0, config) {
        Ok(f) => {
            assert!(config_ok, "{name}: invalid {config:?} accepted");
            assert!(x0.is_finite(), "{name}: non-finite prior accepted");
            let p: f64 = p0.into();
            assert!(
                p > 0.0 && p.is_finite(),
                "{name}: prior variance {p} accepted"
            );
            Some((f, p0))
        }
        Err(e) => {
            let config_err = matches!(
                e,
                RlsError::InvalidForgettingFactor | RlsError::InvalidBounds
            );
            // A bad configuration may be reported as another error that is checked first
            // (e.g. a non-finite x₀), but a configuration error means a bad configuration.
            assert!(!config_err || !config_ok, "{name}: {e:?} for {config:?}");
            let p: f64 = p0.into();
            let x0_moderate = x0.m.iter().all(|r| Into::<f64>::into(r[0]).abs() <= 1e20);
            if config_ok && config.bounds.is_none() && x0_moderate && (1e-6..=1e8).contains(&p) {
                // An invariant failure, reported by panicking as every check of this harness is.
                panic!("{name}: valid prior {p} rejected: {e:?}");
            }
            None
        }
    }
}

/// Whether a value keeps the run in the moderate range (0 or magnitude in [1e-3, 1e3]).
fn track<T: Into<f64>>(moderate: &mut bool, v: T) {
    let a = v.into().abs();
    *moderate &= a == 0.0 || (1e-3..=1e3).contains(&a);
}

/// What one operation did: for a scalar update whether its input was valid and whether it
/// was applied; `w·‖h‖²` of its valid rows; its forgetting factor.
struct Step {
    scalar_input_ok: Option<(bool, bool)>,
    rows: Vec<f64>,
    lambda_step: f64,
}

/// Reads one operation from the input and applies it: a time update (`extra`), a vector
/// update of two rows or a scalar update with or without forgetting.
fn apply_op<T, F, const N: usize>(
    f: &mut F,
    input: &mut Bytes,
    single: bool,
    extra: Option<Extra<T, F, N>>,
    lambda: f64,
    moderate: &mut bool,
    (name, op): (&str, usize),
) -> Step
where
    T: Lane<Scalar = T, Mask = bool> + Into<f64>,
    F: RecursiveLeastSquares<T, N>,
{
    let kind = input.u8();
    let mut scalar_input_ok = None;
    // w·‖h‖² of this operation's valid rows, and its forgetting factor.
    let mut rows: Vec<f64> = Vec::new();
    let mut lambda_step = lambda;
    if let (7, Some(extra)) = (kind % 8, extra) {
        let q = Vector::<T, N>::from_fn(|_, _| T::from_f64(input.value(single)));
        q.m.iter().for_each(|r| track(moderate, r[0]));
        let applied = extra(f, &q);
        let q_ok = q.is_finite() && q.m.iter().all(|r| r[0].simd_ge(T::zero()));
        if !q_ok {
            assert!(!applied, "{name} op {op}: invalid process noise applied");
        }
    } else if kind % 8 == 6 {
        let h = Mat::<T, 2, N>::from_fn(|_, _| T::from_f64(input.value(single)));
        let z = Vector::<T, 2>::from_fn(|_, _| T::from_f64(input.value(single)));
        let w = Vector::<T, 2>::from_fn(|_, _| T::from_f64(input.value(single)));
        h.m.iter()
            .flatten()
            .chain(w.m.iter().flatten())
            .for_each(|&v| track(moderate, v));
        for (row, wi) in h.m.iter().zip(w.m.iter()) {
            let h2: f64 = row.iter().map(|&v| Into::<f64>::into(v).powi(2)).sum();
            note_row(&mut rows, h2, Into::<f64>::into(wi[0]));
        }
        f.update_vector(&h, &z, &w);
    } else {
        let h = Vector::<T, N>::from_fn(|_, _| T::from_f64(input.value(single)));
        let z = T::from_f64(input.value(single));
        let w = T::from_f64(input.value(single));
        h.m.iter().for_each(|r| track(moderate, r[0]));
        track(moderate, w);
        note_row(
            &mut rows,
            Into::<f64>::into(h.dot(&h)),
            Into::<f64>::into(w),
        );
        if kind & 16 == 0 {
            lambda_step = 1.0;
        }
        let applied = f.update_with_forgetting(&h, z, w, kind & 16 != 0);
        let input_ok = h.is_finite()
            && h.dot(&h).is_finite()
            && z.is_finite()
            && w.is_finite()
            && w.simd_gt(T::zero());
        assert!(
            !applied || input_ok,
            "{name} op {op}: invalid sample applied"
        );
        scalar_input_ok = Some((input_ok, applied));
    }
    Step {
        scalar_input_ok,
        rows,
        lambda_step,
    }
}

/// One operation's state, for the `p_max` check ([`check_p_max`]).
struct BoundCheck<'a, T: Lane, const N: usize> {
    name: &'static str,
    op: usize,
    factored: bool,
    /// The forgetting factor of this operation (1 for an update without forgetting).
    lambda_step: f64,
    /// `w·‖h‖²` of the operation's valid rows.
    rows: &'a [f64],
    p: &'a Mat<T, N, N>,
    p_before: &'a Mat<T, N, N>,
    health: &'a Health<T>,
}

/// `P ≤ p_max` within the rounding the form's arithmetic allows (derived below), where it can
/// be checked; returns the new certified bound `p_norm` of `λ_max(P)` (the old one when `P`
/// did not change).
fn check_p_max<T, const N: usize>(c: &BoundCheck<'_, T, N>, b: CovarianceBounds, p_norm: f64) -> f64
where
    T: Lane<Scalar = T, Mask = bool> + Into<f64>,
{
    let BoundCheck {
        name,
        op,
        factored,
        lambda_step,
        rows,
        p,
        p_before,
        health,
    } = *c;
    let p = *p;
    let n_eps = N as f64 * T::EPSILON;
    // The loss of this operation (see `p_norm`), per valid row and, with forgetting,
    // per regularising pseudo-row (w·‖h‖² = (1 − λ)/p_max), with N = p_norm the size of
    // the P the update started from and L = max(p_max, N) the size of the result: the
    // subtraction from P̃ = P/λ_s rounds at P̃'s scale (covariance forms u·N/λ_s;
    // Potter's factor u·√(N/λ_s), times √L in P; found: Potter, f64, P₀ = 1e-3·I,
    // λ = 1e-30, p_max = 1e5 ended at p_max + 4.2), and a row with
    // α = 1 + w·hᵀ(P/λ_s)h loses u·α (Potter u·√α) relative at the result's scale.
    // Plus the contraction of an excess by the exact regularised forgetting (an
    // eigenvalue p > p_max maps below p_max + λ(p − p_max)).
    // Bierman U-D scales `D` by 1/λ_s as the covariance forms scale `P`, so it rounds at
    // the same scale (found: f64, λ = 4.5e-44, p_max = 100, P_02 = −1.2e-8 after 46
    // operations where 100·(1 + 10·n·u) was allowed).
    let covariance_form = matches!(name, "conventional" | "joseph" | "bierman-ud");
    // Inverse QR rotates the same `S̃ = S/√λ_s` that Potter updates, so it rounds at
    // the same scale (found: f32, λ = 1.2e-25, p_max = 100 ended 4.9e-5 relative above).
    let square_root_factor = matches!(name, "potter" | "inverse-qr");
    let (loss, contracted) = if covariance_form || square_root_factor {
        let reg = (1.0 - lambda_step) / b.p_max;
        let large = b.p_max.max(p_norm);
        let loss: f64 = rows
            .iter()
            .copied()
            .chain((0..N).map(|_| reg))
            .map(|wh2| {
                let alpha = 1.0 + wh2 * p_norm / lambda_step;
                4.0 * T::EPSILON
                    * if covariance_form {
                        p_norm / lambda_step + alpha * large
                    } else {
                        (large * p_norm / lambda_step).sqrt() + alpha.sqrt() * large
                    }
            })
            .sum();
        // The square-root factor's P = S Sᵀ also carries δS·δSᵀ: the square of the factor's rounding,
        // which dominates once λ ≲ u² (found: λ = 1.5e-47, P₀ = 1e-3·I, p_max = 100
        // ended at 1.1e12, about (u·‖S/√λ‖)²).
        let factor_rounding: f64 = if covariance_form {
            0.0
        } else {
            (rows.len() + N) as f64 * 4.0 * T::EPSILON * (p_norm / lambda_step).sqrt()
        };
        let excess = (p_norm - b.p_max).max(0.0);
        (
            loss + factor_rounding * factor_rounding,
            lambda_step * excess,
        )
    } else {
        (0.0, 0.0)
    };
    // The bound is kept on the stored factor, so the formed P can exceed it by its
    // rounding, about n·u·κ(P) relative; the factor's pivot ratio stands in for κ (found:
    // information QR at κ ≈ 7e8 overshot the plain 10·n·u slack).
    let (lo, hi): (f64, f64) = (health.min_pivot.into(), health.max_pivot.into());
    let ratio = if factored { (hi / lo).max(1.0) } else { 1.0 };
    let limit64 = b.p_max * (1.0 + 10.0 * n_eps * ratio) + contracted + loss;
    let limit = T::from_f64(limit64);
    let room = Mat::<T, N, N>::identity().scale(limit) - p;
    // A slack beyond the lane type's range leaves nothing to check; nor does a factored
    // form's P formed at a pivot ratio beyond 1/(n·u), whose rounding can exceed any
    // bound (ROBUSTNESS.md; found: information QR with h entries of 1e50, pivot ratio
    // 1e99, formed P_11 = 1e19 where the exact value is below p_max).
    // The pivot ratio is only a lower bound of κ: the formed P itself must also show
    // an eigenvalue gap above its own rounding (found: information QR, f32, pivot
    // ratio within 1/(n·u) but κ(P) ≈ 10²¹; the formed P came out indefinite and
    // 1.39e10 against p_max = 1e10).
    let formed = Mat::<f64, N, N>::from_fn(|i, j| p.m[i][j].into());
    let rounding = 10.0 * n_eps * formed.trace().abs();
    let formed_gap = (formed - Mat::identity().scale(rounding)).cholesky().1;
    let well_conditioned = !factored || (hi <= lo / n_eps && formed_gap);
    // An unchanged P was checked before (its bound carries over).
    let unchanged = bits(&p) == bits(p_before);
    let checkable = Into::<f64>::into(limit).is_finite() && well_conditioned && !unchanged;
    assert!(
        !checkable || room.cholesky().1,
        "{name} op {op}: P above p_max = {} (allowed {limit64:e}): {p:?}",
        b.p_max
    );
    if !unchanged {
        // Both are upper bounds of λ_max(P): the limit just checked (when it was) and
        // the largest absolute row sum.
        let row_sum =
            p.m.iter()
                .map(|r| r.iter().map(|&v| Into::<f64>::into(v).abs()).sum::<f64>())
                .fold(0.0, f64::max);
        return if checkable {
            row_sum.min(limit64)
        } else {
            row_sum
        };
    }
    p_norm
}

fn run<T, F, const N: usize>(
    input: &mut Bytes,
    single: bool,
    factored: bool,
    extra: Option<Extra<T, F, N>>,
) where
    T: Lane<Scalar = T, Mask = bool> + Into<f64>,
    F: RecursiveLeastSquares<T, N>,
{
    let config = config_from(input, single);
    let Some((mut f, p0)) = prior::<T, F, N>(input, single, config) else {
        return;
    };
    let name = F::NAME;
    let n_eps = N as f64 * T::EPSILON;
    // While every regressor entry, weight and process noise is 0 or of magnitude in
    // [1e-3, 1e3] and the prior variance in [1e-6, 1e8], no variance can fall below about
    // 1e-15 in 200 operations, far above underflow: the strict positivity of the pivots is
    // checked then. Outside, a variance may underflow to zero (ROBUSTNESS.md).
    let mut moderate = (1e-6..=1e8).contains(&Into::<f64>::into(p0));
    // The covariance forms subtract P̃·h·hᵀ·P̃/α from P̃ = P/λ itself: one row loses about u·α
    // of P's accuracy, α = 1 + w·hᵀ(P/λ)h; Potter's square factor u·√α (ROBUSTNESS.md). With
    // bounds, α is measured on the P *before* the update, not on p_max: when u·α ≳ 1 (e.g.
    // λ ≲ u) the excess of one update inflates the next update's α and the loss compounds
    // (found: f64, λ = 1e-30, p_max = 1e10: P goes 1e10 → 1.2e24 = 2⁸⁰ → 1.7e38 = 2¹²⁷ in two
    // updates, each one ulp of P/λ; corpus `regression-conventional-bounds-compounding`).
    // `p_norm` is a certified upper bound of λ_max(P) carried from the last check.
    let mut p_norm = Into::<f64>::into(p0) * (1.0 + n_eps);
    for op in 0..MAX_OPS {
        if input.is_empty() {
            break;
        }
        let (x_before, p_before, h_before) = (f.estimate(), f.covariance(), f.health());
        let Step {
            scalar_input_ok,
            rows,
            lambda_step,
        } = apply_op(
            &mut f,
            input,
            single,
            extra,
            config.lambda,
            &mut moderate,
            (name, op),
        );
        let (x, p, health) = (f.estimate(), f.covariance(), f.health());
        if let Some((input_ok, applied)) = scalar_input_ok {
            let c = |a: &T::Counts, b: &T::Counts| a.as_ref()[0] - b.as_ref()[0];
            let (acc, rin, rnum) = (
                c(&health.accepted, &h_before.accepted),
                c(&health.rejected_input, &h_before.rejected_input),
                c(&health.rejected_numerical, &h_before.rejected_numerical),
            );
            assert_eq!(
                (acc, rin, rnum),
                (
                    u64::from(applied),
                    u64::from(!input_ok),
                    u64::from(input_ok && !applied)
                ),
                "{name} op {op}: counters"
            );
            if !applied {
                assert!(
                    bits(&x) == bits(&x_before) && bits(&p) == bits(&p_before),
                    "{name} op {op}: a rejected sample changed the state"
                );
            }
        }
        assert!(x.is_finite(), "{name} op {op}: estimate {x:?}");
        assert!(p.is_finite(), "{name} op {op}: covariance {p:?}");
        assert!(
            bits(&p) == bits(&p.transpose()),
            "{name} op {op}: covariance not symmetric"
        );
        if factored {
            let (lo, hi): (f64, f64) = (health.min_pivot.into(), health.max_pivot.into());
            // Positive finite pivots of a triangular factor are positive definiteness of the
            // represented P; Potter's pivots are P's diagonal (necessary only). Outside the
            // moderate range a variance may underflow to zero, and Potter's square factor may
            // lose a direction to rounding when α = 1 + w·hᵀPh exceeds ~1/u²: P then stays
            // semidefinite (pivots ≥ 0). The P formed in working precision is not checked by
            // Cholesky: for κ(P) ≳ 1/(n·u) its rounding alone can make it indefinite.
            let strict = moderate && name != "potter";
            assert!(
                (lo > 0.0 || (!strict && lo == 0.0)) && hi.is_finite(),
                "{name} op {op}: pivots {lo:e}..{hi:e}, P = {p:?}"
            );
            assert!(
                (0..N).all(|j| p.m[j][j].simd_ge(T::zero())),
                "{name} op {op}: covariance diagonal negative: {p:?}"
            );
        }
        if let Some(b) = config.bounds
            && b.p_max.is_finite()
        {
            let check = BoundCheck {
                name,
                op,
                factored,
                lambda_step,
                rows: &rows,
                p: &p,
                p_before: &p_before,
                health: &health,
            };
            p_norm = check_p_max(&check, b, p_norm);
        }
    }
}
