//! The flagship filter [`SqrtEskf`], a square-root multiplicative error-state Kalman filter.
//! What it is, its units, parameters and methods: the rustdoc of [`SqrtEskf`]. The derivation,
//! with the paper references: docs/methods.md, section "`sqrt-eskf` (the flagship)".

// The factor kernels index several arrays with the same row/column numbers (as the
// formulas are written); iterator chains would hide that.
#![allow(clippy::needless_range_loop)]

use super::upper_factor::{add_diagonal_noise, carlson_apply, carlson_gains};
use super::{
    Dof, LaneParams, OrientationFilter, Rejections, ScreenBounds, Screened, lane_state, params,
};
use crate::blocks::{
    STANDARD_GRAVITY, field_heading_error, lowpass_gain_at_rate, lowpass_gains_at_rates,
    tilt_from_acc,
};
use crate::{ImuSample, Quat, Vec3};
use rootfuse_lane::{Lane, Mask, Mat, Select};

// The per-sample steps and `OrientationFilter::update`.
mod update;
// The time update, deferred to the measurement ticks.
mod time_update;
// Reset, and the orientation and bias set with their uncertainty.
mod set_state;
// The second, longer accelerometer window and the weight that blends the two.
mod two_windows;
// The 9D heading: the field test and the heading offset.
mod heading;
// The reported attitude covariance: `P`'s block and the model errors.
mod report;
// The parameters converted to the filter's precision.
mod coefficients;
// Coefficients cached while the time step repeats.
mod per_dt;
// The parameters of the smoother's passes.
mod for_smoothing;
// The gyroscope's scale factors, estimated online.
mod gyro_scale;
use coefficients::Coefficients;
use gyro_scale::GyroScale;
use per_dt::{Cached, PerDt, PerHeading, PerInterval, divisor};

