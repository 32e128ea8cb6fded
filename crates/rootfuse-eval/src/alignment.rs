//! Aligning an orientation estimate to a reference measured in other frames: motion capture
//! whose reference frame and marker-body frame differ from the IMU's by constant rotations.
//!
//! # Model
//! With `q` the estimate (sensor to the estimate's earth frame) and `r` the reference (marker
//! body to the reference's earth frame), both constant offsets enter as
//!
//! `r ≈ E ⊗ q ⊗ S*`
//!
//! - `E` ([`FrameAlignment::earth`]): the estimate's earth frame to the reference's earth
//!   frame (`v_ref = E ⊗ v_est ⊗ E*`). For [`Alignment::NineD`] any rotation (the optical
//!   system's axes may be anything, e.g. y up); for [`Alignment::SixD`] a rotation about the
//!   reference's vertical only, because a 6D estimate's heading is arbitrary while its
//!   vertical is gravity's. The reference's vertical ([`FrameAlignment::vertical`]) is found
//!   from the data: the estimate's z axis seen in the reference frame, snapped to the nearest
//!   axis within 15° (motion-capture frames are z-up or y-up, levelled to a fraction of a
//!   degree).
//! - `S` ([`FrameAlignment::sensor_to_body`]): the IMU sensor frame to the marker-body frame
//!   (`v_body = S ⊗ v_sensor ⊗ S*`), any rotation.
//!
//! [`FrameAlignment::apply`] gives the aligned estimate `E ⊗ q ⊗ S*`, to be scored with the
//! BROAD metrics ([`crate::metrics`]).
//!
//! # Estimation
//! Robust nonlinear least squares over the samples that count ([`crate::metrics`]: `use = 1`,
//! finite reference) with a finite estimate. The residual of a sample is the rotation vector
//! of `r* ⊗ E ⊗ q ⊗ S*` (rad), whose norm is the total BROAD error of the aligned sample.
//!
//! 1. Start: `S` from the body-frame relative rotations `r_i* ⊗ r_j = S ⊗ (q_i* ⊗ q_j) ⊗ S*`
//!    (in which `E` cancels) and, for 9D, `E` from the earth-frame relative rotations
//!    `r_i ⊗ r_j* = E ⊗ (q_i ⊗ q_j*) ⊗ E*`: the axis·sin(angle/2) vectors of pairs of samples
//!    are matched by the rotation that fits them best in least squares (Davenport's
//!    q-method). For 6D, `E`'s heading then follows in closed form. No initial guess is needed,
//!    so any misalignment, also 180°, is found.
//! 2. Gauss-Newton with iteratively reweighted least squares: per iteration, the linearised
//!    residual `e_i + R(r_i)ᵀ·δe + δs` (`E ← exp(δe) ⊗ E`, `S* ← S* ⊗ exp(δs)`, rotation
//!    vectors; `δe` along earth-z only for 6D) is solved by [`rootfuse_lsq::dense::solve`]
//!    with Cauchy weights `1/(1 + (|e_i|/c)²)`, `c = 2.385·1.4826·median|e_i|`: samples where
//!    the optical system lost track or swapped markers get a small weight instead of pulling
//!    the fit.
//!
//! A recording whose motion cannot separate the two rotations is an
//! [`AlignError::NotExcited`], not a guess: the relative rotations of the estimate between
//! samples must reach [`MIN_EXCITATION_DEG`] (RMS) about a second axis, in the body frame and,
//! for 9D, in the earth frame; one axis alone leaves a rotation about it undetermined, and a
//! still recording turns only by its noise.
//!
//! # Scoring
//! The BROAD metrics split the error into heading and inclination about earth-z. A reference
//! whose vertical is another axis is first turned z-up ([`FrameAlignment::level`]), estimate
//! and reference alike, so that the split is about the true vertical.

