//! The first-order low-pass gain `1 − exp(−dt/τ)`, from a time constant or from its rate
//! `1/τ`, in the lane's own arithmetic.

use super::is_f64;
use rootfuse_lane::{Lane, Mask};

/// The exact discrete gain `k = 1 − exp(−dt/τ)` of a first-order low-pass
/// `y ← y + k·(x − y)` with time constant `tau` (s) over a step `dt` (s): the low-pass
/// discretisation of every filter in this crate (the flagship takes it from rates `1/τ`,
/// [`lowpass_gains_at_rates`]).
///
/// It is exact for every `dt/τ` from 0 to ∞: `k = −expm1(−x)`, `x = dt/τ`, so a small `x`
/// keeps its digits (`1 − exp` would cancel) and a large one gives 1 rather than diverging.
/// Up to `x = 4` (every filter's usual case: `dt` of milliseconds against `τ` of tenths of a
/// second and more, or a few samples against the shortest `τ`) it is computed in the lane's
/// own arithmetic, in SIMD, with no libm call: up to `x = 1/8` from the Taylor series by
/// Horner through `x¹²` in `f64` and `x⁶` in `f32`, up to `1/2` through `x¹⁵` and `x⁹` (the
/// first dropped term is below 2·10⁻¹⁸ and 10⁻⁹ of the result); a larger `x` is halved until
/// it is at most `1/2` (at most 3 times), and the gain of the halved step doubled back as
/// often by `k(2y) = k(y)·(2 − k(y))` (two equal steps; no cancellation, since `2 − k ≥ 1`).
/// A sample rate with jitter, which changes `dt` at every sample, thus costs a few
/// multiply-adds per gain instead of a libm call per lane. Larger `x` calls libm's `expm1` in
/// `f64`, rounded once. Against `−expm1(−dt/τ)` of the lane's `dt` and `τ` the relative error
/// is at most `2ε` in `f64` and `f32` (`ε` the precision's machine epsilon; the division, the
/// series and each doubling round in the lane's precision; `tests/attitude/bad_samples.rs`
/// bounds it). Each lane is computed on its own, with the same operations in the same order,
/// so a lane equals the scalar result bit for bit.
///
/// Special values, per lane:
/// - `tau = 0` means **no low-pass**: `k = 1` (the output is the input) for any `dt > 0`;
///   a negative or NaN `tau` is treated the same way (parameters never give one);
/// - `dt ≤ 0` or NaN (no time passed, a skipped sample): `k = 0`, nothing is taken in, also
///   for `tau = 0`;
/// - `tau = ∞`: `k = 0` (the output holds); `dt = ∞` with a finite `tau`: `k = 1`.
///
/// ```
/// use rootfuse_attitude::blocks::lowpass_gain;
/// assert_eq!(lowpass_gain(0.01_f64, 0.0), 1.0);
/// assert_eq!(lowpass_gain(0.0_f64, 0.0), 0.0);
/// // 1 − exp(−1e-9) = 1e-9 − 5e-19 + …: every digit kept (`1.0 - (-1e-9).exp()` keeps 7).
/// assert!((lowpass_gain(1e-9_f64, 1.0) - (1e-9 - 5e-19)).abs() < 1e-24);
/// ```
#[inline]
pub fn lowpass_gain<T: Lane>(dt: T, tau: T) -> T {
    gain::<TimeConstant, T>(dt, tau)
}

/// [`lowpass_gain`] of one step `dt` (s) for several time constants `tau` (s): the same bits
/// as one call per time constant, with one range test for all of them where every lane of
/// every gain is in the series' range (the usual case), so a jittered `dt` costs a few
/// multiply-adds per gain.
///
/// ```
/// use rootfuse_attitude::blocks::{lowpass_gain, lowpass_gains};
/// let [a, b] = lowpass_gains(0.01_f32, [0.5, 0.0]);
/// assert_eq!((a, b), (lowpass_gain(0.01, 0.5), 1.0));
/// ```
#[inline]
pub fn lowpass_gains<T: Lane, const N: usize>(dt: T, tau: [T; N]) -> [T; N] {
    gains::<TimeConstant, T, N>(dt, tau)
}

