//! Online hard-iron estimation on square-root RLS, gated before it is applied.
//!
//! # Estimator
//! With `S = I` the model `|m_raw − h| = F` is, squared, linear in `x = [h, c]`,
//! `c = F² − |h|²`:
//!
//! ```text
//! |m|² = 2 mᵀh + c        (row [2mᵀ, 1], measurement |m|²)
//! ```
//!
//! the linear form of the sphere fit (Kåsa 1976). Every usable sample is one scalar update of
//! the inverse-QR square-root RLS ([`InverseQr`], `N = 4`) with forgetting `λ = 1 − 1/memory`
//! and windup bounds, in units of the first usable reading's norm (so the estimator does not
//! care whether the field is in µT, gauss or counts). A reading of noise `σ` relative to the
//! field gives `|m|²` a noise of about `2σ` (normalised), which sets the weight.
//!
//! # Gates (per lane, branch-free)
//! - **Learning**: every reading is learned until the estimate has settled (`warmup`
//!   samples learned and the offset's standard deviation below `max_offset_std`); from then
//!   on a reading is learned only if its residual `|m − ĥ| − F̂` is within `gate_sigmas`
//!   running RMS residuals (plus a floor of `residual_std`): a disturbance changes
//!   `|m − h|` and is not learned, however long it lasts. (A disturbance present from the
//!   start, before the estimate settles, is learned: nothing distinguishes it then.)
//! - **Applying**: the learned offset replaces the applied one only when (i) the offset's
//!   standard deviation from the RLS covariance is below `max_offset_std` of the field (the
//!   motion determined it), (ii) the directions of `m − ĥ` spread over the sphere
//!   (`27·det` of their running second moment above `min_spread`: 1 for even coverage, 0
//!   for motion in one plane) and (iii) the running RMS residual is below
//!   `max_residual_rms` of the field (the readings are consistent with a sphere). Until the
//!   first such moment readings pass through uncorrected; afterwards the last validated
//!   offset stays applied while the gates are closed.
//! - **Significance**: the first offset applied must exceed `min_offset` of the field. A
//!   calibrated magnetometer indoors fits a sphere only to a few per cent (field gradients;
//!   on the BROAD trials the norm varies by 2–3 %), and correcting the apparent offset of
//!   that size makes headings worse, not better.
//!
//! Soft iron is not learned online (its 6 extra parameters need far richer motion to be
//! determined); fit it in batch (`rootfuse calibrate mag`) and apply it before this stage.

use crate::vec3::Vec3;
use rootfuse_lane::{Lane, Mask, Mat, Vector};
use rootfuse_lsq::rls::{InverseQr, RecursiveLeastSquares, RlsConfig, RlsError};

/// Parameters of [`OnlineHardIron`]. Relative quantities are fractions of the field norm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OnlineHardIronParams {
    /// Memory of the RLS and of the running gate statistics, samples (`λ = 1 − 1/memory`).
    pub memory_samples: f64,
    /// Noise of one reading relative to the field (sets the RLS weight and the gate floor).
    pub residual_std: f64,
    /// Samples learned without the residual gate at the start.
    pub warmup_samples: f64,
    /// Largest standard deviation of the offset (any axis) for it to be applied.
    pub max_offset_std: f64,
    /// Smallest direction spread `27·det(E[uuᵀ])` for the offset to be applied.
    pub min_spread: f64,
    /// Largest running RMS residual for the offset to be applied.
    pub max_residual_rms: f64,
    /// Learning gate, in running RMS residuals.
    pub gate_sigmas: f64,
    /// Smallest offset (relative) worth applying the first time: a smaller learned offset is
    /// not applied until it grows past this (afterwards every validated offset is).
    pub min_offset: f64,
    /// Memory of the running RMS residual, samples (short: the gate follows the estimate as
    /// it converges).
    pub residual_memory_samples: f64,
}

impl Default for OnlineHardIronParams {
    /// Memory 6000 samples (60 s at 100 Hz), noise 1 %, warm-up 200 samples, offset std
    /// 1 %, spread 0.1, residual 1.5 %, gate 4σ over 500 samples, smallest first offset 5 %.
    fn default() -> Self {
        Self {
            memory_samples: 6000.0,
            residual_std: 0.01,
            warmup_samples: 200.0,
            max_offset_std: 0.01,
            min_spread: 0.1,
            max_residual_rms: 0.015,
            gate_sigmas: 4.0,
            min_offset: 0.05,
            residual_memory_samples: 500.0,
        }
    }
}

