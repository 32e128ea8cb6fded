//! The BROAD orientation error metrics (`docs/conventions.md`), exactly as defined
//! there; every evaluation in this project uses these.
//!
//! Per sample, with estimate `q_est` and reference `q_ref` (both sensor to earth, ENU):
//! `e = q_est ⊗ conj(q_ref)` (the error expressed in the earth frame), then
//! - total `= 2·acos(|e_w|)`,
//! - heading `= 2·atan(|e_z / e_w|)`,
//! - inclination `= 2·acos(sqrt(e_w² + e_z²))`.
//!
//! We evaluate the mathematically identical forms `2·atan2(|e_v|, |e_w|)`,
//! `2·atan2(|e_z|, |e_w|)` and `2·atan2(sqrt(e_x² + e_y²), sqrt(e_w² + e_z²))`: they are exact
//! for a unit `e`, accurate near zero error where `acos` loses half the digits, need no
//! clamping, do not divide by `e_w = 0`, and are insensitive to a slightly non-unit estimate.
//! All are invariant under `q → −q` of either quaternion.
//!
//! The RMSE runs over the samples with `use = 1` and finite truth, in degrees.
//! - 9D: no alignment.
//! - 6D (heading not observable): first remove the constant heading offset
//!   `d = circular mean over those samples of 2·atan2(e_z, e_w)` by `q_est' = qz(−d) ⊗ q_est`,
//!   `qz(a) = [cos(a/2), 0, 0, sin(a/2)]`. The inclination error is unchanged by this.
//!
//! A non-finite estimate on a counted sample makes the RMSE NaN (a diverged filter must not
//! look good by having its bad samples skipped); it is left out of the 6D offset so that one
//! bad sample does not also shift the heading of all others.

use core::f64::consts::PI;
use rootfuse_attitude::Quat;
use rootfuse_attitude::Recording;
use std::vec::Vec;

/// How the estimate is aligned to the reference before errors are computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Alignment {
    /// 9D (magnetometer-aided) estimate: compared as is.
    NineD,
    /// 6D estimate: the constant heading offset (circular mean) is removed first.
    SixD,
}

/// Errors of one sample, rad.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleError {
    /// Total rotation angle of the error, rad in `[0, π]`.
    pub total: f64,
    /// Heading (rotation about earth-z) part, rad in `[0, π]`.
    pub heading: f64,
    /// Inclination (rotation about a horizontal axis) part, rad in `[0, π]`.
    pub inclination: f64,
}

/// RMSE over the counted samples, degrees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rmse {
    /// Total error RMSE, degrees.
    pub total: f64,
    /// Heading error RMSE, degrees.
    pub heading: f64,
    /// Inclination error RMSE, degrees.
    pub inclination: f64,
    /// Number of samples counted (`use = 1` and finite truth).
    pub n_used: usize,
    /// Heading offset removed (6D), degrees in `(−180, 180]`; 0 for 9D.
    pub heading_offset: f64,
}

/// Error over time for plots: one value per sample, degrees, NaN where the truth is unknown.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ErrorSeries {
    /// Total error, degrees.
    pub total: Vec<f64>,
    /// Heading error, degrees.
    pub heading: Vec<f64>,
    /// Inclination error, degrees.
    pub inclination: Vec<f64>,
    /// Whether the sample counts for the RMSE (`use = 1` and finite truth).
    pub used: Vec<bool>,
    /// Heading offset removed (6D), degrees; 0 for 9D.
    pub heading_offset: f64,
}

/// Why errors could not be computed.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum MetricsError {
    /// Estimate, truth and use mask differ in length.
    #[error("length mismatch: {estimates} estimates, {truth} truth samples, {mask} use flags")]
    Length {
        /// Number of estimates.
        estimates: usize,
        /// Number of truth samples.
        truth: usize,
        /// Number of use flags.
        mask: usize,
    },
    /// The recording has no ground truth.
    #[error("the recording has no ground truth")]
    NoTruth,
    /// Estimates and their covariances differ in length.
    #[error("length mismatch: {estimates} estimates, {covariances} covariances")]
    CovarianceLength {
        /// Number of estimates.
        estimates: usize,
        /// Number of covariances.
        covariances: usize,
    },
    /// No sample has `use = 1` and finite truth.
    #[error("no sample counts for evaluation (use = 1 with finite truth)")]
    NoUsableSamples,
    /// An estimate that counts is no orientation: its norm is off 1 by more than
    /// [`UNIT_NORM_TOLERANCE`] (an all-zero row would score as perfect, `2·q` would be
    /// normalised silently), or a component is NaN (unknown) where the truth counts.
    #[error(
        "estimate row {row}: norm {norm} is not 1 (within {UNIT_NORM_TOLERANCE}): not an orientation; unknown rows must be left out with the use mask"
    )]
    NotAnOrientation {
        /// 0-based row.
        row: usize,
        /// Its norm (NaN for an unknown row).
        norm: f64,
    },
    /// A truth row that counts (`use = 1`, finite) is no orientation: its norm is off 1 by
    /// more than [`UNIT_NORM_TOLERANCE`] (all-zero truth rows scored 0° against anything).
    #[error(
        "truth row {row}: norm {norm} is not 1 (within {UNIT_NORM_TOLERANCE}): not an orientation; mark rows without truth with NaN or use = 0"
    )]
    TruthNotAnOrientation {
        /// 0-based row.
        row: usize,
        /// Its norm.
        norm: f64,
    },
}