/// [`lowpass_gains`] with each time constant given as its rate `1/τ` (1/s, per lane): `x =
/// dt·rate` is a multiplication where [`lowpass_gains`] divides, so a filter that converts
/// its time constants to rates once, when it is built, pays no division per gain at a
/// jittered `dt`. `x` rounds twice (the rate and the product) where `dt/τ` rounds once: the
/// gain's relative error against `−expm1(−dt/τ)` is at most `3ε`. A filter takes every gain of one time constant
/// in the same form, or a lane computed in one form would differ from its scalar in the other.
///
/// Special values, per lane: a rate of `+∞` (`τ = 0`), a negative or a NaN rate is **no
/// low-pass** (`k = 1` for `dt > 0`); a rate of ±0 (`τ = ±∞`) holds (`k = +0`); `dt ≤ 0` or
/// NaN takes nothing in (`k = 0`).
///
/// ```
/// use rootfuse_attitude::blocks::{lowpass_gain, lowpass_gains_at_rates};
/// let [a, b, c] = lowpass_gains_at_rates(0.01_f32, [2.0, f32::INFINITY, 0.0]);
/// assert!((a - lowpass_gain(0.01, 0.5)).abs() <= 3.0 * f32::EPSILON * a);
/// assert_eq!((b, c), (1.0, 0.0));
/// ```
#[inline]
pub fn lowpass_gains_at_rates<T: Lane, const N: usize>(dt: T, rates: [T; N]) -> [T; N] {
    gains::<Rate, T, N>(dt, rates)
}

/// [`lowpass_gains_at_rates`] for one rate (1/s): the same bits.
#[inline]
pub fn lowpass_gain_at_rate<T: Lane>(dt: T, rate: T) -> T {
    gain::<Rate, T>(dt, rate)
}

/// How a gain's parameter `p` gives `x = dt/τ`: a time constant divides, a rate multiplies.
trait GainParameter {
    fn x<T: Lane>(dt: T, p: T) -> T;
    /// Whether a parameter that is not positive (zero, negative, NaN) is no low-pass (gain
    /// 1) rather than a hold (gain 0).
    fn passes<S: Lane + PartialOrd>(p: S) -> bool;
}

/// `p = τ`, s: 0, negative or NaN is no low-pass; `∞` holds (`x = 0`).
struct TimeConstant;

impl GainParameter for TimeConstant {
    #[inline(always)]
    fn x<T: Lane>(dt: T, tau: T) -> T {
        dt / tau
    }
    fn passes<S: Lane + PartialOrd>(_: S) -> bool {
        true
    }
}

/// `p = 1/τ`, 1/s: ±0 holds; negative or NaN is no low-pass; `∞` is no low-pass (`x = ∞`).
struct Rate;

impl GainParameter for Rate {
    #[inline(always)]
    fn x<T: Lane>(dt: T, rate: T) -> T {
        dt * rate
    }
    fn passes<S: Lane + PartialOrd>(rate: S) -> bool {
        rate != S::zero()
    }
}

/// One gain: in SIMD where every lane's `dt` and parameter are positive and `x ≤ 4`, else
/// lane by lane.
#[inline(always)]
fn gain<F: GainParameter, T: Lane>(dt: T, p: T) -> T {
    let x = F::x(dt, p);
    let in_range =
        dt.simd_gt(T::zero()) & p.simd_gt(T::zero()) & x.simd_le(T::from_f64(GAIN_HALVING_LIMIT));
    if in_range.all() {
        gain_by_halving(x)
    } else {
        gain_per_lane::<F, T>(dt, p)
    }
}

