//! The flagship filter [`SqrtEskf`]: a square-root multiplicative error-state Kalman filter
//! with decoupled inclination and heading, rest detection, quasi-inertial accelerometer
//! low-pass, χ² gating and magnetic-disturbance rejection.
//!
//! # Structure (one state, 6D and 9D at once)
//!
//! The 6D orientation is `q6 = c ⊗ q_gyr`: `q_gyr` is pure strapdown integration of the
//! bias-corrected gyroscope (the *quasi-inertial* frame `I`, never corrected), `c` the
//! accumulated inclination correction (and whatever heading the bias correlation moves).
//! The 9D orientation is `q9 = qz(δ) ⊗ q6`: the magnetometer only ever moves the scalar
//! heading offset `δ` about earth-z, so a magnetic disturbance can neither tilt the estimate
//! nor corrupt the gyro bias, and the 6D estimate is exactly the 9D one minus its magnetic
//! heading correction (the split of Laidig & Seel 2023, "VQF: Highly accurate IMU
//! orientation estimation with bias estimation and magnetic disturbance rejection",
//! Information Fusion 91).
//!
//! # Error state and its square-root covariance
//!
//! The Kalman state is the 6-vector `x = [δθ, δb]`: `δθ` the attitude error of `q6` **in the
//! (6D) earth frame** (`q_true = Exp(δθ) ⊗ q6`, the "global" error of Solà 2017,
//! "Quaternion kinematics for the error-state Kalman filter", §7) and `δb = b_true − b̂` the
//! gyro-bias error in the sensor frame. The earth-frame error is chosen because it makes the
//! inclination/heading split exact: gravity observes `δθ_x, δθ_y` only, and the
//! error dynamics `δθ̇ = −R(q6)·δb` have an identity attitude block (no `[ω]×` term),
//! so the transition matrix is `F = [[I, −R·dt], [0, I]]`.
//!
//! The covariance is carried as an upper-triangular factor `P = S·Sᵀ` (`S` 6×6). The
//! transition is block upper triangular, so `F·S` is upper triangular again and only its
//! attitude–bias block changes; the time update then folds the diagonal process noise in by
//! Householder reflections from the right that each mix one column of `S` with the noise
//! columns that are non-zero in its row (the square-root time update of Kaminski, Bryson &
//! Schmidt 1971 restricted to what changed; Bierman 1977, "Factorization Methods for
//! Discrete Sequential Estimation", ch. V), so `P` never has to be formed. Measurements are
//! processed as sequential scalar updates by Carlson's triangular square-root form (Carlson
//! 1973; Bierman 1977, ch. V): with `f = Sᵀh` and `α_j = r + Σ_{k≤j} f_k²`,
//! `S ← S·W`, `W` upper triangular (`W_jj = √(α_{j−1}/α_j)`,
//! `W_ij = −f_i·f_j/√(α_{j−1}·α_j)`), `K = S·f/α_n` — Potter's form gives the same `P` and
//! `K` but fills the factor, which would cost a full re-triangularisation per time update.
//! Both steps are orthogonal transformations of, or products with, the factor, so
//! `P = S·Sᵀ` is symmetric and positive semidefinite by construction in f32 as well as f64
//! (Thornton 1976 compares these forms).
//! After each update the error is injected into `c` (`c ← Exp(δθ̂) ⊗ c`) and `b̂`, and reset to
//! zero (Solà 2017, §7.2; the reset Jacobian `I − [δθ̂/2]×` is taken as identity, its effect
//! being second order for the small corrections applied per sample).
//!
//! # Accelerometer: low-pass in the quasi-inertial frame, lag-aware measurement, χ² gate
//!
//! As in VQF, the specific force is rotated into the `I` frame (`q_gyr·a`) and low-passed
//! there (time constant `tau_acc`): in a frame that does not rotate with the body, linear
//! accelerations of bounded velocity average out while gravity stays put, so fast
//! translation cannot tilt the estimate. The low-pass is two equal first-order stages of
//! `τ/2` each (critically damped second order, like VQF's second-order Butterworth it falls
//! at −40 dB/decade, but its gain `1 − exp(−dt/(τ/2))` is exact for any `dt`); its mean
//! delay is still `τ`, which is all the lag model below uses. On BROAD the second stage
//! lowered the fast-translation trial's error (16: 0.78° → 0.74° 9D at the old tuning). The filtered vector is brought to the earth
//! frame by `c`; the rotation vector `ε` that turns it onto up is the measurement of the
//! horizontal components of `δθ`. Because the low-pass averages the past, `ε` lags: a bias
//! error makes `I` drift, and an exponential average of that drift equals
//! `δθ + τ·R̄·δb` with `R̄` the same low-pass of the sensor-to-earth rotation (derivation in
//! the code). This is put into `H`, so the bias is learned from inclination corrections
//! consistently rather than fighting the low-pass lag. The low-passed measurement noise is
//! correlated over `τ`; it is modelled as a continuous-time density (`r = acc_noise²/dt`),
//! which keeps the filter's time constants independent of the sample rate (and of per-sample
//! `dt`). A scalar innovation beyond `acc_gate` standard deviations is rejected (χ² test with
//! one degree of freedom); rejections lasting longer than `acc_reject_time` mean the model is
//! wrong (wrong start, long acceleration), so the inclination covariance is re-inflated and
//! the next measurement is accepted (re-acquisition).
//!
//! # Spikes: corrupted accelerometer samples within the screening limit
//!
//! The screening refuses a specific force beyond `max_acc`; below it, a corrupted sample (a
//! bit error, a glitch) would still enter the low-pass, and at 286 Hz with `τ` = 2 s one
//! sample of 1000 m/s² moves the first stage by 3.5 m/s², a tilt of the low-passed gravity by
//! degrees for seconds (before the limit and this gate, one `ax = 1e39` on BROAD 02 took the
//! RMSE from 1.25° to 94°). A sample whose specific force deviates from the
//! low-passed one (the gravity estimate, compared in the sensor frame) by more than
//! `acc_spike` (default 300 m/s², beyond anything a ±16 g accelerometer reports) is taken as
//! corrupted: it is gated (counted, flag 16) and enters neither the low-passes, nor the
//! rest detector, nor the bias-step detector, nor a correction. Real motion never reaches it
//! (the largest deviation in the 14 BROAD trials is about 170 m/s², on the tapping trial at
//! the sensor's ±16 g saturation), so clean data runs bit for bit as before.
//!
//! # Rest detection and gyro bias
//!
//! Rest is declared when, for at least `rest_time`, the gyro and accelerometer stay within
//! `rest_gyr` / `rest_acc` of their own low-pass (time constant `rest_tau`) — the deviation
//! test of VQF, plus the bias-corrected low-passed rate itself below `rest_gyr` (a slow
//! constant-rate turn has a small deviation too). At rest the low-passed gyro is a direct, strong measurement of the bias
//! (`H = [0, I]`) with noise density `rest_noise` = 4e-4 rad/s·√s: a few times the white
//! noise density of a MEMS gyro (BROAD's: 1e-4 rad/s·√s, measured at rest), the margin
//! covering the correlation the low-pass adds. After the initial rest of a recording the
//! bias is then known to about 0.005°/s, which is what keeps the 6D heading of BROAD 29
//! from drifting (a ten times weaker rest measurement costs 0.5° there); in motion the bias is learned only weakly through the lag-aware
//! accelerometer measurement above and the `−R·dt` coupling in `F`. Heading-axis bias
//! is therefore learned in motion only as the sensor rotates, as gravity allows.
//!
//! # Magnetometer: heading only, disturbance detection and re-acquisition
//!
//! The heading offset `δ` is a scalar Kalman filter (trivially square-root) with random-walk
//! density `heading_walk` and measurement noise density `mag_noise`. Its variance also grows
//! with what the 6D heading variance gains per step (gyro noise, earth-vertical bias
//! uncertainty) and by `(heading_rate_noise·|ω|)²·dt`: gyro scale-factor and misalignment
//! errors make the 6D heading drift in proportion to the rotation, and the offset has to
//! absorb that drift (without this term BROAD 29 9D rises from 2.0° to 2.7°: after a
//! disturbance the magnetometer is trusted too little to pull the heading back). The field norm and dip
//! (angle below the horizontal in the 6D earth frame, independent of heading) are compared
//! with a learned reference; outside `mag_norm_th` (relative) or `mag_dip_th` the sample is
//! rejected. A candidate field is tracked all the time; when rejection has lasted
//! `mag_reject_time`, or the candidate has been stable for `mag_new_time`, the candidate
//! becomes the reference (a new homogeneous field, e.g. another room).
//!
//! # Gyro-bias steps and the start without accelerometer
//!
//! A bias step makes the strapdown frame drift, and the inclination corrections then chase a
//! persistent, one-signed innovation. The running mean of the two horizontal innovations
//! (time constant `bias_step_window`) is compared with the `acc_noise²/(2·window)` per axis
//! that white innovations leave in it; beyond `bias_step_gate` standard deviations the next
//! time update re-inflates the bias covariance by `init_bias_std`, so the lag-aware
//! measurement can learn the new bias faster than at the random-walk rate. It is **off by
//! default** (`bias_step_gate = 0`): on a simulated 0.02 rad/s step, gate 6 detects it and the
//! bias error settles below 0.002 rad/s 26 s after the step (not within 30 s without), yet
//! the attitude after the step is worse (9D 8.9° against 4.9°) as the re-inflated bias swings;
//! on the BROAD trials gate 6 fires in real motion and raises the 9D mean from 2.20° to 2.70°
//! (gate 5: 15.9°, the re-inflated bias absorbs motion), and gate 8 never fires on either.
//!
//! Before the first usable accelerometer sample the gyroscope is integrated (flags:
//! accelerometer skipped); that sample sets the inclination and keeps the integrated heading.
//!
//! # Status on the 14 shared BROAD trials (defaults, RMSE in degrees, f64 = f32 to 0.013°)
//!
//! | | 9D total | 6D total | inclination |
//! |---|---|---|---|
//! | ours, mean | 2.20 (better than VQF on 9 of 14) | 2.40 (7 of 14) | 0.794 (4 of 14) |
//! | VQF online, mean | 2.21 | 2.41 | 0.724 |
//! | ours offline (`smooth::forward_backward`) | 1.72 | 2.35 | 0.62 |
//! | VQF offline | 1.96 | | 0.53 |
//!
//! A tie with VQF online, not the lead the old four trials suggested (the defaults were tuned
//! on 02, 07, 16, 29). Leave-one-trial-out cross-validation over 384 candidate sets
//! (`examples/flagship_cv.rs`, `docs/accuracy.md`) found none better out of sample, so the
//! defaults stay. Inclination loses on the translation and vibration trials (10, 12, 27:
//! 0.49 / 0.43 / 0.60 against 0.30 / 0.25 / 0.37) because `tau_acc` = 2 s is short for them;
//! about 4 s brings them below VQF but costs the fast rotations with breaks (08: 1.60 → 2.1).
//!
//! # Lanes
//!
//! Every branch is computed in every lane and selected by mask; the shared [`Screened`]
//! input screening skips whole samples (bad gyro or `dt`) or single corrections (bad
//! accelerometer or magnetometer) per lane, so NaN, ∞, zero vectors or a bad `dt` in one lane
//! never touch the others. Nothing is allocated.