use crate::metrics::{Alignment, MetricsError, check, counted, error_heading};
use nalgebra::{Matrix3, Matrix4, SymmetricEigen, Vector3};
use rootfuse_attitude::Quat;
use rootfuse_attitude::Recording;
use rootfuse_attitude::Vec3;
use rootfuse_lsq::dense::faer::{Col, Mat};
use rootfuse_lsq::dense::{LsqError, Options, Weights, solve};
use std::vec::Vec;

/// Iterations of the Gauss-Newton / reweighting loop at most.
const MAX_ITERATIONS: usize = 100;
/// The loop stops when a step turns both rotations by less than this, rad.
const STEP_TOLERANCE: f64 = 1e-11;
/// The two rotations are not separable when the design's condition estimate exceeds this.
const MAX_CONDITION: f64 = 1e8;
/// Cauchy tuning constant (95 % efficiency at Gaussian residuals) and MAD-to-σ factor.
const CAUCHY_C: f64 = 2.385;
const MAD_TO_SIGMA: f64 = 1.4826;
/// Smallest robust scale, rad: residuals of exact data do not make every weight zero.
const MIN_SCALE: f64 = 1e-9;
/// The least rotation about a second axis (RMS over the pairs of samples the start uses,
/// degrees) that separates the two rotations: a still sensor turns by its estimate's noise
/// only (a fraction of a degree), a recording of real motion by tens of degrees.
pub const MIN_EXCITATION_DEG: f64 = 5.0;
/// A reference vertical this close to an axis (degrees) is that axis.
const SNAP_DEG: f64 = 15.0;

/// The two constant rotations found by [`align_frames`] (see the [module docs](self)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameAlignment {
    /// Estimate's earth frame to the reference's earth frame, `E` (about earth-z only for 6D).
    pub earth: Quat<f64>,
    /// IMU sensor frame to the reference's body frame, `S`.
    pub sensor_to_body: Quat<f64>,
    /// Samples the fit used (counted, with a finite estimate).
    pub n_used: usize,
    /// Samples whose final robust weight is below ½ (residual above the Cauchy scale `c`):
    /// the ones the fit treated as outliers.
    pub n_downweighted: usize,
    /// Gauss-Newton iterations done.
    pub iterations: usize,
    /// Median total error of the aligned samples, degrees.
    pub median_error_deg: f64,
    /// The reference frame's vertical (unit, reference coordinates): the estimate's earth-z
    /// seen there, snapped to the nearest axis within 15° (`[0, 0, 1]` for a z-up reference,
    /// `[0, 1, 0]` for a y-up one).
    pub vertical: Vec3<f64>,
    /// RMS rotation of the estimate about its second axis over the pairs of samples the start
    /// uses, degrees (see [`MIN_EXCITATION_DEG`]).
    pub excitation_deg: f64,
}

impl FrameAlignment {
    /// The estimate `q` in the reference's frames: `E ⊗ q ⊗ S*`.
    pub fn apply(&self, q: Quat<f64>) -> Quat<f64> {
        self.earth * q * self.sensor_to_body.conj()
    }

    /// [`apply`](Self::apply) to every estimate.
    pub fn apply_all(&self, est: &[Quat<f64>]) -> Vec<Quat<f64>> {
        est.iter().map(|&q| self.apply(q)).collect()
    }

    /// The heading of [`earth`](Self::earth) (rotation about the reference's
    /// [`vertical`](Self::vertical)), degrees in `(−180, 180]`; for 6D the whole earth offset.
    pub fn earth_heading_deg(&self) -> f64 {
        let d = error_heading(self.level() * self.earth)
            .to_degrees()
            .rem_euclid(360.0);
        if d > 180.0 { d - 360.0 } else { d }
    }

    /// The rotation that turns the reference frame z-up (its [`vertical`](Self::vertical) onto
    /// z, the least rotation that does): apply it on the left of the reference and of the
    /// aligned estimate before splitting errors into heading and inclination. The identity
    /// for a z-up reference.
    pub fn level(&self) -> Quat<f64> {
        from_z(self.vertical).conj()
    }
}

