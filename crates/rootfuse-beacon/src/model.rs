//! The log-distance path-loss model `RSSI(d) = A − 10·n·log10(d)` (S42).

use super::BeaconError;
use rootfuse_lsq::dense::faer::{Col, Mat};
use rootfuse_lsq::dense::{Options, Weights, solve};

/// `RSSI(d) = A − 10·n·log10(d)`: `A` the RSSI at 1 m (dBm), `n` the path-loss exponent.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogDistanceModel {
    /// RSSI at 1 m, dBm.
    pub a: f64,
    /// Path-loss exponent (2 in free space).
    pub n: f64,
}

impl LogDistanceModel {
    /// Predicted RSSI (dBm) at distance `d` (m).
    pub fn rssi(&self, d: f64) -> f64 {
        self.a - 10.0 * self.n * d.log10()
    }
    /// The distance (m) at which the model predicts `rssi`: `10^((A − RSSI)/(10·n))`.
    pub fn distance(&self, rssi: f64) -> f64 {
        10f64.powf((self.a - rssi) / (10.0 * self.n))
    }
    /// Standard deviation (m) of the range from one RSSI value with shadowing `sigma_db`
    /// (dB), to first order: `d·ln10·σ/(10·n)` (log-normal ranging error grows with range).
    pub fn range_std(&self, rssi: f64, sigma_db: f64) -> f64 {
        self.distance(rssi) * core::f64::consts::LN_10 * sigma_db / (10.0 * self.n)
    }
    /// Weighted least-squares fit of `A` and `n` to `(distance m, RSSI dBm, weight)` triples
    /// (weight = 1/variance of that RSSI, e.g. the number of readings averaged over `σ²`).
    ///
    /// The model is linear in `(A, n)`: row `[1, −10·log10 d]`. Noise-free data give the exact
    /// parameters (to rounding). Points with a non-positive or non-finite distance, a
    /// non-finite RSSI or a non-positive weight are left out.
    ///
    /// # Errors
    /// [`BeaconError::TooFew`] with fewer than two usable points,
    /// [`BeaconError::Lsq`] when all distances are equal (rank 1) or the solve fails.
    pub fn fit(points: &[(f64, f64, f64)]) -> Result<Self, BeaconError> {
        let usable: std::vec::Vec<_> = points
            .iter()
            .filter(|(d, r, w)| {
                *d > 0.0 && d.is_finite() && r.is_finite() && *w > 0.0 && w.is_finite()
            })
            .collect();
        if usable.len() < 2 {
            return Err(BeaconError::TooFew {
                needed: 2,
                found: usable.len(),
            });
        }
        let m = usable.len();
        let h = Mat::from_fn(m, 2, |i, j| {
            if j == 0 {
                1.0
            } else {
                -10.0 * usable[i].0.log10()
            }
        });
        let z = Col::from_fn(m, |i| usable[i].1);
        let w = Col::from_fn(m, |i| usable[i].2);
        let sol = solve(
            h.as_ref(),
            z.as_ref(),
            Weights::Diagonal(w.as_ref()),
            &Options::default(),
        )?;
        Ok(Self {
            a: sol.estimate[0],
            n: sol.estimate[1],
        })
    }
}