/// Several gains of one `dt`: one range test for all of them where every lane of every gain
/// is in the short series' range (the usual case), else one [`gain`] each (the same bits).
#[inline(always)]
fn gains<F: GainParameter, T: Lane, const N: usize>(dt: T, p: [T; N]) -> [T; N] {
    let x = p.map(|p| F::x(dt, p));
    let mut series = dt.simd_gt(T::zero());
    for (p, x) in p.iter().zip(&x) {
        series = series & p.simd_gt(T::zero()) & x.simd_le(T::from_f64(GAIN_SERIES_LIMIT));
    }
    if series.all() {
        x.map(gain_series)
    } else {
        p.map(|p| gain::<F, T>(dt, p))
    }
}

/// [`gain`] lane by lane: for lanes outside the SIMD range (a skipped sample, `τ = 0`, a long
/// gap), out of line so that the usual path stays small.
#[cold]
#[inline(never)]
fn gain_per_lane<F: GainParameter, T: Lane>(dt: T, p: T) -> T {
    T::from_fn(|i| scalar_gain::<F, _>(dt.extract(i), p.extract(i)))
}

/// The largest `x = dt/τ` whose gain [`lowpass_gain`] computes in the lane's arithmetic
/// (at most 3 halvings into the long series' range).
const GAIN_HALVING_LIMIT: f64 = 4.0;

/// `−expm1(−x) = Σ (−1)ⁿ⁺¹ xⁿ/n!`: the coefficients of `x¹ … x¹⁵`.
const GAIN_SERIES: [f64; 15] = [
    1.0,
    -1.0 / 2.0,
    1.0 / 6.0,
    -1.0 / 24.0,
    1.0 / 120.0,
    -1.0 / 720.0,
    1.0 / 5040.0,
    -1.0 / 40320.0,
    1.0 / 362880.0,
    -1.0 / 3628800.0,
    1.0 / 39916800.0,
    -1.0 / 479001600.0,
    1.0 / 6227020800.0,
    -1.0 / 87178291200.0,
    1.0 / 1307674368000.0,
];

/// The largest `x` [`lowpass_gain`] takes from its short series (through `x¹²` in `f64`,
/// `x⁶` in `f32`).
const GAIN_SERIES_LIMIT: f64 = 0.125;

/// The largest `x` it takes from its long series (through `x¹⁵` in `f64`, `x⁹` in `f32`);
/// larger ones are halved into it.
const GAIN_LONG_SERIES_LIMIT: f64 = 0.5;

/// `−expm1(−x)` for `0 ≤ x ≤ GAIN_HALVING_LIMIT` in the arithmetic of `L` (see
/// [`lowpass_gain`]): the short series where every lane is in its range (the usual case,
/// inline), else [`gain_beyond_short_series`].
#[inline(always)]
fn gain_by_halving<L: Lane>(x: L) -> L {
    if x.simd_gt(L::from_f64(GAIN_SERIES_LIMIT)).none() {
        gain_series(x)
    } else {
        gain_beyond_short_series(x)
    }
}

/// The series of [`GAIN_SERIES`] at `x ≤ 1/8` (Horner) in the arithmetic of `L`, through
/// `x¹²` in `f64` and `x⁶` in `f32` (the first dropped term is below 3·10⁻¹⁹ and 10⁻⁹ of the
/// result, far below one rounding).
#[inline(always)]
fn gain_series<L: Lane>(x: L) -> L {
    gain_series_to(x, if is_f64::<L>() { 12 } else { 6 })
}

/// The series at `x ≤ 1/2`, through `x¹⁵` in `f64` and `x⁹` in `f32` (the first dropped
/// term is below 2·10⁻¹⁸ and 10⁻⁹ of the result).
#[inline(always)]
fn gain_long_series<L: Lane>(x: L) -> L {
    gain_series_to(x, if is_f64::<L>() { 15 } else { 9 })
}

