//! Offline spectra of recorded signals (analysis, not filtering).

/// One-sided amplitude spectrum of a real signal sampled at `rate_hz` (offline analysis):
/// `(frequency in Hz, amplitude)` pairs from 0 to Nyquist, amplitude scaled so a sine of
/// amplitude `A` on a bin shows `A`. Uses `realfft`; the mean is not removed.
pub fn spectrum(signal: &[f64], rate_hz: f64) -> Vec<(f64, f64)> {
    let n = signal.len();
    let valid_rate = rate_hz > 0.0 && rate_hz.is_finite();
    if n < 2 || !valid_rate {
        return Vec::new();
    }
    let mut planner = realfft::RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(n);
    let mut input = signal.to_vec();
    let mut output = fft.make_output_vec();
    // Lengths match by construction of the plan, so processing cannot fail.
    if fft.process(&mut input, &mut output).is_err() {
        return Vec::new();
    }
    output
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let edge = k == 0 || (n.is_multiple_of(2) && k == n / 2);
            let scale = if edge { 1.0 } else { 2.0 } / n as f64;
            (k as f64 * rate_hz / n as f64, c.norm() * scale)
        })
        .collect()
}