// The factor kernels index several arrays with the same row/column numbers (as the
// formulas are written); iterator chains would hide that.
#![allow(clippy::needless_range_loop)]

use super::upper_factor::{add_diagonal_noise, carlson_update};
use super::{
    Dof, LaneParams, OrientationFilter, Rejections, ScreenLimits, Screened, lane_state, params,
};
use crate::blocks::{field_heading_error, lowpass_gain, magnetic_heading_error, tilt_from_acc};
use crate::{ImuSample, Quat, Vec3};
use rootfuse_lane::{Lane, Mask, Mat, Select};

// The per-sample steps and `OrientationFilter::update`.
mod update;
// Reset, and the orientation and bias set with their uncertainty.
mod set_state;

params! {
    /// Parameters of [`SqrtEskf`]. One set for all recordings.
    pub struct SqrtEskfParams {
        /// Attitude random-walk density driving `δθ` (gyro noise plus unmodelled errors).
        gyr_noise: f64 = 0.005, "rad/√s", [1e-9, 10.0];
        /// Gyro-bias random-walk density.
        bias_walk: f64 = 1e-5, "rad/s/√s", [0.0, 10.0];
        /// Time constant of the accelerometer low-pass in the quasi-inertial frame.
        tau_acc: f64 = 2.0, "s", [0.0, 100.0];
        /// Noise density of the low-passed inclination measurement (`r = acc_noise²/dt`).
        acc_noise: f64 = 0.003, "rad·√s", [1e-9, 10.0];
        /// χ² gate of each scalar inclination innovation, in standard deviations.
        acc_gate: f64 = 6.0, "1", [0.0, 1e6];
        /// Time constant of the running mean of the normalised squared inclination
        /// innovation (innovation² over its predicted variance with `acc_noise`), whose excess
        /// over 1 scales the inclination measurement variance (covariance matching, capped at
        /// 1000×): motion accelerations the low-pass leaves in are then weighted as the noise
        /// they are. 0 disables. On the 14 shared BROAD trials the innovations never exceed
        /// their prediction and every estimate is bit for bit that of 0; on the simulated
        /// pendulum (6D, 5 seeds) the inclination falls from 1.17° to 0.89° (`docs/accuracy.md`).
        acc_adapt_window: f64 = 0.3, "s", [0.0, 1e6];
        /// The reported attitude covariance adds, on both inclination axes, this multiple of
        /// the running mean square of the inclination innovation (rad²): the error the motion
        /// acceleration leaves in the low-passed gravity, which `P` does not model (its
        /// noise is white, the error is not). Only the report changes (and with it the
        /// smoother's weights); the forward estimates are bit for bit those of 0, which
        /// reports `P` alone. 2 holds the 95 % coverage on the simulated pendulum and
        /// translation scenarios (`docs/accuracy.md`).
        model_error_scale: f64 = 2.0, "1", [0.0, 1e3];
        /// Time constant of that running mean square, s.
        model_error_window: f64 = 1.0, "s", [0.0, 1e6];
        /// Largest deviation of the specific force from its low-pass (the gravity estimate)
        /// that is taken as motion. A sample further off is a spike, not an acceleration the
        /// body made (its velocity change in one sample would be absurd): it is gated (counted
        /// in `gated`, flag 16) and enters neither the low-pass, nor the rest detector, nor
        /// the bias. The default is above anything a ±16 g accelerometer can report
        /// (157 m/s² per axis, 272 m/s² on three saturated axes, plus gravity).
        acc_spike: f64 = 300.0, "m/s²", [1.0, 1e12];
        /// After this long with every inclination measurement gated, re-inflate and accept.
        acc_reject_time: f64 = 2.0, "s", [0.0, 1e6];
        /// Length of the start-up phase (low-pass time constant ramping up, no gate).
        startup_time: f64 = 3.0, "s", [0.0, 100.0];
        /// Standard deviation the inclination error is re-inflated to on re-acquisition.
        reacquire_std: f64 = 0.5, "rad", [1e-6, 10.0];
        /// Time constant of the low-pass used by rest detection.
        rest_tau: f64 = 0.5, "s", [1e-3, 100.0];
        /// Largest gyro deviation from its low-pass, and largest bias-corrected low-passed
        /// rate, at rest.
        rest_gyr: f64 = 0.035, "rad/s", [0.0, 10.0];
        /// Largest accelerometer deviation from its low-pass at rest.
        rest_acc: f64 = 0.5, "m/s²", [0.0, 100.0];
        /// Minimum duration of a rest before it is declared.
        rest_time: f64 = 1.5, "s", [0.0, 100.0];
        /// Noise density of the at-rest bias measurement (`r = rest_noise²/dt`).
        rest_noise: f64 = 0.0004, "rad/s·√s", [1e-9, 10.0];
        /// Initial standard deviation of each gyro-bias component (also what the bias
        /// covariance is re-inflated by on a detected bias step or a re-acquisition).
        init_bias_std: f64 = 0.01, "rad/s", [1e-9, 10.0];
        /// Time constant of the running mean of the inclination innovation that detects a
        /// gyro-bias step.
        bias_step_window: f64 = 2.0, "s", [1e-3, 100.0];
        /// A running innovation mean beyond this many of its standard deviations (2 degrees
        /// of freedom) is a gyro-bias step: the bias covariance is re-inflated. 0 (the
        /// default) disables: on BROAD every gate that detects a simulated 0.02 rad/s step
        /// (≤ 6) also fires in real motion and costs accuracy (see `docs/accuracy.md`).
        bias_step_gate: f64 = 0.0, "1", [0.0, 1e6];
        /// Initial standard deviation of the inclination error after the first sample.
        init_tilt_std: f64 = 0.05, "rad", [1e-9, 10.0];
        /// Random-walk density of the 9D heading offset beyond the 6D heading drift
        /// (magnetic model errors).
        heading_walk: f64 = 0.0005, "rad/√s", [1e-9, 10.0];
        /// Rate-proportional random-walk density of the 9D heading offset (gyro scale-factor
        /// and misalignment errors make the 6D heading drift in proportion to the rotation):
        /// the offset's variance grows by `(heading_rate_noise·|ω|)²·dt`.
        heading_rate_noise: f64 = 0.001, "√s", [0.0, 10.0];
        /// Noise density of the magnetic heading measurement (`r = mag_noise²/dt`).
        mag_noise: f64 = 0.13, "rad·√s", [1e-9, 10.0];
        /// Largest relative deviation of the field norm from the reference.
        mag_norm_th: f64 = 0.05, "1", [0.0, 10.0];
        /// Largest deviation of the field dip from the reference.
        mag_dip_th: f64 = 0.1, "rad", [0.0, 4.0];
        /// Time constant with which the field reference and candidate are learned.
        mag_ref_tau: f64 = 10.0, "s", [1e-3, 1e6];
        /// A stable candidate field becomes the reference after this long.
        mag_new_time: f64 = 20.0, "s", [0.0, 1e6];
        /// Rejection lasting this long makes the (stable) candidate the reference.
        mag_reject_time: f64 = 60.0, "s", [0.0, 1e6];
        /// 9: use the magnetometer; 6: gravity only.
        dof: Dof = 9.0, "1", [6.0, 9.0];
    }
}

