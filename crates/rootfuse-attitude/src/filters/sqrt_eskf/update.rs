//! The flagship's per-sample steps (time update, start, rest, inclination, bias, heading) and
//! its [`OrientationFilter`] implementation; the state and the public API are in the parent.
//! The design is documented on [`SqrtEskf`], the derivation in docs/methods.md.

use super::*;
use crate::filters::StateError;

/// Variance (rad², 30° standard deviation) of a heading offset taken from a single
/// magnetometer reading: at the start and when a lane takes a new field reference.
pub(super) const INITIAL_HEADING_VAR: f64 = 0.25;

impl<T: Lane> SqrtEskf<T> {
    /// Carlson's square-root scalar update ([`carlson_gains`], then [`carlson_apply`] where
    /// the gate accepts: the factor stays upper triangular) with measurement row `h` (zero
    /// before index `FIRST`) and innovation `nu`, applied where `apply`. `r` is one sample's
    /// measurement variance, `r_update` the variance the update is made with (smaller where
    /// the measurement stands for several samples: `acc_update_every`). The χ² gate (`gate`
    /// standard deviations) is tested here, against one sample's innovation variance.
    /// Returns (state correction `δx`, lanes accepted, that innovation variance).
    fn scalar_update<const FIRST: usize>(
        &mut self,
        h: [T; 6],
        nu: T,
        (r, r_update): (T, T),
        gate: T,
        apply: T::Mask,
    ) -> ([T; 6], T::Mask, T) {
        let gains = carlson_gains::<T, FIRST>(&self.state.factor, &h, r);
        let alpha = gains.innovation_variance();
        let in_gate = (nu * nu).simd_le(gate * gate * alpha);
        // With `r > 0` and a finite `α` (hence finite `f`), every entry of the new factor is
        // finite (`|W_jj| ≤ 1`, `W_ij` bounded): checking `α` and `ν` is enough.
        let update = gains.with_noise::<FIRST>(r_update);
        let alpha_update = update.innovation_variance();
        let ok = apply
            & r.simd_gt(T::zero())
            & r_update.simd_gt(T::zero())
            & alpha.is_finite()
            & alpha_update.is_finite()
            & nu.is_finite();
        let accept = ok & in_gate;
        // The gate decides before the factor is written: where no lane accepts, nothing is.
        if !accept.any() {
            return ([T::zero(); 6], accept, alpha);
        }
        let sf = carlson_apply::<T, FIRST>(&mut self.state.factor, &update, accept);
        let k = nu / T::select(accept, alpha_update, T::one());
        let dx = core::array::from_fn(|i| T::select(accept, sf[i] * k, T::zero()));
        (dx, accept, alpha)
    }

    /// Injects an error-state correction into `c` and `b̂` (then the error is zero again).
    /// Lanes that accepted no update keep `c` and `b̂` bit for bit (no renormalisation),
    /// so whether an update ran at all — some are skipped when no lane needs them — is invisible.
    fn inject(&mut self, correction: Correction<T>) {
        let Correction { dx, accepted } = correction;
        if !accepted.any() {
            return;
        }
        let st = &mut self.state;
        let dtheta = Vec3::new(dx[0], dx[1], dx[2]);
        let corrected = (Quat::from_rotation_vector(dtheta) * st.correction).renormalize();
        st.correction = Quat::select(accepted, corrected, st.correction);
        st.bias = Vec3::select(accepted, st.bias + Vec3::new(dx[3], dx[4], dx[5]), st.bias);
    }

    /// Initialisation from the first usable sample: inclination from gravity, low-passes
    /// seeded with the sample. The heading offset and the field reference are taken from
    /// the first usable magnetometer reading by `correct_heading`.
    fn initialise(&mut self, s: &Screened<T>, acc_raw: Vec3<T>) {
        let st = &mut self.state;
        let fresh = !st.initialized & s.acc_ok;
        // Every assignment below is a per-lane select on `fresh`: skipping the block when no
        // lane starts changes no result and saves the work on every later sample.
        if fresh.any() {
            let zero = T::zero();
            let (tilt, _) = tilt_from_acc(s.acc);
            // Until now the gyroscope was integrated from the identity (or the preset
            // orientation). A preset orientation, carried by the gyro, is kept; otherwise the
            // inclination comes from gravity and the heading the gyro has integrated is kept
            // (the heading of `q_gyr ⊗ tilt*`, as the metrics define it), so the estimate
            // does not jump about earth-z.
            let integrated = st.correction * st.strapdown;
            let e = integrated * tilt.conj();
            let levelled = Quat::from_heading(T::from_f64(2.0) * e.z.atan2(e.w)) * tilt;
            let start = Quat::select(st.preset, integrated, levelled).normalize();
            st.correction = Quat::select(fresh, start, st.correction);
            st.strapdown = Quat::select(fresh, Quat::identity(), st.strapdown);
            st.window.seed(fresh, acc_raw);
            st.long.lowpass.seed(fresh, acc_raw);
            st.rest_acc_lp = Vec3::select(fresh, acc_raw, st.rest_acc_lp);
            st.rest_gyr_lp = Vec3::select(fresh, s.gyr, st.rest_gyr_lp);
            // The heading offset and the field reference come from the first usable
            // magnetometer reading, in `correct_heading` (the lane has no reference yet).
            st.heading_offset = T::select(fresh, zero, st.heading_offset);
            let restart = fresh & !st.preset_covariance;
            st.factor = Mat::select(restart, &self.coef.initial_factor(), &st.factor);
            st.clear_pending(restart);
            // The bias is kept: zero unless `set_bias` gave one before the first sample (the
            // strapdown integration before this sample already used it).
            st.age = T::select(fresh, zero, st.age);
            st.gyro_scale.restart(fresh, st.correction, zero);
            st.heading_offset_var = T::select(
                fresh & !st.preset_covariance,
                T::from_f64(INITIAL_HEADING_VAR),
                st.heading_offset_var,
            );
            st.initialized |= fresh;
        }
    }

