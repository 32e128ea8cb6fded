//! The flagship's parameters converted to its own precision, per lane, once at construction
//! ([`Coefficients`]), and the covariance factor they start from.

use super::*;

lane_state! {
    /// The parameters in the filter's precision, converted once at construction (per lane:
    /// lanes may run with different parameters). Names follow [`SqrtEskfParams`]; `*_var` are
    /// squared densities, `*2` squared thresholds.
    pub(super) struct Coefficients<T: Lane> {
        pub(super) gyr_noise: T,
        pub(super) bias_walk: T,
        pub(super) bias_noise_every: T,
        pub(super) acc_update_every: T,
        pub(super) mag_update_every: T,
        pub(super) rest_update_every: T,
        pub(super) tau_acc: T,
        pub(super) tau_acc_long: T,
        pub(super) window_ratio: T,
        pub(super) acc_noise_rotation_share: T,
        pub(super) acc_var: T,
        pub(super) acc_gate: T,
        pub(super) model_error_scale: T,
        pub(super) model_error_rotation_scale: T,
        pub(super) model_error_ratio: T,
        pub(super) heading_model_error_scale: T,
        pub(super) gyr_scale_error: T,
        pub(super) gyr_scale_window: T,
        /// The scale estimate's prior on the axes' differences from their mean, rad²
        /// (`gyr_scale_axis_ridge` in 6D, `gyr_scale_ridge` in 9D), and the part added to
        /// every entry, `(gyr_scale_ridge − that)/3`: together `λ_d·I + (λ_c − λ_d)/3·11ᵀ`.
        pub(super) gyr_scale_axis_ridge: T,
        pub(super) gyr_scale_common: T,
        /// `gyr_scale_gate²`, rad².
        pub(super) gyr_scale_gate2: T,
        pub(super) acc_excess_scale: T,
        /// `acc_spike²`, (m/s²)².
        pub(super) acc_spike2: T,
        pub(super) acc_reject_time: T,
        /// `startup_time`, at least 1 µs (it divides).
        pub(super) startup_time: T,
        pub(super) reacquire_std: T,
        pub(super) rest_gyr2: T,
        pub(super) rest_acc2: T,
        pub(super) rest_time: T,
        pub(super) rest_var: T,
        pub(super) init_bias_std: T,
        pub(super) init_tilt_std: T,
        pub(super) init_heading_std: T,
        /// `acc_noise²/(2·bias_step_window)·bias_step_gate²`: the squared norm of the running
        /// innovation mean beyond which a bias step is declared (0: never).
        pub(super) bias_step_threshold: T,
        pub(super) heading_walk_var: T,
        pub(super) heading_rate_var: T,
        pub(super) heading_up_rate_var: T,
        pub(super) mag_var: T,
        pub(super) mag_norm_th: T,
        pub(super) mag_dip_th: T,
        pub(super) mag_settle_time: T,
        pub(super) adopted_field_error_scale: T,
        pub(super) mag_new_time: T,
        pub(super) mag_reject_time: T,
        pub(super) mag_home_time: T,
        /// The rates `1/τ` (1/s) of the low-pass gains ([`lowpass_gains_at_rates`]: a
        /// multiplication per gain at a jittered `dt`, no division): `rest_tau`, each stage
        /// of the `tau_acc` and `tau_acc_long` windows (`2/τ`), `window_tau`,
        /// `acc_adapt_window`, `model_error_window`, `bias_step_window`, `mag_ref_tau`,
        /// `mag_lowpass_tau` and `mag_azimuth_tau` (a time constant of 0 is a rate of `∞`).
        pub(super) rest_rate: T,
        pub(super) acc_stage_rate: T,
        pub(super) acc_long_stage_rate: T,
        pub(super) window_rate: T,
        pub(super) adapt_rate: T,
        pub(super) model_error_rate: T,
        pub(super) bias_step_rate: T,
        pub(super) mag_ref_rate: T,
        pub(super) mag_lowpass_rate: T,
        pub(super) mag_azimuth_rate: T,
    }
}

