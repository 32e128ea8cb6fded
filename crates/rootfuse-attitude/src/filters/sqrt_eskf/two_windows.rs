//! The flagship's second accelerometer window: a longer low-pass beside the `tau_acc` one,
//! and the weight that blends their inclination measurements.
//!
//! One time constant cannot serve both kinds of motion: sustained or repeated translation
//! wants a long window (more of the motion acceleration averages out), fast rotation a short
//! one (the gyroscope's scale-factor and misalignment errors build up inside the window, and
//! the longer the window the more of them the lag term must carry). Which regime the sensor
//! is in is read from a signal neither window produces: the ratio of the translation
//! (`|a − â|`, the specific force against the short window's gravity estimate, m/s²) to the
//! rotation rate (`|ω − b̂|`, rad/s), each low-passed over `window_tau`. The weight of the long
//! window is `x⁴ / (1 + x⁴)`, `x = translation / (window_ratio · rotation)`; it moves on the
//! scale of `window_tau`, so the blended measurement never switches quickly. Both windows'
//! innovations and lag terms are blended with the same weight, so the lag row of `H` always
//! matches what is measured. The derivation and the cross-validation are in docs/methods.md
//! and docs/accuracy.md.

use super::*;

/// Floors of the two motion measures (m/s², rad/s): at rest and in slow motion both are
/// noise, and their ratio is then held near `1 / window_ratio` instead of following it.
const TRANSLATION_FLOOR: f64 = 0.05;
const ROTATION_FLOOR: f64 = 0.05;

impl<T: Lane> InertialLowpass<T> {
    /// Before the first sample: a force along `+z` and the identity rotation.
    pub(super) fn new() -> Self {
        let up = Vec3::new(T::zero(), T::zero(), T::one());
        Self {
            acc1: up,
            acc: up,
            rot1: Mat::identity(),
            rot: Mat::identity(),
        }
    }

    /// Both stages seeded with the first sample's force `acc` and the identity rotation,
    /// in the lanes `fresh`.
    pub(super) fn seed(&mut self, fresh: T::Mask, acc: Vec3<T>) {
        self.acc1 = Vec3::select(fresh, acc, self.acc1);
        self.acc = Vec3::select(fresh, acc, self.acc);
        self.rot1 = Mat::select(fresh, &Mat::identity(), &self.rot1);
        self.rot = Mat::select(fresh, &Mat::identity(), &self.rot);
    }

    /// Both rotation stages set to `r`, in the lanes `moved` (the strapdown frame moved).
    pub(super) fn move_rotation(&mut self, moved: T::Mask, r: &Mat<T, 3, 3>) {
        self.rot1 = Mat::select(moved, r, &self.rot1);
        self.rot = Mat::select(moved, r, &self.rot);
    }

    /// One step of gain `k` (each stage) with the specific force `a_i` and the rotation `rg`,
    /// both in the `I` frame; the force only where `ok`.
    #[inline]
    pub(super) fn step(&mut self, k: T, ok: T::Mask, a_i: Vec3<T>, rg: &Mat<T, 3, 3>) {
        self.acc1 = Vec3::select(ok, self.acc1 + (a_i - self.acc1) * k, self.acc1);
        self.acc = Vec3::select(ok, self.acc + (self.acc1 - self.acc) * k, self.acc);
        self.rot1 = Mat::from_fn(|i, j| self.rot1.m[i][j] + (rg.m[i][j] - self.rot1.m[i][j]) * k);
        self.rot =
            Mat::from_fn(|i, j| self.rot.m[i][j] + (self.rot1.m[i][j] - self.rot.m[i][j]) * k);
    }
}

impl<T: Lane> LongWindow<T> {
    pub(super) fn new() -> Self {
        Self {
            lowpass: InertialLowpass::new(),
            translation: T::from_f64(TRANSLATION_FLOOR),
            rotation: T::from_f64(ROTATION_FLOOR),
        }
    }
}

/// One sample in the quasi-inertial frame `I`, which both windows low-pass.
pub(super) struct InertialSample<T: Lane> {
    /// Specific force, m/s².
    pub force: Vec3<T>,
    /// Sensor-to-`I` rotation (the strapdown orientation).
    pub rotation: Mat<T, 3, 3>,
    /// How far the start-up has gone, in `[0, 1]` (the windows' time constants ramp with it).
    pub ramp: T,
}

/// One sample's inclination measurement (see [`SqrtEskf::inclination_measurement`]).
pub(super) struct InclinationMeasurement<T: Lane> {
    /// The horizontal innovation (earth frame, rad) and the lanes where it has a direction.
    pub innovation: ([T; 2], T::Mask),
    /// The lag term of `H`, `τ·R̄` (rows: earth axes; columns: bias components), s.
    pub lag: Mat<T, 3, 3>,
    /// What the reported model error learns from, rad² per axis.
    pub model_error2: T,
    /// `|ā|²` of the low-passed specific force measured, (m/s²)².
    pub acc_norm2: T,
}

impl<T: Lane> SqrtEskf<T> {
    /// Lanes that run two windows (`tau_acc_long > 0`).
    pub(super) fn two_windows(&self) -> T::Mask {
        self.coef.tau_acc_long.simd_gt(T::zero())
    }