    /// Lanes whose accelerometer sample, though within `max_acc`, deviates from the low-passed
    /// specific force by more than `acc_spike`: a corrupted sample, not motion. Compared in
    /// the sensor frame through the strapdown rotation of the previous sample (one sample of
    /// rotation changes the comparison by far less than the threshold). Not before a lane
    /// is initialised: it has no low-pass yet. Also returns that squared deviation, (m/s²)²
    /// (the translation the second window's weight reads).
    fn acc_spike(&self, s: &Screened<T>) -> (T::Mask, T) {
        let st = &self.state;
        let expected = st.strapdown.rotate_inverse(st.window.acc);
        let dev = (s.acc * s.acc_norm - expected).norm_squared();
        // `>` is false for NaN, but a screened accelerometer is finite where `acc_ok`.
        (
            s.acc_ok & st.initialized & dev.simd_gt(self.coef.acc_spike2),
            dev,
        )
    }

    /// Rest detection: deviation of gyro and accelerometer from their own low-pass, and a
    /// small bias-corrected low-passed rate. Returns the lanes at rest.
    fn detect_rest(&mut self, s: &Screened<T>, acc_raw: Vec3<T>) -> T::Mask {
        let c = &self.coef;
        let st = &mut self.state;
        let k_rest = self.per_dt.k_rest;
        st.rest_gyr_lp += (s.gyr - st.rest_gyr_lp) * k_rest;
        let acc_for_rest = Vec3::select(s.acc_ok, acc_raw, st.rest_acc_lp);
        st.rest_acc_lp += (acc_for_rest - st.rest_acc_lp) * k_rest;
        let gyr_dev = (s.gyr - st.rest_gyr_lp).norm_squared();
        let acc_dev = (acc_for_rest - st.rest_acc_lp).norm_squared();
        // A slow constant-rate turn has a small deviation too: the bias-corrected low-passed
        // rate must also be small (a rotating sensor is not at rest).
        let turning = (st.rest_gyr_lp - st.bias)
            .norm_squared()
            .simd_gt(c.rest_gyr2);
        // A sample without a usable accelerometer (skipped or gated) neither confirms nor
        // breaks the rest: `acc_for_rest` holds the low-pass there, so its deviation is zero and
        // the gyroscope alone decides. (Requiring `acc_ok` made one spike restart the
        // `rest_time` wait.)
        let still = gyr_dev.simd_le(c.rest_gyr2) & !turning & acc_dev.simd_le(c.rest_acc2);
        st.rest_timer = T::select(still, st.rest_timer + s.dt, T::zero());
        let rest = self.at_rest();
        let st = &mut self.state;
        let g2 = st.rest_acc_lp.norm_squared().min(st.rest_gravity2);
        st.rest_gravity2 = T::select(rest, g2, st.rest_gravity2);
        rest
    }

