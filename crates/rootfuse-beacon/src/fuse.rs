//! S5: the beacon heading fused into `ψ_MEMS`, and pedestrian dead reckoning.

use super::heading::{BeaconHeading, Fix};
use std::collections::VecDeque;

/// Wraps an angle to `[-π, π]`.
pub fn wrap(a: f64) -> f64 {
    let tau = core::f64::consts::TAU;
    a - tau * (a / tau).round()
}

/// `a + w·wrap(b − a)`, wrapped: the blend `(1 − w)·a + w·b` taken on the circle (the short
/// way round, so blending 179° and −179° gives ±180°, not 0°).
pub fn circular_blend(a: f64, b: f64, w: f64) -> f64 {
    wrap(a + w * wrap(b - a))
}

/// Settings of [`HeadingFusion`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FusionConfig {
    /// Random-walk intensity of the offset `δ`, rad²/s.
    pub q_offset: f64,
    /// Random-walk intensity of the drift rate `r`, rad²/s³.
    pub q_rate: f64,
    /// Initial std of `δ`, rad.
    pub offset_std0: f64,
    /// Initial std of `r`, rad/s (the gyro heading drift rate expected).
    pub rate_std0: f64,
    /// Largest turn of the MEMS heading within a beacon heading's span, rad.
    pub max_turn: f64,
    /// Innovation gate, standard deviations.
    pub gate: f64,
    /// MEMS heading history kept, s.
    pub keep: f64,
}

impl Default for FusionConfig {
    fn default() -> Self {
        Self {
            q_offset: 1e-5,
            q_rate: 1e-10,
            offset_std0: 1.0,
            rate_std0: 0.005,
            max_turn: 15f64.to_radians(),
            gate: 3.0,
            keep: 30.0,
        }
    }
}

/// Fuses beacon headings into the MEMS heading: `ψ = wrap(ψ_MEMS + δ)`, with the offset `δ`
/// and its drift rate `r` (the accumulated gyro error grows about linearly) estimated by a
/// two-state Kalman filter on the circle.
///
/// - Prediction over `Δt`: `δ ← δ + r·Δt`, `P ← F·P·Fᵀ + diag(q_δ, q_r)·Δt`,
///   `F = [[1, Δt], [0, 1]]`.
/// - Update with a [`BeaconHeading`] `ψ_B` over `[t0, t1]`: it is compared with the circular
///   mean `ψ̄` of `ψ_MEMS` over that span, corrected by the offset at the span's middle
///   `t_m`: `ν = wrap(ψ_B − (ψ̄ + δ − r·(t − t_m)))`, `H = [1, −(t − t_m)]`, `R = σ_B²`.
/// - The update is refused (counted in `refused`) when the MEMS heading turned within the
///   span by more than `max_turn` (a beacon heading is a straight-line direction), or when
///   `|ν| > gate·√(HPHᵀ + R)` (an outlier, e.g. two beacons not along the walk).
///
/// Reading of the source: S5 says only that the two headings are fused to remove the
/// accumulated error; this rule (offset and drift rate, span mean, turn and innovation
/// gates) is ours.
#[derive(Clone, Debug)]
pub struct HeadingFusion {
    cfg: FusionConfig,
    offset: f64,
    rate: f64,
    p: [f64; 3],
    last_t: Option<f64>,
    history: VecDeque<(f64, f64)>,
    /// Beacon headings accepted.
    pub accepted: u64,
    /// Beacon headings refused (turning, gate, no MEMS history, non-finite).
    pub refused: u64,
}

