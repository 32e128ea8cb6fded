//! The sensor model: what a real IMU makes of the true motion.
//!
//! Gyroscope and accelerometer (an [`InertialSensor`] each):
//! `y = clamp((I + M)·diag(1 + s)·x + b(t) + n, ±range)` with the true quantity `x` (body rate
//! or specific force, sensor frame), misalignment/cross-coupling `M` (its diagonal is ignored),
//! scale-factor errors `s`, bias `b(t)` = initial bias + random walk + steps, and white noise
//! `n`.
//!
//! Magnetometer: `y = clamp(S·R(q)ᵀ·(m_earth + d_earth(t)) + h + d_sensor(t) + n, ±range)` with
//! the earth field `m_earth = B·[0, cos δ, −sin δ]` (ENU, dip δ below the horizon towards
//! north), soft iron `S`, hard iron `h`, and disturbance episodes `d` fixed in the earth frame
//! (a magnet in the room) or in the sensor frame (a magnet attached to the body).

use super::SimError;
use rootfuse_attitude::Vec3;
use std::vec::Vec;

/// A 3×3 matrix, row-major (`m[row][col]`).
pub type Mat3 = [[f64; 3]; 3];

/// The 3×3 identity.
pub const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// `m·v`.
#[inline]
pub(crate) fn mat_vec(m: &Mat3, v: Vec3<f64>) -> Vec3<f64> {
    Vec3::new(
        m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
        m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
        m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z,
    )
}

/// A step change of a bias at a given time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BiasStep {
    /// Time of the step, s.
    pub time_s: f64,
    /// Change of the bias (sensor unit, per axis).
    pub delta: Vec3<f64>,
}

/// Error model of a 3-axis gyroscope (unit rad/s) or accelerometer (unit m/s²).
#[derive(Clone, Debug, PartialEq)]
pub struct InertialSensor {
    /// White noise standard deviation per sample and axis (sensor unit). For a noise density
    /// `N` (unit/√Hz) at sample rate `f`: `N·sqrt(f)`.
    pub noise_std: f64,
    /// Bias at `t = 0` (sensor unit).
    pub bias: Vec3<f64>,
    /// Bias random walk, sensor unit per √s: over a step `Δt` each axis changes by
    /// `N(0, bias_walk²·Δt)`.
    pub bias_walk: f64,
    /// Bias steps (applied from their time on).
    pub bias_steps: Vec<BiasStep>,
    /// Scale-factor error per axis (relative: 0.01 reads 1 % high).
    pub scale: Vec3<f64>,
    /// Cross-axis coupling: `y_i += Σ_{j≠i} misalignment[i][j]·x_j` (diagonal ignored).
    pub misalignment: Mat3,
    /// Saturation: each axis is clamped to `±range` (`f64::INFINITY` = none).
    pub range: f64,
}

impl InertialSensor {
    /// A perfect sensor: no noise, bias, scale or coupling error, no saturation.
    pub fn ideal() -> Self {
        Self {
            noise_std: 0.0,
            bias: Vec3::zero(),
            bias_walk: 0.0,
            bias_steps: Vec::new(),
            scale: Vec3::zero(),
            misalignment: [[0.0; 3]; 3],
            range: f64::INFINITY,
        }
    }
    /// The deterministic part `(I + M)·diag(1 + s)·x` (no bias, noise or saturation).
    pub fn sensitivity(&self, x: Vec3<f64>) -> Vec3<f64> {
        let xs = Vec3::new(
            x.x * (1.0 + self.scale.x),
            x.y * (1.0 + self.scale.y),
            x.z * (1.0 + self.scale.z),
        );
        let m = &self.misalignment;
        Vec3::new(
            xs.x + m[0][1] * xs.y + m[0][2] * xs.z,
            xs.y + m[1][0] * xs.x + m[1][2] * xs.z,
            xs.z + m[2][0] * xs.x + m[2][1] * xs.y,
        )
    }
    fn validate(&self, name: &'static str) -> Result<(), SimError> {
        let nums = [self.noise_std, self.bias_walk];
        let ok = nums.iter().all(|v| v.is_finite() && *v >= 0.0)
            && finite3(self.bias)
            && finite3(self.scale)
            && self.misalignment.iter().flatten().all(|v| v.is_finite())
            && self
                .bias_steps
                .iter()
                .all(|s| s.time_s.is_finite() && finite3(s.delta))
            && self.range > 0.0;
        if ok {
            Ok(())
        } else {
            Err(SimError::InvalidSensor { sensor: name })
        }
    }
}

