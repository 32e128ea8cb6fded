//! Is a reported attitude covariance honest? The normalised estimation error squared (NEES)
//! of each sample against the truth, and how often the truth lies inside the 95 % ellipsoid.
//!
//! # Definitions
//! With the global (earth-frame) error of `docs/conventions.md`, `q_true = Exp(δθ) ⊗ q_est`,
//! and the filter's attitude covariance `P` (rad², earth axes):
//! - total: `NEES = δθᵀ·(P + f²·I)⁻¹·δθ`, reported as `NEES/3` (1 for an honest covariance),
//!   and the share of samples with `NEES ≤ χ²₃(0.95) = 7.815`;
//! - inclination: the same with the horizontal components `δθ_x, δθ_y` and the upper-left
//!   2×2 block of `P`, `NEES/2`, `χ²₂(0.95) = 5.991`.
//!
//! `f` (rad) is an optional floor for the reference's own error (optical truth is itself off
//! by a fraction of a degree). Samples count as for the BROAD metrics (`use = 1`, finite
//! truth), after the first `skip` share of the recording (the filter's start-up transient is
//! not what its steady covariance claims). For [`Alignment::SixD`] the estimate's constant
//! heading offset is removed first, the covariance turned with it.

use crate::metrics::{Alignment, MetricsError, check, counted, error_quat, heading_offset};
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
use rootfuse_attitude::Quat;
use std::vec::Vec;

/// χ²₃(0.95): the 95 % quantile of the NEES of an honest 3-D covariance.
pub const CHI2_3_95: f64 = 7.814_727_903_251_178;
/// χ²₂(0.95) = −2·ln 0.05: the same for 2-D.
pub const CHI2_2_95: f64 = 5.991_464_547_107_979;

/// NEES statistics of one recording (see the [module docs](self)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Consistency {
    /// Mean NEES/3 of the total error (1 when honest, above 1 when overconfident).
    pub nees_total: f64,
    /// Share of samples whose total error lies inside the 95 % ellipsoid (0.95 when honest).
    pub coverage_total: f64,
    /// Mean NEES/2 of the inclination error.
    pub nees_inclination: f64,
    /// Share of samples whose inclination error lies inside the 95 % ellipse.
    pub coverage_inclination: f64,
    /// Samples evaluated (counted, after the skip, with a finite estimate and a covariance
    /// that is positive definite once the floor is added).
    pub n_used: usize,
    /// Counted samples left out because the estimate or its covariance was not finite or not
    /// positive definite.
    pub n_invalid: usize,
}

/// The attitude covariance of one sample as its upper triangle
/// `[p_xx, p_xy, p_xz, p_yy, p_yz, p_zz]` (the columns `rootfuse run --covariance` writes).
pub type UpperTriangle = [f64; 6];

/// The [`UpperTriangle`] of a filter's attitude covariance
/// ([`OrientationFilter::attitude_covariance`](rootfuse_attitude::OrientationFilter), rad²).
///
/// ```
/// use rootfuse_attitude::Mat;
/// use rootfuse_eval::consistency::upper_triangle;
/// let p = Mat::<f64, 3, 3>::from_fn(|i, j| (3 * i + j) as f64);
/// assert_eq!(upper_triangle(&p), [0.0, 1.0, 2.0, 4.0, 5.0, 8.0]);
/// ```
pub fn upper_triangle(p: &rootfuse_attitude::Mat<f64, 3, 3>) -> UpperTriangle {
    let m = &p.m;
    [m[0][0], m[0][1], m[0][2], m[1][1], m[1][2], m[2][2]]
}

