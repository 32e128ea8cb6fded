//! Trajectories: composable motion segments with an exact (closed-form) true orientation.
//!
//! Every segment describes its orientation relative to where it starts as a closed-form
//! function of time, together with the exact body rate that produces it, so the truth has no
//! integration error at all:
//! - constant-rate rotation about a fixed axis: `Δ(τ) = exp(axis·angle(τ)/2)`;
//! - smooth random rotation: `Δ(τ) = exp(r(τ)/2)` for a smooth rotation vector `r(τ)`, whose
//!   body rate is `ω = J_r(r)·ṙ` with the right Jacobian of SO(3)
//!   `J_r(r) = I − (1 − cos θ)/θ²·[r]× + (θ − sin θ)/θ³·[r]×²`, `θ = |r|`;
//! - vibration: a small windowed wobble `exp(v(τ)/2)` applied on the right of the main motion;
//!   for `q = A ⊗ B` the body rate is `B* ⊗ ω_A ⊗ B + ω_B`;
//! - pendulum swing about a fixed axis through a pivot off the sensor:
//!   `Δ(τ) = exp(u·θ(τ)/2)`, `ω = u·θ'`, and the sensor, at `p = Δ·lever` from the pivot,
//!   accelerates at `θ''·u × p + θ'²·u × (u × p)` (tangential and centripetal), all in closed
//!   form.
//!
//! The true orientation at time `t` is `q_start(segment) ⊗ Δ(τ) ⊗ exp(v(τ)/2)`, sensor to earth
//! (ENU), `τ` the time since the segment began; each segment starts where the previous one
//! ended (the wobble vanishes at segment ends).

use super::SimError;
use core::f64::consts::PI;
use rootfuse_attitude::Quat;
use rootfuse_attitude::Vec3;
use std::vec::Vec;

/// A sinusoid per axis: `amplitude ⊙ sin(2π·freq_hz·τ + phase)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Oscillation {
    /// Peak value per axis (unit of the quantity it describes).
    pub amplitude: Vec3<f64>,
    /// Frequency, Hz (≥ 0).
    pub freq_hz: f64,
    /// Phase per axis, rad.
    pub phase: Vec3<f64>,
}

impl Oscillation {
    fn is_valid(&self) -> bool {
        finite3(self.amplitude)
            && finite3(self.phase)
            && self.freq_hz.is_finite()
            && self.freq_hz >= 0.0
    }
    /// `A·sin(wτ + φ) = (A·cos φ)·sin(wτ) + (A·sin φ)·cos(wτ)`: precomputing the two
    /// coefficients leaves one `sin_cos` per oscillation and time instead of three.
    fn compile(&self) -> Compiled {
        let (sx, cx) = self.phase.x.sin_cos();
        let (sy, cy) = self.phase.y.sin_cos();
        let (sz, cz) = self.phase.z.sin_cos();
        let a = self.amplitude;
        Compiled {
            sin_coef: Vec3::new(a.x * cx, a.y * cy, a.z * cz),
            cos_coef: Vec3::new(a.x * sx, a.y * sy, a.z * sz),
            omega: 2.0 * PI * self.freq_hz,
        }
    }
}

/// An [`Oscillation`] prepared for fast evaluation.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Compiled {
    sin_coef: Vec3<f64>,
    cos_coef: Vec3<f64>,
    omega: f64,
}

/// The oscillations of one segment, prepared.
#[derive(Clone, Debug, Default, PartialEq)]
struct CompiledSegment {
    wobble: Vec<Compiled>,
    translation: Vec<Compiled>,
    vib_angle: Vec<Compiled>,
    vib_acc: Vec<Compiled>,
}

impl CompiledSegment {
    fn new(seg: &Segment) -> Self {
        let c = |v: &[Oscillation]| v.iter().map(Oscillation::compile).collect();
        let (vib_angle, vib_acc) = match &seg.vibration {
            Some(v) => (c(&v.angle), c(&v.acc)),
            None => (Vec::new(), Vec::new()),
        };
        Self {
            wobble: match &seg.rotation {
                Rotation::Smooth { wobble, .. } => c(wobble),
                _ => Vec::new(),
            },
            translation: c(&seg.translation),
            vib_angle,
            vib_acc,
        }
    }
}