/// How far from 1 the norm of an estimate that counts may be: a quaternion written with
/// three decimals is within 2·10⁻³ of unit norm; a zero or unnormalised one is far outside.
pub const UNIT_NORM_TOLERANCE: f64 = 0.01;

/// The first counted row whose estimate is no orientation.
fn check_orientations(
    est: &[Quat<f64>],
    truth: &[Quat<f64>],
    mask: Option<&[bool]>,
) -> Result<(), MetricsError> {
    for (row, q) in est.iter().enumerate() {
        if !counted(truth, mask, row) {
            continue;
        }
        let truth_norm = truth[row].norm();
        if (truth_norm - 1.0).abs() > UNIT_NORM_TOLERANCE {
            return Err(MetricsError::TruthNotAnOrientation {
                row,
                norm: truth_norm,
            });
        }
        let norm = q.norm();
        let off = (norm - 1.0).abs();
        if off.is_nan() || off > UNIT_NORM_TOLERANCE {
            return Err(MetricsError::NotAnOrientation { row, norm });
        }
    }
    Ok(())
}

/// The error quaternion `e = q_est ⊗ conj(q_ref)` (earth frame).
#[inline]
pub fn error_quat(q_est: Quat<f64>, q_ref: Quat<f64>) -> Quat<f64> {
    q_est * q_ref.conj()
}

/// The three BROAD errors of one error quaternion `e` (see the module docs), rad.
#[inline]
pub fn split_error(e: Quat<f64>) -> SampleError {
    let (aw, az) = (e.w.abs(), e.z.abs());
    let horiz = e.x.hypot(e.y);
    let vec = horiz.hypot(az);
    SampleError {
        total: 2.0 * vec.atan2(aw),
        heading: 2.0 * az.atan2(aw),
        inclination: 2.0 * horiz.atan2(aw.hypot(az)),
    }
}

/// The BROAD errors of one estimate against one reference, rad (no alignment).
#[inline]
pub fn sample_error(q_est: Quat<f64>, q_ref: Quat<f64>) -> SampleError {
    split_error(error_quat(q_est, q_ref))
}

/// The heading angle of an error quaternion, `2·atan2(e_z, e_w)`, rad (defined modulo 2π;
/// `e` and `−e` give angles 2π apart, i.e. the same direction).
#[inline]
pub fn error_heading(e: Quat<f64>) -> f64 {
    2.0 * e.z.atan2(e.w)
}

pub(crate) fn counted(truth: &[Quat<f64>], mask: Option<&[bool]>, i: usize) -> bool {
    let q = truth[i];
    mask.is_none_or(|m| m[i])
        && q.w.is_finite()
        && q.x.is_finite()
        && q.y.is_finite()
        && q.z.is_finite()
}

pub(crate) fn check(
    est: &[Quat<f64>],
    truth: &[Quat<f64>],
    mask: Option<&[bool]>,
) -> Result<(), MetricsError> {
    let m = mask.map_or(est.len(), <[bool]>::len);
    if est.len() != truth.len() || m != est.len() {
        return Err(MetricsError::Length {
            estimates: est.len(),
            truth: truth.len(),
            mask: m,
        });
    }
    Ok(())
}

/// The 6D heading offset `d` (rad, in `(−π, π]`): circular mean of `2·atan2(e_z, e_w)` over
/// the counted samples with a finite estimate. `None` when there is no such sample or the
/// mean direction is undefined (headings spread evenly around the circle).
pub fn heading_offset(
    est: &[Quat<f64>],
    truth: &[Quat<f64>],
    use_mask: Option<&[bool]>,
) -> Result<Option<f64>, MetricsError> {
    check(est, truth, use_mask)?;
    let (mut s, mut c, mut n) = (0.0, 0.0, 0usize);
    for i in 0..est.len() {
        if !counted(truth, use_mask, i) {
            continue;
        }
        let a = error_heading(error_quat(est[i], truth[i]));
        if a.is_finite() {
            s += a.sin();
            c += a.cos();
            n += 1;
        }
    }
    // Relative threshold: a resultant this short has no meaningful direction.
    if n == 0 || s.hypot(c) <= 1e-12 * n as f64 {
        return Ok(None);
    }
    Ok(Some(s.atan2(c)))
}