    /// Strapdown propagation and the square-root time update (with re-acquisition and
    /// start-up inflation). Returns (bias-corrected rate, rad/s; growth of the 6D heading
    /// variance, rad²; lanes in the start-up phase).
    fn propagate(&mut self, s: &Screened<T>) -> (Vec3<T>, T, T::Mask) {
        let zero = T::zero();
        let dt = s.dt;
        let w = s.gyr - self.state.bias;
        self.state.strapdown =
            (self.state.strapdown * Quat::from_rotation_vector(w * dt)).renormalize();
        let r6 = (self.state.correction * self.state.strapdown).to_rotation_matrix();
        if self.estimates_gyro_scale() {
            (self.state.gyro_scale).accumulate(&r6, w, dt, s.acc, s.acc_ok);
        }

        // A gate timing out means the model is wrong (wrong start, a bias step): re-inflate
        // the inclination and the bias covariance. During the start-up phase the inclination
        // covariance is inflated continuously (in total by `reacquire_std²`) so a wrong first
        // sample is corrected by the attitude, not absorbed by the bias.
        let c = &self.coef;
        let reacquire = self.state.acc_rejected_time.simd_gt(c.acc_reject_time);
        let starting = self.state.age.simd_lt(c.startup_time);
        // A preset with its own covariance is not a wrong first sample: no inflation.
        let inflating = starting & !self.state.preset_covariance;
        let startup_std = if inflating.any() {
            T::select(
                inflating,
                c.reacquire_std * (dt / c.startup_time).sqrt(),
                zero,
            )
        } else {
            zero
        };
        let extra = T::select(reacquire, c.reacquire_std, startup_std);
        let extra_b = T::select(reacquire | self.state.bias_step, c.init_bias_std, zero);
        self.state.age += dt;
        // The 9D heading offset must follow the 6D heading drift: its variance grows by
        // what the time update adds to the 6D heading variance (gyro noise and the
        // earth-vertical bias uncertainty), plus `heading_walk` for magnetic model errors.
        // (6D has no heading offset.)
        let flush = self.measurement_may_be_due();
        let heading_growth = if self.nine_d {
            let pzz_before = row_norm2(&self.state.factor, 2);
            let flushed = self.time_update(&r6, dt, (extra, extra_b), flush);
            if flushed.any() {
                T::select(flushed, self.heading_growth(pzz_before), zero)
            } else {
                zero
            }
        } else {
            self.time_update(&r6, dt, (extra, extra_b), flush);
            zero
        };
        self.state.acc_rejected_time = T::select(reacquire, zero, self.state.acc_rejected_time);
        (w, heading_growth, starting)
    }

    /// Low-pass of the specific force and of the rotation in the quasi-inertial frame.
    /// Returns the low-pass time constant τ, s, and the sample in that frame (the long
    /// window steps with it too).
    fn lowpass_acc(
        &mut self,
        s: &Screened<T>,
        acc_raw: Vec3<T>,
    ) -> (T, two_windows::InertialSample<T>) {
        let st = &mut self.state;
        // The low-pass time constant grows linearly over the start-up phase, so the first
        // seconds follow the accelerometer (and a wrong start is not frozen into the average).
        let ramp = (st.age / self.coef.startup_time).min(T::one());
        let tau = self.coef.tau_acc * ramp;
        // Two equal first-order stages (τ/2 each): a critically damped second-order low-pass
        // whose mean delay is still τ, with −40 dB/decade above its corner. After the
        // start-up (ramp = 1 in every lane) the gain is the cached one; a lane at ramp 1
        // before its neighbours divides its rate by one, the cached gain's bits.
        let k_acc = if ramp.simd_lt(T::one()).any() {
            lowpass_gain_at_rate(s.dt, self.coef.acc_stage_rate / ramp)
        } else {
            self.per_dt.k_acc
        };
        let sample = two_windows::InertialSample {
            force: st.strapdown.rotate(acc_raw),
            rotation: st.strapdown.to_rotation_matrix(),
            ramp,
        };
        st.window
            .step(k_acc, s.acc_ok, sample.force, &sample.rotation);
        (tau, sample)
    }

    /// The horizontal rotation vector (earth frame, rad) that turns the low-passed specific
    /// force `acc_lp` (`I` frame), brought to the earth frame by `c`, onto up; false where it
    /// has no direction.
    pub(super) fn inclination_innovation(&self, acc_lp: Vec3<T>) -> ([T; 2], T::Mask) {
        let (zero, one) = (T::zero(), T::one());
        let (v, v_ok) = self.state.correction.rotate(acc_lp).try_normalize();
        // Rotation vector turning v onto up: axis v × up = (v_y, −v_x, 0).
        let sxy = (v.x * v.x + v.y * v.y).sqrt();
        let angle = sxy.atan2(v.z);
        let scale = T::select(
            sxy.simd_gt(zero),
            angle / T::select(sxy.simd_gt(zero), sxy, one),
            one,
        );
        ([v.y * scale, -v.x * scale], v_ok)
    }