lane_state! {
    /// Per-lane state of the magnetic-field reference (norm in input units, dip in rad).
    struct FieldReference<T: Lane> {
        norm: T,
        dip: T,
        /// Candidate field and how long (s) it has been stable.
        candidate_norm: T,
        candidate_dip: T,
        candidate_time: T,
        /// How long (s) the field has been rejected without interruption.
        rejected_time: T,
    }
}

lane_state! {
    /// Everything a sample changes; a lane that skips a sample keeps all of it.
    struct State<T: Lane> {
        /// Strapdown integration of the bias-corrected gyro: sensor to the quasi-inertial
        /// frame `I`, never corrected.
        strapdown: Quat<T>,
        /// Earth-frame correction `c` of the strapdown orientation: `q6 = c ⊗ strapdown`.
        correction: Quat<T>,
        /// Heading offset `δ` (rad) that the magnetometer adds: `q9 = qz(δ) ⊗ q6`.
        heading_offset: T,
        /// Variance of `δ`, rad².
        heading_offset_var: T,
        /// Gyro-bias estimate, rad/s, sensor frame.
        bias: Vec3<T>,
        /// Covariance factor `S` of `[δθ, δb]`: `P = S·Sᵀ`.
        factor: Mat<T, 6, 6>,
        /// Low-passed specific force in the `I` frame, m/s².
        acc_lp: Vec3<T>,
        /// First stage of the two-stage low-pass.
        acc_lp1: Vec3<T>,
        rot_lp1: Mat<T, 3, 3>,
        /// Low-passed sensor-to-`I` rotation matrix (for the lag term of `H`).
        rot_lp: Mat<T, 3, 3>,
        /// Rest detection: low-passed gyro (rad/s) and accelerometer (m/s², sensor frame).
        rest_gyr_lp: Vec3<T>,
        rest_acc_lp: Vec3<T>,
        /// How long (s) the rest conditions have held.
        rest_timer: T,
        /// How long (s) every inclination measurement has been gated.
        acc_rejected_time: T,
        /// Running mean (time constant `bias_step_window`) of the two horizontal inclination
        /// innovations before correction, rad.
        innovation_mean_x: T,
        innovation_mean_y: T,
        /// Running mean of the normalised squared inclination innovation (1 when the model
        /// holds; see `acc_adapt_window`).
        innovation_nis: T,
        /// Running mean square of the inclination innovation (rad², per axis), time constant
        /// `model_error_window`: the model error the covariance reports beside `P`.
        innovation_ms: T,
        /// A gyro-bias step was detected by the last sample: the next time update re-inflates
        /// the bias covariance.
        bias_step: T::Mask,
        /// Time since initialisation, s.
        age: T,
        field: FieldReference<T>,
        initialized: T::Mask,
        /// The orientation was set ([`OrientationFilter::set_quat`]) before the first sample:
        /// start from it rather than from the accelerometer.
        preset: T::Mask,
        /// The attitude covariance came with the preset orientation
        /// (`set_quat` with a `sigma`): the first sample keeps it.
        preset_covariance: T::Mask,
        mag_disturbed: T::Mask,
    }
}

