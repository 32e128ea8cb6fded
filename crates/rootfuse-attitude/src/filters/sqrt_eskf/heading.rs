//! The flagship's 9D heading: the field test (disturbance detection against the learned
//! field reference, re-acquisition of a new field) and the scalar heading-offset update.

use super::update::{INITIAL_HEADING_VAR, count_since, every_nth};
use super::*;

impl<T: Lane> SqrtEskf<T> {
    /// Heading offset from the magnetometer (9D): disturbance detection against the learned
    /// field reference, re-acquisition of a new field, and the scalar heading update.
    ///
    /// A lane without a reference (a new filter, a magnetometer that starts after the
    /// accelerometer, or `forget_field_reference`) takes its next usable reading as the
    /// reference, pointing north, and its heading offset from it with the initial heading
    /// variance (unless the orientation was preset); that reading does not correct the
    /// heading. While the field corrects the heading, the reference's azimuth decays to 0
    /// with `mag_azimuth_tau`.
    ///
    /// The offset's variance grows at every sample; the field is tested, and the heading
    /// corrected, every `mag_update_every` samples where the reading is usable (at once where
    /// a lane has no reference), each test and correction standing for the usable magnetometer time since
    /// the last one. Between tests a usable reading is flagged as the last test found the field.
    pub(super) fn correct_heading(&mut self, s: &Screened<T>, w: Vec3<T>, heading_growth: T) {
        let one = T::one();
        let dt = s.dt;
        let c = &self.coef;
        let q6 = self.quat6();
        let w_up = q6.up_in_sensor().dot(w);
        self.state.heading_offset_var += (c.heading_walk_var
            + c.heading_rate_var * w.norm_squared()
            + c.heading_up_rate_var * w_up * w_up)
            * dt
            + heading_growth;
        let (due, time, h, norm) = self.heading_due(s, q6.rotate(s.mag));
        if !due.any() {
            self.state.mag_disturbed = s.mag_ok & self.state.field_disturbed;
            self.rejections.reject_field(self.state.mag_disturbed);
            return;
        }
        self.per_heading
            .refresh(T::select(due, time, self.per_heading.time), &self.coef);
        // The field in the 9D frame is `h` turned by the heading offset about earth-z: its
        // heading error is that of `h` less the offset (no second rotation, no sine/cosine).
        let (psi6, psi_ok) = field_heading_error(h);
        let seeded = !self.state.field.known & due & psi_ok;
        let st = &mut self.state;
        let heading_from_field = seeded & !st.preset;
        st.heading_offset = T::select(heading_from_field, psi6, st.heading_offset);
        st.heading_offset_var = T::select(
            heading_from_field,
            st.heading_offset_var.max(T::from_f64(INITIAL_HEADING_VAR)),
            st.heading_offset_var,
        );
        let azimuth = (psi6 - st.heading_offset).wrap_pi();
        let use_mag = self.track_field(s, (due, time), (h, norm), azimuth, (psi_ok, seeded));

        let st = &mut self.state;
        let apply = use_mag & psi_ok & !seeded;
        let az = st.field.azimuth;
        let keep = one - self.per_heading.k_azimuth;
        let az = T::select(apply, az - az * self.per_heading.k_azimuth, az);
        st.field.azimuth = az;
        // The error the adoption inherited decays with the azimuth (report only).
        let v = st.field.azimuth_var;
        st.field.azimuth_var = T::select(apply, v * (keep * keep), v);
        // One wrap of the whole difference: with `mag_azimuth_tau = 0` (az = 0) this is the
        // innovation of a reference that always points north, to the bit.
        let psi = (psi6 - st.heading_offset - az).wrap_pi();
        let r_mag = self.per_heading.r_mag;
        let alpha = st.heading_offset_var + r_mag;
        let k = st.heading_offset_var / alpha;
        let m = st.heading_innovation_ms;
        let k_model = self.per_heading.k_model;
        st.heading_innovation_ms = T::select(apply, m + (psi * psi - m) * k_model, m);
        st.heading_offset = T::select(
            apply,
            (st.heading_offset + k * psi).wrap_pi(),
            st.heading_offset,
        );
        st.heading_offset_var = T::select(
            apply,
            st.heading_offset_var * (one - k),
            st.heading_offset_var,
        );
    }