    /// The lanes that correct their inclination at this sample (every `acc_update_every`th
    /// sample where the accelerometer is usable, else at the next such tick; the start-up
    /// too, where the gate is open and the low-pass short, so that the first seconds do not
    /// cost 1.7 updates each) and the usable accelerometer time since the last correction, s,
    /// which the correction stands for (`dt` where every sample is corrected: `0 + dt`). The
    /// time starts again where a lane corrects; the ticks keep their phase, so lanes started
    /// together correct at the same samples (a correction costs every lane).
    fn inclination_due(&mut self, s: &Screened<T>) -> (T::Mask, T) {
        let zero = T::zero();
        let st = &mut self.state;
        let tick = every_nth(&mut st.inclination_phase, self.coef.acc_update_every);
        let time = st.inclination_time + T::select(s.acc_ok, s.dt, zero);
        let due = s.acc_ok & tick;
        st.inclination_time = T::select(due, zero, time);
        (due, time)
    }

    /// Gyro-bias step detection by innovation consistency: a bias step makes the strapdown
    /// frame drift, and the inclination corrections then chase a persistent, one-signed
    /// innovation, while a consistent filter's innovations average out. The running mean of
    /// the innovation (time constant `bias_step_window`) is compared with what white
    /// innovations of density `acc_noise²` leave in it; beyond `bias_step_gate` standard
    /// deviations the next time update re-inflates the bias covariance by `init_bias_std`,
    /// and the lag-aware inclination measurement (`H` contains `τ·R̄`) then learns the new
    /// bias within seconds rather than at the random-walk rate. Not during start-up.
    fn detect_bias_step(&mut self, starting: T::Mask, due: T::Mask, (eps, ok): ([T; 2], T::Mask)) {
        let c = &self.coef;
        let st = &mut self.state;
        // Disabled in every lane (the default): the running means are read nowhere else.
        if !c.bias_step_threshold.simd_gt(T::zero()).any() {
            st.bias_step = <T::Mask as Mask>::splat(false);
            return;
        }
        let use_it = due & ok & !starting;
        let k = self.per_interval.k_bias_step;
        let mx = st.innovation_mean_x + (eps[0] - st.innovation_mean_x) * k;
        let my = st.innovation_mean_y + (eps[1] - st.innovation_mean_y) * k;
        let step = use_it
            & c.bias_step_threshold.simd_gt(T::zero())
            & (mx * mx + my * my).simd_gt(c.bias_step_threshold);
        // After a detection the mean starts again from zero, so one step inflates once per
        // window at most.
        let zero = T::zero();
        st.innovation_mean_x = T::select(step, zero, T::select(use_it, mx, st.innovation_mean_x));
        st.innovation_mean_y = T::select(step, zero, T::select(use_it, my, st.innovation_mean_y));
        st.bias_step = step;
    }

    /// Per lane: the last sample detected a gyro-bias step
    /// (see [`SqrtEskfParams::bias_step_gate`]).
    pub fn bias_step_detected(&self) -> T::Mask {
        self.state.bias_step
    }