/// Online hard-iron estimator over lanes (see the [module documentation](self)).
#[derive(Clone, Copy, Debug)]
pub struct OnlineHardIron<T: Lane> {
    rls: InverseQr<T, 4>,
    params: OnlineHardIronParams,
    /// Unit of the normalised problem: the first usable reading's norm (raw units).
    scale: T,
    scaled: T::Mask,
    /// Samples learned so far (saturates far above the warm-up).
    learned: T,
    /// Warm and the offset's covariance small: from here on the learning gate is applied.
    settled: T::Mask,
    /// Running mean square of the relative residual.
    residual_ms: T,
    /// Running second moment of the unit directions of `m − ĥ`, and the total weight of its
    /// exponential average (it starts at zero, so `moment / weight` is the unbiased mean).
    moment: Mat<T, 3, 3>,
    moment_weight: T,
    /// The offset applied (raw units) and where one has been validated.
    applied: Vec3<T>,
    active: T::Mask,
    /// The last sample's learning decision and residual (relative).
    last_learned: T::Mask,
    last_residual: T,
    rejected: T::Counts,
}

impl<T: Lane> OnlineHardIron<T> {
    /// A fresh estimator (no offset applied yet). Fails only if `memory_samples` is not
    /// `≥ 1` (the forgetting factor would leave `(0, 1]`).
    pub fn new(params: OnlineHardIronParams) -> Result<Self, RlsError> {
        let lambda = 1.0 - 1.0 / params.memory_samples;
        // Offset and c within a few field norms: an eigenvalue bound of 10 (normalised units²)
        // stops windup in unexcited directions without ever binding an excited one.
        let config = RlsConfig::new(lambda).with_bounds(0.0, 10.0);
        let x0 = Vector::from_column([T::zero(), T::zero(), T::zero(), T::one()]);
        let rls = InverseQr::with_isotropic_prior(&x0, T::one(), config)?;
        Ok(Self {
            rls,
            params,
            scale: T::one(),
            scaled: T::Mask::splat(false),
            learned: T::zero(),
            settled: T::Mask::splat(false),
            residual_ms: T::from_f64(params.max_residual_rms * params.max_residual_rms),
            moment: Mat::zeros(),
            moment_weight: T::zero(),
            applied: Vec3::zero(),
            active: T::Mask::splat(false),
            last_learned: T::Mask::splat(false),
            last_residual: T::zero(),
            rejected: T::Counts::default(),
        })
    }

    /// Back to the state of a new estimator with the same parameters.
    pub fn reset(&mut self) {
        // `new` succeeded with these parameters when `self` was built, so it does again.
        if let Ok(fresh) = Self::new(self.params) {
            *self = fresh;
        }
    }

