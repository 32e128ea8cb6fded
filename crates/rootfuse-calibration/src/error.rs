//! Why a calibration was refused.

use crate::FittedModel;

/// Why a batch calibration did not return parameters. A refusal is always preferred to a
/// calibration that would be wrong.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CalibrationError {
    /// Fewer usable (finite) samples than the smallest model needs.
    #[error(
        "{usable} usable samples ({skipped_non_finite} non-finite rows skipped); at least {needed} are needed"
    )]
    TooFewSamples {
        /// Finite samples.
        usable: usize,
        /// Rows skipped because a component was NaN or infinite.
        skipped_non_finite: usize,
        /// The minimum.
        needed: usize,
    },
    /// The readings hardly change: the sensor was not turned (or the field is constant).
    #[error(
        "constant reading: spread {spread:.3e} against magnitude {magnitude:.3e}; turn the sensor through many orientations"
    )]
    ConstantField {
        /// RMS distance of the samples from their mean (raw units).
        spread: f64,
        /// Norm of the mean reading (raw units).
        magnitude: f64,
    },
    /// An axis sits at the same extreme value in many samples: the sensor clipped.
    #[error("axis {axis} saturated: {count} samples at {value} (more than {limit} allowed)")]
    Saturated {
        /// 0 = x, 1 = y, 2 = z.
        axis: usize,
        /// The clipped value (raw units).
        value: f64,
        /// Samples at that value.
        count: usize,
        /// The largest count accepted.
        limit: usize,
    },
    /// Not even the offset in the plane of motion is determined by the data.
    #[error(
        "motion does not determine any calibration (condition {condition:.3e} > {limit:.3e} for every model)"
    )]
    Unobservable {
        /// Condition number of the smallest model's design.
        condition: f64,
        /// The accepted maximum.
        limit: f64,
    },
    /// The data do not lie on an ellipsoid (the fitted quadric is not positive definite).
    #[error("the {model} fit is not an ellipsoid (the quadric is not positive definite)")]
    NotAnEllipsoid {
        /// The model that was fitted.
        model: FittedModel,
    },
    /// The fit converged but its residual is too large to trust (disturbed field, moving
    /// magnet, wrong sensor data).
    #[error("residual RMS {rms_relative:.4} of the norm exceeds the limit {limit:.4}")]
    ResidualTooLarge {
        /// RMS of `|y_cal| − norm`, relative to the norm.
        rms_relative: f64,
        /// The accepted maximum.
        limit: f64,
    },
    /// A three-dimensional model was fitted to readings that cover too little of the sphere of
    /// directions ([`FitQuality::coverage`](crate::FitQuality::coverage) below
    /// [`FitOptions::min_coverage`](crate::FitOptions::min_coverage)): the fit extrapolates
    /// the rest of the ellipsoid from a cap of it.
    #[error(
        "the readings cover {:.0} % of the sphere of directions, at least {:.0} % needed: a {model} fit to part of it extrapolates the rest and can make heading far worse; turn the sensor through more orientations (each axis up and down), or lower min_coverage",
        100.0 * coverage,
        100.0 * limit
    )]
    LowCoverage {
        /// Share of the direction cells with data.
        coverage: f64,
        /// The accepted minimum.
        limit: f64,
        /// The model the condition test allowed.
        model: FittedModel,
    },
    /// Fewer rest phases than the accelerometer calibration needs.
    #[error("{found} rest phases found; at least {needed} (different orientations) are needed")]
    TooFewRestPhases {
        /// Rest phases detected.
        found: usize,
        /// The minimum.
        needed: usize,
    },
    /// The `norm` option is not a positive finite number.
    #[error(
        "norm {norm} is not a positive finite number: give the field strength in the recording's units, or leave it out"
    )]
    InvalidNorm {
        /// The value given.
        norm: f64,
    },
    /// The numerical solver failed (reported with its reason).
    #[error("least-squares solver: {0}")]
    Solver(String),
}