/// Sum of oscillations: value and time derivative at `tau`.
fn eval_sum(list: &[Compiled], tau: f64) -> (Vec3<f64>, Vec3<f64>) {
    let mut v = Vec3::zero();
    let mut d = Vec3::zero();
    for o in list {
        let (s, c) = (o.omega * tau).sin_cos();
        v += o.sin_coef * s + o.cos_coef * c;
        d += (o.sin_coef * c - o.cos_coef * s) * o.omega;
    }
    (v, d)
}

/// How the orientation changes during a segment.
#[derive(Clone, Debug, PartialEq)]
pub enum Rotation {
    /// No rotation.
    Rest,
    /// Rotation about a fixed sensor-frame axis (normalised internally) at `rate` rad/s, with
    /// linear ramps of `ramp_s` seconds from and back to rest at both ends (0 = a rate step,
    /// as a turntable switched on; ramps are cut to half the segment when longer).
    ConstantRate {
        /// Rotation axis, sensor frame (any non-zero length).
        axis: Vec3<f64>,
        /// Rate on the plateau, rad/s (sign gives the direction).
        rate: f64,
        /// Ramp duration at each end, s.
        ramp_s: f64,
    },
    /// Smooth rotation `r(τ) = c(u)·end + sin²(πu)·Σ wobble(τ)`, `u = τ/T`,
    /// `c(u) = 3u² − 2u³`: starts and ends at rest (zero rate), reaches the rotation vector
    /// `end` (rad, sensor frame of the segment start), with random-looking smooth motion in
    /// between. Keep `|r|` below 2π (the Jacobian is singular there); presets stay below π.
    Smooth {
        /// Net rotation vector reached at the end, rad.
        end: Vec3<f64>,
        /// Wobble of the rotation vector, rad.
        wobble: Vec<Oscillation>,
    },
    /// A pendulum swing: rotation about the fixed sensor-frame `axis` through a pivot, by the
    /// angle `θ(τ) = amplitude·e(τ)·sin(2π·freq_hz·τ)`, `e` a smoothstep envelope rising over
    /// the first and falling over the last `min(2 s, T/4)`: the swing starts and ends at rest
    /// at the segment's start orientation. The sensor sits at `lever` (m, sensor frame at the
    /// segment start) from the pivot and feels the swing's tangential and centripetal
    /// acceleration.
    Swing {
        /// Swing axis, sensor frame (any non-zero length).
        axis: Vec3<f64>,
        /// Peak swing angle, rad.
        amplitude: f64,
        /// Swing frequency, Hz (≥ 0).
        freq_hz: f64,
        /// From the pivot to the sensor, m, sensor frame at the segment start.
        lever: Vec3<f64>,
    },
}

/// Mechanical vibration of the sensor: a small orientation wobble and a sensor-frame
/// acceleration, both faded in and out over the segment's edges.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Vibration {
    /// Orientation wobble (rotation vector), rad.
    pub angle: Vec<Oscillation>,
    /// Linear acceleration, sensor frame, m/s².
    pub acc: Vec<Oscillation>,
}

/// One piece of a trajectory.
#[derive(Clone, Debug, PartialEq)]
pub struct Segment {
    /// Length, s (> 0).
    pub duration: f64,
    /// Orientation change.
    pub rotation: Rotation,
    /// Linear acceleration of the sensor, earth frame (ENU), m/s², faded in and out over the
    /// segment's edges (edges of `min(0.1 s, T/4)`).
    pub translation: Vec<Oscillation>,
    /// Vibration (none by default).
    pub vibration: Option<Vibration>,
}

impl Segment {
    /// Rest for `duration` seconds.
    pub fn rest(duration: f64) -> Self {
        Self {
            duration,
            rotation: Rotation::Rest,
            translation: Vec::new(),
            vibration: None,
        }
    }
    /// Rotation at `rate` rad/s about `axis` (sensor frame) for `duration` seconds, no ramps.
    pub fn rotate(duration: f64, axis: Vec3<f64>, rate: f64) -> Self {
        Self {
            rotation: Rotation::ConstantRate {
                axis,
                rate,
                ramp_s: 0.0,
            },
            ..Self::rest(duration)
        }
    }
    /// A smooth rotation (see [`Rotation::Smooth`]).
    pub fn smooth(duration: f64, end: Vec3<f64>, wobble: Vec<Oscillation>) -> Self {
        Self {
            rotation: Rotation::Smooth { end, wobble },
            ..Self::rest(duration)
        }
    }
    /// A pendulum swing (see [`Rotation::Swing`]).
    pub fn swing(
        duration: f64,
        axis: Vec3<f64>,
        amplitude: f64,
        freq_hz: f64,
        lever: Vec3<f64>,
    ) -> Self {
        Self {
            rotation: Rotation::Swing {
                axis,
                amplitude,
                freq_hz,
                lever,
            },
            ..Self::rest(duration)
        }
    }
    /// This segment with an added earth-frame linear acceleration.
    pub fn with_translation(mut self, acc: Oscillation) -> Self {
        self.translation.push(acc);
        self
    }
    /// This segment with vibration.
    pub fn with_vibration(mut self, vibration: Vibration) -> Self {
        self.vibration = Some(vibration);
        self
    }