lane_state! {
    /// The parameters in the filter's precision, converted once at construction (per lane:
    /// lanes may run with different parameters). Names follow [`SqrtEskfParams`]; `*_var` are
    /// squared densities, `*2` squared thresholds.
    struct Coefficients<T: Lane> {
        gyr_noise: T,
        bias_walk: T,
        tau_acc: T,
        acc_var: T,
        acc_gate: T,
        acc_adapt_window: T,
        model_error_scale: T,
        model_error_window: T,
        /// `acc_spike²`, (m/s²)².
        acc_spike2: T,
        acc_reject_time: T,
        /// `startup_time`, at least 1 µs (it divides).
        startup_time: T,
        reacquire_std: T,
        rest_tau: T,
        rest_gyr2: T,
        rest_acc2: T,
        rest_time: T,
        rest_var: T,
        init_bias_std: T,
        init_tilt_std: T,
        bias_step_window: T,
        /// `acc_noise²/(2·bias_step_window)·bias_step_gate²`: the squared norm of the running
        /// innovation mean beyond which a bias step is declared (0: never).
        bias_step_threshold: T,
        heading_walk_var: T,
        heading_rate_var: T,
        mag_var: T,
        mag_norm_th: T,
        mag_dip_th: T,
        mag_ref_tau: T,
        mag_new_time: T,
        mag_reject_time: T,
    }
}