    /// Inclination: two sequential scalar updates on the horizontal error components.
    /// The low-passed vector measures δθ + τ·R̄·δb with R̄ = R(c)·LP(R(q_strapdown)): the
    /// exponential average of the drift ∫R·δb over the window has weight e^{−v/τ} at lag v.
    /// The second component's innovation is the first's residual to first order
    /// (`ε_y − δθ_y` of the first correction): the measurement is linearised once per sample,
    /// and the correction is injected once ([`Correction`]), which is what keeps the
    /// per-sample chain of dependent square roots and rotations short. In the lanes `due`
    /// only (`acc_update_every`): the gate and the covariance matching judge the innovation
    /// against one sample's variance, the update is made with the variance of the usable
    /// accelerometer `time` since the last correction.
    fn correct_inclination(
        &mut self,
        measured: &two_windows::InclinationMeasurement<T>,
        starting: T::Mask,
        (due, time): (T::Mask, T),
    ) -> Correction<T> {
        let (eps, v_ok) = measured.innovation;
        let lag = &measured.lag;
        let zero = T::zero();
        // The noise follows the motion (`acc_noise_rotation_share`; 1, or one window: as is).
        let share = self.coef.acc_noise_rotation_share;
        let (r_nominal, r_interval) = if share.simd_lt(T::one()).any() {
            let w = self.long_window_weight();
            let s = share + (T::one() - share) * w;
            let s2 = T::select(self.two_windows(), s * s, T::one());
            (self.per_dt.r_acc * s2, self.per_interval.r_acc * s2)
        } else {
            (self.per_dt.r_acc, self.per_interval.r_acc)
        };
        // Covariance matching: where the innovations have been larger than predicted, the
        // measurement variance grows by that ratio (bits unchanged where disabled).
        // A window of 0 (off) is a rate of ∞ (so is one below f32's smallest reciprocal,
        // about 3e-39 s, in `f32` lanes).
        let adapt = self.coef.adapt_rate.simd_lt(T::from_f64(f64::INFINITY));
        let scale = self
            .state
            .innovation_nis
            .max(T::one())
            .min(T::from_f64(1000.0));
        let r_acc = T::select(adapt, r_nominal * scale, r_nominal);
        let r_update = T::select(adapt, r_interval * scale, r_interval);
        let gate = T::select(starting, T::from_f64(1e6), self.coef.acc_gate);
        let apply = due & v_ok;
        let row = |axis: usize| {
            let mut h = [zero; 6];
            h[axis] = T::one();
            h[3..].copy_from_slice(&lag.m[axis]);
            h
        };
        let (dx0, accepted0, alpha0) =
            self.scalar_update::<0>(row(0), eps[0], (r_acc, r_update), gate, apply);
        let nu1 = eps[1] - dx0[1];
        let (dx1, accepted1, alpha1) =
            self.scalar_update::<1>(row(1), nu1, (r_acc, r_update), gate, apply);
        // The model error's mean square (reported with the covariance): the innovation before
        // this sample's correction, per axis (see `inclination_measurement`).
        {
            let e2 = measured.model_error2;
            let k = self.per_interval.k_model;
            let m = self.state.innovation_ms;
            let learn = apply & !starting & e2.is_finite();
            self.state.innovation_ms = T::select(learn, m + (e2 - m) * k, m);
            let c = &self.coef;
            let sf = c.gyr_scale_error * self.state.long.rotation * c.tau_acc;
            let seen = self.state.rest_gravity2;
            let g2 = T::select(
                seen.is_finite(),
                seen,
                T::from_f64(STANDARD_GRAVITY * STANDARD_GRAVITY),
            );
            let excess = (measured.acc_norm2 / g2 - T::one()).max(zero) * c.acc_excess_scale;
            // Where the scale is 0, exactly `sf²` (no `0 · ∞` from a wild low-pass).
            let excess = T::select(c.acc_excess_scale.simd_gt(zero), excess, zero);
            self.state.scale_error2 = T::select(learn, sf * sf + excess, self.state.scale_error2);
        }
        if adapt.any() {
            // Each innovation against its variance predicted with the nominal noise.
            let nominal = |alpha: T| alpha - r_acc + r_nominal;
            let nis = (eps[0] * eps[0] / nominal(alpha0) + nu1 * nu1 / nominal(alpha1))
                * T::from_f64(0.5);
            let k = self.per_interval.k_adapt;
            let m = self.state.innovation_nis;
            let learn = adapt & apply & !starting & nis.is_finite();
            self.state.innovation_nis = T::select(learn, m + (nis - m) * k, m);
        }
        let accepted = accepted0 | accepted1;
        let gated = apply & !accepted;
        self.rejections.gate(gated);
        // Only an accepted measurement ends a rejection period; a gated one adds the usable
        // accelerometer time it stands for, and a sample without a usable accelerometer holds
        // the timer (resetting it let a spike or a dropped sample postpone the re-acquisition
        // by up to `acc_reject_time`).
        let t = self.state.acc_rejected_time;
        self.state.acc_rejected_time = T::select(gated, t + time, T::select(apply, zero, t));
        Correction {
            dx: core::array::from_fn(|i| dx0[i] + dx1[i]),
            accepted,
        }
    }

    /// Bias at rest: the low-passed gyro measures `b` directly, one scalar update per
    /// component against the bias as corrected so far (`b̂ + δb` of `correction`: the
    /// measurement is linear, so this is exact), added to `correction`. Every
    /// `rest_update_every` samples, in the lanes at rest then, each measurement standing for
    /// the stepping time since the last tick (`r = rest_noise²/T`; with 1, `T = dt`).
    fn correct_bias_at_rest(
        &mut self,
        s: &Screened<T>,
        rest: T::Mask,
        correction: &mut Correction<T>,
    ) {
        let st = &mut self.state;
        let tick = every_nth(&mut st.rest_phase, self.coef.rest_update_every);
        let time = st.rest_interval_time + s.dt;
        st.rest_interval_time = T::select(tick, T::zero(), time);
        let due = rest & tick;
        // Every lane not due discards these updates: skipping them when no lane is due
        // changes no result.
        if !due.any() {
            return;
        }
        let r = self.coef.rest_var / divisor(time);
        self.rest_axis::<3>(due, r, correction);
        self.rest_axis::<4>(due, r, correction);
        self.rest_axis::<5>(due, r, correction);
    }

    /// The at-rest measurement of bias component `STATE − 3` (`H = e_STATE`), variance `r`.
    fn rest_axis<const STATE: usize>(
        &mut self,
        due: T::Mask,
        r: T,
        correction: &mut Correction<T>,
    ) {
        let mut h = [T::zero(); 6];
        h[STATE] = T::one();
        let k = STATE - 3;
        let z = self.state.rest_gyr_lp.to_array()[k]
            - (self.state.bias.to_array()[k] + correction.dx[STATE]);
        let (dx, accepted, _) = self.scalar_update::<STATE>(h, z, (r, r), T::from_f64(1e6), due);
        for (total, d) in correction.dx.iter_mut().zip(dx) {
            *total += d;
        }
        correction.accepted |= accepted;
    }
}