    fn validate(&self, index: usize) -> Result<(), SimError> {
        let bad = |what: &'static str| SimError::InvalidSegment { index, what };
        if !(self.duration.is_finite() && self.duration > 0.0) {
            return Err(bad("duration must be finite and > 0"));
        }
        match &self.rotation {
            Rotation::Rest => {}
            Rotation::ConstantRate { axis, rate, ramp_s } => {
                if !(finite3(*axis) && axis.norm() > 0.0) {
                    return Err(bad("rotation axis must be finite and non-zero"));
                }
                if !rate.is_finite() || !ramp_s.is_finite() || *ramp_s < 0.0 {
                    return Err(bad("rate must be finite, ramp finite and >= 0"));
                }
            }
            Rotation::Smooth { end, wobble } => {
                if !finite3(*end) || !wobble.iter().all(Oscillation::is_valid) {
                    return Err(bad("smooth rotation values must be finite"));
                }
            }
            Rotation::Swing {
                axis,
                amplitude,
                freq_hz,
                lever,
            } => {
                if !(finite3(*axis) && axis.norm() > 0.0) {
                    return Err(bad("swing axis must be finite and non-zero"));
                }
                if !(amplitude.is_finite()
                    && freq_hz.is_finite()
                    && *freq_hz >= 0.0
                    && finite3(*lever))
                {
                    return Err(bad(
                        "swing amplitude and lever must be finite, frequency >= 0",
                    ));
                }
            }
        }
        let vib_ok = self
            .vibration
            .as_ref()
            .is_none_or(|v| v.angle.iter().chain(&v.acc).all(Oscillation::is_valid));
        if !self.translation.iter().all(Oscillation::is_valid) || !vib_ok {
            return Err(bad("oscillation values must be finite, frequencies >= 0"));
        }
        Ok(())
    }

    /// Relative orientation and body rate of the main rotation at `tau ∈ [0, T]`.
    fn rotation_at(&self, comp: &CompiledSegment, tau: f64) -> (Quat<f64>, Vec3<f64>) {
        let big_t = self.duration;
        match &self.rotation {
            Rotation::Rest => (Quat::identity(), Vec3::zero()),
            Rotation::ConstantRate { axis, rate, ramp_s } => {
                let u = *axis * (1.0 / axis.norm());
                let ramp = ramp_s.min(0.5 * big_t);
                let (angle, r) = if ramp <= 0.0 {
                    (rate * tau, *rate)
                } else if tau < ramp {
                    (rate * tau * tau / (2.0 * ramp), rate * tau / ramp)
                } else if tau <= big_t - ramp {
                    (rate * (tau - 0.5 * ramp), *rate)
                } else {
                    let s = (big_t - tau).max(0.0);
                    (
                        rate * (big_t - ramp) - rate * s * s / (2.0 * ramp),
                        rate * s / ramp,
                    )
                };
                (Quat::from_axis_angle(u, angle), u * r)
            }
            Rotation::Smooth { end, .. } => {
                let u = (tau / big_t).clamp(0.0, 1.0);
                let c = u * u * (3.0 - 2.0 * u);
                let dc = 6.0 * u * (1.0 - u) / big_t;
                // sin²(πu) and its derivative (π/T)·sin(2πu) = (2π/T)·sin(πu)·cos(πu).
                let (sp, cp) = (PI * u).sin_cos();
                let w = sp * sp;
                let dw = 2.0 * PI / big_t * sp * cp;
                let (g, dg) = eval_sum(&comp.wobble, tau);
                let r = *end * c + g * w;
                let dr = *end * dc + g * dw + dg * w;
                (Quat::from_rotation_vector(r), right_jacobian_times(r, dr))
            }
            Rotation::Swing { axis, .. } => {
                let u = *axis * (1.0 / axis.norm());
                let (angle, rate, _) = self.swing_angle(tau);
                (Quat::from_axis_angle(u, angle), u * rate)
            }
        }
    }

