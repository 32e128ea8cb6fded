//! Ellipsoid fit: the calibration `y_cal = S·(y_raw − h)` that makes `|y_cal|` constant.
//!
//! An undisturbed reading `y_raw = S⁻¹·y + h` with `|y| = F` lies on the ellipsoid
//! `(y_raw − h)ᵀ·S²·(y_raw − h) = F²`. The fit runs in three stages (method and references in
//! `docs/methods.md`, "Sensor calibration"):
//!
//! 1. **Normalise**: subtract the mean reading and divide by the RMS distance from it, so
//!    every model below is posed on data of unit size.
//! 2. **Observability and algebraic fit**: the quadric `pᵀA p + 2bᵀp = 1` is linear in the
//!    entries of `A` and `b`; each model restricts `A` (full symmetric, diagonal, a multiple
//!    of `I`) and is solved by least squares (SVD on our dense solvers). The condition number
//!    of its design is the observability test: the first model, from the richest down, whose
//!    condition stays below [`FitOptions::max_condition`] is taken, and every model refused
//!    on the way is reported with its condition. A sensor turned about one axis only leaves
//!    its readings on a circle: no three-dimensional model is determined, and the fit falls
//!    back to the offset within the plane of motion ([`FittedModel::InPlaneOffset`]).
//! 3. **Geometric refinement**: Levenberg–Marquardt on the residuals `|S(p − h)| − 1` over
//!    the parameters of the chosen model (symmetric `S` entries and `h`), each step a
//!    least-squares solve of the damped Gauss–Newton system.
//!
//! The scale of `S` is not determined by the data (any multiple of `S` also makes `|y_cal|`
//! constant): with [`FitOptions::norm`] it is scaled so that `|y_cal|` is that norm (field
//! strength, gravity); without, so that `det S = 1`, and the resulting norm is reported.

use crate::mat3::{det3, dist2, dot3, mat_vec, norm3, sub3, sym_apply, sym_eigen, sym_function};
use crate::quality::{FitQuality, quality};
use crate::{CalibrationError, FittedModel, RefusedModel};
use rootfuse_attitude::{SensorCalibration, Vec3};
use rootfuse_lsq::dense::faer::{Col, Mat};
use rootfuse_lsq::dense::{Method, Options, Weights, solve};

/// Options of [`fit_ellipsoid`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitOptions {
    /// The norm `|y_cal|` should have (field strength, gravity), calibrated units; `None`:
    /// scale `S` to `det S = 1` and report the norm.
    pub norm: Option<f64>,
    /// Largest condition number (`σ_max/σ_min`) of a model's normalised design for the model
    /// to count as determined by the data.
    pub max_condition: f64,
    /// Largest accepted residual RMS relative to the norm (above it the fit is refused).
    pub max_residual_relative: f64,
    /// Iterations of the geometric refinement (0: the algebraic fit only).
    pub max_iterations: usize,
    /// Smallest [`FitQuality::coverage`] of the sphere of directions for a three-dimensional
    /// model (the in-plane offset of a turn about one axis is exempt: it covers a band by
    /// design). The condition test alone passes a noisy cap of readings: on the 14 BROAD
    /// trials, full fits at 4–33 % coverage made the flagship's 9D error 3–165° where it was
    /// 0.8–7° without them; at 67–100 % they changed it by 0.0–1.1°; a simulated slow
    /// rotation covering 46 % recovers its hard iron to 0.25 µT. The default, 40 %, lies
    /// between.
    pub min_coverage: f64,
    /// An axis whose extreme value recurs in more than this fraction of the samples (and at
    /// least [`SATURATION_MIN_COUNT`] times) is taken as saturated.
    pub saturation_fraction: f64,
}

/// Readings whose RMS distance from their mean is below this fraction of the mean's norm are
/// refused as a constant field ([`CalibrationError::ConstantField`]).
pub const MIN_RELATIVE_SPREAD: f64 = 0.01;

/// The smallest number of samples at one extreme value that counts as saturation.
pub const SATURATION_MIN_COUNT: usize = 5;