/// [`GAIN_SERIES`] through `xᵗᵉʳᵐˢ` by Horner.
#[inline(always)]
fn gain_series_to<L: Lane>(x: L, terms: usize) -> L {
    let mut p = L::from_f64(GAIN_SERIES[terms - 1]);
    for &c in GAIN_SERIES[..terms - 1].iter().rev() {
        p = p * x + L::from_f64(c);
    }
    p * x
}

/// [`gain_by_halving`] where some lane's `x` is above the short series' range. Per lane: `x ≤
/// 1/8` from the short series, `x ≤ 1/2` from the long one, a larger `x` halved until it is
/// at most 1/2 and its long series doubled back as often. The loops run as often as the lane
/// that needs most; every other lane keeps its value through a select, so its result is the
/// one it would have alone. A sample interval against the shortest window (a correction
/// every few samples, 8 at 100 Hz against 0.3 s: `x ≈ 0.27`) takes the long series, without
/// halving.
#[inline(never)]
fn gain_beyond_short_series<L: Lane>(x: L) -> L {
    // `GAIN_HALVING_LIMIT` needs at most 3 halvings; the bound keeps a caller's larger `x`
    // from looping on.
    const MAX_HALVINGS: usize = 3;
    let limit = L::from_f64(GAIN_LONG_SERIES_LIMIT);
    let (mut y, mut halvings, mut n) = (x, L::zero(), 0);
    while n < MAX_HALVINGS {
        let over = y.simd_gt(limit);
        if over.none() {
            break;
        }
        y = L::select(over, y * L::from_f64(0.5), y);
        halvings = L::select(over, halvings + L::one(), halvings);
        n += 1;
    }
    // Only a lane that was never halved can be in the short series' range.
    let short = y.simd_le(L::from_f64(GAIN_SERIES_LIMIT));
    let mut k = if short.any() {
        L::select(short, gain_series(y), gain_long_series(y))
    } else {
        gain_long_series(y)
    };
    for j in (0..n).rev() {
        let doubled = halvings.simd_gt(L::from_f64(j as f64));
        k = L::select(doubled, k * (L::from_f64(2.0) - k), k);
    }
    k
}

/// One lane of [`gain`], in the lane's precision. NaN lands on the documented side: a NaN
/// `dt` takes nothing in, a NaN parameter is no low-pass.
#[inline]
fn scalar_gain<F: GainParameter, S: Lane + PartialOrd + Into<f64>>(dt: S, p: S) -> S {
    if dt > S::zero() && p > S::zero() {
        let x = F::x(dt, p);
        if x <= S::from_f64(GAIN_HALVING_LIMIT) {
            gain_by_halving(x)
        } else {
            S::from_f64(-libm::expm1(-F::x(dt.into(), p.into())))
        }
    } else if dt > S::zero() && F::passes(p) {
        S::one()
    } else {
        S::zero()
    }
}

/// A [`lowpass_gain`] for one time constant, per lane, cached for the `dt` it was last
/// computed for: with a constant sample rate (the usual case) the exponential is evaluated
/// once instead of every sample. The cache is exact (the same bits as a fresh computation),
/// so it changes no result.
#[derive(Clone, Copy, Debug)]
pub struct LowPassGain<T: Lane> {
    tau: T,
    dt: T,
    gain: T,
}

impl<T: Lane> LowPassGain<T> {
    /// The gain of time constant `tau` (s, per lane; 0 = no low-pass, see [`lowpass_gain`]).
    pub fn new(tau: T) -> Self {
        Self {
            tau,
            dt: T::zero(),
            gain: lowpass_gain(T::zero(), tau),
        }
    }
    /// The time constant, s.
    pub fn tau(&self) -> T {
        self.tau
    }
    /// `1 − exp(−dt/τ)` per lane for a step `dt` (s); recomputed only when a lane's `dt`
    /// differs from the last one's.
    #[inline]
    pub fn gain(&mut self, dt: T) -> T {
        if dt.simd_ne(self.dt).any() {
            self.dt = dt;
            self.gain = lowpass_gain(dt, self.tau);
        }
        self.gain
    }
}