/// Counts one more sample in `phase` (per lane) and tells the lanes where that completes
/// `every` samples, restarting the count there: ticks every `every` samples, the same
/// samples in every lane started together whatever their data (a tick that depends on
/// the data would put lanes out of step, and a correction due in any lane costs all).
pub(super) fn every_nth<T: Lane>(phase: &mut T, every: T) -> T::Mask {
    let next = *phase + T::one();
    let tick = next.simd_ge(every);
    *phase = T::select(tick, T::zero(), next);
    tick
}

/// The usable samples and their summed time (s) since the last field test, counting this
/// sample where `ok` (its `dt`), and counting from zero in the lanes `restart`: the mean
/// reading and the time a test stands for (`mag_update_every`).
pub(super) fn count_since<T: Lane>(
    (samples, time): (T, T),
    ok: T::Mask,
    dt: T,
    restart: T::Mask,
) -> (T, T) {
    let zero = T::zero();
    (
        T::select(restart, zero, samples) + T::select(ok, T::one(), zero),
        T::select(restart, zero, time) + T::select(ok, dt, zero),
    )
}

/// `Σ_j S_ij²`: the variance `P_ii` of state `i` from the factor.
pub(super) fn row_norm2<T: Lane>(s: &Mat<T, 6, 6>, i: usize) -> T {
    let mut v = T::zero();
    for x in s.m[i] {
        v += x * x;
    }
    v
}

impl<T: Lane> OrientationFilter<T> for SqrtEskf<T> {
    /// The estimated scale error of the gyroscope per sensor axis, a fraction: the readings
    /// are taken as `(1 + s)` times the rate. Zero with `gyr_scale_window = 0`, and until the
    /// end of the first window that starts after the start-up (windows start at the first
    /// usable accelerometer sample: with the defaults the estimate comes at 20 s).
    ///
    /// ```
    /// use rootfuse_attitude::prelude::*;
    ///
    /// let filter = SqrtEskf::<f64>::new(&SqrtEskfParams::default());
    /// assert_eq!(filter.gyro_scale(), Vec3::zero());
    /// ```
    fn gyro_scale(&self) -> Vec3<T> {
        self.state.gyro_scale.scale()
    }
    fn smoothing_gyro_tau(&self) -> f64 {
        self.params.smoothing_gyro_tau
    }
    fn update(&mut self, sample: &ImuSample<T>, dt: T) {
        let mut s = Screened::for_dof(sample, dt, &self.bounds, &mut self.rejections, self.nine_d);
        // The readings divided by their estimated scale (the readings themselves before the
        // first estimate): the start, the rest detector and the propagation all take these,
        // so that the bias measured at rest is the one the propagation subtracts.
        s.gyr = self.state.gyro_scale.corrected(s.gyr);
        // A spike is an unusable accelerometer sample from here on: every low-pass, detector
        // and correction below takes the accelerometer only where `acc_ok`.
        let (spike, translation2) = self.acc_spike(&s);
        s.acc_ok &= !spike;
        self.rejections.gate(spike);
        self.per_dt.refresh(s.dt, &self.coef);
        // Lanes that cannot step keep their whole state; lanes not yet initialised integrate
        // the gyroscope (strapdown only) until the first usable accelerometer sample. When
        // every lane steps from a running state there is nothing to restore, and the state
        // is not copied.
        let before = if (s.step & self.state.initialized).all() {
            None
        } else {
            Some(self.state)
        };
        let acc_raw = s.acc * s.acc_norm;
        self.initialise(&s, acc_raw);
        let rest = self.detect_rest(&s, acc_raw);
        let (w, heading_growth, starting) = self.propagate(&s);
        let (tau, inertial) = self.lowpass_acc(&s, acc_raw);
        let tau_long = if self.two_windows().any() {
            self.lowpass_long(&s, &inertial, translation2, w, rest)
        } else {
            T::zero()
        };
        let (due, time) = self.inclination_due(&s);
        // Where no lane corrects its inclination at this sample, the measurement is not
        // even formed (`acc_update_every`).
        let mut correction = if due.any() {
            self.per_interval
                .refresh(T::select(due, time, self.per_interval.time), &self.coef);
            let measured = self.inclination_measurement(tau, tau_long);
            self.detect_bias_step(starting, due, measured.innovation);
            self.correct_inclination(&measured, starting, (due, time))
        } else {
            self.state.bias_step = <T::Mask as Mask>::splat(false);
            Correction {
                dx: [T::zero(); 6],
                accepted: <T::Mask as Mask>::splat(false),
            }
        };
        self.correct_bias_at_rest(&s, rest, &mut correction);
        self.inject(correction);
        if self.estimates_gyro_scale() {
            let st = &mut self.state;
            st.gyro_scale.close(st.correction, st.age, &self.coef);
        }
        if self.nine_d {
            self.correct_heading(&s, w, heading_growth);
        }
        if let Some(before) = before {
            let keep = s.step & (before.initialized | self.state.initialized);
            let strapdown = self.state.strapdown;
            self.state = Select::select(keep, &self.state, &before);
            let integrating = s.step & !self.state.initialized;
            self.state.strapdown = Quat::select(integrating, strapdown, self.state.strapdown);
        }
    }
    fn reset(&mut self) {
        self.reset_state();
    }
    fn set_quat(&mut self, q: Quat<T>, sigma: Option<T>) -> Result<(), StateError> {
        self.set_orientation(q, sigma)
    }
    fn set_bias(&mut self, bias: Vec3<T>, sigma: Option<T>) -> Result<(), StateError> {
        self.set_gyro_bias(bias, sigma)
    }
    fn quat(&self) -> Quat<T> {
        if self.nine_d {
            self.quat9()
        } else {
            self.quat6()
        }
    }
    fn bias(&self) -> Vec3<T> {
        self.state.bias
    }
    fn rejections(&self) -> &Rejections<T> {
        &self.rejections
    }
    /// In 9D the heading variance is that of the magnetic heading offset and its correlation
    /// with the inclination is not tracked (set to zero). Both inclination variances include
    /// the model error: `model_error_scale` times the running mean square of the inclination
    /// innovation. Always `Some`.
    fn attitude_covariance(&self) -> Option<Mat<T, 3, 3>> {
        Some(self.attitude_block())
    }
    fn rest_detected(&self) -> Option<T::Mask> {
        Some(self.at_rest())
    }
    /// 9D only (`false` in 6D).
    fn magnetic_disturbance(&self) -> Option<T::Mask> {
        Some(self.state.mag_disturbed)
    }
    /// 9D: the next usable magnetometer reading becomes the field reference, pointing north,
    /// and sets the heading, as the first reading of a new filter does (unless the
    /// orientation was preset with `set_quat` before the first sample).
    fn forget_field_reference(&mut self, lanes: T::Mask) {
        self.state.field.known &= !lanes;
    }
}