impl Default for FitOptions {
    /// Norm from `det S = 1`, condition limit 40, residual limit 5 %, 50 refinement
    /// iterations, saturation at 2 % of the samples, coverage at least 40 %.
    fn default() -> Self {
        Self {
            norm: None,
            max_condition: 40.0,
            max_residual_relative: 0.05,
            max_iterations: 50,
            saturation_fraction: 0.02,
            min_coverage: 0.4,
        }
    }
}

/// The result of [`fit_ellipsoid`].
#[derive(Clone, Debug, PartialEq)]
pub struct EllipsoidFit {
    /// The calibration (`S`, `h` in raw units, the norm).
    pub calibration: SensorCalibration<f64>,
    /// Which parameters were fitted.
    pub model: FittedModel,
    /// Richer models refused because the data did not determine them, richest first.
    pub refused: Vec<RefusedModel>,
    /// Residual, coverage and conditioning figures.
    pub quality: FitQuality,
    /// Rows skipped because a component was NaN or infinite (they are not used).
    pub skipped_non_finite: usize,
    /// Rows (indices into the input) left out as outliers: readings far from every other
    /// (a glitch, a bit flip, a spike), or whose norm residual after a first fit is beyond
    /// [`RESIDUAL_OUTLIER_SIGMAS`] robust standard deviations. At most
    /// [`MAX_OUTLIER_FRACTION`] of the rows; more than that is disturbed data, not glitches,
    /// and is left for the residual check to refuse.
    pub outliers: Vec<usize>,
}

/// Readings farther from the coordinate-wise median than this many times the 90th
/// percentile of the distances are gross outliers, left out before the fit: a glitch of 1e6
/// or 1e200 would otherwise decide it. The percentile, not the median distance, is the
/// scale: a real recording covers the sphere of readings unevenly, its coordinate-wise
/// median lies off the centre, and the median distance can be a fraction of the radius
/// (BROAD 02: a third of its rows lay beyond four median distances).
pub const GROSS_OUTLIER_FACTOR: f64 = 4.0;

/// The share of the rows a trimmed fit keeps: the readings with the smallest norm residual
/// under the previous fit ([`TRIM_STEPS`] times), so that up to [`MAX_OUTLIER_FRACTION`] of
/// readings off the ellipsoid cannot pull the fit that judges them.
const TRIM_KEEP: f64 = 0.9;

/// Concentration steps of the trimmed fit (each refits on the best-fitting [`TRIM_KEEP`]).
const TRIM_STEPS: usize = 3;

/// After a first fit, readings whose relative norm residual is this many robust standard
/// deviations (1.4826 × the median absolute deviation) from the median residual, and at
/// least [`MIN_OUTLIER_RESIDUAL`], are left out and the fit is repeated once.
pub const RESIDUAL_OUTLIER_SIGMAS: f64 = 6.0;

/// A relative norm residual below this (1 % of the norm) is never an outlier: a clean fit's
/// noise is not trimmed.
pub const MIN_OUTLIER_RESIDUAL: f64 = 0.01;

/// The largest fraction of the rows left out as outliers.
pub const MAX_OUTLIER_FRACTION: f64 = 0.05;

/// The three-dimensional models, richest first, as the observability ladder tries them
/// (the in-plane offset is the last resort).
const LADDER_3D: [FittedModel; 3] = [
    FittedModel::Full,
    FittedModel::DiagonalScale,
    FittedModel::OffsetOnly,
];