impl HeadingFusion {
    /// A fusion with the given settings.
    pub fn new(cfg: FusionConfig) -> Self {
        Self {
            cfg,
            offset: 0.0,
            rate: 0.0,
            p: [cfg.offset_std0.powi(2), 0.0, cfg.rate_std0.powi(2)],
            last_t: None,
            history: VecDeque::new(),
            accepted: 0,
            refused: 0,
        }
    }
    /// Records the MEMS heading at time `t` (s) and returns the fused heading.
    pub fn push_mems(&mut self, t: f64, psi_mems: f64) -> f64 {
        if let Some(t_last) = self.last_t {
            let dt = t - t_last;
            if dt > 0.0 && dt.is_finite() {
                let [p00, p01, p11] = self.p;
                self.offset = wrap(self.offset + self.rate * dt);
                self.p = [
                    p00 + 2.0 * dt * p01 + dt * dt * p11 + self.cfg.q_offset * dt,
                    p01 + dt * p11,
                    p11 + self.cfg.q_rate * dt,
                ];
            }
        }
        if t.is_finite() {
            self.last_t = Some(t);
        }
        if psi_mems.is_finite() && t.is_finite() {
            self.history.push_back((t, psi_mems));
        }
        while self
            .history
            .front()
            .is_some_and(|(t0, _)| *t0 < t - self.cfg.keep)
        {
            self.history.pop_front();
        }
        self.heading(psi_mems)
    }
    /// The fused heading for a MEMS heading.
    pub fn heading(&self, psi_mems: f64) -> f64 {
        wrap(psi_mems + self.offset)
    }
    /// The current offset `δ`, rad.
    pub fn offset(&self) -> f64 {
        self.offset
    }
    /// The current drift-rate estimate `r`, rad/s.
    pub fn rate(&self) -> f64 {
        self.rate
    }
    /// Fuses one beacon heading; returns whether it was accepted.
    pub fn update(&mut self, b: &BeaconHeading) -> bool {
        let in_span: std::vec::Vec<f64> = self
            .history
            .iter()
            .filter(|(t, _)| *t >= b.span[0] && *t <= b.span[1])
            .map(|(_, p)| *p)
            .collect();
        let now = self.last_t.unwrap_or(b.span[1]);
        let std_ok = b.std.is_finite() && b.std > 0.0;
        if in_span.is_empty() || !b.psi.is_finite() || !std_ok {
            self.refused += 1;
            return false;
        }
        let (s, c) = in_span
            .iter()
            .fold((0.0, 0.0), |(s, c), p| (s + p.sin(), c + p.cos()));
        let mean = s.atan2(c);
        let turn = in_span
            .iter()
            .map(|p| wrap(p - mean).abs())
            .fold(0.0, f64::max);
        let h1 = -(now - 0.5 * (b.span[0] + b.span[1]));
        let [p00, p01, p11] = self.p;
        // P·Hᵀ and H·P·Hᵀ for H = [1, h1].
        let ph = [p00 + h1 * p01, p01 + h1 * p11];
        let s_var = ph[0] + h1 * ph[1] + b.std * b.std;
        let nu = wrap(b.psi - (mean + self.offset + h1 * self.rate));
        if turn > self.cfg.max_turn || nu.abs() > self.cfg.gate * s_var.sqrt() {
            self.refused += 1;
            return false;
        }
        let k = [ph[0] / s_var, ph[1] / s_var];
        self.offset = wrap(self.offset + k[0] * nu);
        self.rate += k[1] * nu;
        self.p = [p00 - k[0] * ph[0], p01 - k[0] * ph[1], p11 - k[1] * ph[1]];
        self.accepted += 1;
        true
    }
}

/// Pedestrian dead reckoning: each step moves the position by `length` along the heading,
/// `p ← p + L·(−sin ψ, cos ψ)`, and adds `var_per_step` (m²) to an isotropic position
/// variance; [`correct`](Self::correct) blends in a beacon fix by a Kalman update with the
/// fix's covariance (taken isotropic, its mean diagonal).
///
/// Step detection and step-length estimation are not part of the source method: the caller supplies
/// steps and lengths (the simulator's are exact, so position errors come from heading and
/// fixes only).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pdr {
    /// Position `[east, north]`, m.
    pub position: [f64; 2],
    /// Isotropic position variance, m².
    pub var: f64,
    var_per_step: f64,
}

impl Pdr {
    /// Starts at `position` with variance `var` (m²).
    pub fn new(position: [f64; 2], var: f64, var_per_step: f64) -> Self {
        Self {
            position,
            var,
            var_per_step,
        }
    }
    /// One step of `length` m at heading `psi` rad.
    pub fn step(&mut self, length: f64, psi: f64) {
        if length.is_finite() && psi.is_finite() {
            self.position[0] -= length * psi.sin();
            self.position[1] += length * psi.cos();
            self.var += self.var_per_step;
        }
    }
    /// Kalman update with a position fix; a fix with a non-finite value is ignored.
    pub fn correct(&mut self, fix: &Fix) {
        let r = 0.5 * (fix.covariance[0][0] + fix.covariance[1][1]);
        let finite = fix.position.iter().all(|v| v.is_finite());
        let r_ok = r.is_finite() && r > 0.0;
        if !r_ok || !finite {
            return;
        }
        let k = self.var / (self.var + r);
        for i in 0..2 {
            self.position[i] += k * (fix.position[i] - self.position[i]);
        }
        self.var *= 1.0 - k;
    }
}