impl<T: Lane> Coefficients<T> {
    fn new(p: &LaneParams<'_, SqrtEskfParams, T>) -> Self {
        Self {
            gyr_noise: p.coef(|p| p.gyr_noise),
            bias_walk: p.coef(|p| p.bias_walk),
            tau_acc: p.coef(|p| p.tau_acc),
            acc_var: p.coef(|p| p.acc_noise * p.acc_noise),
            acc_gate: p.coef(|p| p.acc_gate),
            acc_adapt_window: p.coef(|p| p.acc_adapt_window),
            model_error_scale: p.coef(|p| p.model_error_scale),
            model_error_window: p.coef(|p| p.model_error_window),
            acc_spike2: p.coef(|p| p.acc_spike * p.acc_spike),
            acc_reject_time: p.coef(|p| p.acc_reject_time),
            startup_time: p.coef(|p| p.startup_time.max(1e-6)),
            reacquire_std: p.coef(|p| p.reacquire_std),
            rest_tau: p.coef(|p| p.rest_tau),
            rest_gyr2: p.coef(|p| p.rest_gyr * p.rest_gyr),
            rest_acc2: p.coef(|p| p.rest_acc * p.rest_acc),
            rest_time: p.coef(|p| p.rest_time),
            rest_var: p.coef(|p| p.rest_noise * p.rest_noise),
            init_bias_std: p.coef(|p| p.init_bias_std),
            init_tilt_std: p.coef(|p| p.init_tilt_std),
            bias_step_window: p.coef(|p| p.bias_step_window),
            bias_step_threshold: p.coef(|p| {
                // White innovation of density acc_noise² averaged with time constant T has
                // variance acc_noise²/(2T) per axis.
                p.acc_noise * p.acc_noise / (2.0 * p.bias_step_window)
                    * p.bias_step_gate
                    * p.bias_step_gate
            }),
            heading_walk_var: p.coef(|p| p.heading_walk * p.heading_walk),
            heading_rate_var: p.coef(|p| p.heading_rate_noise * p.heading_rate_noise),
            mag_var: p.coef(|p| p.mag_noise * p.mag_noise),
            mag_norm_th: p.coef(|p| p.mag_norm_th),
            mag_dip_th: p.coef(|p| p.mag_dip_th),
            mag_ref_tau: p.coef(|p| p.mag_ref_tau),
            mag_new_time: p.coef(|p| p.mag_new_time),
            mag_reject_time: p.coef(|p| p.mag_reject_time),
        }
    }