impl FittedModel {
    /// Free entries of `S` in the geometric refinement (0 for the in-plane fallback).
    fn matrix_basis(self) -> &'static [[[f64; 3]; 3]] {
        const XX: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]];
        const YY: [[f64; 3]; 3] = [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]];
        const ZZ: [[f64; 3]; 3] = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
        const XY: [[f64; 3]; 3] = [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]];
        const XZ: [[f64; 3]; 3] = [[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
        const YZ: [[f64; 3]; 3] = [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]];
        const I: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        match self {
            FittedModel::Full => &[XX, YY, ZZ, XY, XZ, YZ],
            FittedModel::DiagonalScale => &[XX, YY, ZZ],
            FittedModel::OffsetOnly => &[I],
            FittedModel::InPlaneOffset => &[],
        }
    }
    /// Row of the algebraic design `pᵀA p + 2bᵀp = 1` for the normalised sample `p`.
    fn design_row(self, p: [f64; 3], out: &mut Vec<f64>) {
        let [x, y, z] = p;
        out.clear();
        match self {
            FittedModel::Full => {
                out.extend([x * x, y * y, z * z, 2.0 * x * y, 2.0 * x * z, 2.0 * y * z])
            }
            FittedModel::DiagonalScale => out.extend([x * x, y * y, z * z]),
            FittedModel::OffsetOnly => out.push(x * x + y * y + z * z),
            // Plane coordinates (u, v) = (x, y): a circle.
            FittedModel::InPlaneOffset => {
                out.extend([x * x + y * y, 2.0 * x, 2.0 * y]);
                return;
            }
        }
        out.extend([2.0 * x, 2.0 * y, 2.0 * z]);
    }
    /// `A` from the quadratic part of an algebraic solution.
    fn quadric(self, a: &[f64]) -> [[f64; 3]; 3] {
        match self {
            FittedModel::Full => [[a[0], a[3], a[4]], [a[3], a[1], a[5]], [a[4], a[5], a[2]]],
            FittedModel::DiagonalScale => [[a[0], 0.0, 0.0], [0.0, a[1], 0.0], [0.0, 0.0, a[2]]],
            FittedModel::OffsetOnly | FittedModel::InPlaneOffset => {
                [[a[0], 0.0, 0.0], [0.0, a[0], 0.0], [0.0, 0.0, a[0]]]
            }
        }
    }
}

/// Fits `y_cal = S·(y_raw − h)` with `|y_cal|` constant to raw three-axis readings (a
/// magnetometer turned through many orientations, or an accelerometer's rest readings).
///
/// Rows with a non-finite component are skipped and counted
/// ([`EllipsoidFit::skipped_non_finite`]); outliers are left out and listed
/// ([`EllipsoidFit::outliers`]). Refused, with a [`CalibrationError`]: a `norm` option that is
/// not a positive finite number, fewer than 12
/// finite rows, a constant reading (spread below [`MIN_RELATIVE_SPREAD`] of the mean), a saturated axis, motion that determines nothing, a
/// quadric that is no ellipsoid, a residual above [`FitOptions::max_residual_relative`].
pub fn fit_ellipsoid(
    samples: &[Vec3<f64>],
    options: &FitOptions,
) -> Result<EllipsoidFit, CalibrationError> {
    const MIN_SAMPLES: usize = 12;
    if let Some(norm) = options.norm
        && !(norm.is_finite() && norm > 0.0)
    {
        return Err(CalibrationError::InvalidNorm { norm });
    }
    // (row, reading) of the finite rows.
    let finite: Vec<(usize, [f64; 3])> = samples
        .iter()
        .map(|v| v.to_array())
        .enumerate()
        .filter(|(_, v)| v.iter().all(|c| c.is_finite()))
        .collect();
    let skipped = samples.len() - finite.len();
    if finite.len() < MIN_SAMPLES {
        return Err(CalibrationError::TooFewSamples {
            usable: finite.len(),
            skipped_non_finite: skipped,
            needed: MIN_SAMPLES,
        });
    }
    let max_outliers = (MAX_OUTLIER_FRACTION * finite.len() as f64) as usize;
    let mut out = gross_outliers(&finite);
    if out.iter().filter(|o| **o).count() > max_outliers {
        out.fill(false);
    }
    let kept = |out: &[bool]| -> Vec<[f64; 3]> {
        finite
            .iter()
            .zip(out)
            .filter(|(_, o)| !**o)
            .map(|(r, _)| r.1)
            .collect()
    };
    // The first fit finds the readings off the ellipsoid; only the fit without them must
    // meet the residual limit (a 1 % burst at twice the field alone gives 10 % RMS).
    let loose = FitOptions {
        max_residual_relative: f64::INFINITY,
        ..*options
    };
    // The start of the trimmed fit: the rows nearest the coordinate-wise median (a burst of
    // far readings can make the fit of all rows no ellipsoid at all), else all rows.
    let central = {
        let (dist, typical) = median_distances(&finite);
        let near: Vec<bool> = dist
            .iter()
            .zip(&out)
            .map(|(&d, &o)| o || d.is_nan() || d > typical)
            .collect();
        kept(&near)
    };
    let mut first = match fit_finite(&central, skipped, &loose) {
        Ok(fit) => fit,
        Err(_) => fit_finite(&kept(&out), skipped, &loose)?,
    };
    for _ in 0..TRIM_STEPS {
        let trimmed = best_fitting(&first.calibration, &finite, &out);
        match fit_finite(&trimmed, skipped, &loose) {
            Ok(fit) => first = fit,
            // A trimmed set the model cannot fit: judge with the fit of all rows.
            Err(_) => break,
        }
    }
    let more = residual_outliers(&first.calibration, &finite, &out);
    if out.iter().filter(|o| **o).count() + more.len() <= max_outliers {
        for i in more {
            out[i] = true;
        }
    }
    fit_finite(&kept(&out), skipped, options).map(|mut fit| {
        fit.outliers = finite
            .iter()
            .zip(&out)
            .filter(|(_, o)| **o)
            .map(|(r, _)| r.0)
            .collect();
        fit
    })
}

