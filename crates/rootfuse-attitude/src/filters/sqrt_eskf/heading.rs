//! The flagship's 9D heading: the field test (disturbance detection against the learned
//! field reference, re-acquisition of a new field) and the scalar heading-offset update.

use super::update::INITIAL_HEADING_VAR;
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
        let h = q6.rotate(s.mag);
        // The field in the 9D frame is `h` turned by the heading offset about earth-z: its
        // heading error is that of `h` less the offset (no second rotation, no sine/cosine).
        let (psi6, psi_ok) = field_heading_error(h);
        let seeded = !self.state.field.known & s.mag_ok & psi_ok;
        let st = &mut self.state;
        let heading_from_field = seeded & !st.preset;
        st.heading_offset = T::select(heading_from_field, psi6, st.heading_offset);
        st.heading_offset_var = T::select(
            heading_from_field,
            st.heading_offset_var.max(T::from_f64(INITIAL_HEADING_VAR)),
            st.heading_offset_var,
        );
        let azimuth = (psi6 - st.heading_offset).wrap_pi();
        let use_mag = self.track_field(s, h, azimuth, psi_ok, seeded);

        let st = &mut self.state;
        let apply = use_mag & psi_ok & !seeded;
        let az = st.field.azimuth;
        let az = T::select(apply, az - az * self.per_dt.k_azimuth, az);
        st.field.azimuth = az;
        // One wrap of the whole difference: with `mag_azimuth_tau = 0` (az = 0) this is the
        // innovation of a reference that always points north, to the bit.
        let psi = (psi6 - st.heading_offset - az).wrap_pi();
        let r_mag = self.per_dt.r_mag;
        let alpha = st.heading_offset_var + r_mag;
        let k = st.heading_offset_var / alpha;
        let m = st.heading_innovation_ms;
        st.heading_innovation_ms = T::select(apply, m + (psi * psi - m) * self.per_dt.k_model, m);
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

    /// The field test of one sample: the low-passed norm and dip against the reference and
    /// the candidate, re-acquisition, a new reference where `seeded`, and the settle time.
    /// Returns the lanes whose reading may correct the heading; flags and counts the others.
    fn track_field(
        &mut self,
        s: &Screened<T>,
        h: Vec3<T>,
        azimuth: T,
        psi_ok: T::Mask,
        seeded: T::Mask,
    ) -> T::Mask {
        let zero = T::zero();
        let one = T::one();
        let dt = s.dt;
        let c = &self.coef;
        let f = self.state.field;
        // A lane without a reference starts the low-pass at the sample.
        let keep = one - self.per_dt.k_mag;
        let lowpass = |y: T, x: T| T::select(f.known, lowpass_step(y, x, keep), x);
        let norm = lowpass(f.lowpass_norm, s.mag_norm);
        let dip = lowpass(f.lowpass_dip, (-h.z).clamp(-one, one).asin());
        let matches = |rn: T, rd: T| {
            (norm - rn).abs().simd_le(c.mag_norm_th * rn) & (dip - rd).abs().simd_le(c.mag_dip_th)
        };
        let ok_ref = matches(f.norm, f.dip) & s.mag_ok & f.known;
        let ok_cand = matches(f.candidate_norm, f.candidate_dip) & s.mag_ok;
        let k_ref = self.per_dt.k_ref;
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
        let rejected = s.mag_ok & !ok_ref;
        nf.rejected_time = T::select(rejected, f.rejected_time + dt, zero);
        // Re-acquisition: a candidate stable for mag_new_time, or any stable candidate
        // (≥ rest_time) once rejection has lasted mag_reject_time.
        let adopt = rejected
            & (nf.candidate_time.simd_ge(c.mag_new_time)
                | (nf.rejected_time.simd_ge(c.mag_reject_time)
                    & nf.candidate_time.simd_ge(c.rest_time)));
        nf.norm = T::select(adopt, nf.candidate_norm, nf.norm);
        nf.dip = T::select(adopt, nf.candidate_dip, nf.dip);
        // The adopted field keeps the heading: it is measured from its own azimuth.
        nf.azimuth = T::select(adopt, nf.candidate_azimuth, nf.azimuth);
        nf.rejected_time = T::select(adopt, zero, nf.rejected_time);
        let reference = FieldReference {
            norm,
            dip,
            candidate_norm: norm,
            candidate_dip: dip,
            candidate_time: zero,
            rejected_time: zero,
            azimuth: zero,
            candidate_azimuth: azimuth,
            undisturbed_time: zero,
            lowpass_norm: norm,
            lowpass_dip: dip,
            known: <T::Mask as Mask>::splat(true),
        };
        // (Selects skipped where every lane would keep one side: the same bits.)
        if seeded.any() {
            nf = Select::select(seeded, &reference, &nf);
        }
        let adopt = adopt | seeded;
        nf.known = f.known | adopt;
        let matched = ok_ref | adopt;
        nf.undisturbed_time = T::select(matched, f.undisturbed_time + dt, zero);
        // A new reference corrects the heading at once.
        let settled = nf.undisturbed_time.max(c.mag_settle_time);
        nf.undisturbed_time = T::select(seeded, settled, nf.undisturbed_time);
        let use_mag = matched & s.mag_ok & nf.undisturbed_time.simd_ge(c.mag_settle_time);
        self.state.field = if s.mag_ok.all() {
            nf
        } else {
            Select::select(s.mag_ok, &nf, &f)
        };
        // Disturbed: a usable sample that does not correct the heading, because the field
        // does not match the reference or has not matched it for `mag_settle_time` yet.
        self.state.mag_disturbed = s.mag_ok & !use_mag;
        self.rejections.reject_field(self.state.mag_disturbed);
        use_mag
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