    /// The lanes whose field is tested at this sample (every `mag_update_every`th sample
    /// where the reading is usable, else at the next such tick, the ticks shared by lanes
    /// started together; at once where a lane has no reference), the usable
    /// magnetometer time since the last test, s (`dt` where every reading is tested:
    /// `0 + dt`), and the mean of those readings: the unit field `h` in the 6D earth frame
    /// (`q6·m̂` of each) and the field norm. The mean, not the test's own reading, because
    /// the readings are noisy and independent (a low-passed gravity is not): one reading
    /// standing for eight would weigh its noise eightfold. The count, the time and the sums
    /// start again where a lane tests; a first reading is taken as it is (one reading is its
    /// own mean, to the bit).
    fn heading_due(&mut self, s: &Screened<T>, h: Vec3<T>) -> (T::Mask, T, Vec3<T>, T) {
        let (zero, one) = (T::zero(), T::one());
        let st = &mut self.state;
        // A lane without a reference (a new filter, or one told to forget it after a new
        // calibration) takes the reading as it is: the readings before belong to another field.
        let first = st.heading_samples.simd_eq(zero) | !st.field.known;
        let (samples, time) =
            count_since((st.heading_samples, st.heading_time), s.mag_ok, s.dt, first);
        let sum = Vec3::select(first, h, st.mag_sum + h);
        let norm_sum = T::select(first, s.mag_norm, st.mag_norm_sum + s.mag_norm);
        let sum = Vec3::select(s.mag_ok, sum, st.mag_sum);
        let norm_sum = T::select(s.mag_ok, norm_sum, st.mag_norm_sum);
        let tick = every_nth(&mut st.heading_phase, self.coef.mag_update_every);
        let due = s.mag_ok & (tick | !st.field.known);
        st.heading_samples = T::select(due, zero, samples);
        st.heading_time = T::select(due, zero, time);
        st.mag_sum = sum;
        st.mag_norm_sum = norm_sum;
        let inv = one / T::select(due, samples, one);
        (due, time, sum * inv, norm_sum * inv)
    }

    /// The field test of the lanes `due`, standing for the usable magnetometer `time` (s)
    /// since the last, with the mean unit field `h` (6D earth frame) and norm of its
    /// readings: the low-passed norm and dip against the reference and the candidate,
    /// re-acquisition, a new reference where `seeded`, and the settle time. Returns the lanes
    /// whose reading may correct the heading; flags and counts the others.
    fn track_field(
        &mut self,
        s: &Screened<T>,
        (due, time): (T::Mask, T),
        (h, mag_norm): (Vec3<T>, T),
        azimuth: T,
        (psi_ok, seeded): (T::Mask, T::Mask),
    ) -> T::Mask {
        let zero = T::zero();
        let one = T::one();
        let dt = time;
        let c = &self.coef;
        let f = self.state.field;
        // A lane without a reference starts the low-pass at the sample.
        let keep = one - self.per_heading.k_mag;
        let lowpass = |y: T, x: T| T::select(f.known, lowpass_step(y, x, keep), x);
        let norm = lowpass(f.lowpass_norm, mag_norm);
        let dip = lowpass(f.lowpass_dip, (-h.z).clamp(-one, one).asin());
        let matches = |rn: T, rd: T| {
            (norm - rn).abs().simd_le(c.mag_norm_th * rn) & (dip - rd).abs().simd_le(c.mag_dip_th)
        };
        let ok_ref = matches(f.norm, f.dip) & due & f.known;
        let ok_home = matches(f.home_norm, f.home_dip) & due & f.known & !f.at_home;
        let ok_cand = matches(f.candidate_norm, f.candidate_dip) & due;
        let k_ref = self.per_heading.k_ref;
        let mut nf = f;
        nf.lowpass_norm = norm;
        nf.lowpass_dip = dip;
        nf.candidate_norm = T::select(
            ok_cand,
            f.candidate_norm + (norm - f.candidate_norm) * k_ref,
            norm,
        );
        nf.candidate_dip = T::select(
            ok_cand,
            f.candidate_dip + (dip - f.candidate_dip) * k_ref,
            dip,
        );
        nf.candidate_time = T::select(ok_cand, f.candidate_time + dt, zero);
        let candidate_azimuth = T::select(
            ok_cand,
            (f.candidate_azimuth + (azimuth - f.candidate_azimuth).wrap_pi() * k_ref).wrap_pi(),
            azimuth,
        );
        nf.candidate_azimuth = T::select(psi_ok, candidate_azimuth, f.candidate_azimuth);
        nf.norm = T::select(ok_ref, f.norm + (norm - f.norm) * k_ref, f.norm);
        nf.dip = T::select(ok_ref, f.dip + (dip - f.dip) * k_ref, f.dip);
        let rejected = due & !ok_ref;
        nf.rejected_time = T::select(rejected, f.rejected_time + dt, zero);
        // The home field back: the reference again at once, pointing north. Otherwise
        // re-acquisition: a candidate stable for mag_new_time, or any stable candidate
        // (≥ rest_time) once rejection has lasted mag_reject_time.
        let home = rejected & ok_home;
        let adopt = rejected
            & !home
            & (nf.candidate_time.simd_ge(c.mag_new_time)
                | (nf.rejected_time.simd_ge(c.mag_reject_time)
                    & nf.candidate_time.simd_ge(c.rest_time)));
        // An adopted field's azimuth was measured with today's heading: it inherits that
        // heading's variance against north, the offset's and the old reference's. Where the
        // home field is back, the error the old reference's azimuth carried is the offset's:
        // its variance takes it, so the offset turns to north quickly.
        let old_reference = f.azimuth_error_var();
        let offset_var = self.state.heading_offset_var;
        nf.switch(adopt, home, old_reference + offset_var);
        self.state.heading_offset_var = T::select(home, offset_var + old_reference, offset_var);
        let reference = FieldReference::first(norm, dip, azimuth);
        // (Selects skipped where every lane would keep one side: the same bits.)
        if seeded.any() {
            nf = Select::select(seeded, &reference, &nf);
        }
        let adopt = adopt | seeded;
        nf.known = f.known | adopt;
        let matched = ok_ref | adopt | home;
        nf.undisturbed_time = T::select(matched, f.undisturbed_time + dt, zero);
        // A new reference corrects the heading at once.
        let settled = nf.undisturbed_time.max(c.mag_settle_time);
        nf.undisturbed_time = T::select(seeded, settled, nf.undisturbed_time);
        // An adopted field that has held long enough is home; home follows the reference.
        nf.at_home =
            ((f.at_home & !adopt) | home | seeded) | nf.undisturbed_time.simd_ge(c.mag_home_time);
        nf.home_norm = T::select(nf.at_home, nf.norm, nf.home_norm);
        nf.home_dip = T::select(nf.at_home, nf.dip, nf.home_dip);
        let use_mag = matched & due & nf.undisturbed_time.simd_ge(c.mag_settle_time);
        self.state.field = if due.all() {
            nf
        } else {
            Select::select(due, &nf, &f)
        };
        // Disturbed: a tested reading that does not correct the heading, because the field
        // does not match the reference or has not matched it for `mag_settle_time` yet; the
        // usable readings until the next test are flagged the same.
        self.state.field_disturbed = (due & !use_mag) | (!due & self.state.field_disturbed);
        self.state.mag_disturbed = s.mag_ok & self.state.field_disturbed;
        self.rejections.reject_field(self.state.mag_disturbed);
        use_mag
    }
}