/// Per finite row: true for a reading farther than [`GROSS_OUTLIER_FACTOR`] times the 90th
/// percentile of the distances from the coordinate-wise median.
fn gross_outliers(finite: &[(usize, [f64; 3])]) -> Vec<bool> {
    let (dist, typical) = median_distances(finite);
    // An infinite or NaN distance (a 1e200 glitch squared) is an outlier.
    dist.iter()
        .map(|&d| d.is_nan() || d > GROSS_OUTLIER_FACTOR * typical)
        .collect()
}

/// Per finite row its distance from the coordinate-wise median, and the 90th percentile of
/// those distances.
fn median_distances(finite: &[(usize, [f64; 3])]) -> (Vec<f64>, f64) {
    let centre: [f64; 3] = core::array::from_fn(|k| {
        let mut c: Vec<f64> = finite.iter().map(|r| r.1[k]).collect();
        median(&mut c)
    });
    let dist: Vec<f64> = finite.iter().map(|r| dist2(r.1, centre).sqrt()).collect();
    let mut sorted = dist.clone();
    let at = ((0.9 * sorted.len() as f64) as usize).min(sorted.len().saturating_sub(1));
    let typical = sorted
        .select_nth_unstable_by(at, f64::total_cmp)
        .1
        .to_owned();
    (dist, typical)
}

/// The [`TRIM_KEEP`] share of the rows not `out` with the smallest relative norm residual
/// under `cal`.
fn best_fitting(
    cal: &SensorCalibration<f64>,
    finite: &[(usize, [f64; 3])],
    out: &[bool],
) -> Vec<[f64; 3]> {
    let residual =
        |y: [f64; 3]| ((cal.apply(Vec3::from_array(y)).norm() - cal.norm) / cal.norm).abs();
    let mut rows: Vec<(f64, [f64; 3])> = finite
        .iter()
        .zip(out)
        .filter(|(_, o)| !**o)
        .map(|(r, _)| (residual(r.1), r.1))
        .collect();
    let keep = ((TRIM_KEEP * rows.len() as f64) as usize)
        .max(1)
        .min(rows.len());
    if keep < rows.len() {
        rows.select_nth_unstable_by(keep, |a, b| a.0.total_cmp(&b.0));
        rows.truncate(keep);
    }
    rows.into_iter().map(|r| r.1).collect()
}