    /// Swing angle θ (rad) and its first two time derivatives at `tau`; zeros for other
    /// rotations.
    fn swing_angle(&self, tau: f64) -> (f64, f64, f64) {
        let Rotation::Swing {
            amplitude, freq_hz, ..
        } = &self.rotation
        else {
            return (0.0, 0.0, 0.0);
        };
        let big_t = self.duration;
        let edge = (2.0_f64).min(0.25 * big_t);
        let step = |x: f64| {
            if x <= 0.0 || x >= 1.0 {
                (x.clamp(0.0, 1.0).round(), 0.0, 0.0)
            } else {
                (x * x * (3.0 - 2.0 * x), 6.0 * x * (1.0 - x), 6.0 - 12.0 * x)
            }
        };
        let (a, da, dda) = step(tau / edge);
        let (b, db, ddb) = step((big_t - tau) / edge);
        // e = a(τ/E)·b((T−τ)/E): each factor's derivative carries ±1/E.
        let e = a * b;
        let de = (da * b - a * db) / edge;
        let dde = (dda * b - 2.0 * da * db + a * ddb) / (edge * edge);
        let w = 2.0 * PI * freq_hz;
        let (sn, cs) = (w * tau).sin_cos();
        (
            amplitude * e * sn,
            amplitude * (de * sn + e * w * cs),
            amplitude * (dde * sn + 2.0 * de * w * cs - e * w * w * sn),
        )
    }

    /// Edge envelope (0 at both ends, 1 inside) and its derivative.
    fn envelope(&self, tau: f64) -> (f64, f64) {
        let edge = (0.1_f64).min(0.25 * self.duration);
        let (a, da) = smoothstep(tau / edge);
        let (b, db) = smoothstep((self.duration - tau) / edge);
        (a * b, (da * b - a * db) / edge)
    }

    /// State at `tau` seconds into this segment, starting from orientation `start`.
    fn state(&self, comp: &CompiledSegment, start: Quat<f64>, tau: f64) -> MotionState {
        let (delta, mut omega) = self.rotation_at(comp, tau);
        let mut q = start * delta;
        let (env, denv) = self.envelope(tau);
        let mut acc_earth = Vec3::zero();
        let mut acc_sensor = Vec3::zero();
        if !comp.translation.is_empty() {
            acc_earth = eval_sum(&comp.translation, tau).0 * env;
        }
        if let Rotation::Swing { axis, lever, .. } = &self.rotation {
            // The sensor at p = Δ·lever from the pivot (start-frame coordinates).
            let u = *axis * (1.0 / axis.norm());
            let (_, rate, accel) = self.swing_angle(tau);
            let p = delta.rotate(*lever);
            let up = u.cross(p);
            acc_earth += start.rotate(up * accel + u.cross(up) * (rate * rate));
        }
        if !comp.vib_angle.is_empty() {
            let (g, dg) = eval_sum(&comp.vib_angle, tau);
            let v = g * env;
            let dv = g * denv + dg * env;
            let b = Quat::from_rotation_vector(v);
            omega = b.rotate_inverse(omega) + right_jacobian_times(v, dv);
            q = q * b;
        }
        if !comp.vib_acc.is_empty() {
            acc_sensor = eval_sum(&comp.vib_acc, tau).0 * env;
        }
        MotionState {
            q: q.normalize(),
            omega,
            acc_earth,
            acc_sensor,
        }
    }
}

/// `smoothstep(x) = 3x² − 2x³` on `[0, 1]` (0 below, 1 above) and its derivative.
fn smoothstep(x: f64) -> (f64, f64) {
    if x <= 0.0 {
        (0.0, 0.0)
    } else if x >= 1.0 {
        (1.0, 0.0)
    } else {
        (x * x * (3.0 - 2.0 * x), 6.0 * x * (1.0 - x))
    }
}

/// `J_r(r)·x`: the body rate of `exp(r/2)` when `r` changes at `x` (see the module docs).
fn right_jacobian_times(r: Vec3<f64>, x: Vec3<f64>) -> Vec3<f64> {
    let t2 = r.norm_squared();
    // Below θ = 0.01 the series (two terms past the leading one) are exact to rounding; above,
    // the closed forms lose at most ~eps/θ² relative, i.e. < 1e-11.
    let (a, b) = if t2 < 1e-4 {
        (
            0.5 - t2 / 24.0 + t2 * t2 / 720.0,
            1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0,
        )
    } else {
        let t = t2.sqrt();
        let (s, c) = t.sin_cos();
        ((1.0 - c) / t2, (t - s) / (t2 * t))
    };
    let rx = r.cross(x);
    x - rx * a + r.cross(rx) * b
}