impl<T: Lane> Coefficients<T> {
    pub(super) fn new(p: &LaneParams<'_, SqrtEskfParams, T>) -> Self {
        Self {
            gyr_noise: p.coef(|p| p.gyr_noise),
            bias_walk: p.coef(|p| p.bias_walk),
            bias_noise_every: p.coef(|p| p.bias_noise_every),
            acc_update_every: p.coef(|p| p.acc_update_every),
            mag_update_every: p.coef(|p| p.mag_update_every),
            rest_update_every: p.coef(|p| p.rest_update_every),
            tau_acc: p.coef(|p| p.tau_acc),
            tau_acc_long: p.coef(|p| p.tau_acc_long),
            window_ratio: p.coef(|p| p.window_ratio),
            acc_noise_rotation_share: p.coef(|p| p.acc_noise_rotation_share),
            acc_var: p.coef(|p| p.acc_noise * p.acc_noise),
            acc_gate: p.coef(|p| p.acc_gate),
            model_error_scale: p.coef(|p| p.model_error_scale),
            model_error_rotation_scale: p.coef(|p| p.model_error_rotation_scale),
            model_error_ratio: p.coef(|p| p.model_error_ratio),
            heading_model_error_scale: p.coef(|p| p.heading_model_error_scale),
            gyr_scale_error: p.coef(|p| p.gyr_scale_error),
            gyr_scale_window: p.coef(|p| p.gyr_scale_window),
            gyr_scale_axis_ridge: p.coef(|p| gyr_scale_prior(p).1),
            gyr_scale_common: p.coef(|p| (p.gyr_scale_ridge - gyr_scale_prior(p).1) / 3.0),
            gyr_scale_gate2: p.coef(|p| p.gyr_scale_gate * p.gyr_scale_gate),
            acc_excess_scale: p.coef(|p| p.acc_excess_scale),
            acc_spike2: p.coef(|p| p.acc_spike * p.acc_spike),
            acc_reject_time: p.coef(|p| p.acc_reject_time),
            startup_time: p.coef(|p| p.startup_time.max(1e-6)),
            reacquire_std: p.coef(|p| p.reacquire_std),
            rest_gyr2: p.coef(|p| p.rest_gyr * p.rest_gyr),
            rest_acc2: p.coef(|p| p.rest_acc * p.rest_acc),
            rest_time: p.coef(|p| p.rest_time),
            rest_var: p.coef(|p| p.rest_noise * p.rest_noise),
            init_bias_std: p.coef(|p| p.init_bias_std),
            init_tilt_std: p.coef(|p| p.init_tilt_std),
            init_heading_std: p.coef(|p| p.init_heading_std),
            bias_step_threshold: p.coef(|p| {
                // White innovation of density acc_noise² averaged with time constant T has
                // variance acc_noise²/(2T) per axis.
                p.acc_noise * p.acc_noise / (2.0 * p.bias_step_window)
                    * p.bias_step_gate
                    * p.bias_step_gate
            }),
            heading_walk_var: p.coef(|p| p.heading_walk * p.heading_walk),
            heading_rate_var: p.coef(|p| p.heading_rate_noise * p.heading_rate_noise),
            heading_up_rate_var: p.coef(|p| p.heading_up_rate_noise * p.heading_up_rate_noise),
            mag_var: p.coef(|p| p.mag_noise * p.mag_noise),
            mag_norm_th: p.coef(|p| p.mag_norm_th),
            mag_dip_th: p.coef(|p| p.mag_dip_th),
            mag_settle_time: p.coef(|p| p.mag_settle_time),
            adopted_field_error_scale: p.coef(|p| p.adopted_field_error_scale),
            mag_new_time: p.coef(|p| p.mag_new_time),
            mag_reject_time: p.coef(|p| p.mag_reject_time),
            mag_home_time: p.coef(|p| p.mag_home_time),
            rest_rate: p.coef(|p| 1.0 / p.rest_tau),
            acc_stage_rate: p.coef(|p| 2.0 / p.tau_acc),
            acc_long_stage_rate: p.coef(|p| 2.0 / p.tau_acc_long),
            window_rate: p.coef(|p| 1.0 / p.window_tau),
            adapt_rate: p.coef(|p| 1.0 / p.acc_adapt_window),
            model_error_rate: p.coef(|p| 1.0 / p.model_error_window),
            bias_step_rate: p.coef(|p| 1.0 / p.bias_step_window),
            mag_ref_rate: p.coef(|p| 1.0 / p.mag_ref_tau),
            mag_lowpass_rate: p.coef(|p| 1.0 / p.mag_lowpass_tau),
            mag_azimuth_rate: p.coef(|p| 1.0 / p.mag_azimuth_tau),
        }
    }

    /// The covariance factor right after initialisation.
    pub(super) fn initial_factor(&self) -> Mat<T, 6, 6> {
        let mut s = Mat::zeros();
        s.m[0][0] = self.init_tilt_std;
        s.m[1][1] = self.init_tilt_std;
        // The 6D heading error is unobservable: its variance bookkeeps the drift from the
        // start.
        s.m[2][2] = self.init_heading_std;
        for i in 3..6 {
            s.m[i][i] = self.init_bias_std;
        }
        s
    }
}

/// The scale estimate's prior on the axes' mean and on their differences from it, rad²:
/// `(gyr_scale_ridge, gyr_scale_axis_ridge)`, the second equal to the first in 9D, where the
/// field corrects the heading the axis about up would drift (each axis on its own), and at
/// most `MAX_AXIS_RIDGE_RATIO` times it in 6D.
fn gyr_scale_prior(p: &SqrtEskfParams) -> (f64, f64) {
    let mean = p.gyr_scale_ridge;
    if p.dof.uses_magnetometer() {
        (mean, mean)
    } else {
        (
            mean,
            p.gyr_scale_axis_ridge.min(MAX_AXIS_RIDGE_RATIO * mean),
        )
    }
}

/// Largest ratio of the prior on the axes' differences to the prior on their mean: beyond it
/// the mean's own prior, `λ_d + 3·(λ_c − λ_d)/3`, is lost to `f32`'s rounding of the matrix's
/// entries (a ratio of 10⁴ leaves it 10⁻⁴ of them, a thousand times `f32`'s epsilon).
const MAX_AXIS_RIDGE_RATIO: f64 = 1e4;
