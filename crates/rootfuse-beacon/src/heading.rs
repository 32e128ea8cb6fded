//! Heading from beacons (S43): weak beacons by RSSI trend, medium/strong ones by
//! multilateration.

use super::{BeaconClass, BeaconError, BeaconId, BeaconMap, BeaconSet};
use rootfuse_lsq::dense::faer::{Col, Mat};
use rootfuse_lsq::dense::{Options, Weights, solve};
use std::vec::Vec;

/// The yaw (rad, counter-clockwise from north) of the direction from `from` to `to`
/// (`[east, north]`, m): `atan2(−Δe, Δn)`.
pub fn direction(from: [f64; 2], to: [f64; 2]) -> f64 {
    (-(to[0] - from[0])).atan2(to[1] - from[1])
}

/// A heading decided from beacons.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeaconHeading {
    /// Heading, rad (project yaw).
    pub psi: f64,
    /// Its standard deviation, rad (our stated confidence, used by the fusion).
    pub std: f64,
    /// The time span the heading describes, s: `[start, end]`.
    pub span: [f64; 2],
}

/// Settings of [`weak_heading`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrendConfig {
    /// RSSI substituted for a 0 ("not heard") record, dBm: below the scan threshold.
    pub floor: f64,
    /// Smallest RSSI slope magnitude that counts as leaving or approaching, dB/s.
    pub min_slope: f64,
    /// Largest distance between the two beacons for their direction to be the walk's, m.
    pub max_pair_distance: f64,
    /// Heading standard deviation reported, rad.
    pub std: f64,
}

impl Default for TrendConfig {
    fn default() -> Self {
        Self {
            floor: -100.0,
            min_slope: 1.0,
            max_pair_distance: 15.0,
            std: 0.15,
        }
    }
}

/// Least-squares slope (dB/s) of a beacon's records, 0 records at `floor`.
fn slope(records: &std::collections::VecDeque<super::Record>, floor: f64) -> f64 {
    let n = records.len() as f64;
    let value = |r: &super::Record| if r.missed() { floor } else { r.rssi };
    let tm = records.iter().map(|r| r.t).sum::<f64>() / n;
    let vm = records.iter().map(value).sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for r in records {
        sxy += (r.t - tm) * (value(r) - vm);
        sxx += (r.t - tm) * (r.t - tm);
    }
    if sxx > 0.0 { sxy / sxx } else { 0.0 }
}

/// Heading from weak beacons: the walker leaves the beacon whose RSSI falls fastest and
/// approaches the one whose RSSI rises fastest, so it walks from the first toward the second.
/// Only full windows (`capacity` records) of weak beacons count; returns `None` when no pair
/// qualifies. The caller clears the map after a decision (S424).
///
/// Reading of the source: claim 8 keeps a per-beacon "Indicator" updated from the map (the
/// text breaks off there); the indicator here is the least-squares RSSI slope over the window,
/// with "not heard" records at `floor`. Leaving = slope ≤ −`min_slope` and heard in the first
/// half of the window; approaching = slope ≥ `min_slope` and heard in the last record. The
/// heading is the direction between the two known positions, so it is the walk's heading only
/// when the beacons line the walked corridor (as in the deployment the source describes).
pub fn weak_heading(
    map: &BeaconMap,
    beacons: &BeaconSet,
    cfg: &TrendConfig,
) -> Option<BeaconHeading> {
    let full = map.capacity();
    let mut leaving: Option<(f64, BeaconId)> = None;
    let mut approaching: Option<(f64, BeaconId)> = None;
    let (mut t0, mut t1) = (f64::INFINITY, f64::NEG_INFINITY);
    for (id, records) in map.iter() {
        let weak = beacons
            .get(id)
            .is_some_and(|b| b.class == BeaconClass::Weak);
        if !weak || records.len() < full || full < 2 {
            continue;
        }
        let s = slope(records, cfg.floor);
        let heard_early = records.iter().take(full / 2).any(|r| !r.missed());
        let heard_now = records.back().is_some_and(|r| !r.missed());
        if s <= -cfg.min_slope && heard_early && leaving.is_none_or(|(b, _)| s < b) {
            leaving = Some((s, id));
        }
        if s >= cfg.min_slope && heard_now && approaching.is_none_or(|(b, _)| s > b) {
            approaching = Some((s, id));
        }
        t0 = t0.min(records.front().map_or(t0, |r| r.t));
        t1 = t1.max(records.back().map_or(t1, |r| r.t));
    }
    let (from, to) = (beacons.get(leaving?.1)?, beacons.get(approaching?.1)?);
    let (dx, dy) = (
        to.position[0] - from.position[0],
        to.position[1] - from.position[1],
    );
    let dist = dx.hypot(dy);
    if dist == 0.0 || dist > cfg.max_pair_distance {
        return None;
    }
    Some(BeaconHeading {
        psi: direction(from.position, to.position),
        std: cfg.std,
        span: [t0, t1],
    })
}

/// A position fix from multilateration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fix {
    /// Time, s.
    pub t: f64,
    /// Position `[east, north]`, m.
    pub position: [f64; 2],
    /// Covariance of the position, m² (`(HᵀWH)⁻¹` at the solution).
    pub covariance: [[f64; 2]; 2],
}