/// NEES and coverage of estimates `est` with covariances `cov` against `truth` (see the
/// [module docs](self)); `floor_rad` the reference-error floor per axis, `skip` the leading
/// share of samples left out (0.1 in `rootfuse eval --consistency`).
///
/// ```
/// use rootfuse_attitude::{Quat, Vec3};
/// use rootfuse_eval::consistency::consistency;
/// use rootfuse_eval::metrics::Alignment;
/// // Errors of exactly one standard deviation about x: NEES/3 = 1/3.
/// let truth = vec![Quat::identity(); 4];
/// let est = vec![Quat::from_rotation_vector(Vec3::new(0.01, 0.0, 0.0)); 4];
/// let cov = vec![[1e-4, 0.0, 0.0, 1e-4, 0.0, 1e-4]; 4];
/// let c = consistency(&est, &cov, &truth, None, Alignment::NineD, 0.0, 0.0).unwrap();
/// assert!((c.nees_total - 1.0 / 3.0).abs() < 1e-9);
/// assert_eq!(c.coverage_total, 1.0);
/// ```
pub fn consistency(
    est: &[Quat<f64>],
    cov: &[UpperTriangle],
    truth: &[Quat<f64>],
    use_mask: Option<&[bool]>,
    mode: Alignment,
    floor_rad: f64,
    skip: f64,
) -> Result<Consistency, MetricsError> {
    check(est, truth, use_mask)?;
    if cov.len() != est.len() {
        return Err(MetricsError::CovarianceLength {
            estimates: est.len(),
            covariances: cov.len(),
        });
    }
    let offset = match mode {
        Alignment::NineD => 0.0,
        Alignment::SixD => heading_offset(est, truth, use_mask)?.unwrap_or(0.0),
    };
    let turn = Quat::from_heading(-offset);
    let (c, s) = (offset.cos(), -offset.sin());
    let rz = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
    let floor = floor_rad * floor_rad;
    let first = ((skip.clamp(0.0, 1.0) * est.len() as f64).ceil() as usize).min(est.len());
    let (mut totals, mut inclinations): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
    let mut n_invalid = 0;
    for i in (first..est.len()).filter(|&i| counted(truth, use_mask, i)) {
        let [xx, xy, xz, yy, yz, zz] = cov[i];
        let p = rz * Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz) * rz.transpose()
            + Matrix3::identity() * floor;
        // q_true = Exp(δθ) ⊗ q_est: δθ is the rotation vector of q_true ⊗ q_est*.
        let d = error_quat(truth[i], turn * est[i]).to_rotation_vector();
        let d = Vector3::new(d.x, d.y, d.z);
        let horizontal = Vector2::new(d.x, d.y);
        let p2 = Matrix2::new(p[(0, 0)], p[(0, 1)], p[(1, 0)], p[(1, 1)]);
        let nees = p.cholesky().map(|l| d.dot(&l.solve(&d)));
        let nees2 = p2.cholesky().map(|l| horizontal.dot(&l.solve(&horizontal)));
        match (nees, nees2) {
            (Some(a), Some(b)) if a.is_finite() && b.is_finite() => {
                totals.push(a);
                inclinations.push(b);
            }
            _ => n_invalid += 1,
        }
    }
    let mean = |v: &[f64], k: f64| v.iter().sum::<f64>() / (k * v.len() as f64);
    let share =
        |v: &[f64], limit: f64| v.iter().filter(|&&x| x <= limit).count() as f64 / v.len() as f64;
    Ok(Consistency {
        nees_total: mean(&totals, 3.0),
        coverage_total: share(&totals, CHI2_3_95),
        nees_inclination: mean(&inclinations, 2.0),
        coverage_inclination: share(&inclinations, CHI2_2_95),
        n_used: totals.len(),
        n_invalid,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};
    use rootfuse_attitude::Vec3;

    /// Errors drawn from the covariance they are scored with: NEES/k near 1, coverage near
    /// 95 %; the same errors with a covariance four times too small: NEES/k near 4.
    #[test]
    fn honest_and_overconfident_covariances() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let n = 20_000;
        // P = L·Lᵀ with correlation between x and y, heading variance larger.
        let l = Matrix3::new(0.01, 0.0, 0.0, 0.004, 0.008, 0.0, 0.001, -0.002, 0.03);
        let p = l * l.transpose();
        let upper = [
            p[(0, 0)],
            p[(0, 1)],
            p[(0, 2)],
            p[(1, 1)],
            p[(1, 2)],
            p[(2, 2)],
        ];
        let truth: Vec<Quat<f64>> = (0..n)
            .map(|i| Quat::from_rotation_vector(Vec3::new(0.3, -0.2, i as f64 * 1e-3)))
            .collect();
        let est: Vec<Quat<f64>> = truth
            .iter()
            .map(|&r| {
                let z = Vector3::from_fn(|_, _| StandardNormal.sample(&mut rng));
                let d = l * z;
                // q_true = Exp(δθ) ⊗ q_est.
                Quat::from_rotation_vector(Vec3::new(-d.x, -d.y, -d.z)) * r
            })
            .collect();
        let honest = consistency(
            &est,
            &vec![upper; n],
            &truth,
            None,
            Alignment::NineD,
            0.0,
            0.0,
        )
        .unwrap();
        assert_eq!(honest.n_used, n);
        assert!((honest.nees_total - 1.0).abs() < 0.03, "{honest:?}");
        assert!((honest.nees_inclination - 1.0).abs() < 0.03, "{honest:?}");
        assert!((honest.coverage_total - 0.95).abs() < 0.01, "{honest:?}");
        assert!(
            (honest.coverage_inclination - 0.95).abs() < 0.01,
            "{honest:?}"
        );
        let small = upper.map(|v| v / 4.0);
        let over = consistency(
            &est,
            &vec![small; n],
            &truth,
            None,
            Alignment::NineD,
            0.0,
            0.1,
        )
        .unwrap();
        assert!((over.nees_total - 4.0).abs() < 0.15, "{over:?}");
        assert!(over.coverage_total < 0.6, "{over:?}");
        assert_eq!(over.n_used, n - n / 10);
        // A floor as large as the errors restores coverage.
        let floored = consistency(
            &est,
            &vec![small; n],
            &truth,
            None,
            Alignment::NineD,
            0.03,
            0.0,
        )
        .unwrap();
        assert!(floored.coverage_total > 0.95, "{floored:?}");
        // A covariance that is no covariance is counted, not used.
        let mut bad = vec![upper; n];
        bad[7] = [f64::NAN; 6];
        bad[8] = [-1.0, 0.0, 0.0, 1.0, 0.0, 1.0];
        let c = consistency(&est, &bad, &truth, None, Alignment::NineD, 0.0, 0.0).unwrap();
        assert_eq!((c.n_used, c.n_invalid), (n - 2, 2));
    }

    /// 6D: a constant heading offset is not an error, with its covariance turned alike.
    #[test]
    fn six_d_removes_the_heading_offset() {
        let truth: Vec<Quat<f64>> = (0..100)
            .map(|i| Quat::from_rotation_vector(Vec3::new(0.2, 0.1, i as f64 * 0.01)))
            .collect();
        let est: Vec<Quat<f64>> = truth
            .iter()
            .map(|&r| {
                Quat::from_heading(1.0) * Quat::from_rotation_vector(Vec3::new(0.001, 0.0, 0.0)) * r
            })
            .collect();
        let cov = vec![[1e-6, 0.0, 0.0, 1e-6, 0.0, 1e-6]; 100];
        let six = consistency(&est, &cov, &truth, None, Alignment::SixD, 0.0, 0.0).unwrap();
        assert!((six.nees_total - 1.0 / 3.0).abs() < 1e-6, "{six:?}");
        let nine = consistency(&est, &cov, &truth, None, Alignment::NineD, 0.0, 0.0).unwrap();
        assert!(nine.nees_total > 1e4, "{nine:?}");
    }
}