/// The least rotation taking earth-z onto the unit vector `up`.
fn from_z(up: Vec3<f64>) -> Quat<f64> {
    let z = Vec3::new(0.0, 0.0, 1.0);
    let axis = z.cross(up);
    let (sin, cos) = (axis.norm(), z.dot(up));
    if sin < 1e-12 {
        // Parallel: the identity, or a half turn about x for a z-down frame.
        return if cos > 0.0 {
            Quat::identity()
        } else {
            Quat::new(0.0, 1.0, 0.0, 0.0)
        };
    }
    Quat::from_axis_angle(axis * (1.0 / sin), sin.atan2(cos))
}

/// `v` snapped to the nearest coordinate axis when within [`SNAP_DEG`], else `v` normalised.
fn snap_to_axis(v: Vec3<f64>) -> Vec3<f64> {
    let v = v * (1.0 / v.norm());
    let a = v.to_array();
    let k = (0..3)
        .max_by(|&i, &j| a[i].abs().total_cmp(&a[j].abs()))
        .unwrap_or(2);
    if a[k].abs() >= SNAP_DEG.to_radians().cos() {
        let mut axis = [0.0; 3];
        axis[k] = a[k].signum();
        Vec3::from_f64(axis)
    } else {
        v
    }
}

/// Why no alignment could be estimated.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum AlignError {
    /// The inputs do not fit together (lengths) or there is no truth, as for the metrics.
    #[error(transparent)]
    Input(#[from] MetricsError),
    /// Too few samples count (use = 1, finite truth and estimate) to fit two rotations.
    #[error("{0} usable samples (use = 1, finite truth and estimate): too few to align")]
    TooFewSamples(usize),
    /// The motion does not separate the earth offset from the sensor-to-body rotation.
    #[error(
        "the recording does not rotate enough to separate the earth-frame offset from the sensor-to-body rotation: it turns {excitation_deg:.2}° (RMS) about a second axis, at least {MIN_EXCITATION_DEG}° needed{}; align on a recording that turns about two axes",
        if *six_d { " (6D: the tilt must change)" } else { "" }
    )]
    NotExcited {
        /// Whether the fit was the 6D (heading-only earth offset) one.
        six_d: bool,
        /// The rotation about a second axis found, degrees (RMS; see
        /// [`MIN_EXCITATION_DEG`]).
        excitation_deg: f64,
    },
    /// The least-squares step failed otherwise.
    #[error("least squares: {0}")]
    Lsq(LsqError),
}

/// Estimates the earth-frame offset and the sensor-to-body rotation of estimates `est`
/// against `truth` over the samples with `use = 1` (all when `use_mask` is `None`), finite
/// truth and a finite estimate; `mode` [`Alignment::SixD`] restricts the earth offset to a
/// heading. See the [module docs](self).
pub fn align_frames(
    est: &[Quat<f64>],
    truth: &[Quat<f64>],
    use_mask: Option<&[bool]>,
    mode: Alignment,
) -> Result<FrameAlignment, AlignError> {
    check(est, truth, use_mask)?;
    let (q, r): (Vec<Quat<f64>>, Vec<Quat<f64>>) = (0..est.len())
        .filter(|&i| counted(truth, use_mask, i) && est[i].to_array().iter().all(|c| c.is_finite()))
        .map(|i| (est[i].normalize(), truth[i].normalize()))
        .unzip();
    let six_d = mode == Alignment::SixD;
    // Two rotations of three (6D: one plus three) parameters: far more samples than that, or
    // the robust scale means nothing.
    if q.len() < 10 {
        return Err(AlignError::TooFewSamples(q.len()));
    }
    let excitation_deg = excitation_deg(&q, six_d);
    // A NaN excitation is no excitation.
    if excitation_deg.is_nan() || excitation_deg < MIN_EXCITATION_DEG {
        return Err(AlignError::NotExcited {
            six_d,
            excitation_deg,
        });
    }
    let sensor_to_body = initial_sensor_to_body(&q, &r);
    let earth = initial_earth(&q, &r);
    let vertical = snap_to_axis(earth.rotate(Vec3::new(0.0, 0.0, 1.0)));
    let start = Start {
        earth,
        sensor_to_body,
        vertical,
        excitation_deg,
    };
    if six_d {
        // A heading about the vertical: E = T ⊗ qz(ψ), T taking z onto the vertical, so
        // T* ⊗ r_i ≈ qz(ψ) ⊗ q_i ⊗ S* is the z-up problem.
        let tilt = from_z(vertical);
        let levelled: Vec<Quat<f64>> = r.iter().map(|&ri| tilt.conj() * ri).collect();
        let earth = tilt * heading_given_body(&q, &levelled, sensor_to_body);
        refine(&q, &r, Start { earth, ..start }, true)
    } else {
        refine(&q, &r, start, false)
    }
}

