//! The flagship's coefficients that depend on a time step only, cached while it repeats:
//! per sample ([`PerDt`]), per inclination correction ([`PerInterval`]) and per 9D field
//! test ([`PerHeading`]).

use super::Coefficients;
use crate::blocks::lowpass_gain;
use rootfuse_lane::{Lane, Mask};

/// The coefficients that depend on the time step only, per lane, for the `dt` they were
/// computed for: with a constant `dt` (the usual case) they are computed once instead of
/// every sample (`exp`, `sqrt` and divisions). Bit for bit what the formulas give, so
/// caching changes no result; not part of the state, a lane that skips a sample needs no
/// restore.
#[derive(Clone, Copy, Debug)]
pub(super) struct PerDt<T: Lane> {
    /// The `dt` of the screened sample (zero where it is skipped), s.
    pub dt: T,
    /// `σ_θ·√dt` and `σ_b·√dt`: the process-noise standard deviations per step.
    pub gyr_std: T,
    pub bias_std: T,
    /// Per-sample measurement variances from the noise densities, `density²/dt` (`dt = 0`,
    /// a skipped sample, divides by 1: finite, and discarded).
    pub r_acc: T,
    pub r_rest: T,
    /// Low-pass gains `1 − exp(−dt/τ)` of the rest detection and the accelerometer
    /// low-pass after the start-up (each stage τ/2).
    pub k_rest: T,
    pub k_acc: T,
    /// The long window's low-pass gain (each stage `tau_acc_long/2`) and its motion
    /// measures' gain (`window_tau`).
    pub k_acc_long: T,
    pub k_window: T,
}

impl<T: Lane> PerDt<T> {
    pub(super) fn new(c: &Coefficients<T>) -> Self {
        Self::compute(T::zero(), c)
    }

    fn compute(dt: T, c: &Coefficients<T>) -> Self {
        let sdt = dt.sqrt();
        let per_sample = T::select(dt.simd_gt(T::zero()), dt, T::one());
        // The long window's gains only where some lane runs it (a jittered `dt` recomputes
        // every gain at every sample).
        let two_windows = c.tau_acc_long.simd_gt(T::zero()).any();
        Self {
            dt,
            gyr_std: c.gyr_noise * sdt,
            bias_std: c.bias_walk * sdt,
            r_acc: c.acc_var / per_sample,
            r_rest: c.rest_var / per_sample,
            k_rest: lowpass_gain(dt, c.rest_tau),
            k_acc: lowpass_gain(dt, c.tau_acc * T::from_f64(0.5)),
            k_acc_long: if two_windows {
                lowpass_gain(dt, c.tau_acc_long * T::from_f64(0.5))
            } else {
                T::zero()
            },
            k_window: if two_windows {
                lowpass_gain(dt, c.window_tau)
            } else {
                T::zero()
            },
        }
    }

    /// Recomputes every lane when any lane's `dt` differs from the cached one.
    #[inline]
    pub(super) fn refresh(&mut self, dt: T, c: &Coefficients<T>) {
        if dt.simd_ne(self.dt).any() {
            *self = Self::compute(dt, c);
        }
    }
}

/// The coefficients of one inclination correction, for the time its measurement stands for:
/// the usable accelerometer time since the previous correction (`acc_update_every` samples,
/// `dt` where every sample is corrected, so that the formulas are [`PerDt`]'s). Cached like
/// [`PerDt`] while that time repeats (with a constant `dt` it does: the same sum in the same
/// order); bit for bit what the formulas give.
#[derive(Clone, Copy, Debug)]
pub(super) struct PerInterval<T: Lane> {
    /// The time the coefficients are for, s.
    pub time: T,
    /// The measurement variance of the low-passed inclination, `acc_noise²/time`: the
    /// information of all the samples the correction stands for.
    pub r_acc: T,
    /// Gains `1 − exp(−time/τ)` of the running means a correction updates: the normalised
    /// squared innovation (`acc_adapt_window`), the innovation's mean square
    /// (`model_error_window`) and the bias-step detector's mean (`bias_step_window`).
    pub k_adapt: T,
    pub k_model: T,
    pub k_bias_step: T,
}

impl<T: Lane> PerInterval<T> {
    pub(super) fn new(c: &Coefficients<T>) -> Self {
        Self::compute(T::zero(), c)
    }

    fn compute(time: T, c: &Coefficients<T>) -> Self {
        let per_time = T::select(time.simd_gt(T::zero()), time, T::one());
        Self {
            time,
            r_acc: c.acc_var / per_time,
            k_adapt: lowpass_gain(time, c.acc_adapt_window),
            k_model: lowpass_gain(time, c.model_error_window),
            // Only where some lane detects bias steps (off by default).
            k_bias_step: if c.bias_step_threshold.simd_gt(T::zero()).any() {
                lowpass_gain(time, c.bias_step_window)
            } else {
                T::zero()
            },
        }
    }

    /// Recomputes every lane when any lane's time differs from the cached one.
    #[inline]
    pub(super) fn refresh(&mut self, time: T, c: &Coefficients<T>) {
        if time.simd_ne(self.time).any() {
            *self = Self::compute(time, c);
        }
    }
}

/// The coefficients of one 9D field test and heading correction, for the usable magnetometer
/// time since the previous one (`mag_update_every` readings; `dt` where every reading is
/// tested, so that the formulas are those of a sample). Cached like [`PerDt`] while that time
/// repeats; bit for bit what the formulas give.
#[derive(Clone, Copy, Debug)]
pub(super) struct PerHeading<T: Lane> {
    /// The time the coefficients are for, s.
    pub time: T,
    /// The heading measurement variance, `mag_noise²/time`.
    pub r_mag: T,
    /// Gains `1 − exp(−time/τ)` of the field reference and candidate (`mag_ref_tau`), the
    /// field low-pass (`mag_lowpass_tau`), the reference azimuth's decay (`mag_azimuth_tau`)
    /// and the heading innovation's mean square (`model_error_window`).
    pub k_ref: T,
    pub k_mag: T,
    pub k_azimuth: T,
    pub k_model: T,
}

impl<T: Lane> PerHeading<T> {
    pub(super) fn new(c: &Coefficients<T>) -> Self {
        Self::compute(T::zero(), c)
    }

    fn compute(time: T, c: &Coefficients<T>) -> Self {
        let per_time = T::select(time.simd_gt(T::zero()), time, T::one());
        Self {
            time,
            r_mag: c.mag_var / per_time,
            k_ref: lowpass_gain(time, c.mag_ref_tau),
            k_mag: lowpass_gain(time, c.mag_lowpass_tau),
            k_azimuth: lowpass_gain(time, c.mag_azimuth_tau),
            k_model: lowpass_gain(time, c.model_error_window),
        }
    }

    /// Recomputes every lane when any lane's time differs from the cached one.
    #[inline]
    pub(super) fn refresh(&mut self, time: T, c: &Coefficients<T>) {
        if time.simd_ne(self.time).any() {
            *self = Self::compute(time, c);
        }
    }
}