    /// The covariance factor right after initialisation.
    fn initial_factor(&self) -> Mat<T, 6, 6> {
        let mut s = Mat::zeros();
        s.m[0][0] = self.init_tilt_std;
        s.m[1][1] = self.init_tilt_std;
        // The 6D heading error is unobservable: its variance only bookkeeps the drift.
        s.m[2][2] = T::from_f64(0.1);
        for i in 3..6 {
            s.m[i][i] = self.init_bias_std;
        }
        s
    }
}

/// The error-state correction `δx = [δθ, δb]` of one sample's scalar updates, summed, and
/// the lanes that accepted at least one of them (`δx` is zero in the others): injected once
/// per sample.
struct Correction<T: Lane> {
    dx: [T; 6],
    accepted: T::Mask,
}

/// The coefficients that depend on the time step only, per lane, for the `dt` they were
/// computed for: with a constant `dt` (the usual case) they are computed once instead of
/// every sample (`exp`, `sqrt` and divisions). Bit for bit what the formulas give, so
/// caching changes no result; not part of the state, a lane that skips a sample needs no
/// restore.
#[derive(Clone, Copy, Debug)]
struct PerDt<T: Lane> {
    /// The `dt` of the screened sample (zero where it is skipped), s.
    dt: T,
    /// `σ_θ·√dt` and `σ_b·√dt`: the process-noise standard deviations per step.
    gyr_std: T,
    bias_std: T,
    /// Per-sample measurement variances from the noise densities, `density²/dt` (`dt = 0`,
    /// a skipped sample, divides by 1: finite, and discarded).
    r_acc: T,
    r_rest: T,
    r_mag: T,
    /// Low-pass gains `1 − exp(−dt/τ)` of the rest detection, the field reference, the
    /// accelerometer low-pass after the start-up (each stage τ/2) and the innovation
    /// covariance matching (`acc_adapt_window`) and the model-error mean square
    /// (`model_error_window`).
    k_rest: T,
    k_ref: T,
    k_acc: T,
    k_adapt: T,
    k_model: T,
}