/// Positions in `finite` (not yet `out`) whose relative norm residual under `cal` is an
/// outlier ([`RESIDUAL_OUTLIER_SIGMAS`], [`MIN_OUTLIER_RESIDUAL`]).
fn residual_outliers(
    cal: &SensorCalibration<f64>,
    finite: &[(usize, [f64; 3])],
    out: &[bool],
) -> Vec<usize> {
    let residual = |y: [f64; 3]| (cal.apply(Vec3::from_array(y)).norm() - cal.norm) / cal.norm;
    let r: Vec<(usize, f64)> = finite
        .iter()
        .enumerate()
        .filter(|(i, _)| !out[*i])
        .map(|(i, row)| (i, residual(row.1)))
        .collect();
    let mut values: Vec<f64> = r.iter().map(|x| x.1).collect();
    let centre = median(&mut values);
    let mut deviations: Vec<f64> = values.iter().map(|v| (v - centre).abs()).collect();
    let sigma = 1.4826 * median(&mut deviations);
    let limit = (RESIDUAL_OUTLIER_SIGMAS * sigma).max(MIN_OUTLIER_RESIDUAL);
    r.iter()
        .filter(|(_, v)| v.is_nan() || (v - centre).abs() > limit)
        .map(|(i, _)| *i)
        .collect()
}

/// The median of finite values (reorders them); 0 for none.
fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mid = values.len() / 2;
    *values.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// [`fit_ellipsoid`] on finite readings.
fn fit_finite(
    data: &[[f64; 3]],
    skipped: usize,
    options: &FitOptions,
) -> Result<EllipsoidFit, CalibrationError> {
    let n = data.len() as f64;
    let mean = core::array::from_fn::<f64, 3, _>(|k| data.iter().map(|v| v[k]).sum::<f64>() / n);
    let spread = (data.iter().map(|v| dist2(*v, mean)).sum::<f64>() / n).sqrt();
    let magnitude = dist2(mean, [0.0; 3]).sqrt();
    // Readings that vary by less than 1 % of their size come from a sensor that was not
    // turned: sensor noise forms an isotropic ball that every model would fit.
    if spread.is_nan() || spread <= MIN_RELATIVE_SPREAD * magnitude || spread == 0.0 {
        return Err(CalibrationError::ConstantField { spread, magnitude });
    }
    check_saturation(data, options)?;
    let normalised: Vec<[f64; 3]> = data
        .iter()
        .map(|v| core::array::from_fn(|k| (v[k] - mean[k]) / spread))
        .collect();

    let mut refused = Vec::new();
    for model in LADDER_3D {
        let (coeffs, condition) = algebraic_fit(model, &normalised)?;
        // NaN (a singular design) must be refused too: `is_le` of a failed comparison is false.
        if !condition
            .partial_cmp(&options.max_condition)
            .is_some_and(|o| o.is_le())
        {
            refused.push(RefusedModel { model, condition });
            continue;
        }
        let (mut s, mut h) = ellipsoid_from_quadric(model, &coeffs)?;
        let mut iterations = 0;
        if options.max_iterations > 0 {
            (s, h, iterations) = refine(model, &normalised, s, h, options.max_iterations)?;
        }
        let calibration = to_raw_units(s, h, mean, spread, options.norm);
        return finish(
            calibration,
            model,
            refused,
            data,
            condition,
            iterations,
            skipped,
            options,
        );
    }
    // No three-dimensional model is determined: the offset within the plane of motion.
    let model = FittedModel::InPlaneOffset;
    let (points, plane) = project_to_plane(&normalised)?;
    let (coeffs, condition) = algebraic_fit(model, &points)?;
    if !(condition <= options.max_condition && coeffs[0] > 0.0) {
        return Err(CalibrationError::Unobservable {
            condition,
            limit: options.max_condition,
        });
    }
    // a(u² + v²) + 2b₁u + 2b₂v = 1: centre (−b₁/a, −b₂/a).
    let centre = [-coeffs[1] / coeffs[0], -coeffs[2] / coeffs[0]];
    let calibration = in_plane_calibration(centre, plane, mean, spread, data);
    finish(
        calibration,
        model,
        refused,
        data,
        condition,
        0,
        skipped,
        options,
    )
}