#[cfg(test)]
mod tests {
    use super::super::{SqrtEskf, SqrtEskfParams};
    use crate::{ImuSample, OrientationFilter, Quat, Vec3};
    use rootfuse_lane::{Lane, Mat, wide::f32x8};

    /// A 9D `f64` flagship after `samples` samples at 100 Hz of a slow turn with a slight
    /// tilt and a dipping field.
    fn turning_filter(samples: u32) -> SqrtEskf<f64> {
        turning_filter_with(&SqrtEskfParams::default(), samples)
    }

    /// [`turning_filter`] with parameters `p` (in 6D the field readings are ignored).
    fn turning_filter_with(p: &SqrtEskfParams, samples: u32) -> SqrtEskf<f64> {
        let mut f = SqrtEskf::<f64>::new(p);
        for k in 0..samples {
            let t = f64::from(k) * 0.01;
            let sample = ImuSample::new(
                Vec3::new(0.8 * t.sin(), 0.5, -0.3 * t.cos()),
                Vec3::new(0.3 * t.cos(), -0.2, 9.8),
                Vec3::new(0.0, 20.0, -40.0),
            );
            f.update(&sample, 0.01);
        }
        f
    }

    /// Setting the bias between two flushes keeps the heading variance the report showed:
    /// the growth the deferred time update still held is handed to the 9D heading offset,
    /// as at a flush (dropped, the report would fall by the samples since the last one).
    #[test]
    fn setting_the_bias_between_flushes_keeps_the_heading_variance() {
        let mut f = turning_filter(402);
        assert!(
            f.state.yaw_noise_var > 0.0,
            "mid-interval: something is pending"
        );
        let before = f.attitude_covariance().unwrap().m[2][2];
        f.set_bias(f.bias(), Some(0.01)).unwrap();
        let after = f.attitude_covariance().unwrap().m[2][2];
        assert!(
            (after - before).abs() <= 1e-12 * before,
            "{before} → {after}"
        );
    }