params! {
    /// Parameters of [`SqrtEskf`]. One set for all recordings.
    pub struct SqrtEskfParams {
        /// Attitude random-walk density driving `δθ` (gyro noise plus unmodelled errors).
        gyr_noise: f64 = 0.005, "rad/√s", [1e-9, 10.0];
        /// Gyro-bias random-walk density.
        bias_walk: f64 = 1e-5, "rad/s/√s", [0.0, 10.0];
        /// The bias random walk's noise is folded into the covariance factor every this many
        /// samples, the variance of the samples between accumulated (and at once where a
        /// bias step or re-acquisition inflates the bias); the attitude noise accumulates
        /// every sample and is folded with the deferred time update at the measurement ticks.
        /// The fold of all six states costs about a fifth of an update, the attitude's alone
        /// a sixth of that. 1 is every sample. The accuracy cost of 2, 4 and 8 is in
        /// `docs/flagship_cost.md`.
        bias_noise_every: f64 = 8.0, "samples", [1.0, 1e6];
        /// The inclination is corrected every this many samples (where the accelerometer is
        /// usable, else at the next such tick; the start-up too), with the
        /// information of all usable samples since the last correction: the
        /// measurement variance is `acc_noise²` over their summed time. The low-passes step
        /// every sample, so the low-passed gravity a correction reads is as current as ever;
        /// the χ² gate and the running means the correction feeds are tested and updated at
        /// the corrections. 1 is every sample. The accuracy and the cost of 1, 2, 4 and 8 are
        /// in `docs/flagship_cost.md`.
        acc_update_every: f64 = 8.0, "samples", [1.0, 1e6];
        /// 9D: the field is tested, and the heading corrected, every this many samples (where
        /// the magnetometer is usable, else at the next such tick; at once where a lane has no
        /// field reference), on the mean of the usable readings since the last test, each test
        /// standing for the usable magnetometer time since the last (its low-pass gains,
        /// timers and measurement variance `mag_noise²` over that time); the heading
        /// variance grows every sample. Between tests a usable reading is flagged as the last
        /// test found the field. 1 is every sample. Accuracy and cost in
        /// `docs/flagship_cost.md`.
        mag_update_every: f64 = 4.0, "samples", [1.0, 1e6];
        /// At rest, the gyro bias is measured every this many samples (where the sensor is
        /// at rest at the tick), each measurement standing for the time since the last tick
        /// (variance `rest_noise²` over that time): the rest low-pass steps every sample, so
        /// the measurement is as current as ever. 1 is every sample. Accuracy and cost in
        /// `docs/flagship_cost.md`.
        rest_update_every: f64 = 8.0, "samples", [1.0, 1e6];
        /// Time constant of the accelerometer low-pass in the quasi-inertial frame.
        tau_acc: f64 = 2.0, "s", [0.0, 100.0];
        /// Time constant of a second, longer accelerometer window (0: one window). The two
        /// windows' inclination measurements are blended by the motion: sustained
        /// translation weighs the long window, fast rotation the short one (see
        /// `window_ratio`).
        tau_acc_long: f64 = 4.0, "s", [0.0, 100.0];
        /// The ratio of translation (low-passed `|a − â|`, m/s²) to rotation (low-passed
        /// `|ω − b̂|`, rad/s) at which the two windows weigh equally; the long window's weight
        /// is `x⁴/(1 + x⁴)` of `x = translation / (window_ratio·rotation)`.
        window_ratio: f64 = 1.1, "m/s", [1e-3, 1e3];
        /// With two windows: the accelerometer noise (`acc_noise`) under rotation, as a share
        /// of the noise under translation; the share grows with the long window's weight `w`,
        /// `σ = acc_noise·(s + (1 − s)·w)`. Under rotation the low-passed gravity is good and
        /// is trusted more; 1 is one noise for all motion.
        acc_noise_rotation_share: f64 = 1.0, "1", [1e-3, 1.0];
        /// Time constant of the two low-passed motion measures that set the weight.
        window_tau: f64 = 8.0, "s", [1e-3, 1e4];
        /// Noise density of the low-passed inclination measurement (`r = acc_noise²/dt`).
        acc_noise: f64 = 0.003, "rad·√s", [1e-9, 10.0];
        /// χ² gate of each scalar inclination innovation, in standard deviations.
        acc_gate: f64 = 6.0, "1", [0.0, 1e6];
        /// Time constant of the running mean of the normalised squared inclination
        /// innovation (over its predicted variance), whose excess over 1 scales the
        /// inclination measurement variance (covariance matching, capped at 1000×). 0
        /// disables. BROAD's 14 trials: bit for bit as 0; the simulated pendulum (6D, 5 seeds,
        /// one window): inclination 1.17° → 0.89° (`docs/accuracy.md`).
        acc_adapt_window: f64 = 0.3, "s", [0.0, 1e6];
        /// The reported attitude covariance adds, on both inclination axes, this multiple of
        /// the running mean square of the inclination innovation (rad²): the error the motion
        /// acceleration leaves in the low-passed gravity, which `P` does not model (its
        /// noise is white, the error is not). Only the report changes (and with it the
        /// smoother's weights); the forward estimates are bit for bit those of 0, which
        /// reports `P` alone. This is the scale where the motion is translation; with two
        /// windows it falls toward `model_error_rotation_scale` as rotation dominates. 0.6 with
        /// `acc_excess_scale` 0.15: 95 % coverage 0.93–0.97 of the inclination on the
        /// simulated hard cases, 0.96 on BROAD with a 0.5° floor (`docs/accuracy.md`).
        model_error_scale: f64 = 0.6, "1", [0.0, 1e3];
        /// The model error's scale where the motion acceleration comes with rotation (two
        /// windows only): the scale is `model_error_scale` blended toward this one by
        /// `1/(1 + x⁴)`, `x = translation / (model_error_ratio · rotation)`, the two windows'
        /// motion measures. Measured where the truth is exact, the innovation's mean square
        /// overstates the error of a swinging sensor (a pendulum's specific force stays along
        /// its arm in the sensor frame and averages toward vertical in the windows) and
        /// understates that of a sensor carried back and forth: with one scale, 0.6, the
        /// simulated pendulum's coverage was 0.98 and the handheld translation's 0.93; with
        /// 0.28 here both are within 0.93–0.97 (`docs/accuracy.md`). Report only.
        model_error_rotation_scale: f64 = 0.28, "1", [0.0, 1e3];
        /// The ratio of translation (m/s²) to rotation (rad/s) at which the model error's two
        /// scales weigh equally (`model_error_rotation_scale`), m/s: a sensor at 1 m from the
        /// axis it swings about sees about `ω²·1 m` of centripetal acceleration, a ratio of
        /// `ω·1 m`; 7 puts a swing below 7 rad/s at 1 m on the rotation side.
        model_error_ratio: f64 = 7.0, "m/s", [1e-3, 1e6];
        /// Time constant of that running mean square, s.
        model_error_window: f64 = 1.0, "s", [0.0, 1e6];
        /// 9D: the reported heading variance adds this multiple of the running mean square
        /// (time constant `model_error_window`) of the magnetic heading innovation (rad²): a
        /// field distorted by the sensor's own iron turns with the sensor, so the heading it
        /// gives disagrees with the gyroscope's as the sensor turns, an error `P`'s white
        /// noise does not model (on BROAD 27, a phone's vibration motor beside the sensor,
        /// `P` alone puts a 5–8° heading error outside its 95 % ellipsoid at every sample).
        /// Report only, like `model_error_scale`; the smoother's passes leave it out
        /// ([`SqrtEskfParams::for_smoothing`]). 1 is the mean square itself; 2 holds the
        /// simulated vehicle with a disturbed field (whose turns drift the heading by the
        /// gyroscope's scale factor while no field is adopted) at 0.96 coverage of the total
        /// error instead of 0.92, BROAD's 9D within 0.001 (`docs/accuracy.md`).
        heading_model_error_scale: f64 = 2.0, "1", [0.0, 1e3];
        /// The gyroscope's scale-factor and misalignment error (relative) as a model error of
        /// the report: both inclination variances add `(gyr_scale_error · |ω| · tau_acc)²`,
        /// `|ω|` the rotation rate low-passed over `window_tau` (held at rest; with one
        /// window, `tau_acc_long = 0`, it stays at its 0.05 rad/s floor). The gyroscope
        /// turns the estimate by `gyr_scale_error · |ω|` rad/s too much or too little, which
        /// the accelerometer correction, time constant `tau_acc`, holds to that drift times
        /// `tau_acc`; `P`'s gyro noise is white and does not model it. 0.0005 holds the
        /// shared BROAD trials' coverage in the 0.90–0.98 band; the simulator's IMU (0.3 %)
        /// needs its own 0.003 (`docs/accuracy.md`). Report only.
        gyr_scale_error: f64 = 0.0005, "1", [0.0, 1.0];
        /// Window of the online estimate of the gyroscope's scale factors (0: none): over
        /// each window the filter's own inclination corrections are regressed on the
        /// rotation the gyroscope measured, every window so far at once, and the readings
        /// are divided by `1 + s` per axis from then on (`docs/methods.md`).
        gyr_scale_window: f64 = 10.0, "s", [0.0, 1e6];
        /// How firmly that estimate is held at zero: as if each axis had already turned
        /// `√gyr_scale_ridge` rad with no scale error seen (in 9D an axis the motion never
        /// turns about keeps zero; in 6D this holds the axes' mean, and such an axis takes
        /// the mean, `gyr_scale_axis_ridge`; at least 1e-6, so that it cannot stop the
        /// others' estimate).
        gyr_scale_ridge: f64 = 1.0, "rad²", [1e-6, 1e12];
        /// In 6D, how firmly the three axes' estimates are held to their mean: as if the
        /// axes had turned `√gyr_scale_axis_ridge` rad with no difference between their scale
        /// errors seen. The inclination cannot see the scale of the axis about up, whose
        /// error turns only the heading, which nothing corrects in 6D; held to the mean, that
        /// axis takes the error the others show (BROAD's gyroscope errs alike on its axes;
        /// `docs/accuracy.md`). Equal to `gyr_scale_ridge`, each axis is estimated on its own,
        /// as it always is in 9D, where the field corrects that heading. Taken as at most 10⁴
        /// times `gyr_scale_ridge`: beyond, `f32` rounding would lose the mean's own prior.
        gyr_scale_axis_ridge: f64 = 30.0, "rad²", [1e-6, 1e12];
        /// A window whose accelerometer disagrees with the estimated up by `d` (rms, rad)
        /// weighs `1/(1 + (d/gyr_scale_gate)⁴)`: motion acceleration, not the scale, moves
        /// the corrections there.
        gyr_scale_gate: f64 = 0.05, "rad", [1e-6, 10.0];
        /// A sustained acceleration as a model error of the report: both inclination
        /// variances add `acc_excess_scale · max(|ā|²/g² − 1, 0)`, `ā` the low-passed specific
        /// force the inclination is measured from, `g²` the least `|a|²` seen at rest (standard
        /// gravity before the first rest). A sustained horizontal acceleration `a_h` (a turn)
        /// tilts `ā` by `atan(|a_h|/g)` while the innovation vanishes; `|ā|² − g² = |a_h|²`
        /// shows it. 0.15: the simulated vehicle's inclination coverage 0.70 → 0.96, BROAD's
        /// within 0.01 (`docs/accuracy.md`). Report only; not in the smoother's passes. A
        /// sensor reading gravity 0.5 % high that never rests gets (2.2°)² more: give it 0.
        acc_excess_scale: f64 = 0.15, "1", [0.0, 100.0];
        /// Offline only (the forward–backward smoother, [`SqrtEskfParams::for_smoothing`]):
        /// both passes run their long window with `tau_acc_long` times this (with one window,
        /// `tau_acc_long = 0`, their only window with `tau_acc` times this). Each pass's
        /// low-pass lag is cancelled by the other's, so offline longer time constants remove
        /// more motion acceleration at no cost in lag (cross-validated on BROAD,
        /// docs/accuracy.md). The filter itself does not read it.
        smoothing_tau_scale: f64 = 1.25, "1", [1.0, 10.0];
        /// Offline only, with two windows: both passes run their short window with `tau_acc`
        /// times this. Shorter than online: where rotation dominates (the short window's
        /// regime) the lag cancels between the passes and the gyroscope refinement
        /// (`smoothing_gyro_tau`) removes what motion acceleration the short window lets
        /// through, while the gyroscope's own errors build up over a shorter time
        /// (cross-validated on BROAD with the simulated hard cases as a constraint,
        /// docs/accuracy.md). The filter itself does not read it.
        smoothing_short_tau_scale: f64 = 0.25, "1", [0.05, 10.0];
        /// Offline only: the smoother's fused estimate refined by the gyroscope with this time
        /// constant ([`OrientationFilter::smoothing_gyro_tau`](crate::OrientationFilter);
        /// 0 keeps it), so motion acceleration the passes let through above `1/(2π·τ)` goes.
        smoothing_gyro_tau: f64 = 1.7, "s", [0.0, 1e3];
        /// Offline only: 1 makes the smoother (`smooth::smooth_spec`, with `std`) first run
        /// the filter forward once, online (`f32`, at half the recording's rate), and divide
        /// the gyroscope's readings by the scale error it estimated over the whole recording
        /// (`gyr_scale_window`), so that both passes share one estimate; 0 leaves the
        /// readings as they are. The passes estimate none of their own: from opposite ends of
        /// the recording they would disagree while they learn it. It costs that pass, about a
        /// sixth of the smoother's time (BROAD 14 smoothed, 0 → 1: 9D 1.562° → 1.547°, 6D
        /// 2.288° → 1.911°, inclination 0.528° → 0.522° in 9D, 0.524° in 6D; the time,
        /// docs/performance.md).
        smoothing_gyro_scale: bool = 1.0, "1", [0.0, 1.0];
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
        /// Noise density of the at-rest bias measurement (`r = rest_noise²/T`, `T` the time
        /// one measurement stands for: `rest_update_every`).
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
        /// Initial standard deviation of the 6D heading error. Nothing observes a 6D
        /// heading: it is relative to the heading the filter starts with, and it is scored
        /// after its constant offset is removed (`docs/conventions.md`), so its reported
        /// variance starts here and grows with the gyroscope noise and the bias uncertainty.
        /// Report only: the estimates are those of any other value to rounding. 0 holds BROAD's
        /// 6D coverage with the 0.5° floor at 0.935 with NEES/3 0.89 (0.1: 0.968 with 0.40,
        /// `docs/accuracy.md`). In 9D the heading offset's own variance is reported instead.
        init_heading_std: f64 = 0.0, "rad", [0.0, 10.0];
        /// Random-walk density of the 9D heading offset beyond the 6D heading drift
        /// (magnetic model errors).
        heading_walk: f64 = 0.0005, "rad/√s", [1e-9, 10.0];
        /// Rate-proportional random-walk density of the 9D heading offset (gyro scale-factor
        /// and misalignment errors make the 6D heading drift in proportion to the rotation):
        /// the offset's variance grows by `(heading_rate_noise·|ω|)²·dt`.
        heading_rate_noise: f64 = 0.001, "√s", [0.0, 10.0];
        /// Random-walk density of the 9D heading offset per unit of rotation about earth-z:
        /// the offset's variance grows by `(heading_up_rate_noise·ω_z)²·dt`, `ω_z` the
        /// bias-corrected rate about the vertical. A gyro scale-factor error drifts the 6D
        /// heading by a fraction of the angle turned about the vertical, more than by the
        /// same angle about a horizontal axis.
        heading_up_rate_noise: f64 = 0.004, "√s", [0.0, 10.0];
        /// Noise density of the magnetic heading measurement (`r = mag_noise²/dt`).
        mag_noise: f64 = 0.13, "rad·√s", [1e-9, 10.0];
        /// Largest relative deviation of the field norm from the reference.
        mag_norm_th: f64 = 0.07, "1", [0.0, 10.0];
        /// Largest deviation of the field dip from the reference.
        mag_dip_th: f64 = 0.1, "rad", [0.0, 4.0];
        /// Time constant with which the field reference and candidate are learned.
        mag_ref_tau: f64 = 10.0, "s", [1e-3, 1e6];
        /// Time constant of the low-pass of the field norm and dip that the disturbance
        /// tests and the reference see (sensor noise alone moves a single sample's norm by a
        /// few percent); 0 tests each sample as it comes. The heading measurement itself is
        /// not low-passed.
        mag_lowpass_tau: f64 = 0.05, "s", [0.0, 100.0];
        /// The field must have matched the reference this long without interruption before
        /// it corrects the heading again (a short disturbance often passes through the
        /// thresholds at its edges).
        mag_settle_time: f64 = 0.5, "s", [0.0, 1e6];
        /// A field adopted as the new reference keeps the heading: its azimuth in the 9D frame
        /// at adoption becomes the reference's, and that azimuth decays to 0 (the new field
        /// becomes north) with this time constant while the field corrects the heading. A
        /// homogeneous disturbance that lasts longer than `mag_new_time` (a car, a steel
        /// building) then turns the heading slowly instead of at once; a recording that
        /// starts inside one reaches the true north as slowly. 0 makes an adopted field north
        /// at once.
        mag_azimuth_tau: f64 = 60.0, "s", [0.0, 1e9];
        /// 9D: the reported heading variance adds this multiple of the variance of the
        /// reference field's azimuth against north ([`SqrtEskf`]'s field reference, 0 for the
        /// first field): an adopted field's azimuth was measured with the heading of its
        /// adoption, so it inherits that heading's variance (and the previous reference's),
        /// which shrinks as the azimuth decays toward north (`mag_azimuth_tau`); and that
        /// decay is itself an error where the adopted field is a lasting disturbance, not the
        /// earth's, so the square of the turn it has made since adoption is added too. Without
        /// it the heading's variance shrinks against the adopted field as if it pointed north,
        /// and over minutes of a disturbed field the 95 % ellipsoid holds too few of the
        /// errors (`docs/accuracy.md`, "The adopted field's azimuth error in the report").
        /// Online it is report only; the smoother's passes keep it, since their fusion weighs
        /// each pass's heading by its variance: a pass that has turned toward an adopted field
        /// yields to the other.
        adopted_field_error_scale: f64 = 1.0, "1", [0.0, 1e3];
        /// A stable candidate field becomes the reference after this long.
        mag_new_time: f64 = 20.0, "s", [0.0, 1e6];
        /// Rejection lasting this long makes the (stable) candidate the reference.
        mag_reject_time: f64 = 60.0, "s", [0.0, 1e6];
        /// The home field is the one that defines north: the first, or an adopted field
        /// once it has corrected the heading this long without interruption (its azimuth has
        /// decayed to north by then: about 3·`mag_azimuth_tau`). Where the field stops
        /// matching an adopted reference and matches the home field, the home field is the
        /// reference again at once, pointing north, and the heading's variance takes the left
        /// reference's azimuth error (`adopted_field_error_scale`'s): a lasting disturbance
        /// that ends (a car, a lift) gives the heading back at once instead of after
        /// `mag_new_time` of rejection and minutes of `mag_azimuth_tau`. 0 makes every adopted
        /// field home at once (no return).
        mag_home_time: f64 = 180.0, "s", [0.0, 1e9];
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
        /// Azimuth (rad) of the reference field in the 9D frame (0: it points north). An
        /// adopted field takes the candidate's azimuth, its running mean over `mag_ref_tau`
        /// (where the field is within a few degrees of vertical the azimuth is undefined and
        /// the candidate keeps its last one).
        azimuth: T,
        /// Variance (rad²) of `azimuth`'s error against north at adoption, decayed with
        /// `azimuth` since (0 for the first field).
        azimuth_var: T,
        /// `azimuth` at adoption (0 for the first field).
        adopted_azimuth: T,
        /// The home field's norm and dip (`mag_home_time`), and whether it is the reference.
        home_norm: T,
        home_dip: T,
        at_home: T::Mask,
        candidate_azimuth: T,
        /// How long (s) the field has matched the reference (or been adopted) without
        /// interruption; a new reference starts at `mag_settle_time` (it corrects at once).
        undisturbed_time: T,
        /// Low-passed field norm (input units) and dip (rad).
        lowpass_norm: T,
        lowpass_dip: T,
        /// The lane has a reference: false until its first usable reading, and again after
        /// `forget_field_reference`.
        known: T::Mask,
    }
}