/// Quality figures, the residual check, and the result.
#[allow(clippy::too_many_arguments)]
fn finish(
    calibration: SensorCalibration<f64>,
    model: FittedModel,
    refused: Vec<RefusedModel>,
    data: &[[f64; 3]],
    condition: f64,
    iterations: usize,
    skipped: usize,
    options: &FitOptions,
) -> Result<EllipsoidFit, CalibrationError> {
    let quality = quality(&calibration, data, condition, iterations);
    // NaN coverage is refused too: `is_ge` of a failed comparison is false.
    let covered = quality
        .coverage
        .partial_cmp(&options.min_coverage)
        .is_some_and(|o| o.is_ge());
    if model != FittedModel::InPlaneOffset && !covered {
        return Err(CalibrationError::LowCoverage {
            coverage: quality.coverage,
            limit: options.min_coverage,
            model,
        });
    }
    if !quality
        .residual_rms_relative
        .partial_cmp(&options.max_residual_relative)
        .is_some_and(|o| o.is_le())
    {
        return Err(CalibrationError::ResidualTooLarge {
            rms_relative: quality.residual_rms_relative,
            limit: options.max_residual_relative,
        });
    }
    Ok(EllipsoidFit {
        calibration,
        model,
        refused,
        quality,
        skipped_non_finite: skipped,
        outliers: Vec::new(),
    })
}

/// Refuses data whose extreme value on some axis recurs in too many samples.
fn check_saturation(data: &[[f64; 3]], options: &FitOptions) -> Result<(), CalibrationError> {
    let limit =
        ((options.saturation_fraction * data.len() as f64) as usize).max(SATURATION_MIN_COUNT);
    for axis in 0..3 {
        let (lo, hi) = data
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v[axis]), hi.max(v[axis]))
            });
        for value in [lo, hi] {
            let count = data.iter().filter(|v| v[axis] == value).count();
            if count > limit {
                return Err(CalibrationError::Saturated {
                    axis,
                    value,
                    count,
                    limit,
                });
            }
        }
    }
    Ok(())
}

/// Least squares of the model's algebraic design against 1: the coefficients and the
/// condition number `σ_max/σ_min` of the (unequilibrated) design.
fn algebraic_fit(
    model: FittedModel,
    points: &[[f64; 3]],
) -> Result<(Vec<f64>, f64), CalibrationError> {
    let mut row = Vec::with_capacity(9);
    model.design_row([0.0; 3], &mut row);
    let cols = row.len();
    let mut design = Mat::<f64>::zeros(points.len(), cols);
    for (i, p) in points.iter().enumerate() {
        model.design_row(*p, &mut row);
        for (j, v) in row.iter().enumerate() {
            design[(i, j)] = *v;
        }
    }
    let ones = Col::<f64>::from_fn(points.len(), |_| 1.0);
    // No column scaling: a column that is small because the data barely vary along it is
    // exactly what the condition number has to see.
    let opts = Options {
        equilibrate: false,
        ..Options::with_method(Method::Svd)
    };
    let sol = solve(design.as_ref(), ones.as_ref(), Weights::Unit, &opts)
        .map_err(|e| CalibrationError::Solver(e.to_string()))?;
    let coeffs = (0..cols).map(|j| sol.estimate[j]).collect();
    Ok((coeffs, sol.condition))
}