/// The start of [`refine`] and what it keeps.
#[derive(Clone, Copy)]
struct Start {
    earth: Quat<f64>,
    sensor_to_body: Quat<f64>,
    /// The reference's vertical (6D: the fixed axis of the earth offset).
    vertical: Vec3<f64>,
    excitation_deg: f64,
}

/// RMS rotation about the second axis of the estimate's relative rotations over
/// [`pairs`] of samples, degrees: the square root of the middle eigenvalue of the mean outer
/// product of their rotation vectors, in the body frame (`q_i* ⊗ q_j`) and for 9D also the
/// earth frame (`q_i ⊗ q_j*`), the smaller of the two.
fn excitation_deg(q: &[Quat<f64>], six_d: bool) -> f64 {
    let spread = |relative: &dyn Fn(usize, usize) -> Quat<f64>| {
        let (mut m, mut n) = (Matrix3::<f64>::zeros(), 0usize);
        for (i, j) in pairs(q.len()) {
            let v = relative(i, j).to_rotation_vector();
            let v = Vector3::new(v.x, v.y, v.z);
            m += v * v.transpose();
            n += 1;
        }
        if n == 0 {
            return 0.0;
        }
        let mut eigen: Vec<f64> = SymmetricEigen::new(m / n as f64)
            .eigenvalues
            .iter()
            .copied()
            .collect();
        eigen.sort_by(|a, b| b.total_cmp(a));
        eigen[1].max(0.0).sqrt().to_degrees()
    };
    let body = spread(&|i, j| q[i].conj() * q[j]);
    if six_d {
        body
    } else {
        body.min(spread(&|i, j| q[i] * q[j].conj()))
    }
}

/// [`align_frames`] of estimates against a recording's truth and use mask.
pub fn align_recording(
    rec: &Recording,
    est: &[Quat<f64>],
    mode: Alignment,
) -> Result<FrameAlignment, AlignError> {
    let truth = rec.truth.as_deref().ok_or(MetricsError::NoTruth)?;
    align_frames(est, truth, rec.use_mask.as_deref(), mode)
}

/// Pairs of samples for the relative rotations of the start: each sample with the ones a
/// sixteenth, a quarter and half of the recording later, so slow and fast motion both
/// contribute rotations well away from zero.
fn pairs(n: usize) -> impl Iterator<Item = (usize, usize)> {
    [n / 16, n / 4, n / 2]
        .into_iter()
        .filter(|&lag| lag > 0)
        .flat_map(move |lag| (0..n - lag).map(move |i| (i, i + lag)))
}

/// The vector part of `d` with `w ≥ 0`: `sin(angle/2)·axis` of the shorter rotation.
fn half_angle_axis(d: Quat<f64>) -> Vec3<f64> {
    if d.w < 0.0 { -d.vector() } else { d.vector() }
}

/// `S` from `r_i* ⊗ r_j = S ⊗ (q_i* ⊗ q_j) ⊗ S*`.
fn initial_sensor_to_body(q: &[Quat<f64>], r: &[Quat<f64>]) -> Quat<f64> {
    best_rotation(pairs(q.len()).map(|(i, j)| {
        (
            half_angle_axis(r[i].conj() * r[j]),
            half_angle_axis(q[i].conj() * q[j]),
        )
    }))
}