    /// The report's inclination block, which applies a pending time update in closed form,
    /// is the full covariance's (which folds it in by reflections) to rounding, with a time
    /// update pending: in 6D (where the block keeps its heading correlations) and 9D.
    #[test]
    fn the_reported_inclination_block_is_the_covariances() {
        for nine_d in [true, false] {
            let dof = if nine_d {
                crate::Dof::Nine
            } else {
                crate::Dof::Six
            };
            let f = turning_filter_with(
                &SqrtEskfParams {
                    dof,
                    ..Default::default()
                },
                402,
            );
            assert!(f.state.tilt_noise_var > 0.0, "something is pending");
            let (a, p) = (f.attitude_covariance().unwrap(), f.covariance());
            let scale = (p.m[0][0] * p.m[1][1]).sqrt();
            assert!(
                (a.m[0][1] - p.m[0][1]).abs() <= 1e-12 * scale,
                "{a:?} vs {p:?}"
            );
            assert!(
                (a.m[1][0] - p.m[1][0]).abs() <= 1e-12 * scale,
                "{a:?} vs {p:?}"
            );
            // The report adds the model error (never negative) to the diagonal.
            for i in 0..2 {
                assert!(
                    a.m[i][i] >= p.m[i][i] * (1.0 - 1e-12),
                    "{i}: {a:?} vs {p:?}"
                );
            }
            if !nine_d {
                let scale = (p.m[0][0] * p.m[2][2]).sqrt();
                assert!(
                    (a.m[0][2] - p.m[0][2]).abs() <= 1e-12 * scale,
                    "{a:?} vs {p:?}"
                );
            }
        }
    }

    /// The time update deferred over several samples (the transitions summed, the attitude
    /// noise's variances added, one flush) gives the covariance of a time update at every
    /// sample, to rounding: over 1 to 12 samples of a turning orientation with the start-up's
    /// extra tilt noise, including a bias-noise tick and a bias inflation on the way.
    #[test]
    fn a_deferred_time_update_is_the_time_update_of_every_sample() {
        let f = turning_filter(400);
        let p = |g: &SqrtEskf<f64>| {
            let s = g.covariance_factor();
            s * s.transpose()
        };
        for steps in 1..=12 {
            let (mut each, mut deferred) = (f.clone(), f.clone());
            for k in 0..steps {
                let r = Quat::from_euler_zyx(0.3 * f64::from(k), 0.2, -0.1).to_rotation_matrix();
                let dt = 0.01 + 0.001 * f64::from(k % 3);
                each.per_dt.refresh(dt, &each.coef);
                deferred.per_dt.refresh(dt, &deferred.coef);
                let extra = (0.02, if k == 5 { 0.01 } else { 0.0 });
                each.time_update(&r, dt, extra, true);
                deferred.time_update(&r, dt, extra, false);
            }
            let (a, b): (Mat<f64, 6, 6>, Mat<f64, 6, 6>) = (p(&each), p(&deferred));
            for i in 0..6 {
                for j in 0..6 {
                    let scale = (a.m[i][i] * a.m[j][j]).sqrt();
                    assert!(
                        (a.m[i][j] - b.m[i][j]).abs() <= 1e-13 * scale,
                        "{steps} steps, P[{i}][{j}]: {} every sample, {} deferred",
                        a.m[i][j],
                        b.m[i][j]
                    );
                }
            }
            // Before the bias inflation (k = 5) nothing flushes the deferred one: its factor
            // still waits for the noise (what `covariance_factor` applied to a copy).
            if steps <= 5 {
                assert!(deferred.state.tilt_noise_var > 0.0 && each.state.tilt_noise_var == 0.0);
            }
        }
    }

    /// Lanes whose start-ups end at different samples (each its own time step) still correct
    /// the inclination, test the field, measure the bias at rest (the sample is still) and
    /// fold the bias noise at the same samples once
    /// every lane runs: a correction due in any lane costs every lane, so lanes out of step
    /// would pay for up to eight times as many.
    #[test]
    fn lanes_started_together_correct_at_the_same_samples() {
        let mut f = SqrtEskf::<f32x8>::new(&SqrtEskfParams::default());
        let dt = f32x8::from_fn(|i| 0.01 * (1.0 + 0.07 * i as f32));
        let sample = ImuSample::new(
            Vec3::from_f64([0.01, -0.02, 0.005]),
            Vec3::from_f64([0.3, -0.2, 9.8]),
            Vec3::from_f64([0.0, 20.0, -40.0]),
        );
        let mut corrections = 0;
        for k in 0..3000 {
            f.update(&sample, dt);
            let st = &f.state;
            if k < 2000 {
                continue; // the longest start-up (the smallest `dt`) is over well before
            }
            for (what, v) in [
                ("inclination", st.inclination_time),
                ("field", st.heading_time),
                ("bias noise", st.bias_noise_pending),
                ("bias at rest", st.rest_interval_time),
            ] {
                let reset = v.simd_eq(f32x8::zero());
                assert!(reset.all() || reset.none(), "{what} at sample {k}: {v:?}");
            }
            corrections += usize::from(st.inclination_time.simd_eq(f32x8::zero()).all());
        }
        assert_eq!(corrections, 1000 / 8);
    }
}