/// The earth magnetic field in ENU.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EarthField {
    /// Field strength (any unit; presets use µT).
    pub magnitude: f64,
    /// Dip (inclination) below the horizon, degrees; positive points down (northern
    /// hemisphere).
    pub dip_deg: f64,
}

impl EarthField {
    /// The field vector, earth frame (ENU): `magnitude·[0, cos dip, −sin dip]` (north is +y).
    pub fn vector(&self) -> Vec3<f64> {
        let d = self.dip_deg.to_radians();
        Vec3::new(0.0, d.cos(), -d.sin()) * self.magnitude
    }
}

impl Default for EarthField {
    /// 50 µT with a dip of 64° (mid-latitude northern hemisphere).
    fn default() -> Self {
        Self {
            magnitude: 50.0,
            dip_deg: 64.0,
        }
    }
}

/// In which frame a magnetic disturbance is fixed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Frame {
    /// Fixed in the room (earth frame, ENU): its sensor-frame reading turns with the body.
    Earth,
    /// Fixed to the body (sensor frame): like a change of hard iron.
    Sensor,
}

/// A magnetic disturbance episode: `field` is added between `start_s` and `end_s`, faded in
/// and out over `ramp_s` seconds (smoothstep) inside that interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MagDisturbance {
    /// Start, s.
    pub start_s: f64,
    /// End, s.
    pub end_s: f64,
    /// Added field at full strength (magnetometer unit), in `frame`.
    pub field: Vec3<f64>,
    /// Frame the field is fixed in.
    pub frame: Frame,
    /// Fade duration at each end, s.
    pub ramp_s: f64,
}

impl MagDisturbance {
    /// Strength in `[0, 1]` at time `t`.
    pub fn envelope(&self, t: f64) -> f64 {
        if t <= self.start_s || t >= self.end_s {
            return 0.0;
        }
        let ramp = self.ramp_s.min(0.5 * (self.end_s - self.start_s));
        if ramp <= 0.0 {
            return 1.0;
        }
        let s = |x: f64| {
            let x = x.clamp(0.0, 1.0);
            x * x * (3.0 - 2.0 * x)
        };
        s((t - self.start_s) / ramp) * s((self.end_s - t) / ramp)
    }
}

/// Error model of a 3-axis magnetometer.
#[derive(Clone, Debug, PartialEq)]
pub struct Magnetometer {
    /// The undisturbed earth field.
    pub field: EarthField,
    /// White noise standard deviation per sample and axis (field unit).
    pub noise_std: f64,
    /// Hard iron offset, sensor frame (field unit).
    pub hard_iron: Vec3<f64>,
    /// Soft iron matrix `S` (identity = none).
    pub soft_iron: Mat3,
    /// Disturbance episodes.
    pub disturbances: Vec<MagDisturbance>,
    /// Saturation per axis (`f64::INFINITY` = none).
    pub range: f64,
}