/// `E` from `r_i ⊗ r_j* = E ⊗ (q_i ⊗ q_j*) ⊗ E*`.
fn initial_earth(q: &[Quat<f64>], r: &[Quat<f64>]) -> Quat<f64> {
    best_rotation(pairs(q.len()).map(|(i, j)| {
        (
            half_angle_axis(r[i] * r[j].conj()),
            half_angle_axis(q[i] * q[j].conj()),
        )
    }))
}

/// The rotation `C` maximising `Σ u·(C ⊗ v ⊗ C*)` over pairs `(u, v)` (Wahba's problem), by
/// Davenport's q-method: `u·(C v C*) = ⟨u ⊗ C, C ⊗ v⟩` is a quadratic form in `C`, maximised
/// on the unit sphere by the eigenvector of the largest eigenvalue of its symmetric matrix.
fn best_rotation(pairs: impl Iterator<Item = (Vec3<f64>, Vec3<f64>)>) -> Quat<f64> {
    let basis = |k: usize| {
        let mut c = [0.0; 4];
        c[k] = 1.0;
        Quat::from_f64(c)
    };
    let mut k = Matrix4::<f64>::zeros();
    for (u, v) in pairs {
        let (u, v) = (Quat::pure(u), Quat::pure(v));
        for a in 0..4 {
            let ua = u * basis(a);
            for b in 0..4 {
                k[(a, b)] += ua.dot(basis(b) * v);
            }
        }
    }
    let eigen = SymmetricEigen::new((k + k.transpose()) * 0.5);
    let best = eigen.eigenvalues.imax();
    let c = eigen.eigenvectors.column(best);
    Quat::new(c[0], c[1], c[2], c[3]).normalize()
}

/// The heading `E = qz(ψ)` maximising `Σ ⟨r_i, qz(ψ) ⊗ p_i⟩²`, `p_i = q_i ⊗ S*`, in closed
/// form: with `qz(ψ) = c + s·k`, the sum is the quadratic form of `(c, s)` with the 2×2 matrix
/// of `a_i = ⟨r_i, p_i⟩`, `b_i = ⟨r_i, k ⊗ p_i⟩`, maximised by its leading eigenvector.
fn heading_given_body(q: &[Quat<f64>], r: &[Quat<f64>], sensor_to_body: Quat<f64>) -> Quat<f64> {
    let k = Quat::new(0.0, 0.0, 0.0, 1.0);
    let (mut aa, mut ab, mut bb) = (0.0, 0.0, 0.0);
    for (qi, ri) in q.iter().zip(r) {
        let p = *qi * sensor_to_body.conj();
        let (a, b) = (ri.dot(p), ri.dot(k * p));
        aa += a * a;
        ab += a * b;
        bb += b * b;
    }
    let half_psi = 0.5 * (2.0 * ab).atan2(aa - bb);
    Quat::from_heading(2.0 * half_psi)
}

/// Rotation-vector residual (rad, body frame) of one sample under `E`, `S`.
fn residual(q: Quat<f64>, r: Quat<f64>, earth: Quat<f64>, sensor_to_body: Quat<f64>) -> Vec3<f64> {
    (r.conj() * earth * q * sensor_to_body.conj()).to_rotation_vector()
}

/// Median of `values` (reordered), 0 for none.
fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mid = values.len() / 2;
    *values.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Gauss-Newton with Cauchy reweighting from `start`; for 6D the earth offset turns about
