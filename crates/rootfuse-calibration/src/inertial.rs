//! Gyroscope bias and accelerometer offset and scale from rest phases.
//!
//! At rest a gyroscope reads its bias and an accelerometer reads gravity through its errors:
//! `a_raw = S⁻¹·g_sensor + h` with `|g_sensor| = g`. Rest phases in different orientations
//! (six: each axis up and down, the *six-position method*) therefore put the mean readings on
//! the ellipsoid of [`fit_ellipsoid`], with the norm known (gravity), and the same fit,
//! observability ladder and quality figures apply. With six positions the full symmetric `S`
//! is not determined (six clusters, nine parameters): the ladder reports that and fits
//! offset and per-axis scale.

use crate::{CalibrationError, EllipsoidFit, FitOptions, fit_ellipsoid};
use rootfuse_attitude::{Mat, SensorCalibration, Vec3};

/// How rest is detected: blocks of `block_s` seconds whose per-axis standard deviations stay
/// below the limits, and whose mean angular rate is no more than a gyroscope bias can be
/// (`max_gyro_bias`), are still; runs of still blocks with the same gravity direction (within
/// `max_turn_rad` of the previous block) and, when a magnetometer is given, the same field
/// direction (within `max_field_turn_rad` of the phase's first block) lasting at least
/// `min_duration_s` are rest phases. A steady turn (a turntable) has a steady gyroscope and
/// accelerometer: its rate, and the turning field, tell it from rest.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RestOptions {
    /// Block length, s.
    pub block_s: f64,
    /// Largest per-axis gyroscope standard deviation within a still block, rad/s.
    pub gyro_std_max: f64,
    /// Largest per-axis accelerometer standard deviation within a still block, m/s².
    pub acc_std_max: f64,
    /// Largest angle between the mean accelerometer directions of adjacent still blocks of one
    /// phase, rad.
    pub max_turn_rad: f64,
    /// Shortest rest phase, s.
    pub min_duration_s: f64,
    /// Largest mean angular-rate magnitude of a still block, rad/s: above any plausible
    /// gyroscope bias, so a steady turn is not taken for rest.
    pub max_gyro_bias: f64,
    /// Largest angle between a still block's mean field direction and the phase's first
    /// block's, rad (magnetometer given): a turn slower than a bias can be still turns the
    /// field.
    pub max_field_turn_rad: f64,
}

impl Default for RestOptions {
    /// Blocks of 0.25 s; 0.02 rad/s and 0.1 m/s²; 2°; phases of at least 1 s; a mean rate of
    /// at most 0.1 rad/s (5.7 °/s, several times a consumer MEMS gyroscope's bias); the field
    /// within 0.5° (block means of a 0.3 µT-noise magnetometer in a 50 µT field scatter by
    /// about 0.05°).
    fn default() -> Self {
        Self {
            block_s: 0.25,
            gyro_std_max: 0.02,
            acc_std_max: 0.1,
            max_turn_rad: 2f64.to_radians(),
            min_duration_s: 1.0,
            max_gyro_bias: 0.1,
            max_field_turn_rad: 0.5f64.to_radians(),
        }
    }
}

/// One rest phase: samples `start..end` of the recording.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RestPhase {
    /// First sample.
    pub start: usize,
    /// One past the last sample.
    pub end: usize,
    /// Mean gyroscope reading, rad/s.
    pub mean_gyr: Vec3<f64>,
    /// Mean accelerometer reading, m/s².
    pub mean_acc: Vec3<f64>,
}

/// Finds the rest phases of a recording (`t` in s, gyroscope rad/s, accelerometer m/s², the
/// magnetometer in any unit when there is one; equal lengths). Blocks holding a non-finite
/// gyroscope or accelerometer value are not still; a block without a finite field reading
/// is judged without the magnetometer.
pub fn rest_phases(
    t: &[f64],
    gyr: &[Vec3<f64>],
    acc: &[Vec3<f64>],
    mag: Option<&[Vec3<f64>]>,
    options: &RestOptions,
) -> Vec<RestPhase> {
    let n = t.len().min(gyr.len()).min(acc.len());
    if n < 2 {
        return Vec::new();
    }
    let span = t[n - 1] - t[0];
    let rate = if span > 0.0 {
        (n - 1) as f64 / span
    } else {
        0.0
    };
    let block = ((options.block_s * rate).round() as usize).max(2);
    let mut phases: Vec<RestPhase> = Vec::new();
    // The open run: start, end, the last block's gravity direction, the first block's field.
    type Run = (usize, usize, Vec3<f64>, Option<Vec3<f64>>);
    let mut open: Option<Run> = None;
    let close = |phases: &mut Vec<RestPhase>, run: Option<Run>| {
        if let Some((start, end, _, _)) = run
            && t[end - 1] - t[start] >= options.min_duration_s
        {
            phases.push(RestPhase {
                start,
                end,
                mean_gyr: mean(&gyr[start..end]),
                mean_acc: mean(&acc[start..end]),
            });
        }
    };
    for b in (0..n).step_by(block) {
        let e = (b + block).min(n);
        if block_verdict(&gyr[b..e], &acc[b..e], options) != BlockVerdict::Still {
            close(&mut phases, open.take());
            continue;
        }
        let dir = mean(&acc[b..e]);
        let field = mag
            .and_then(|m| m.get(b..e))
            .map(mean)
            .filter(|f| f.is_finite());
        open = match open {
            Some((start, _, prev, first_field))
                if angle(prev, dir) <= options.max_turn_rad
                    && match (first_field, field) {
                        (Some(a), Some(b)) => angle(a, b) <= options.max_field_turn_rad,
                        _ => true,
                    } =>
            {
                Some((start, e, dir, first_field.or(field)))
            }
            run => {
                close(&mut phases, run);
                Some((b, e, dir, field))
            }
        };
    }
    close(&mut phases, open);
    phases
}

