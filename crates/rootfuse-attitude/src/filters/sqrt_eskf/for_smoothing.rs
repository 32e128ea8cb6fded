//! The parameters each pass of the offline smoother runs with.

use super::SqrtEskfParams;

impl SqrtEskfParams {
    /// The parameters each pass of the offline smoother runs with: the long window's time
    /// constant `tau_acc_long` scaled by `smoothing_tau_scale` and the short one's `tau_acc` by
    /// `smoothing_short_tau_scale` (with one window, `tau_acc_long = 0`, by
    /// `smoothing_tau_scale`), no heading model error (`heading_model_error_scale` 0) and no
    /// sustained-acceleration term (`acc_excess_scale` 0), the field tested at every reading
    /// (`mag_update_every` 1), no online estimate of the gyroscope's scale
    /// (`gyr_scale_window` 0), everything else as given.
    ///
    /// The two model errors are left out because the passes' reported covariances are the
    /// smoother's weights: an error term both passes share flattens the weights toward equal
    /// and hides which pass has just been corrected (measured with the passes' earlier
    /// windows: BROAD 9D offline 1.70° without the heading term, 1.87° with it; BROAD offline
    /// inclination 0.543° without the acceleration term, 0.597° with it at 0.15;
    /// `docs/accuracy.md`). For the same reason each pass corrects its heading at every
    /// reading: a correction every `mag_update_every` readings makes the heading variance a
    /// saw-tooth that the weights follow (then: BROAD 9D offline 1.641° at 1, 1.653° at 4;
    /// `docs/flagship_cost.md`). The scale estimate is left out because the two passes make
    /// it from opposite ends of the recording and disagree while they learn it, which the
    /// fused heading shows (BROAD 9D offline 1.562° without it, 1.618° with it;
    /// `docs/accuracy.md`).
    ///
    /// ```
    /// use rootfuse_attitude::SqrtEskfParams;
    /// let p = SqrtEskfParams::default();
    /// assert_eq!(p.for_smoothing().tau_acc, p.tau_acc * p.smoothing_short_tau_scale);
    /// assert_eq!(p.for_smoothing().tau_acc_long, p.tau_acc_long * p.smoothing_tau_scale);
    /// let one_window = SqrtEskfParams { tau_acc_long: 0.0, ..p };
    /// assert_eq!(one_window.for_smoothing().tau_acc, p.tau_acc * p.smoothing_tau_scale);
    /// assert_eq!(p.for_smoothing().heading_model_error_scale, 0.0);
    /// assert_eq!(p.for_smoothing().acc_excess_scale, 0.0);
    /// assert_eq!(p.for_smoothing().mag_update_every, 1.0);
    /// assert_eq!(p.for_smoothing().gyr_scale_window, 0.0);
    /// ```
    pub fn for_smoothing(&self) -> Self {
        Self {
            tau_acc: self.tau_acc
                * if self.tau_acc_long > 0.0 {
                    self.smoothing_short_tau_scale
                } else {
                    self.smoothing_tau_scale
                },
            tau_acc_long: self.tau_acc_long * self.smoothing_tau_scale,
            heading_model_error_scale: 0.0,
            acc_excess_scale: 0.0,
            // The passes weigh each other by today's single scale (their smoothed
            // estimates are those measured with it, docs/accuracy.md).
            model_error_rotation_scale: self.model_error_scale,
            mag_update_every: 1.0,
            gyr_scale_window: 0.0,
            ..self.clone()
        }
    }
}