    /// The long window's low-pass step (time constant `tau_acc_long`, ramped over the
    /// start-up as the short one) and its motion measures: `translation2` is `|a − â|²`
    /// (m/s², against the short window before this sample), `rate` the bias-corrected rate.
    /// The measures learn only from usable samples and hold at rest. Returns the long
    /// window's time constant, s.
    pub(super) fn lowpass_long(
        &mut self,
        s: &Screened<T>,
        inertial: &InertialSample<T>,
        translation2: T,
        rate: Vec3<T>,
        rest: T::Mask,
    ) -> T {
        let ramp = inertial.ramp;
        let tau = self.coef.tau_acc_long * ramp;
        let k = if ramp.simd_lt(T::one()).any() {
            lowpass_gain_at_rate(s.dt, self.coef.acc_long_stage_rate / ramp)
        } else {
            self.per_dt.k_acc_long
        };
        let w = &mut self.state.long;
        w.lowpass
            .step(k, s.acc_ok, inertial.force, &inertial.rotation);
        let kw = self.per_dt.k_window;
        let learn = s.acc_ok & !rest & translation2.is_finite();
        let translation = translation2.sqrt().max(T::from_f64(TRANSLATION_FLOOR));
        let rotation = rate.norm().max(T::from_f64(ROTATION_FLOOR));
        w.translation = T::select(
            learn,
            w.translation + (translation - w.translation) * kw,
            w.translation,
        );
        w.rotation = T::select(learn, w.rotation + (rotation - w.rotation) * kw, w.rotation);
        tau
    }

    /// The inclination innovation (horizontal, earth frame, rad; and the lanes where it has a
    /// direction) and the lag term `τ·R̄` of `H` (rows: earth axes; columns: bias components;
    /// s) of the `tau_acc` window, or, where a lane runs two, of the two windows blended by
    /// [`long_window_weight`](Self::long_window_weight): the low-passed specific forces
    /// (both along gravity within the motion left in them, so blending the vectors blends
    /// the innovations to first order, with one innovation to compute) and the lag terms
    /// `τ·LP(R)` alike; `tau` and `tau_long` are the windows' time constants at this sample
    /// (both windows have stepped).
    ///
    /// Also returns what the reported model error learns from (rad², per axis): the mean
    /// square of the `tau_acc` window's innovation. With two windows that is the short
    /// window's (its small-angle `sin²`), not the blend's: the blend leaves less motion in
    /// the innovation but not less error in the estimate, so its innovation would make the
    /// reported covariance overconfident exactly where the long window weighs.
    pub(super) fn inclination_measurement(&self, tau: T, tau_long: T) -> InclinationMeasurement<T> {
        let on = self.two_windows();
        let short_lag = Mat::from_fn(|i, k| tau * self.state.window.rot.m[i][k]);
        let (acc_lp, lag, short_error2) = if on.any() {
            let weight = self.long_window_weight();
            let st = &self.state;
            let blend = |a: T, b: T| T::select(on, a + (b - a) * weight, a);
            let acc_lp = Vec3::new(
                blend(st.window.acc.x, st.long.lowpass.acc.x),
                blend(st.window.acc.y, st.long.lowpass.acc.y),
                blend(st.window.acc.z, st.long.lowpass.acc.z),
            );
            let lag = Mat::from_fn(|i, k| {
                blend(short_lag.m[i][k], tau_long * st.long.lowpass.rot.m[i][k])
            });
            let v = st.correction.rotate(st.window.acc);
            let sin2 = (v.x * v.x + v.y * v.y) / v.norm_squared();
            (acc_lp, lag, Some(sin2 * T::from_f64(0.5)))
        } else {
            (self.state.window.acc, short_lag, None)
        };
        let rc = self.state.correction.to_rotation_matrix();
        let innovation = self.inclination_innovation(acc_lp);
        let eps = innovation.0;
        let error2 = (eps[0] * eps[0] + eps[1] * eps[1]) * T::from_f64(0.5);
        InclinationMeasurement {
            innovation,
            lag: rc * lag,
            model_error2: short_error2.map_or(error2, |e2| T::select(on, e2, error2)),
            acc_norm2: acc_lp.norm_squared(),
        }
    }

    /// The scale of the reported inclination model error at this motion:
    /// `model_error_scale` blended toward `model_error_rotation_scale` by `1/(1 + x⁴)`,
    /// `x = translation / (model_error_ratio · rotation)` (the motion measures of
    /// [`lowpass_long`](Self::lowpass_long)); `model_error_scale` in lanes with one window,
    /// whose measures are not learned.
    pub(super) fn model_error_scale_now(&self) -> T {
        let c = &self.coef;
        let rotation_share = T::one() / (T::one() + self.motion_ratio4(c.model_error_ratio));
        let blended = c.model_error_scale
            + (c.model_error_rotation_scale - c.model_error_scale) * rotation_share;
        T::select(self.two_windows(), blended, c.model_error_scale)
    }

    /// `x⁴` of `x = translation / (ratio · rotation)`, the long window's motion measures
    /// against a ratio in m/s: what both the window's weight and the model error's scale
    /// follow.
    fn motion_ratio4(&self, ratio: T) -> T {
        let w = &self.state.long;
        let x = w.translation / (ratio * w.rotation);
        let x2 = x * x;
        x2 * x2
    }

    /// Weight of the long window, in `[0, 1]`: `x⁴ / (1 + x⁴)` of
    /// `x = translation / (window_ratio · rotation)`; zero in lanes with one window.
    pub(super) fn long_window_weight(&self) -> T {
        let x4 = self.motion_ratio4(self.coef.window_ratio);
        T::select(self.two_windows(), x4 / (T::one() + x4), T::zero())
    }
}