/// Why a block of samples is or is not still (the first test it fails, in this order).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum BlockVerdict {
    Still,
    /// Fewer than two samples.
    Short,
    GyroNoisy,
    AccNoisy,
    /// Steady, but turning faster than a bias can be.
    Turning,
}

/// `x` above `limit`, or NaN: a non-finite value in the block is not still.
fn exceeds(x: f64, limit: f64) -> bool {
    x.is_nan() || x > limit
}

fn block_verdict(gyr: &[Vec3<f64>], acc: &[Vec3<f64>], options: &RestOptions) -> BlockVerdict {
    if gyr.len() < 2 {
        BlockVerdict::Short
    } else if exceeds(std_max(gyr), options.gyro_std_max) {
        BlockVerdict::GyroNoisy
    } else if exceeds(std_max(acc), options.acc_std_max) {
        BlockVerdict::AccNoisy
    } else if exceeds(mean(gyr).norm(), options.max_gyro_bias) {
        BlockVerdict::Turning
    } else {
        BlockVerdict::Still
    }
}

/// Why [`rest_phases`] found what it found: per test, how many blocks failed it, the
/// slowest mean rate among the steady but turning blocks and the longest run of still
/// blocks. Its `Display` is one sentence for a user whose recording has no rest.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RestSearch {
    /// Blocks examined.
    pub blocks: usize,
    /// Length of one block, s.
    pub block_s: f64,
    /// Blocks whose gyroscope varied more than `gyro_std_max`.
    pub gyro_noisy: usize,
    /// Blocks whose accelerometer varied more than `acc_std_max`.
    pub acc_noisy: usize,
    /// Steady blocks turning faster than `max_gyro_bias`.
    pub turning: usize,
    /// The slowest mean rate among the turning blocks, rad/s (NaN when none).
    pub slowest_turn: f64,
    /// The longest run of consecutive still blocks, s.
    pub longest_still_s: f64,
    /// The options searched with.
    pub options: RestOptions,
}

/// The block-by-block account of a rest search (same arguments as [`rest_phases`]).
pub fn rest_search(
    t: &[f64],
    gyr: &[Vec3<f64>],
    acc: &[Vec3<f64>],
    options: &RestOptions,
) -> RestSearch {
    let n = t.len().min(gyr.len()).min(acc.len());
    let span = if n >= 2 { t[n - 1] - t[0] } else { 0.0 };
    let rate = if span > 0.0 {
        (n - 1) as f64 / span
    } else {
        0.0
    };
    let block = ((options.block_s * rate).round() as usize).max(2);
    let mut r = RestSearch {
        blocks: 0,
        block_s: if rate > 0.0 { block as f64 / rate } else { 0.0 },
        gyro_noisy: 0,
        acc_noisy: 0,
        turning: 0,
        slowest_turn: f64::NAN,
        longest_still_s: 0.0,
        options: *options,
    };
    let mut run = 0.0f64;
    for b in (0..n).step_by(block) {
        let e = (b + block).min(n);
        r.blocks += 1;
        let verdict = block_verdict(&gyr[b..e], &acc[b..e], options);
        match verdict {
            BlockVerdict::GyroNoisy => r.gyro_noisy += 1,
            BlockVerdict::AccNoisy => r.acc_noisy += 1,
            BlockVerdict::Turning => {
                r.turning += 1;
                r.slowest_turn = r.slowest_turn.min(mean(&gyr[b..e]).norm());
            }
            BlockVerdict::Still | BlockVerdict::Short => {}
        }
        run = if verdict == BlockVerdict::Still {
            run + (t[e - 1] - t[b])
        } else {
            0.0
        };
        r.longest_still_s = r.longest_still_s.max(run);
    }
    r
}