impl<T: Lane> PerDt<T> {
    fn new(c: &Coefficients<T>) -> Self {
        Self::compute(T::zero(), c)
    }

    fn compute(dt: T, c: &Coefficients<T>) -> Self {
        let sdt = dt.sqrt();
        let per_sample = T::select(dt.simd_gt(T::zero()), dt, T::one());
        Self {
            dt,
            gyr_std: c.gyr_noise * sdt,
            bias_std: c.bias_walk * sdt,
            r_acc: c.acc_var / per_sample,
            r_rest: c.rest_var / per_sample,
            r_mag: c.mag_var / per_sample,
            k_rest: lowpass_gain(dt, c.rest_tau),
            k_ref: lowpass_gain(dt, c.mag_ref_tau),
            k_acc: lowpass_gain(dt, c.tau_acc * T::from_f64(0.5)),
            k_adapt: lowpass_gain(dt, c.acc_adapt_window),
            k_model: lowpass_gain(dt, c.model_error_window),
        }
    }

    /// Recomputes every lane when any lane's `dt` differs from the cached one.
    #[inline]
    fn refresh(&mut self, dt: T, c: &Coefficients<T>) {
        if dt.simd_ne(self.dt).any() {
            *self = Self::compute(dt, c);
        }
    }
}

impl<T: Lane> State<T> {
    /// The state of a new filter: nothing seen yet, covariance from the initial standard
    /// deviations.
    fn new(coef: &Coefficients<T>) -> Self {
        let zero = T::zero();
        State {
            strapdown: Quat::identity(),
            correction: Quat::identity(),
            heading_offset: zero,
            heading_offset_var: T::one(),
            bias: Vec3::zero(),
            factor: coef.initial_factor(),
            acc_lp: Vec3::new(zero, zero, T::one()),
            acc_lp1: Vec3::new(zero, zero, T::one()),
            rot_lp1: Mat::identity(),
            rot_lp: Mat::identity(),
            rest_gyr_lp: Vec3::zero(),
            rest_acc_lp: Vec3::zero(),
            rest_timer: zero,
            acc_rejected_time: zero,
            innovation_mean_x: zero,
            innovation_mean_y: zero,
            innovation_nis: T::one(),
            innovation_ms: zero,
            bias_step: <T::Mask as Mask>::splat(false),
            age: zero,
            field: FieldReference {
                norm: zero,
                dip: zero,
                candidate_norm: zero,
                candidate_dip: zero,
                candidate_time: zero,
                rejected_time: zero,
            },
            initialized: <T::Mask as Mask>::splat(false),
            preset: <T::Mask as Mask>::splat(false),
            preset_covariance: <T::Mask as Mask>::splat(false),
            mag_disturbed: <T::Mask as Mask>::splat(false),
        }
    }
}

