//! The flagship's coefficients that depend on one time only, cached while it repeats
//! ([`Cached`]): per sample ([`PerDt`]), per inclination correction ([`PerInterval`]) and
//! per 9D field test ([`PerHeading`]).

use super::Coefficients;
use super::lowpass_gains_at_rates;
use core::ops::Deref;
use rootfuse_lane::{Lane, Mask};

/// Coefficients that are a function of one time (s) and the parameters.
pub(super) trait ForTime<T: Lane>: Copy {
    /// The coefficients for `time` (zero where a lane skips: finite, and discarded).
    fn compute(time: T, c: &Coefficients<T>) -> Self;
}

/// Coefficients `V`, per lane, for the time they were computed for: with a constant `dt`
/// (the usual case) they are computed once instead of every sample (`exp`, `sqrt` and
/// divisions). Bit for bit what the formulas give, so caching changes no result; not part
/// of the state, a lane that skips a sample needs no restore.
#[derive(Clone, Copy, Debug)]
pub(super) struct Cached<T: Lane, V> {
    /// The time the coefficients are for, s.
    pub time: T,
    values: V,
}

impl<T: Lane, V: ForTime<T>> Cached<T, V> {
    pub(super) fn new(c: &Coefficients<T>) -> Self {
        Self {
            time: T::zero(),
            values: V::compute(T::zero(), c),
        }
    }

    /// Recomputes every lane when any lane's time differs from the cached one.
    #[inline]
    pub(super) fn refresh(&mut self, time: T, c: &Coefficients<T>) {
        if time.simd_ne(self.time).any() {
            *self = Self {
                time,
                values: V::compute(time, c),
            };
        }
    }
}

impl<T: Lane, V> Deref for Cached<T, V> {
    type Target = V;
    fn deref(&self) -> &V {
        &self.values
    }
}

/// `time` where it is positive, else 1: the divisor of a variance from a density (a skipped
/// sample divides by 1: finite, and discarded).
pub(super) fn divisor<T: Lane>(time: T) -> T {
    T::select(time.simd_gt(T::zero()), time, T::one())
}

/// The coefficients of one sample's time step `dt`.
#[derive(Clone, Copy, Debug)]
pub(super) struct PerDt<T: Lane> {
    /// `σ_θ·√dt` and `σ_b·√dt`: the process-noise standard deviations per step.
    pub gyr_std: T,
    pub bias_std: T,
    /// Per-sample measurement variance from the noise density, `acc_noise²/dt`.
    pub r_acc: T,
    /// Low-pass gains `1 − exp(−dt/τ)` of the rest detection and the accelerometer
    /// low-pass after the start-up (each stage τ/2).
    pub k_rest: T,
    pub k_acc: T,
    /// The long window's low-pass gain (each stage `tau_acc_long/2`) and its motion
    /// measures' gain (`window_tau`).
    pub k_acc_long: T,
    pub k_window: T,
}

impl<T: Lane> ForTime<T> for PerDt<T> {
    #[inline]
    fn compute(dt: T, c: &Coefficients<T>) -> Self {
        let sdt = dt.sqrt();
        let per_sample = divisor(dt);
        // The long window's gains only where some lane runs it (a jittered `dt` recomputes
        // every gain at every sample).
        let two_windows = c.tau_acc_long.simd_gt(T::zero()).any();
        let [k_rest, k_acc, k_acc_long, k_window] = if two_windows {
            lowpass_gains_at_rates(
                dt,
                [
                    c.rest_rate,
                    c.acc_stage_rate,
                    c.acc_long_stage_rate,
                    c.window_rate,
                ],
            )
        } else {
            let [k_rest, k_acc] = lowpass_gains_at_rates(dt, [c.rest_rate, c.acc_stage_rate]);
            [k_rest, k_acc, T::zero(), T::zero()]
        };
        Self {
            gyr_std: c.gyr_noise * sdt,
            bias_std: c.bias_walk * sdt,
            r_acc: c.acc_var / per_sample,
            k_rest,
            k_acc,
            k_acc_long,
            k_window,
        }
    }
}

/// The coefficients of one inclination correction, for the time its measurement stands for:
/// the usable accelerometer time since the previous correction (`acc_update_every` samples,
/// `dt` where every sample is corrected, so that the formulas are those of a sample; with a
/// constant `dt` the time repeats: the same sum in the same order).
#[derive(Clone, Copy, Debug)]
pub(super) struct PerInterval<T: Lane> {
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

impl<T: Lane> ForTime<T> for PerInterval<T> {
    #[inline]
    fn compute(time: T, c: &Coefficients<T>) -> Self {
        // The bias-step detector's gain only where some lane detects bias steps (off by
        // default).
        let [k_adapt, k_model, k_bias_step] = if c.bias_step_threshold.simd_gt(T::zero()).any() {
            lowpass_gains_at_rates(time, [c.adapt_rate, c.model_error_rate, c.bias_step_rate])
        } else {
            let [k_adapt, k_model] =
                lowpass_gains_at_rates(time, [c.adapt_rate, c.model_error_rate]);
            [k_adapt, k_model, T::zero()]
        };
        Self {
            r_acc: c.acc_var / divisor(time),
            k_adapt,
            k_model,
            k_bias_step,
        }
    }
}

/// The coefficients of one 9D field test and heading correction, for the usable magnetometer
/// time since the previous one (`mag_update_every` readings; `dt` where every reading is
/// tested, so that the formulas are those of a sample).
#[derive(Clone, Copy, Debug)]
pub(super) struct PerHeading<T: Lane> {
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

impl<T: Lane> ForTime<T> for PerHeading<T> {
    #[inline]
    fn compute(time: T, c: &Coefficients<T>) -> Self {
        let [k_ref, k_mag, k_azimuth, k_model] = lowpass_gains_at_rates(
            time,
            [
                c.mag_ref_rate,
                c.mag_lowpass_rate,
                c.mag_azimuth_rate,
                c.model_error_rate,
            ],
        );
        Self {
            r_mag: c.mag_var / divisor(time),
            k_ref,
            k_mag,
            k_azimuth,
            k_model,
        }
    }
}
