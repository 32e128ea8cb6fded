//! How good a calibration is: residual of the norm, coverage of the sphere of directions,
//! conditioning.

use crate::mat3::sym_eigen;
use rootfuse_attitude::{SensorCalibration, Vec3};

/// Number of direction cells [`FitQuality::coverage`] counts (a cube's faces, each cut into
/// quadrants: 24 cells of roughly equal solid angle).
pub const DIRECTION_CELLS: usize = 24;

/// Quality figures of a calibration on the data it was fitted to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitQuality {
    /// RMS of `|y_cal| − norm` relative to the norm (for a full fit, the constancy of the
    /// calibrated norm).
    pub residual_rms_relative: f64,
    /// Largest `||y_cal| − norm|` relative to the norm.
    pub residual_max_relative: f64,
    /// Fraction of the [`DIRECTION_CELLS`] cells of the sphere of calibrated directions that
    /// hold at least 2 % of their fair share of the samples (and at least 3): 1 for full
    /// coverage, about 1/3 for a turn about one axis.
    pub coverage: f64,
    /// `3·λ_min` of the mean outer product of the calibrated unit directions: 1 for directions
    /// spread evenly over the sphere, 0 for directions in one plane.
    pub direction_spread: f64,
    /// Condition number `σ_max/σ_min` of the chosen model's normalised design.
    pub condition: f64,
    /// Accepted steps of the geometric refinement.
    pub iterations: usize,
    /// Samples used.
    pub samples: usize,
}

/// The quality figures of `cal` on `data` (raw readings, all finite).
pub(crate) fn quality(
    cal: &SensorCalibration<f64>,
    data: &[[f64; 3]],
    condition: f64,
    iterations: usize,
) -> FitQuality {
    let n = data.len();
    let mut sum_sq = 0.0;
    let mut max_abs: f64 = 0.0;
    let mut cells = [0usize; DIRECTION_CELLS];
    let mut outer = [[0.0; 3]; 3];
    for y in data {
        let c = cal.apply(Vec3::from_array(*y));
        let norm = c.norm();
        let r = (norm - cal.norm) / cal.norm;
        sum_sq += r * r;
        max_abs = max_abs.max(r.abs());
        if norm > 0.0 {
            let u = (c * (1.0 / norm)).to_array();
            cells[direction_cell(u)] += 1;
            for i in 0..3 {
                for j in 0..3 {
                    outer[i][j] += u[i] * u[j] / n as f64;
                }
            }
        }
    }
    let min_count = (n / (DIRECTION_CELLS * 50)).max(3);
    let covered = cells.iter().filter(|&&c| c >= min_count).count();
    let spread = sym_eigen(outer).map_or(0.0, |(vals, _)| (3.0 * vals[0]).max(0.0));
    FitQuality {
        residual_rms_relative: (sum_sq / n as f64).sqrt(),
        residual_max_relative: max_abs,
        coverage: covered as f64 / DIRECTION_CELLS as f64,
        direction_spread: spread,
        condition,
        iterations,
        samples: n,
    }
}

/// The cell of a unit direction: dominant axis and its sign (the cube face), then the signs
/// of the two other components (the quadrant of the face).
fn direction_cell(u: [f64; 3]) -> usize {
    let a = u.map(f64::abs);
    let axis = if a[0] >= a[1] && a[0] >= a[2] {
        0
    } else if a[1] >= a[2] {
        1
    } else {
        2
    };
    let (o1, o2) = ((axis + 1) % 3, (axis + 2) % 3);
    let face = axis * 2 + usize::from(u[axis] < 0.0);
    face * 4 + usize::from(u[o1] < 0.0) * 2 + usize::from(u[o2] < 0.0)
}
