//! Forgetting-factor weighted least-squares denoising of one signal per lane.

use rootfuse_lane::{Lane, Mask, Mat, Vector};
use rootfuse_lsq::rls::{Potter, RecursiveLeastSquares, RlsConfig};

/// Causal local-polynomial denoiser: at each sample `t_k` it fits
/// `y(t) = c₀ + c₁·s + … + c_{N−1}·s^{N−1}`, `s = (t − t_k)/τ`, to all samples so far by
/// minimising `Σᵢ λ_{k,i}·w·(yᵢ − y(tᵢ))²` and returns the fitted value at `t_k`, `c₀`.
///
/// The fit is the square-root (Potter) recursive least squares of `rootfuse-lsq`: the
/// coefficients are its state, each sample is the scalar measurement `z = c₀` (the regressor
/// is `[1, 0, …]` because the origin is the current sample), and between samples the
/// polynomial is re-expanded about the new origin by [`Potter::predict`] with the upper
/// triangular binomial matrix `F_ji = C(i, j)·(dt/τ)^{i−j}` and the step's forgetting factor
/// `λ = τ/(τ + dt)` (first order in `dt/τ` equal to `exp(−dt/τ)`: the memory is about `τ`
/// seconds whatever the rate, and `λ_{k,i}` is the product of the steps' factors). The weight
/// `w = 1/σ²` is the Markov choice `W = R⁻¹`; with one sensor it scales the covariance only.
///
/// Properties (tested): a polynomial of degree `< N` is reproduced exactly once the prior has
/// been forgotten; on white noise at a uniform step the output variance is
/// `σ²·e₁ᵀ M⁻¹ M₂ M⁻¹ e₁` with `M = Σ_j θ^j h_j h_jᵀ`, `M₂ = Σ_j θ^{2j} h_j h_jᵀ`,
/// `h_j = [1, −j·dt/τ, …]`, `θ = τ/(τ + dt)` (Brown's discounted least squares; for `N = 2`
/// this is `(1 − θ)(1 + 4θ + 5θ²)/(1 + θ)³`).
///
/// Time is measured in units of `τ` so the coefficients are all in the unit of `y` and the
/// factor stays well conditioned in `f32`.
#[derive(Clone, Debug)]
pub struct PolyDenoiser<T: Lane, const N: usize> {
    rls: Potter<T, N>,
    inv_tau: T,
    weight: T,
}

impl<T: Lane, const N: usize> PolyDenoiser<T, N> {
    /// A denoiser of memory `tau` seconds for a signal of noise standard deviation `noise`
    /// (unit of the signal; both are clamped to sane positive values, NaN to the defaults
    /// 0.05 s and 0.01). The prior is `c = 0` with standard deviation 100 per coefficient, so
    /// the first sample is taken almost as it is.
    pub fn new(tau: f64, noise: f64) -> Self {
        let tau = if tau.is_finite() && tau > 0.0 {
            tau.clamp(1e-6, 1e6)
        } else {
            0.05
        };
        let noise = if noise.is_finite() && noise > 0.0 {
            noise.clamp(1e-12, 1e12)
        } else {
            0.01
        };
        let prior =
            Potter::with_isotropic_prior(&Vector::zeros(), T::from_f64(1e4), RlsConfig::new(1.0));
        Self {
            // Unreachable: construction fails only for λ ∉ (0, 1], invalid bounds, a
            // non-finite x₀ or P₀ not PD; here λ = 1, no bounds, x₀ = 0, P₀ = 1e4·I.
            rls: prior.expect("unreachable: constant, valid prior"),
            inv_tau: T::from_f64(1.0 / tau),
            weight: T::from_f64(1.0 / (noise * noise)),
        }
    }

    /// Takes sample `y` at `dt` seconds after the previous one, in `active` lanes (elsewhere
    /// the state is left exactly as it was), and returns the denoised value at this sample
    /// (the last one in inactive lanes).
    pub fn update(&mut self, y: T, dt: T, active: T::Mask) -> T {
        let r = T::select(active, dt * self.inv_tau, T::zero());
        let mut f = Mat::<T, N, N>::identity();
        // Row j, column i: C(i, j)·r^(i−j), built column by column from the previous one.
        for i in 1..N {
            for j in 0..=i {
                let from_left = if j > 0 { f.m[j - 1][i - 1] } else { T::zero() };
                let from_above = if j < i { f.m[j][i - 1] * r } else { T::zero() };
                f.m[j][i] = from_left + from_above;
            }
        }
        let lambda = T::one() / (T::one() + r);
        // No bounds are configured, so the transition is always accepted as a call.
        let _ = self.rls.predict(&f, lambda);
        let mut h = Vector::<T, N>::zeros();
        h[0] = T::one();
        let weight = T::select(active & y.is_finite(), self.weight, T::zero());
        self.rls
            .update_with_forgetting(&h, y, weight, <T::Mask as Mask>::splat(false));
        self.rls.estimate()[0]
    }

    /// The current coefficients `[c₀, c₁, …]` (unit of the signal; `c_i` multiplies
    /// `((t − t_k)/τ)^i`).
    pub fn coefficients(&self) -> Vector<T, N> {
        self.rls.estimate()
    }
}