impl<T: Lane> FieldReference<T> {
    /// A lane's first field: the reference and the home field, pointing north, from the
    /// low-passed `norm` and `dip` of its reading, whose `azimuth` starts the candidate's.
    fn first(norm: T, dip: T, azimuth: T) -> Self {
        let zero = T::zero();
        let yes = <T::Mask as Mask>::splat(true);
        FieldReference {
            norm,
            dip,
            candidate_norm: norm,
            candidate_dip: dip,
            candidate_time: zero,
            rejected_time: zero,
            azimuth: zero,
            azimuth_var: zero,
            adopted_azimuth: zero,
            home_norm: norm,
            home_dip: dip,
            at_home: yes,
            candidate_azimuth: azimuth,
            undisturbed_time: zero,
            lowpass_norm: norm,
            lowpass_dip: dip,
            known: yes,
        }
    }

    /// Where `adopt`, the candidate becomes the reference and keeps the heading (its azimuth
    /// is the candidate's, with the variance `inherited`, rad²); where `home`, the home field
    /// becomes the reference, pointing north. The rejection time starts again in both.
    fn switch(&mut self, adopt: T::Mask, home: T::Mask, inherited: T) {
        let zero = T::zero();
        let pick = |candidate: T, home_value: T, now: T| {
            T::select(adopt, candidate, T::select(home, home_value, now))
        };
        self.norm = pick(self.candidate_norm, self.home_norm, self.norm);
        self.dip = pick(self.candidate_dip, self.home_dip, self.dip);
        self.azimuth = pick(self.candidate_azimuth, zero, self.azimuth);
        self.azimuth_var = pick(inherited, zero, self.azimuth_var);
        self.adopted_azimuth = pick(self.candidate_azimuth, zero, self.adopted_azimuth);
        self.rejected_time = T::select(adopt | home, zero, self.rejected_time);
    }
}

/// One step of a first-order low-pass from `y` towards the sample `x`, `keep = 1 − k`.
/// Written `x − (x − y)·keep` rather than `y + (x − y)·k` so that `keep = 0` (a time constant
/// of 0) gives the sample exactly, whatever the signs and magnitudes.
#[inline]
fn lowpass_step<T: Lane>(y: T, x: T, keep: T) -> T {
    x - (x - y) * keep
}

#[cfg(test)]
mod tests {
    use super::lowpass_step;

    #[test]
    fn a_low_pass_without_memory_passes_the_sample_exactly() {
        // `y + (x − y)·1` is 0.10000000000000009 for the first pair.
        for (y, x) in [(-3.0, 0.1), (1e-17, -0.3), (7.5, 2.0e-3), (-0.2, 0.2)] {
            assert_eq!(lowpass_step(y, x, 0.0_f64), x);
            assert_eq!(lowpass_step(y as f32, x as f32, 0.0_f32), x as f32);
        }
        assert_eq!(-3.0 + (0.1 - -3.0) * 1.0, 0.10000000000000009);
    }
}