/// Square-root multiplicative error-state Kalman filter (see the module documentation).
///
/// State: the strapdown quaternion (quasi-inertial frame), the earth-frame correction `c`
/// (`q6 = c ⊗ q_strapdown`), the heading offset `δ` (rad, `q9 = qz(δ) ⊗ q6`), the bias `b̂`
/// (rad/s, sensor frame) and the covariance factor `S` of `[δθ (earth frame, rad), δb (rad/s)]`.
#[derive(Clone, Debug)]
pub struct SqrtEskf<T: Lane> {
    state: State<T>,
    coef: Coefficients<T>,
    nine_d: bool,
    limits: ScreenLimits,
    rejections: Rejections<T>,
    per_dt: PerDt<T>,
    params: SqrtEskfParams,
}

impl<T: Lane> SqrtEskf<T> {
    crate::filters::uniform_constructors!(SqrtEskfParams);

    /// A filter whose lanes may have different parameters (see [`LaneParams`]); `dof` and
    /// the screening limits are those of the first set.
    pub fn with_lane_params(p: &LaneParams<'_, SqrtEskfParams, T>) -> Self {
        let coef = Coefficients::new(p);
        let per_dt = PerDt::new(&coef);
        Self {
            state: State::new(&coef),
            coef,
            nine_d: p.first().dof.uses_magnetometer(),
            limits: p.first().screen_limits(),
            rejections: Rejections::default(),
            per_dt,
            params: p.first().clone(),
        }
    }

    /// The 6D orientation (gravity and gyro only; heading drifts), sensor to earth.
    pub fn quat6(&self) -> Quat<T> {
        (self.state.correction * self.state.strapdown).normalize()
    }

    /// The 9D orientation (heading from the magnetometer), sensor to earth.
    pub fn quat9(&self) -> Quat<T> {
        let st = &self.state;
        (Quat::from_heading(st.heading_offset) * st.correction * st.strapdown).normalize()
    }

    /// The upper-triangular covariance factor `S` of the error
    /// state `[δθ (rad, earth frame of q6), δb (rad/s, sensor frame)]`: `P = S·Sᵀ`.
    pub fn covariance_factor(&self) -> &Mat<T, 6, 6> {
        &self.state.factor
    }

    /// The error-state covariance `P = S·Sᵀ` (symmetric PSD by construction).
    pub fn covariance(&self) -> Mat<T, 6, 6> {
        self.state.factor * self.state.factor.transpose()
    }

    /// [`OrientationFilter::attitude_covariance`] without its `Option`.
    fn attitude_block(&self) -> Mat<T, 3, 3> {
        // The attitude block of `S·Sᵀ` only (`S` upper triangular: `S_ik = 0` for `k < i`):
        // a quarter of the full product, the same sums in the same order.
        let s = &self.state.factor;
        let mut a = Mat::<T, 3, 3>::from_fn(|i, j| {
            let mut v = T::zero();
            for k in i.max(j)..6 {
                v = s.m[i][k].mul_add(s.m[j][k], v);
            }
            v
        });
        if self.nine_d {
            for i in 0..2 {
                a.m[i][2] = T::zero();
                a.m[2][i] = T::zero();
            }
            a.m[2][2] = self.state.heading_offset_var;
        }
        let e = self.state.innovation_ms * self.coef.model_error_scale;
        a.m[0][0] += e;
        a.m[1][1] += e;
        a
    }

    /// Per lane: the sensor is detected at rest now ([`OrientationFilter::rest_detected`]
    /// without its `Option`).
    fn at_rest(&self) -> T::Mask {
        self.state.rest_timer.simd_ge(self.coef.rest_time)
    }

    /// Heading offset `δ` (rad) that the magnetometer adds to the 6D estimate.
    pub fn heading_offset(&self) -> T {
        self.state.heading_offset
    }
}