/// `start.vertical` only.
fn refine(
    q: &[Quat<f64>],
    r: &[Quat<f64>],
    start: Start,
    six_d: bool,
) -> Result<FrameAlignment, AlignError> {
    let Start {
        mut earth,
        mut sensor_to_body,
        vertical,
        excitation_deg,
    } = start;
    let not_excited = AlignError::NotExcited {
        six_d,
        excitation_deg,
    };
    let n = q.len();
    // Unknowns: δe (along the vertical only for 6D), then δs.
    let n_earth = if six_d { 1 } else { 3 };
    let cols = n_earth + 3;
    let mut iterations = 0;
    while iterations < MAX_ITERATIONS {
        let res: Vec<Vec3<f64>> = (0..n)
            .map(|i| residual(q[i], r[i], earth, sensor_to_body))
            .collect();
        let mut angles: Vec<f64> = res.iter().map(|e| e.norm()).collect();
        let scale = robust_scale(&mut angles);
        let weight = |e: &Vec3<f64>| 1.0 / (1.0 + (e.norm() / scale).powi(2));
        // Rows 3i..3i+3: e_i + R(r_i)ᵀ·δe + δs = 0 (the earth perturbation seen in the body
        // frame of sample i; for 6D only its column along the vertical).
        let earth_axes: [Vec3<f64>; 3] = if six_d {
            [vertical; 3]
        } else {
            [
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
                Vec3::new(0.0, 0.0, 1.0),
            ]
        };
        let rt: Vec<[Vec3<f64>; 3]> = r
            .iter()
            .map(|ri| earth_axes.map(|a| ri.rotate_inverse(a)))
            .collect();
        let h = Mat::<f64>::from_fn(3 * n, cols, |row, col| {
            let (i, k) = (row / 3, row % 3);
            if col < n_earth {
                rt[i][col].to_array()[k]
            } else {
                f64::from(u8::from(col - n_earth == k))
            }
        });
        let z = Col::<f64>::from_fn(3 * n, |row| -res[row / 3].to_array()[row % 3]);
        let w = Col::<f64>::from_fn(3 * n, |row| weight(&res[row / 3]));
        let solution = solve(
            h.as_ref(),
            z.as_ref(),
            Weights::Diagonal(w.as_ref()),
            &Options::default(),
        )
        .map_err(|e| match e {
            LsqError::RankDeficient { .. } => not_excited.clone(),
            e => AlignError::Lsq(e),
        })?;
        if solution.condition.is_nan() || solution.condition > MAX_CONDITION {
            return Err(not_excited);
        }
        let x = &solution.estimate;
        let delta_earth = if six_d {
            vertical * x[0]
        } else {
            Vec3::new(x[0], x[1], x[2])
        };
        let delta_body = Vec3::new(x[n_earth], x[n_earth + 1], x[n_earth + 2]);
        earth = (Quat::from_rotation_vector(delta_earth) * earth).normalize();
        // S* ← S* ⊗ exp(δs)  ⇔  S ← exp(−δs) ⊗ S.
        sensor_to_body = (Quat::from_rotation_vector(-delta_body) * sensor_to_body).normalize();
        iterations += 1;
        if delta_earth.norm().max(delta_body.norm()) < STEP_TOLERANCE {
            break;
        }
    }
    let vertical = if six_d {
        vertical
    } else {
        snap_to_axis(earth.rotate(Vec3::new(0.0, 0.0, 1.0)))
    };
    Ok(finish(
        q,
        r,
        Start {
            earth,
            sensor_to_body,
            vertical,
            excitation_deg,
        },
        iterations,
    ))
}

/// The Cauchy scale `c` of residual angles (reordered), rad.
fn robust_scale(angles: &mut [f64]) -> f64 {
    (CAUCHY_C * MAD_TO_SIGMA * median(angles)).max(MIN_SCALE)
}

