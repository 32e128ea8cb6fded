//! The flagship's square-root time update, deferred to the samples where a measurement update
//! may read the covariance factor (the design on [`SqrtEskf::time_update`]).

use super::update::{every_nth, row_norm2};
use super::*;

impl<T: Lane> SqrtEskf<T> {
    /// Square-root time update on the upper-triangular factor `S = [[A, B], [0, D]]`,
    /// deferred to the samples where a measurement update may read `S` (`flush`; the bias
    /// noise's own ticks and inflations flush too). Every sample only accumulates: the
    /// transitions `F_k = [[I, −R_k·dt_k], [0, I]]` compose to `[[I, −M], [0, I]]` with
    /// `M = Σ R_k·dt_k` (their diagonal blocks are identities), and the attitude noise
    /// `diag(σ_θ²·dt_k)` on `δθ` is left unchanged by every later transition (`F·Q·Fᵀ = Q` for
    /// noise on the attitude block alone), so its variances add up. A flush applies both:
    /// `F·S = [[A, B − M·D], [0, D]]` is still upper triangular (only `B` changes; `D` upper
    /// triangular: 18 products), then the noise is folded in by [`add_diagonal_noise`] (the
    /// earth-frame attitude noise is isotropic, `R·Rᵀ = I`), with extra variances on
    /// `δθ_x, δθ_y` and on `δb` (start-up and re-acquisition). Exact in exact arithmetic: `P`
    /// at a flush is the `P` of a time update at every sample, to rounding (the 9D heading
    /// offset's variance takes the 6D heading's growth per flush, clamped at zero per flush
    /// where it was per sample). Each lane flushes
    /// by its own ticks (`flush`, and its own bias noise), so a lane's factor is that of its
    /// scalar run, bit for bit. Returns the lanes that flushed.
    pub(super) fn time_update(
        &mut self,
        r: &Mat<T, 3, 3>,
        dt: T,
        (extra_tilt_std, extra_bias_std): (T, T),
        flush: T::Mask,
    ) -> T::Mask {
        let st = &mut self.state;
        for i in 0..3 {
            for j in 0..3 {
                st.transition_sum.m[i][j] = r.m[i][j].mul_add(dt, st.transition_sum.m[i][j]);
            }
        }
        let (qt, qb) = (self.per_dt.gyr_std, self.per_dt.bias_std);
        // Re-acquisition noise is independent of the gyro noise: add it in quadrature.
        st.tilt_noise_var += qt.mul_add(qt, extra_tilt_std * extra_tilt_std);
        st.yaw_noise_var += qt * qt;
        // Only when a lane has some: `√(q²) = q` exactly, so skipping changes nothing.
        let qb = if extra_bias_std.simd_ne(T::zero()).any() {
            (qb * qb + extra_bias_std * extra_bias_std).sqrt()
        } else {
            qb
        };
        // The bias noise every `bias_noise_every` samples (and at once where the bias is
        // inflated, which keeps the phase: lanes started together stay in step), with the
        // variance of the samples in between. Where nothing is pending, `qb` itself (so 1
        // gives the bits of folding every sample).
        let pending = st.bias_noise_pending;
        let tick = every_nth(&mut st.bias_noise_samples, self.coef.bias_noise_every);
        let due = tick | extra_bias_std.simd_ne(T::zero());
        st.bias_noise_pending = T::select(due, T::zero(), pending + qb * qb);
        let flush = flush | due;
        if flush.any() {
            let qb = T::select(pending.simd_eq(T::zero()), qb, (pending + qb * qb).sqrt());
            st.fold_pending(flush, due.any().then_some((due, qb)));
        }
        flush
    }

    /// The deferred time update applied in every lane now (before the state is set from
    /// outside), with the 9D heading offset's variance grown by what it adds to the 6D
    /// heading's, as at a flush in [`propagate`](Self::propagate).
    pub(super) fn flush_time_update(&mut self) {
        let before = row_norm2(&self.state.factor, 2);
        self.state
            .fold_pending(<T::Mask as Mask>::splat(true), None);
        if self.nine_d {
            self.state.heading_offset_var += self.heading_growth(before);
        }
    }

    /// What the flushes since the 6D heading variance was `pzz_before` (rad²) have added to
    /// it, at least zero: the 9D heading offset's variance grows by as much.
    pub(super) fn heading_growth(&self, pzz_before: T) -> T {
        (row_norm2(&self.state.factor, 2) - pzz_before).max(T::zero())
    }