lane_state! {
    /// One accelerometer window: the two-stage low-pass (two equal first-order stages) of the
    /// specific force and of the strapdown rotation, both in the `I` frame.
    struct InertialLowpass<T: Lane> {
        /// First stage of the force's low-pass.
        acc1: Vec3<T>,
        /// Low-passed specific force in the `I` frame, m/s².
        acc: Vec3<T>,
        /// First stage of the rotation's low-pass.
        rot1: Mat<T, 3, 3>,
        /// Low-passed sensor-to-`I` rotation matrix (for the lag term of `H`).
        rot: Mat<T, 3, 3>,
    }
}

lane_state! {
    /// The long window ([`two_windows`]) and the two low-passed motion measures that weigh it.
    struct LongWindow<T: Lane> {
        lowpass: InertialLowpass<T>,
        /// Low-passed `|a − â|`, m/s².
        translation: T,
        /// Low-passed `|ω − b̂|`, rad/s.
        rotation: T,
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
        /// Covariance factor `S` of `[δθ, δb]`: `P = S·Sᵀ` at the last flush of the time
        /// update (`fold_pending`).
        factor: Mat<T, 6, 6>,
        /// The time update since that flush: `M = Σ R_k·dt_k` (s) and the attitude noise
        /// variances, rad², on `δθ_x, δθ_y` (with the start-up and re-acquisition extra) and
        /// on `δθ_z`.
        transition_sum: Mat<T, 3, 3>,
        tilt_noise_var: T,
        yaw_noise_var: T,
        /// Bias random-walk variance (rad²/s², per axis) not yet folded into `S`, and the
        /// samples it has accumulated over (`bias_noise_every`).
        bias_noise_pending: T,
        bias_noise_samples: T,
        /// The `tau_acc` window.
        window: InertialLowpass<T>,
        /// The second accelerometer window (`tau_acc_long`) and its motion measures.
        long: LongWindow<T>,
        /// Rest detection: low-passed gyro (rad/s) and accelerometer (m/s², sensor frame).
        rest_gyr_lp: Vec3<T>,
        rest_acc_lp: Vec3<T>,
        /// How long (s) the rest conditions have held.
        rest_timer: T,
        /// The least `|a|²` low-passed at rest, (m/s²)² (∞ before the first rest): gravity as
        /// this accelerometer measures it, for the `acc_excess_scale` report term. The least,
        /// because a steady acceleration in a straight line passes for rest and reads more.
        rest_gravity2: T,
        /// How long (s) every inclination measurement has been gated.
        acc_rejected_time: T,
        /// Samples since the last inclination tick (every `acc_update_every` samples, usable
        /// or not, so that lanes started together stay in phase), and the summed time (s) of
        /// the samples with a usable accelerometer since the last correction.
        inclination_phase: T,
        inclination_time: T,
        /// Samples since the last at-rest bias tick (`rest_update_every`) and the summed time
        /// (s) of the stepping samples since then.
        rest_phase: T,
        rest_interval_time: T,
        /// The same for the field test (`mag_update_every`), the usable magnetometer readings
        /// since the last test, and the last test's verdict: the field was disturbed.
        heading_phase: T,
        heading_samples: T,
        heading_time: T,
        field_disturbed: T::Mask,
        /// Sums over those readings of the unit field in the 6D earth frame and of the norm.
        mag_sum: Vec3<T>,
        mag_norm_sum: T,
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
        /// Running mean square of the magnetic heading innovation (rad², 9D), time constant
        /// `model_error_window`.
        heading_innovation_ms: T,
        /// `(gyr_scale_error · |ω| · tau_acc)²` plus the `acc_excess_scale` term at the last
        /// inclination update, rad². Kept,
        /// not derived from `long.rotation` when reported, so that `set_quat` with a `sigma`
        /// clears it with the other model errors (the rotation measure is not reset).
        scale_error2: T,
        /// A gyro-bias step was detected by the last sample: the next time update re-inflates
        /// the bias covariance.
        bias_step: T::Mask,
        /// Time since initialisation, s.
        age: T,
        field: FieldReference<T>,
        /// The gyroscope's scale factors, estimated online (`gyr_scale_window`).
        gyro_scale: GyroScale<T>,
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

/// The error-state correction `δx = [δθ, δb]` of one sample's scalar updates, summed, and
/// the lanes that accepted at least one of them (`δx` is zero in the others): injected once
/// per sample.
struct Correction<T: Lane> {
    dx: [T; 6],
    accepted: T::Mask,
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
            transition_sum: Mat::zeros(),
            tilt_noise_var: zero,
            yaw_noise_var: zero,
            bias_noise_pending: zero,
            bias_noise_samples: zero,
            window: InertialLowpass::new(),
            long: LongWindow::new(),
            rest_gyr_lp: Vec3::zero(),
            rest_acc_lp: Vec3::zero(),
            rest_timer: zero,
            rest_gravity2: T::from_f64(f64::INFINITY),
            acc_rejected_time: zero,
            inclination_phase: zero,
            inclination_time: zero,
            rest_phase: zero,
            rest_interval_time: zero,
            heading_phase: zero,
            heading_samples: zero,
            heading_time: zero,
            field_disturbed: <T::Mask as Mask>::splat(false),
            mag_sum: Vec3::zero(),
            mag_norm_sum: zero,
            innovation_mean_x: zero,
            innovation_mean_y: zero,
            innovation_nis: T::one(),
            innovation_ms: zero,
            heading_innovation_ms: zero,
            scale_error2: zero,
            bias_step: <T::Mask as Mask>::splat(false),
            age: zero,
            field: FieldReference {
                norm: zero,
                dip: zero,
                candidate_norm: zero,
                candidate_dip: zero,
                candidate_time: zero,
                rejected_time: zero,
                azimuth: zero,
                azimuth_var: zero,
                adopted_azimuth: zero,
                home_norm: zero,
                home_dip: zero,
                at_home: <T::Mask as Mask>::splat(false),
                candidate_azimuth: zero,
                undisturbed_time: zero,
                lowpass_norm: zero,
                lowpass_dip: zero,
                known: <T::Mask as Mask>::splat(false),
            },
            gyro_scale: GyroScale::new(),
            initialized: <T::Mask as Mask>::splat(false),
            preset: <T::Mask as Mask>::splat(false),
            preset_covariance: <T::Mask as Mask>::splat(false),
            mag_disturbed: <T::Mask as Mask>::splat(false),
        }
    }
}