/// Centre and `S` (with `|S(p − h)| = 1` on the quadric) from `pᵀA p + 2bᵀp = 1`.
fn ellipsoid_from_quadric(
    model: FittedModel,
    coeffs: &[f64],
) -> Result<([[f64; 3]; 3], [f64; 3]), CalibrationError> {
    let k = coeffs.len();
    let a = model.quadric(&coeffs[..k - 3]);
    let b = [coeffs[k - 3], coeffs[k - 2], coeffs[k - 1]];
    let not_ellipsoid = || CalibrationError::NotAnEllipsoid { model };
    // Centre: A h = −b; then (p − h)ᵀA(p − h) = 1 + hᵀA h.
    let (vals, vecs) = sym_eigen(a).ok_or_else(not_ellipsoid)?;
    if vals.iter().any(|&v| v.is_nan() || v <= 0.0) {
        return Err(not_ellipsoid());
    }
    let h = sym_apply(&vecs, &vals.map(|v| -1.0 / v), b);
    let ah = mat_vec(&a, h);
    let scale = 1.0 + (0..3).map(|i| h[i] * ah[i]).sum::<f64>();
    if scale.is_nan() || scale <= 0.0 {
        return Err(not_ellipsoid());
    }
    let s = sym_function(&vecs, &vals.map(|v| (v / scale).sqrt()));
    Ok((s, h))
}

/// `S`, `h` (normalised units) and the accepted refinement steps.
type Refined = ([[f64; 3]; 3], [f64; 3], usize);

/// Levenberg–Marquardt on `r_i = |S(p_i − h)| − 1` over the model's entries of `S` and `h`.
/// Returns the refined `S`, `h` and the number of accepted steps.
fn refine(
    model: FittedModel,
    points: &[[f64; 3]],
    s0: [[f64; 3]; 3],
    h0: [f64; 3],
    max_iterations: usize,
) -> Result<Refined, CalibrationError> {
    let basis = model.matrix_basis();
    let ks = basis.len();
    let k = ks + 3;
    // Coordinates of S in the basis: the basis matrices have disjoint supports, so each
    // coordinate is read off at the first nonzero entry of its matrix.
    let mut theta: Vec<f64> = basis
        .iter()
        .map(|b| {
            let (i, j) = first_nonzero(b);
            s0[i][j]
        })
        .chain(h0)
        .collect();
    let assemble = |theta: &[f64]| {
        let mut s = [[0.0; 3]; 3];
        for (c, b) in theta[..ks].iter().zip(basis) {
            for i in 0..3 {
                for j in 0..3 {
                    s[i][j] += c * b[i][j];
                }
            }
        }
        (s, [theta[ks], theta[ks + 1], theta[ks + 2]])
    };
    let cost = |theta: &[f64]| {
        let (s, h) = assemble(theta);
        points
            .iter()
            .map(|p| (norm3(mat_vec(&s, sub3(*p, h))) - 1.0).powi(2))
            .sum::<f64>()
    };
    let m = points.len();
    let mut current = cost(&theta);
    let mut mu = 1e-3 * m as f64;
    let mut accepted = 0;
    let mut jac = Mat::<f64>::zeros(m + k, k);
    let mut rhs = Col::<f64>::zeros(m + k);
    for _ in 0..max_iterations {
        let (s, h) = assemble(&theta);
        for (i, p) in points.iter().enumerate() {
            let u = sub3(*p, h);
            let v = mat_vec(&s, u);
            let nv = norm3(v).max(f64::MIN_POSITIVE);
            for (j, b) in basis.iter().enumerate() {
                jac[(i, j)] = dot3(v, mat_vec(b, u)) / nv;
            }
            let sv = mat_vec(&s, v);
            for c in 0..3 {
                jac[(i, ks + c)] = -sv[c] / nv;
            }
            rhs[i] = 1.0 - nv;
        }
        // Damping rows √μ·I with zero right-hand side: the Levenberg step.
        let mut step = None;
        for _ in 0..20 {
            for j in 0..k {
                for c in 0..k {
                    jac[(m + j, c)] = if c == j { mu.sqrt() } else { 0.0 };
                }
                rhs[m + j] = 0.0;
            }
            let sol = solve(
                jac.as_ref(),
                rhs.as_ref(),
                Weights::Unit,
                &Options::default(),
            )
            .map_err(|e| CalibrationError::Solver(e.to_string()))?;
            let trial: Vec<f64> = (0..k).map(|j| theta[j] + sol.estimate[j]).collect();
            let c = cost(&trial);
            if c < current {
                mu = (mu / 10.0).max(1e-12);
                step = Some((trial, c));
                break;
            }
            mu *= 10.0;
        }
        let Some((trial, c)) = step else { break };
        let improvement = current - c;
        theta = trial;
        current = c;
        accepted += 1;
        if improvement <= 1e-14 * current.max(f64::MIN_POSITIVE) {
            break;
        }
    }
    let (s, h) = assemble(&theta);
    Ok((s, h, accepted))
}