fn finite3(v: Vec3<f64>) -> bool {
    v.x.is_finite() && v.y.is_finite() && v.z.is_finite()
}

/// The true motion at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionState {
    /// Orientation, sensor to earth (ENU), unit.
    pub q: Quat<f64>,
    /// Angular rate, rad/s, sensor frame (what an ideal gyroscope reads).
    pub omega: Vec3<f64>,
    /// Linear acceleration of the sensor, earth frame, m/s² (without gravity).
    pub acc_earth: Vec3<f64>,
    /// Extra linear acceleration given in the sensor frame (vibration), m/s².
    pub acc_sensor: Vec3<f64>,
}

impl MotionState {
    /// The specific force an ideal accelerometer reads, sensor frame, m/s²:
    /// `R(q)ᵀ·(a_earth + [0, 0, g]) + a_sensor` (at rest `+g` along earth-up in sensor
    /// coordinates).
    pub fn specific_force(&self, gravity: f64) -> Vec3<f64> {
        self.q
            .rotate_inverse(self.acc_earth + Vec3::new(0.0, 0.0, gravity))
            + self.acc_sensor
    }
}

/// A sequence of segments from an initial orientation.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    q0: Quat<f64>,
    segments: Vec<Segment>,
    compiled: Vec<CompiledSegment>,
    /// Orientation at the start of each segment, and one past the end.
    starts: Vec<Quat<f64>>,
    /// Start time of each segment, and the total duration at the end.
    times: Vec<f64>,
}

impl Trajectory {
    /// A trajectory starting at `q0` (sensor to earth; normalised here). Rejects non-finite
    /// or non-positive durations and non-finite parameters.
    pub fn new(q0: Quat<f64>, segments: Vec<Segment>) -> Result<Self, SimError> {
        let (q0, ok) = q0.try_normalize();
        let finite = q0.w.is_finite() && q0.x.is_finite() && q0.y.is_finite() && q0.z.is_finite();
        if !ok || !finite {
            return Err(SimError::InvalidParameter {
                name: "initial orientation",
                value: f64::NAN,
            });
        }
        let mut starts = Vec::with_capacity(segments.len() + 1);
        let mut times = Vec::with_capacity(segments.len() + 1);
        let (mut q, mut t) = (q0, 0.0);
        let mut compiled = Vec::with_capacity(segments.len());
        for (i, seg) in segments.iter().enumerate() {
            seg.validate(i)?;
            compiled.push(CompiledSegment::new(seg));
            starts.push(q);
            times.push(t);
            q = (q * seg.rotation_at(&compiled[i], seg.duration).0).normalize();
            t += seg.duration;
        }
        starts.push(q);
        times.push(t);
        Ok(Self {
            q0,
            segments,
            compiled,
            starts,
            times,
        })
    }
    /// Initial orientation (sensor to earth).
    pub fn initial(&self) -> Quat<f64> {
        self.q0
    }
    /// The segments.
    pub fn segments(&self) -> &[Segment] {
        &self.segments
    }
    /// Total duration, s.
    pub fn duration(&self) -> f64 {
        self.times[self.times.len() - 1]
    }
    /// Start time (s) and start orientation of segment `i`.
    pub fn segment_start(&self, i: usize) -> Option<(f64, Quat<f64>)> {
        (i < self.segments.len()).then(|| (self.times[i], self.starts[i]))
    }
    /// The true motion at time `t` (s from the start). Before 0 and after the end the sensor
    /// rests at the initial or final orientation.
    pub fn state_at(&self, t: f64) -> MotionState {
        let rest = |q| MotionState {
            q,
            omega: Vec3::zero(),
            acc_earth: Vec3::zero(),
            acc_sensor: Vec3::zero(),
        };
        if self.segments.is_empty() || t.is_nan() || t < 0.0 {
            return rest(self.q0);
        }
        if t >= self.duration() {
            return rest(self.starts[self.segments.len()]);
        }
        // The last segment whose start is <= t.
        let i = self.times.partition_point(|&s| s <= t) - 1;
        let i = i.min(self.segments.len() - 1);
        self.segments[i].state(&self.compiled[i], self.starts[i], t - self.times[i])
    }
}