/// The result at the solution: residual statistics.
fn finish(q: &[Quat<f64>], r: &[Quat<f64>], at: Start, iterations: usize) -> FrameAlignment {
    let (earth, sensor_to_body) = (at.earth, at.sensor_to_body);
    let mut angles: Vec<f64> = (0..q.len())
        .map(|i| residual(q[i], r[i], earth, sensor_to_body).norm())
        .collect();
    let scale = robust_scale(&mut angles);
    let n_downweighted = angles.iter().filter(|&&a| a > scale).count();
    // A unique sign: w ≥ 0.
    let canonical = |p: Quat<f64>| if p.w < 0.0 { -p } else { p };
    FrameAlignment {
        earth: canonical(earth),
        sensor_to_body: canonical(sensor_to_body),
        n_used: q.len(),
        n_downweighted,
        iterations,
        median_error_deg: median(&mut angles).to_degrees(),
        vertical: at.vertical,
        excitation_deg: at.excitation_deg,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::scenario;
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A motion-capture view of a simulated recording: estimates `q_i = E* ⊗ r_i ⊗ S ⊗ n_i`
    /// with white rotation noise `n_i` (`noise_deg` per axis) for the reference `r_i` = the
    /// simulated truth, in which 5 % of the samples are gross outliers (random rotations: a
    /// swapped marker) and 2 % NaN (tracking lost).
    fn mocap(
        name: &str,
        seed: u64,
        earth: Quat<f64>,
        sensor_to_body: Quat<f64>,
        noise_deg: f64,
    ) -> (Vec<Quat<f64>>, Vec<Quat<f64>>) {
        let rec = scenario(name, seed, 120.0, 100.0).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut truth = rec.truth.unwrap();
        let noise = noise_deg.to_radians();
        let est = truth
            .iter()
            .map(|&r| {
                let n = Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                ) * (noise * 3f64.sqrt());
                earth.conj() * r * sensor_to_body * Quat::from_rotation_vector(n)
            })
            .collect();
        for r in &mut truth {
            let u: f64 = rng.random();
            if u < 0.05 {
                let v = Vec3::new(rng.random(), rng.random(), rng.random());
                *r = Quat::from_rotation_vector(v * 3.0);
            } else if u < 0.07 {
                *r = Quat::new(f64::NAN, f64::NAN, f64::NAN, f64::NAN);
            }
        }
        (est, truth)
    }

    fn rotation() -> impl Strategy<Value = Quat<f64>> {
        (-3.1f64..3.1, -3.1f64..3.1, -3.1f64..3.1).prop_map(|(x, y, z)| {
            let v = Vec3::new(x, y, z);
            // Angles up to π: beyond, the same rotation has a shorter vector.
            let scale = if v.norm() > 3.1 { 3.1 / v.norm() } else { 1.0 };
            Quat::from_rotation_vector(v * scale)
        })
    }

    fn error_deg(found: Quat<f64>, expected: Quat<f64>) -> f64 {
        found.angle_to(expected).to_degrees()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(12))]

        /// 9D: any earth offset and any sensor-to-body rotation are recovered to 0.01°
        /// despite 0.1° noise, 5 % gross outliers and 2 % lost samples (2 min at 100 Hz).
        #[test]
        fn recovers_both_rotations_9d(earth in rotation(), body in rotation(), seed in 0u64..1000) {
            let (est, truth) = mocap("slow-rotation", seed, earth, body, 0.1);
            let a = align_frames(&est, &truth, None, Alignment::NineD).unwrap();
            prop_assert!(error_deg(a.earth, earth) < 0.01, "earth off by {}°", error_deg(a.earth, earth));
            prop_assert!(error_deg(a.sensor_to_body, body) < 0.01, "body off by {}°", error_deg(a.sensor_to_body, body));
            // The outliers (5 % of the samples) are what was down-weighted, give or take.
            prop_assert!(a.n_downweighted < a.n_used / 5, "{a:?}");
        }

        /// 6D: a heading offset and any sensor-to-body rotation, to 0.01°.
        #[test]
        fn recovers_heading_and_body_6d(psi in -core::f64::consts::PI..core::f64::consts::PI, body in rotation(), seed in 0u64..1000) {
            let earth = Quat::from_heading(psi);
            let (est, truth) = mocap("translation", seed, earth, body, 0.1);
            let a = align_frames(&est, &truth, None, Alignment::SixD).unwrap();
            prop_assert!(error_deg(a.earth, earth) < 0.01, "earth off by {}°", error_deg(a.earth, earth));
            prop_assert!(error_deg(a.sensor_to_body, body) < 0.01, "body off by {}°", error_deg(a.sensor_to_body, body));
            prop_assert!((a.earth_heading_deg() - psi.to_degrees()).abs() < 0.01);
        }
    }

    /// 6D against a y-up reference (motion capture's other convention): the vertical is
    /// found, the earth offset turns about it, both rotations are recovered to 0.01°.
    #[test]
    fn six_d_finds_a_y_up_reference() {
        let y_up = Quat::from_axis_angle(Vec3::new(1.0, 0.0, 0.0), -core::f64::consts::FRAC_PI_2);
        let up = y_up.rotate(Vec3::new(0.0, 0.0, 1.0));
        assert!((up - Vec3::new(0.0, 1.0, 0.0)).norm() < 1e-12, "{up:?}");
        for (seed, psi) in [(1u64, 0.7f64), (2, -2.5)] {
            let earth = y_up * Quat::from_heading(psi);
            let body = Quat::from_rotation_vector(Vec3::new(0.4, -1.2, 2.0));
            let (est, truth) = mocap("translation", seed, earth, body, 0.1);
            let a = align_frames(&est, &truth, None, Alignment::SixD).unwrap();
            assert_eq!(a.vertical.to_array(), [0.0, 1.0, 0.0]);
            assert!(
                error_deg(a.earth, earth) < 0.01,
                "earth off by {}°",
                error_deg(a.earth, earth)
            );
            assert!(error_deg(a.sensor_to_body, body) < 0.01, "{a:?}");
            assert!(
                (a.earth_heading_deg() - psi.to_degrees()).abs() < 0.01,
                "{a:?}"
            );
            // Levelled, the reference is z-up again.
            assert!(error_deg(a.level() * earth, Quat::from_heading(psi)) < 0.01);
        }
    }

    /// A still sensor with a noisy estimate (0.1°): its noise is not excitation.
    #[test]
    fn still_noisy_recording_is_not_excited() {
        let earth = Quat::from_heading(1.0);
        let body = Quat::from_rotation_vector(Vec3::new(0.4, -1.2, 2.0));
        let (est, truth) = mocap("static", 4, earth, body, 0.1);
        for mode in [Alignment::NineD, Alignment::SixD] {
            let got = align_frames(&est, &truth, None, mode);
            assert!(
                matches!(got, Err(AlignError::NotExcited { excitation_deg, .. }) if excitation_deg < 1.0),
                "{got:?}"
            );
            let message = got.unwrap_err().to_string();
            assert!(message.contains("at least 5° needed"), "{message}");
        }
    }

    /// Aligned estimates are the reference again (noise-free: to rounding).
    #[test]
    fn apply_undoes_the_offsets() {
        let (earth, body) = (
            Quat::from_rotation_vector(Vec3::new(0.3, -2.0, 1.0)),
            Quat::from_rotation_vector(Vec3::new(-1.0, 0.5, 2.5)),
        );
        let rec = scenario("slow-rotation", 7, 20.0, 100.0).unwrap();
        let truth = rec.truth.clone().unwrap();
        let est: Vec<Quat<f64>> = truth.iter().map(|&r| earth.conj() * r * body).collect();
        let a = align_recording(&rec, &est, Alignment::NineD).unwrap();
        for (q, r) in a.apply_all(&est).iter().zip(&truth) {
            assert!(q.angle_to(*r) < 1e-9, "{}", q.angle_to(*r));
        }
        assert!(a.median_error_deg < 1e-9);
    }

    /// A sensor that does not move cannot tell the earth offset from the body rotation.
    #[test]
    fn static_recording_is_not_excited() {
        let rec = scenario("static", 3, 10.0, 100.0).unwrap();
        let truth = rec.truth.clone().unwrap();
        for mode in [Alignment::NineD, Alignment::SixD] {
            let got = align_frames(&truth, &truth, None, mode);
            assert!(
                matches!(got, Err(AlignError::NotExcited { six_d, excitation_deg })
                    if six_d == (mode == Alignment::SixD) && excitation_deg < 0.1),
                "{got:?}"
            );
        }
        let nan = Quat::new(f64::NAN, 0.0, 0.0, 0.0);
        assert_eq!(
            align_frames(&[nan; 20], &truth[..20], None, Alignment::NineD),
            Err(AlignError::TooFewSamples(0))
        );
    }
}