fn first_nonzero(b: &[[f64; 3]; 3]) -> (usize, usize) {
    for (i, row) in b.iter().enumerate() {
        for (j, v) in row.iter().enumerate() {
            if *v != 0.0 {
                return (i, j);
            }
        }
    }
    (0, 0)
}

/// From normalised units (`p = (y − mean)/spread`) back to raw units, scaled to the norm.
fn to_raw_units(
    s: [[f64; 3]; 3],
    h: [f64; 3],
    mean: [f64; 3],
    spread: f64,
    norm: Option<f64>,
) -> SensorCalibration<f64> {
    // |S(p − h)| = 1  ⇔  |(S/spread)(y − (mean + spread·h))| = 1.
    let offset = core::array::from_fn(|k| mean[k] + spread * h[k]);
    let unit: [[f64; 3]; 3] = s.map(|r| r.map(|v| v / spread));
    let (factor, norm) = match norm {
        Some(f) => (f, f),
        None => {
            let d = det3(&unit).cbrt();
            (1.0 / d, 1.0 / d)
        }
    };
    SensorCalibration {
        matrix: rootfuse_attitude::Mat::from_rows(unit.map(|r| r.map(|v| v * factor))),
        offset: Vec3::from_array(offset),
        norm,
    }
}

/// The offset within the plane of motion (its normal component left at zero: no correction
/// where the data say nothing), `S = I`, the norm the mean `|y − h|`.
fn in_plane_calibration(
    centre: [f64; 2],
    (e1, e2, normal): ([f64; 3], [f64; 3], [f64; 3]),
    mean: [f64; 3],
    spread: f64,
    data: &[[f64; 3]],
) -> SensorCalibration<f64> {
    // `centre` is in plane coordinates (u, v) of the normalised data.
    let c: [f64; 3] =
        core::array::from_fn(|k| mean[k] + spread * (centre[0] * e1[k] + centre[1] * e2[k]));
    let along = dot3(c, normal);
    let offset: [f64; 3] = core::array::from_fn(|k| c[k] - along * normal[k]);
    let norm = data.iter().map(|y| norm3(sub3(*y, offset))).sum::<f64>() / data.len() as f64;
    SensorCalibration {
        matrix: rootfuse_attitude::Mat::identity(),
        offset: Vec3::from_array(offset),
        norm,
    }
}

/// Projects normalised points onto their plane of least spread: plane coordinates `(u, v, 0)`
/// and the plane's axes `(e1, e2, normal)`.
#[allow(clippy::type_complexity)]
fn project_to_plane(
    points: &[[f64; 3]],
) -> Result<(Vec<[f64; 3]>, ([f64; 3], [f64; 3], [f64; 3])), CalibrationError> {
    let mut c = [[0.0; 3]; 3];
    for p in points {
        for i in 0..3 {
            for j in 0..3 {
                c[i][j] += p[i] * p[j];
            }
        }
    }
    let (_, vecs) = sym_eigen(c).ok_or_else(|| CalibrationError::Solver("eigen".into()))?;
    // Eigenvalues ascend: the first eigenvector is the normal.
    let col = |j: usize| [vecs[0][j], vecs[1][j], vecs[2][j]];
    let (normal, e1, e2) = (col(0), col(1), col(2));
    let pts = points
        .iter()
        .map(|p| [dot3(*p, e1), dot3(*p, e2), 0.0])
        .collect();
    Ok((pts, (e1, e2, normal)))
}