impl core::fmt::Display for RestSearch {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let o = &self.options;
        write!(
            f,
            "of {} blocks of {:.2} s, {} had a gyroscope varying by more than {} rad/s, {} an accelerometer varying by more than {} m/s²",
            self.blocks,
            self.block_s,
            self.gyro_noisy,
            o.gyro_std_max,
            self.acc_noisy,
            o.acc_std_max
        )?;
        if self.turning > 0 {
            write!(
                f,
                ", {} were steady but turning at {:.3} rad/s or more, faster than a bias can be ({} rad/s: a turntable is not rest)",
                self.turning, self.slowest_turn, o.max_gyro_bias
            )?;
        }
        write!(
            f,
            "; the longest still stretch lasted {:.2} s, {} s needed: record the sensor lying still for a few seconds",
            self.longest_still_s, o.min_duration_s
        )
    }
}

fn mean(v: &[Vec3<f64>]) -> Vec3<f64> {
    let mut s = Vec3::zero();
    for x in v {
        s += *x;
    }
    s * (1.0 / v.len() as f64)
}

/// Largest per-axis standard deviation (NaN, hence "not still", if a value is not finite).
fn std_max(v: &[Vec3<f64>]) -> f64 {
    let m = mean(v);
    let mut var = [0.0f64; 3];
    for x in v {
        let d = (*x - m).to_array();
        for k in 0..3 {
            var[k] += d[k] * d[k];
        }
    }
    let n = (v.len() - 1) as f64;
    let worst = var[0].max(var[1]).max(var[2]);
    if var.iter().any(|x| x.is_nan()) {
        f64::NAN
    } else {
        (worst / n).sqrt()
    }
}

/// The readings of `v` inside the rest phases (indices past the end are ignored).
fn rest_samples(v: &[Vec3<f64>], phases: &[RestPhase]) -> Vec<Vec3<f64>> {
    phases
        .iter()
        .flat_map(|p| v[p.start.min(v.len())..p.end.min(v.len())].iter().copied())
        .collect()
}

fn angle(a: Vec3<f64>, b: Vec3<f64>) -> f64 {
    a.cross(b).norm().atan2(a.dot(b))
}

/// Gyroscope bias from rest phases.
#[derive(Clone, Debug, PartialEq)]
pub struct GyroBiasFit {
    /// `S = I`, offset = the bias (rad/s), norm NaN.
    pub calibration: SensorCalibration<f64>,
    /// Standard error of the bias per axis, rad/s (sample standard deviation over `√n`).
    pub std_error: Vec3<f64>,
    /// Largest distance of one phase's mean from the bias, rad/s: a large value next to a
    /// small standard error means the bias drifted between phases.
    pub phase_spread: f64,
    /// Rest phases used.
    pub phases: usize,
    /// Samples used.
    pub samples: usize,
}

/// The gyroscope bias as the mean reading over all rest phases (refused without any).
pub fn gyro_bias(gyr: &[Vec3<f64>], phases: &[RestPhase]) -> Result<GyroBiasFit, CalibrationError> {
    let samples = rest_samples(gyr, phases);
    if phases.is_empty() || samples.len() < 2 {
        return Err(CalibrationError::TooFewRestPhases {
            found: phases.len(),
            needed: 1,
        });
    }
    let bias = mean(&samples);
    let n = samples.len() as f64;
    let mut var = [0.0f64; 3];
    for x in &samples {
        let d = (*x - bias).to_array();
        for k in 0..3 {
            var[k] += d[k] * d[k] / (n - 1.0);
        }
    }
    let std_error = Vec3::from_array(var.map(|v| (v / n).sqrt()));
    let phase_spread = phases
        .iter()
        .map(|p| (p.mean_gyr - bias).norm())
        .fold(0.0, f64::max);
    Ok(GyroBiasFit {
        calibration: SensorCalibration {
            matrix: Mat::identity(),
            offset: bias,
            norm: f64::NAN,
        },
        std_error,
        phase_spread,
        phases: phases.len(),
        samples: samples.len(),
    })
}

/// Accelerometer offset and scale from rest phases.
#[derive(Clone, Debug, PartialEq)]
pub struct AccelerometerFit {
    /// The ellipsoid fit of the rest readings with the norm fixed to gravity.
    pub fit: EllipsoidFit,
    /// Rest phases used.
    pub phases: usize,
}

/// The six-position method: fits `a_cal = S·(a_raw − h)` with `|a_cal| = gravity` to the
/// readings of the rest phases (at least six, in different orientations). Six orientations
/// cover six of the sphere's direction cells by design: `options.min_coverage` is not
/// applied (the count of rest phases stands for it).
pub fn accelerometer(
    acc: &[Vec3<f64>],
    phases: &[RestPhase],
    gravity: f64,
    options: &FitOptions,
) -> Result<AccelerometerFit, CalibrationError> {
    const NEEDED: usize = 6;
    if phases.len() < NEEDED {
        return Err(CalibrationError::TooFewRestPhases {
            found: phases.len(),
            needed: NEEDED,
        });
    }
    let samples = rest_samples(acc, phases);
    let fit = fit_ellipsoid(
        &samples,
        &FitOptions {
            norm: Some(gravity),
            min_coverage: 0.0,
            ..*options
        },
    )?;
    Ok(AccelerometerFit {
        fit,
        phases: phases.len(),
    })
}