/// Per-sample errors (degrees, NaN where the truth is unknown) after the alignment of `mode`.
pub fn error_series(
    est: &[Quat<f64>],
    truth: &[Quat<f64>],
    use_mask: Option<&[bool]>,
    mode: Alignment,
) -> Result<ErrorSeries, MetricsError> {
    check(est, truth, use_mask)?;
    let d = match mode {
        Alignment::NineD => 0.0,
        Alignment::SixD => heading_offset(est, truth, use_mask)?.unwrap_or(0.0),
    };
    let align = Quat::<f64>::from_heading(-d);
    let n = est.len();
    let mut out = ErrorSeries {
        total: Vec::with_capacity(n),
        heading: Vec::with_capacity(n),
        inclination: Vec::with_capacity(n),
        used: Vec::with_capacity(n),
        heading_offset: d.to_degrees(),
    };
    for i in 0..n {
        let used = counted(truth, use_mask, i);
        let q = match mode {
            Alignment::NineD => est[i],
            Alignment::SixD => align * est[i],
        };
        let e = if truth[i].w.is_finite() {
            sample_error(q, truth[i])
        } else {
            SampleError {
                total: f64::NAN,
                heading: f64::NAN,
                inclination: f64::NAN,
            }
        };
        out.total.push(e.total.to_degrees());
        out.heading.push(e.heading.to_degrees());
        out.inclination.push(e.inclination.to_degrees());
        out.used.push(used);
    }
    Ok(out)
}

/// The BROAD RMSE (degrees) of estimates against truth over the samples with `use = 1`
/// (all when `use_mask` is `None`) and finite truth. Refused: an estimate that counts and is
/// no unit quaternion ([`MetricsError::NotAnOrientation`]).
pub fn rmse(
    est: &[Quat<f64>],
    truth: &[Quat<f64>],
    use_mask: Option<&[bool]>,
    mode: Alignment,
) -> Result<Rmse, MetricsError> {
    check(est, truth, use_mask)?;
    check_orientations(est, truth, use_mask)?;
    let series = error_series(est, truth, use_mask, mode)?;
    let (mut st, mut sh, mut si, mut n) = (0.0, 0.0, 0.0, 0usize);
    for i in 0..est.len() {
        if series.used[i] {
            st += series.total[i].powi(2);
            sh += series.heading[i].powi(2);
            si += series.inclination[i].powi(2);
            n += 1;
        }
    }
    if n == 0 {
        return Err(MetricsError::NoUsableSamples);
    }
    let nf = n as f64;
    Ok(Rmse {
        total: (st / nf).sqrt(),
        heading: (sh / nf).sqrt(),
        inclination: (si / nf).sqrt(),
        n_used: n,
        heading_offset: series.heading_offset,
    })
}

/// [`rmse`] of estimates against a recording's truth and use mask.
pub fn evaluate(rec: &Recording, est: &[Quat<f64>], mode: Alignment) -> Result<Rmse, MetricsError> {
    let truth = rec.truth.as_deref().ok_or(MetricsError::NoTruth)?;
    rmse(est, truth, rec.use_mask.as_deref(), mode)
}

/// [`error_series`] of estimates against a recording's truth and use mask.
pub fn evaluate_series(
    rec: &Recording,
    est: &[Quat<f64>],
    mode: Alignment,
) -> Result<ErrorSeries, MetricsError> {
    let truth = rec.truth.as_deref().ok_or(MetricsError::NoTruth)?;
    error_series(est, truth, rec.use_mask.as_deref(), mode)
}

/// Roll, pitch and yaw RMSE (degrees) of estimates against a recording's truth over the
/// samples from `skip_s` seconds on (all samples, the use mask is not read): ZYX Euler
/// angles ([`Quat::to_euler_zyx`]), differences wrapped to `[−π, π)`.
///
/// With `align` (6D estimates, whose heading is relative) the estimate is first turned about
/// earth-z by the heading offset at the first evaluated sample, so the yaw error is the
/// heading drift from there. Returns NaN where no sample is evaluated or there is no truth.
pub fn euler_rmse(rec: &Recording, est: &[Quat<f64>], skip_s: f64, align: bool) -> [f64; 3] {
    let Some(truth) = rec.truth.as_ref() else {
        return [f64::NAN; 3];
    };
    let wrap = |d: f64| (d + PI).rem_euclid(2.0 * PI) - PI;
    let (mut sum, mut n) = ([0.0; 3], 0usize);
    let mut turn = None;
    for ((t, e), q) in rec.t.iter().zip(est).zip(truth) {
        if *t < skip_s {
            continue;
        }
        let turn = *turn.get_or_insert_with(|| {
            if align {
                Quat::from_heading(error_heading(error_quat(*q, *e)))
            } else {
                Quat::identity()
            }
        });
        let (ye, pe, re) = (turn * *e).to_euler_zyx();
        let (yt, pt, rt) = q.to_euler_zyx();
        for (s, d) in sum.iter_mut().zip([re - rt, pe - pt, ye - yt]) {
            *s += wrap(d) * wrap(d);
        }
        n += 1;
    }
    sum.map(|s| (s / n as f64).sqrt().to_degrees())
}