/// Longest Gauss–Newton step of [`multilaterate`], m.
const MAX_STEP: f64 = 2.0;
/// Farthest accepted solution from the weighted centroid of the beacons, m.
const MAX_FROM_CENTROID: f64 = 30.0;

/// Position from ranges to known points by weighted least squares (Gauss–Newton on
/// `‖p − b_i‖ = r_i` with weights `1/σ_i²`), from the weighted centroid; `ranges` holds
/// `(beacon position, range m, range std m)`.
///
/// Exact ranges to three or more non-collinear points give the position to rounding.
///
/// # Errors
/// [`BeaconError::TooFew`] with fewer than three usable ranges (positive, finite),
/// [`BeaconError::Lsq`] when the geometry is degenerate (collinear beacons, a point on a
/// beacon), [`BeaconError::NoSolution`] when the damped iteration (steps ≤ 2 m) does not
/// converge in 50 steps or ends more than 30 m from the beacons' weighted centroid.
pub fn multilaterate(t: f64, ranges: &[([f64; 2], f64, f64)]) -> Result<Fix, BeaconError> {
    let usable: Vec<_> = ranges
        .iter()
        .filter(|(b, r, s)| {
            b[0].is_finite() && b[1].is_finite() && r.is_finite() && *r >= 0.0 && *s > 0.0
        })
        .collect();
    if usable.len() < 3 {
        return Err(BeaconError::TooFew {
            needed: 3,
            found: usable.len(),
        });
    }
    let m = usable.len();
    let w = Col::from_fn(m, |i| 1.0 / (usable[i].2 * usable[i].2));
    let wsum: f64 = (0..m).map(|i| w[i]).sum();
    let mut p = [0.0, 0.0];
    for (i, (b, _, _)) in usable.iter().enumerate() {
        p[0] += w[i] * b[0] / wsum;
        p[1] += w[i] * b[1] / wsum;
    }
    let centroid = p;
    let mut cov = [[0.0; 2]; 2];
    let mut converged = false;
    for _ in 0..50 {
        let dist = |i: usize| (p[0] - usable[i].0[0]).hypot(p[1] - usable[i].0[1]);
        let h = Mat::from_fn(m, 2, |i, j| (p[j] - usable[i].0[j]) / dist(i));
        let z = Col::from_fn(m, |i| usable[i].1 - dist(i));
        let sol = solve(
            h.as_ref(),
            z.as_ref(),
            Weights::Diagonal(w.as_ref()),
            &Options::default(),
        )?;
        // Steps longer than `MAX_STEP` are shortened: far from the solution the linearisation
        // overshoots (a damped Gauss–Newton).
        let len = sol.estimate[0].hypot(sol.estimate[1]);
        let scale = MAX_STEP / len.max(MAX_STEP);
        p[0] += scale * sol.estimate[0];
        p[1] += scale * sol.estimate[1];
        cov = [
            [sol.covariance[(0, 0)], sol.covariance[(0, 1)]],
            [sol.covariance[(1, 0)], sol.covariance[(1, 1)]],
        ];
        if len < 1e-9 * (1.0 + p[0].hypot(p[1])) {
            converged = true;
            break;
        }
    }
    let far = (p[0] - centroid[0]).hypot(p[1] - centroid[1]) > MAX_FROM_CENTROID;
    if !converged || far || !p[0].is_finite() || !p[1].is_finite() {
        return Err(BeaconError::NoSolution);
    }
    Ok(Fix {
        t,
        position: p,
        covariance: cov,
    })
}

/// Heading from successive fixes: the direction of the least-squares velocity of the fixes
/// (position linear in time), with the standard deviation `σ_p / (v·√(Σ(t − t̄)²))` for a
/// per-fix position std `σ_p` (the root mean trace of the covariances / 2).
///
/// Returns `None` with fewer than `3` fixes or when the fitted displacement over the span is
/// below `min_displacement` m (standing still has no heading).
pub fn heading_from_fixes(fixes: &[Fix], min_displacement: f64) -> Option<BeaconHeading> {
    if fixes.len() < 3 {
        return None;
    }
    let n = fixes.len() as f64;
    let tm = fixes.iter().map(|f| f.t).sum::<f64>() / n;
    let mean = |k: usize| fixes.iter().map(|f| f.position[k]).sum::<f64>() / n;
    let (em, nm) = (mean(0), mean(1));
    let (mut se, mut sn, mut stt) = (0.0, 0.0, 0.0);
    for f in fixes {
        let dt = f.t - tm;
        se += dt * (f.position[0] - em);
        sn += dt * (f.position[1] - nm);
        stt += dt * dt;
    }
    if stt <= 0.0 {
        return None;
    }
    let (ve, vn) = (se / stt, sn / stt);
    let speed = ve.hypot(vn);
    let span = [fixes[0].t, fixes[fixes.len() - 1].t];
    let moved = speed * (span[1] - span[0]);
    if moved.is_nan() || moved < min_displacement {
        return None;
    }
    let var_p = fixes
        .iter()
        .map(|f| 0.5 * (f.covariance[0][0] + f.covariance[1][1]))
        .sum::<f64>()
        / n;
    Some(BeaconHeading {
        psi: (-ve).atan2(vn),
        std: var_p.sqrt() / (speed * stt.sqrt()),
        span,
    })
}