    /// Whether any lane's inclination, at-rest bias or (9D) field tick falls on this sample,
    /// or a lane has no field reference yet (it tests every reading): where a measurement
    /// update may read the factor, so the deferred time update must be applied first
    /// ([`time_update`](Self::time_update)). Peeks at the counters [`every_nth`] advances
    /// later in the sample.
    pub(super) fn measurement_may_be_due(&self) -> T::Mask {
        let (st, c) = (&self.state, &self.coef);
        let next = |phase: T, every: T| (phase + T::one()).simd_ge(every);
        let mut due = next(st.inclination_phase, c.acc_update_every)
            | next(st.rest_phase, c.rest_update_every);
        if self.nine_d {
            due |= next(st.heading_phase, c.mag_update_every) | !st.field.known;
        }
        due
    }
}

impl<T: Lane> State<T> {
    /// The factor's attitude–bias block after the transitions summed since the last flush,
    /// `B − M·D` (`D` upper triangular: 18 products): what a flush writes there, and what the
    /// report reads.
    pub(super) fn transitioned_block(&self) -> Mat<T, 3, 3> {
        transitioned(&self.factor, &self.transition_sum)
    }

    /// Applies the time update accumulated since the last flush ([`SqrtEskf::time_update`])
    /// in the lanes `lanes` (the others keep theirs, bit for bit): `B ← B − M·D`, then the
    /// attitude noise folded in, and in the lanes of `bias` also the bias noise `q_b` (rad/s)
    /// on `δb`; the sums start again.
    pub(super) fn fold_pending(&mut self, lanes: T::Mask, bias: Option<(T::Mask, T)>) {
        let noise = self.noise_std();
        // Every lane, and the bias noise in all or none of them (a scalar filter's only
        // cases): folded in place, without the copies and selects the mixed cases need (the
        // smoother's 9D passes flush at every sample).
        if lanes.all() && bias.is_none_or(|(due, _)| due.all()) {
            apply_transition(&mut self.factor, &self.transition_sum);
            add_noise(&mut self.factor, noise, bias.map(|(_, qb)| qb));
        } else {
            let mut flushed = self.factor;
            apply_transition(&mut flushed, &self.transition_sum);
            match bias {
                Some((due, qb)) => {
                    let mut all = flushed;
                    add_noise(&mut all, noise, Some(qb));
                    add_noise(&mut flushed, noise, None);
                    flushed = Mat::select(due, &all, &flushed);
                }
                None => add_noise(&mut flushed, noise, None),
            }
            self.factor = Mat::select(lanes, &flushed, &self.factor);
        }
        self.clear_pending(lanes);
    }

    /// The sums of the deferred time update started again in the lanes `lanes` (after a
    /// flush, or where the factor itself starts again).
    pub(super) fn clear_pending(&mut self, lanes: T::Mask) {
        let zero = T::zero();
        if lanes.all() {
            self.transition_sum = Mat::zeros();
            self.tilt_noise_var = zero;
            self.yaw_noise_var = zero;
        } else {
            self.transition_sum = Mat::select(lanes, &Mat::zeros(), &self.transition_sum);
            self.tilt_noise_var = T::select(lanes, zero, self.tilt_noise_var);
            self.yaw_noise_var = T::select(lanes, zero, self.yaw_noise_var);
        }
    }

    /// The pending attitude-noise standard deviations, `(tilt, yaw)` (rad).
    fn noise_std(&self) -> (T, T) {
        (self.tilt_noise_var.sqrt(), self.yaw_noise_var.sqrt())
    }
}

/// `B ← B − M·D` in the factor `s` ([`transitioned`]: each entry reads only itself and `D`).
fn apply_transition<T: Lane>(s: &mut Mat<T, 6, 6>, m: &Mat<T, 3, 3>) {
    let b = transitioned(s, m);
    for i in 0..3 {
        for j in 3..6 {
            s.m[i][j] = b.m[i][j - 3];
        }
    }
}

/// The attitude noise `(tilt, yaw)` std (rad), and the bias std `qb` (rad/s) where given,
/// folded into the factor `s`.
fn add_noise<T: Lane>(s: &mut Mat<T, 6, 6>, (qxy, qz): (T, T), qb: Option<T>) {
    match qb {
        Some(qb) => add_diagonal_noise(s, &[qxy, qxy, qz, qb, qb, qb]),
        None => add_diagonal_noise(s, &[qxy, qxy, qz]),
    }
}

/// The attitude–bias block `B − M·D` of the factor `s = [[A, B], [0, D]]` after the summed
/// transitions `m = M` (`D` upper triangular: 18 products).
fn transitioned<T: Lane>(s: &Mat<T, 6, 6>, m: &Mat<T, 3, 3>) -> Mat<T, 3, 3> {
    Mat::from_fn(|i, c| {
        let j = c + 3;
        let mut v = T::zero();
        for k in 3..=j {
            v += m.m[i][k - 3] * s.m[k][j];
        }
        s.m[i][j] - v
    })
}