    /// Learns from one raw reading (NaN = no reading: nothing happens in that lane) and
    /// returns it corrected by the applied offset (unchanged where none is applied yet).
    pub fn update(&mut self, mag: Vec3<T>) -> Vec3<T> {
        let p = &self.params;
        let usable = mag.is_finite() & mag.norm_squared().simd_gt(T::zero());
        let fresh = usable & !self.scaled;
        self.scale = T::select(fresh, mag.norm(), self.scale);
        self.scaled |= fresh;
        let m = Vec3::select(
            usable,
            mag * self.scale.recip(),
            Vec3::new(T::one(), T::zero(), T::zero()),
        );

        // Residual against the current estimate, before learning from this sample.
        let x = self.rls.estimate();
        let h = Vec3::new(x[0], x[1], x[2]);
        let f = (x[3] + h.norm_squared()).max(T::from_f64(1e-12)).sqrt();
        let d = m - h;
        let dn = d.norm();
        let r = (dn - f) / f;
        let warm = self.learned.simd_ge(T::from_f64(p.warmup_samples));
        let gate =
            T::from_f64(p.gate_sigmas) * self.residual_ms.sqrt() + T::from_f64(p.residual_std);
        let consistent = r.abs().simd_le(gate);
        let learn = usable & self.scaled & (!self.settled | consistent);
        T::count(&mut self.rejected, usable & !learn);
        self.last_learned = learn;
        self.last_residual = T::select(usable, r, T::zero());

        if learn.any() {
            let row = Vector::from_column([m.x + m.x, m.y + m.y, m.z + m.z, T::one()]);
            let sigma = T::from_f64(2.0 * p.residual_std);
            let w = T::select(learn, (sigma * sigma).recip(), T::zero());
            let z = T::select(learn, m.norm_squared(), T::zero());
            // Weight 0 in the other lanes: the form leaves them exactly as they were.
            self.rls.update_with_forgetting(&row, z, w, learn);
            let alpha = T::from_f64(1.0 / p.memory_samples);
            self.learned = T::select(
                learn,
                (self.learned + T::one()).min(T::from_f64(1e9)),
                self.learned,
            );
            let beta = T::from_f64(1.0 / p.residual_memory_samples);
            let ms = self.residual_ms + beta * (r * r - self.residual_ms);
            self.residual_ms = T::select(learn & warm, ms, self.residual_ms);
            let u = d * dn.max(T::from_f64(1e-12)).recip();
            let u = [u.x, u.y, u.z];
            let mut moment = self.moment;
            for i in 0..3 {
                for j in 0..3 {
                    moment.m[i][j] = moment.m[i][j] + alpha * (u[i] * u[j] - moment.m[i][j]);
                }
            }
            self.moment = Mat::select(learn, &moment, &self.moment);
            let weight = self.moment_weight + alpha * (T::one() - self.moment_weight);
            self.moment_weight = T::select(learn, weight, self.moment_weight);
        }

        // Validate and apply.
        let x = self.rls.estimate();
        let cov = self.rls.covariance();
        let std_max = cov.m[0][0].max(cov.m[1][1]).max(cov.m[2][2]).sqrt();
        let f = (x[3] + x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
            .max(T::from_f64(1e-12))
            .sqrt();
        let wm = self.moment_weight.max(T::from_f64(1e-12));
        let spread = T::from_f64(27.0) * det3(&self.moment) / (wm * wm * wm);
        let converged = std_max.simd_le(T::from_f64(p.max_offset_std) * f);
        self.settled |= warm & self.scaled & converged;
        let valid = warm
            & self.scaled
            & converged
            & spread.simd_ge(T::from_f64(p.min_spread))
            & self
                .residual_ms
                .sqrt()
                .simd_le(T::from_f64(p.max_residual_rms))
            & x.is_finite();
        let h_norm2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
        let significant = h_norm2.simd_ge(T::from_f64(p.min_offset * p.min_offset) * f * f);
        let valid = valid & (self.active | significant);
        let h_raw = Vec3::new(x[0], x[1], x[2]) * self.scale;
        self.applied = Vec3::select(valid, h_raw, self.applied);
        self.active |= valid;
        Vec3::select(self.active & usable, mag - self.applied, mag)
    }

    /// The offset being applied, raw units (zero where none has been validated yet).
    pub fn applied_offset(&self) -> Vec3<T> {
        self.applied
    }

    /// Lanes where an offset has been validated and is being applied.
    pub fn active(&self) -> T::Mask {
        self.active
    }

    /// The current (not necessarily validated) offset estimate, raw units.
    pub fn estimate(&self) -> Vec3<T> {
        let x = self.rls.estimate();
        Vec3::new(x[0], x[1], x[2]) * self.scale
    }

    /// The current field-norm estimate `|m − ĥ|`, raw units.
    pub fn field_norm(&self) -> T {
        let x = self.rls.estimate();
        (x[3] + x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
            .max(T::zero())
            .sqrt()
            * self.scale
    }

    /// Whether the last reading was learned (false: no reading, or refused by the gate).
    pub fn last_learned(&self) -> T::Mask {
        self.last_learned
    }

    /// The last reading's residual `(|m − ĥ| − F̂)/F̂` (0 where there was none).
    pub fn last_residual(&self) -> T {
        self.last_residual
    }

    /// Readings refused by the learning gate, per lane.
    pub fn rejected(&self) -> &T::Counts {
        &self.rejected
    }
}

fn det3<T: Lane>(m: &Mat<T, 3, 3>) -> T {
    let a = &m.m;
    a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
}