/// The flagship orientation filter (registry name `sqrt-eskf`, alias `flagship`): a
/// square-root multiplicative error-state Kalman filter with decoupled inclination and
/// heading, rest detection and gyro-bias estimation, an accelerometer low-pass in a
/// quasi-inertial frame, χ² gating of the inclination measurement and magnetic-disturbance
/// rejection. It runs in 6D (gyroscope and accelerometer) or 9D (plus magnetometer), in `f32`,
/// `f64` or SIMD lanes (each lane an independent channel with the same bits as alone), and
/// allocates nothing.
///
/// # Structure
///
/// - `q6 = c ⊗ q_gyr`: `q_gyr` integrates the bias-corrected gyroscope into a quasi-inertial
///   frame and is never corrected; `c` accumulates the Kalman attitude corrections.
/// - `q9 = qz(δ) ⊗ q6`: the magnetometer only moves the scalar heading offset `δ` about
///   earth-up, so a disturbed field can neither tilt the estimate nor corrupt the gyro bias
///   (the split of VQF, Laidig & Seel 2023).
/// - The Kalman error state is `[δθ, δb]`: `δθ` the attitude error of `q6` in the earth frame
///   (rad, `q_true = Exp(δθ) ⊗ q6`), `δb` the gyro-bias error in the sensor frame (rad/s).
///   Its covariance is carried as an upper-triangular factor, `P = S·Sᵀ` (`S` 6×6), and is
///   symmetric positive semidefinite by construction, in `f32` as in `f64`. The heading
///   offset `δ` has a scalar variance of its own.
///
/// The derivation (square-root time update, Carlson's measurement update, the lag-aware
/// inclination measurement, the χ² gate, rest detection, magnetic disturbance, heading
/// offset, model error) is in docs/methods.md, section "`sqrt-eskf` (the flagship)";
/// measured accuracy in docs/accuracy.md.
///
/// # Units and frames
///
/// Inputs ([`crate::ImuSample`]), all in the sensor frame:
///
/// - gyroscope in rad/s;
/// - accelerometer in m/s²: the corrections use its direction only, but the thresholds
///   `rest_acc`, `acc_spike` and `max_acc` are in m/s²;
/// - magnetometer in µT (9D only; its norm is compared relative to a learned reference, only
///   `max_mag` is absolute: 1000, in µT, refuses a field in nT unless it is set); a 6D sample
///   carries none;
/// - `dt`, seconds since the previous sample (may vary from sample to sample).
///
/// Outputs:
///
/// - orientation: unit quaternion `[w, x, y, z]` rotating **sensor to earth**, earth ENU
///   (x east, y north, z up);
/// - gyro bias: rad/s, sensor frame (the estimate subtracted from the gyroscope);
/// - attitude covariance: rad², of the earth-frame error `δθ` of the orientation, earth axes:
///   the upper-left 2×2 block is the inclination, `[2][2]` the heading variance (in 9D that of
///   `δ`, its correlation with the inclination not tracked).
///
/// Unusable input (NaN, ∞, a zero vector, a bad `dt`, a value beyond the screening limits) skips
/// the sample or the one correction in that lane only, and is counted.
///
/// # Parameters that matter most
///
/// All in [`SqrtEskfParams`] (each field's doc gives its unit, default and range):
///
/// - `dof`: [`crate::Dof::Six`] ignores the magnetometer (the heading then drifts with the
///   gyroscope), [`crate::Dof::Nine`] (default) uses it;
/// - `tau_acc` (2 s): time constant of the accelerometer low-pass; longer rides out longer
///   accelerations (translation, vibration) but corrects the inclination more slowly;
/// - `tau_acc_long` (4 s): a second, longer window, blended in by the ratio of translation to
///   rotation (`window_ratio`, `window_tau`); 0 runs one window;
/// - `gyr_noise` (0.005 rad/√s) against `acc_noise` (0.003 rad·√s): how far the gyroscope is
///   trusted over gravity; `acc_gate` (6 standard deviations) rejects outlying inclination
///   innovations;
/// - `rest_gyr` (0.035 rad/s), `rest_acc` (0.5 m/s²), `rest_time` (1.5 s): rest detection,
///   where the gyro bias is measured directly (`rest_noise`); `bias_walk` is how fast the
///   bias is assumed to wander;
/// - `mag_noise` (0.13 rad·√s), `mag_norm_th` (7 %), `mag_dip_th` (0.1 rad): how fast the
///   magnetometer pulls the heading, and when a field counts as disturbed;
/// - the screening limits `max_dt`, `max_gyr`, `max_acc`, `max_mag` that every filter shares.
///
/// `try_new` validates the parameters, `new` does not; `with_lane_params` gives each lane its
/// own set.
///
/// # Methods
///
/// - `update(sample, dt)` ([`crate::OrientationFilter`]) processes one sample;
/// - `quat` is the estimate (`q9` in 9D, `q6` in 6D); `quat6` and `quat9` give both, and
///   `heading_offset` gives `δ`;
/// - `bias` is the gyro-bias estimate;
/// - `attitude_covariance` is the 3×3 attitude covariance above, with model error terms: its
///   inclination block adds `model_error_scale` times the running mean square of the
///   inclination innovation and the drift of a gyroscope scale-factor error
///   (`gyr_scale_error`) and of a sustained acceleration (`acc_excess_scale`), and in 9D
///   its heading variance adds `heading_model_error_scale`
///   times the running mean square of the magnetic heading innovation; `covariance_factor` is
///   `S` and `covariance` is `P = S·Sᵀ` of `[δθ, δb]`;
/// - `reset` returns to the state of a new filter with the same parameters;
/// - `set_quat(q, sigma)` and `set_bias(b, sigma)` set the orientation or the bias, with its
///   standard deviation when `sigma` is given (out-of-range values are refused with a
///   [`crate::StateError`], nothing changed); `set_heading` turns about earth-up;
/// - `flags` tells what happened to the last sample ([`crate::filters::SampleFlags`]: skips,
///   gating, rest, magnetic disturbance), `rejections` counts skips by reason
///   ([`crate::filters::Rejections`]); `rest_detected` and `magnetic_disturbance` are the
///   detector states; `params` returns the parameters.
///
/// # Example
///
/// 6D in `f64`: a sensor lying still, tilted, with a gyroscope bias.
///
/// ```
/// use rootfuse_attitude::prelude::*;
///
/// let params = SqrtEskfParams { dof: Dof::Six, ..Default::default() };
/// let mut filter = SqrtEskf::<f64>::try_new(&params).expect("valid parameters");
/// let acc = Vec3::new(0.0, 3.0, 9.3); // m/s², sensor frame: gravity of a tilted sensor
/// let gyr = Vec3::new(0.01, 0.0, 0.0); // rad/s: at rest, so all of it is bias
/// let sample = ImuSample::six_d(gyr, acc);
/// for _ in 0..2000 {
///     filter.update(&sample, 0.01); // 20 s at 100 Hz
/// }
/// // At rest the bias is measured directly...
/// assert!((filter.bias().x - 0.01).abs() < 1e-3);
/// // ...and the orientation (sensor to earth) turns the measured gravity onto earth-up.
/// let up = filter.quat().rotate(acc);
/// assert!(up.x.hypot(up.y) < 0.01 * up.norm());
///
/// filter.reset(); // a new filter with the same parameters
/// assert_eq!(filter.bias(), Vec3::zero());
/// ```
#[derive(Clone, Debug)]
pub struct SqrtEskf<T: Lane> {
    state: State<T>,
    coef: Coefficients<T>,
    nine_d: bool,
    bounds: ScreenBounds<T>,
    rejections: Rejections<T>,
    per_dt: Cached<T, PerDt<T>>,
    per_interval: Cached<T, PerInterval<T>>,
    per_heading: Cached<T, PerHeading<T>>,
    params: SqrtEskfParams,
}

impl<T: Lane> SqrtEskf<T> {
    crate::filters::uniform_constructors!(SqrtEskfParams);

    /// A filter whose lanes may have different parameters (see [`LaneParams`]); `dof` and
    /// the screening limits are those of the first set.
    pub fn with_lane_params(p: &LaneParams<'_, SqrtEskfParams, T>) -> Self {
        let coef = Coefficients::new(p);
        let per_dt = Cached::new(&coef);
        Self {
            state: State::new(&coef),
            coef,
            nine_d: p.first().dof.uses_magnetometer(),
            bounds: p.first().screen_limits().bounds(),
            rejections: Rejections::default(),
            per_dt,
            per_interval: Cached::new(&coef),
            per_heading: Cached::new(&coef),
            params: p.first().clone(),
        }
    }

    /// The 6D orientation (gravity and gyro only; heading drifts), sensor to earth.
    pub fn quat6(&self) -> Quat<T> {
        (self.state.correction * self.state.strapdown).renormalize()
    }

    /// The 9D orientation (heading from the magnetometer), sensor to earth.
    pub fn quat9(&self) -> Quat<T> {
        let st = &self.state;
        (Quat::from_heading(st.heading_offset) * st.correction * st.strapdown).renormalize()
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