impl Magnetometer {
    /// A perfect magnetometer in the default earth field.
    pub fn ideal() -> Self {
        Self {
            field: EarthField::default(),
            noise_std: 0.0,
            hard_iron: Vec3::zero(),
            soft_iron: IDENTITY,
            disturbances: Vec::new(),
            range: f64::INFINITY,
        }
    }
    fn validate(&self) -> Result<(), SimError> {
        let ok = self.field.magnitude.is_finite()
            && self.field.dip_deg.is_finite()
            && self.noise_std.is_finite()
            && self.noise_std >= 0.0
            && finite3(self.hard_iron)
            && self.soft_iron.iter().flatten().all(|v| v.is_finite())
            && self.disturbances.iter().all(|d| {
                d.start_s.is_finite()
                    && d.end_s.is_finite()
                    && finite3(d.field)
                    && d.ramp_s.is_finite()
                    && d.ramp_s >= 0.0
            })
            && self.range > 0.0;
        if ok {
            Ok(())
        } else {
            Err(SimError::InvalidSensor {
                sensor: "magnetometer",
            })
        }
    }
}

/// Sampling: nominal rate, time jitter, dropped samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timing {
    /// Nominal sample rate, Hz; sample `k` is nominally at `k / rate_hz`.
    pub rate_hz: f64,
    /// Standard deviation of the sample-time jitter, s (Gaussian, clipped to ±0.45 of the
    /// nominal interval so that times strictly increase). The recorded time stamps are the
    /// true (jittered) instants: the data are irregular, not mislabelled.
    pub jitter_std_s: f64,
    /// Probability that a sample is lost (independently per sample); the first sample is
    /// always kept.
    pub drop_prob: f64,
}

impl Timing {
    /// Regular sampling at `rate_hz`.
    pub fn regular(rate_hz: f64) -> Self {
        Self {
            rate_hz,
            jitter_std_s: 0.0,
            drop_prob: 0.0,
        }
    }
    pub(crate) fn validate(&self) -> Result<(), SimError> {
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0) {
            return Err(SimError::InvalidParameter {
                name: "rate_hz",
                value: self.rate_hz,
            });
        }
        if !(self.jitter_std_s.is_finite() && self.jitter_std_s >= 0.0) {
            return Err(SimError::InvalidParameter {
                name: "jitter_std_s",
                value: self.jitter_std_s,
            });
        }
        if !(0.0..1.0).contains(&self.drop_prob) {
            return Err(SimError::InvalidParameter {
                name: "drop_prob",
                value: self.drop_prob,
            });
        }
        Ok(())
    }
}

/// The whole IMU: gyroscope, accelerometer, optional magnetometer (`None` = 6D IMU), gravity.
#[derive(Clone, Debug, PartialEq)]
pub struct SensorModel {
    /// Gyroscope, rad/s.
    pub gyro: InertialSensor,
    /// Accelerometer, m/s².
    pub acc: InertialSensor,
    /// Magnetometer; `None` for a 6D IMU.
    pub mag: Option<Magnetometer>,
    /// Gravity magnitude, m/s² (the accelerometer reads `+gravity` along earth-up at rest).
    pub gravity: f64,
}

impl SensorModel {
    /// A perfect 9D IMU (no errors at all), gravity [`super::GRAVITY`].
    pub fn ideal() -> Self {
        Self {
            gyro: InertialSensor::ideal(),
            acc: InertialSensor::ideal(),
            mag: Some(Magnetometer::ideal()),
            gravity: super::GRAVITY,
        }
    }
    pub(crate) fn validate(&self) -> Result<(), SimError> {
        self.gyro.validate("gyroscope")?;
        self.acc.validate("accelerometer")?;
        if let Some(m) = &self.mag {
            m.validate()?;
        }
        if !self.gravity.is_finite() {
            return Err(SimError::InvalidParameter {
                name: "gravity",
                value: self.gravity,
            });
        }
        Ok(())
    }
}

fn finite3(v: Vec3<f64>) -> bool {
    v.x.is_finite() && v.y.is_finite() && v.z.is_finite()
}

/// Clamps each axis to `±range` (saturation).
#[inline]
pub(crate) fn saturate(v: Vec3<f64>, range: f64) -> Vec3<f64> {
    Vec3::new(
        v.x.clamp(-range, range),
        v.y.clamp(-range, range),
        v.z.clamp(-range, range),
    )
}
