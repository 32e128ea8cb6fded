//! Shared input screening: one rule for every filter about what is usable.

use crate::{ImuSample, Vec3};
use rootfuse_lane::{Lane, Mask};

/// Limits that decide whether a sample is usable.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScreenLimits {
    /// Largest accepted time step, s; larger gaps are skipped (the orientation would be a guess).
    pub max_dt: f64,
    /// Largest accepted angular rate magnitude, rad/s (a saturated gyroscope lies).
    pub max_gyr: f64,
    /// Largest accepted specific-force magnitude, m/s²: beyond it no accelerometer can have
    /// measured the sample, so it is a corrupted one and only its correction is skipped.
    pub max_acc: f64,
    /// Largest accepted magnetic-field magnitude, in the input's units (the default assumes
    /// µT or gauss; raw counts or nT need a larger limit).
    pub max_mag: f64,
}

impl Default for ScreenLimits {
    fn default() -> Self {
        // 1 s covers any real sample rate with dropouts; 35 rad/s ≈ 2000 °/s, the usual
        // full-scale range of MEMS gyroscopes. 1000 m/s² ≈ 102 g is beyond the usual MEMS
        // accelerometer ranges (±16 g ≈ 157 m/s², ±24 g, ±100 g): no body carrying an IMU
        // meets it without breaking. 1000 field units is 1 mT in µT, fifteen times the
        // strongest geomagnetic field (65 µT): a field so strong is a magnet on the sensor,
        // useless for heading either way.
        Self {
            max_dt: 1.0,
            max_gyr: 35.0,
            max_acc: 1000.0,
            max_mag: 1000.0,
        }
    }
}

impl ScreenLimits {
    /// The limits in the precision of lane type `T`, squared where a squared norm is compared:
    /// what a filter keeps, so that no sample converts them again.
    pub fn bounds<T: Lane>(&self) -> ScreenBounds<T> {
        let f = <T::Scalar as Lane>::from_f64;
        ScreenBounds {
            max_dt: f(self.max_dt),
            max_gyr2: f(self.max_gyr * self.max_gyr),
            max_acc2: f(self.max_acc * self.max_acc),
            max_mag2: f(self.max_mag * self.max_mag),
        }
    }
}

/// [`ScreenLimits`] converted once to the precision of `T` (its scalar: one value for every
/// lane), the magnitudes squared: the bounds [`Screened`] compares each sample with.
///
/// ```
/// use rootfuse_attitude::filters::{Rejections, ScreenLimits, Screened};
/// use rootfuse_attitude::{ImuSample, Vec3};
/// let bounds = ScreenLimits::default().bounds::<f64>();
/// let mut counts = Rejections::<f64>::default();
/// // 40 rad/s is beyond `max_gyr` (35 rad/s): the whole sample is skipped and counted.
/// let spin = ImuSample::new(Vec3::new(0.0, 0.0, 40.0), Vec3::new(0.0, 0.0, 9.81), Vec3::zero());
/// let s = Screened::new(&spin, 0.01, &bounds, &mut counts);
/// assert!(!s.step && counts.gyr[0] == 1 && counts.last.gyr);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScreenBounds<T: Lane> {
    /// `max_dt`, s.
    max_dt: T::Scalar,
    /// `max_gyr²`, (rad/s)².
    max_gyr2: T::Scalar,
    /// `max_acc²`, (m/s²)².
    max_acc2: T::Scalar,
    /// `max_mag²`, squared input units.
    max_mag2: T::Scalar,
}

/// What happened to the last sample, per lane: Fusion's per-update flags, for every filter.
///
/// A whole-sample skip (`dt`, `gyr`) leaves the state untouched; a skipped correction
/// (`acc`, `mag`) or a gated one (`acc_gated`, `mag_disturbed`) leaves the orientation to the
/// gyroscope for that sample. `at_rest` is a detector state, not a skip.
#[derive(Clone, Copy, Debug)]
pub struct SampleFlags<T: Lane> {
    /// Skipped whole: `dt` not finite, `≤ 0` or above `max_dt`.
    pub dt: T::Mask,
    /// Skipped whole: gyroscope not finite or faster than `max_gyr`.
    pub gyr: T::Mask,
    /// Accelerometer correction skipped: not finite, zero or above `max_acc`.
    pub acc: T::Mask,
    /// Magnetometer correction skipped (9D): absent, not finite, zero or above `max_mag`.
    pub mag: T::Mask,
    /// A correction refused by the filter's own gate (acceleration norm, innovation test,
    /// the flagship's accelerometer spike gate).
    pub acc_gated: T::Mask,
    /// The magnetometer sample was rejected as a disturbed field.
    pub mag_disturbed: T::Mask,
    /// The filter detects the sensor at rest (filters with rest detection).
    pub at_rest: T::Mask,
}

impl<T: Lane> Default for SampleFlags<T> {
    fn default() -> Self {
        let no = <T::Mask as Mask>::splat(false);
        Self {
            dt: no,
            gyr: no,
            acc: no,
            mag: no,
            acc_gated: no,
            mag_disturbed: no,
            at_rest: no,
        }
    }
}

impl<T: Lane> SampleFlags<T> {
    /// Bit for a whole sample skipped because of `dt`.
    pub const DT: u8 = 1;
    /// Bit for a whole sample skipped because of the gyroscope.
    pub const GYR: u8 = 2;
    /// Bit for a skipped accelerometer correction.
    pub const ACC: u8 = 4;
    /// Bit for a skipped magnetometer correction.
    pub const MAG: u8 = 8;
    /// Bit for a correction refused by the filter's gate.
    pub const ACC_GATED: u8 = 16;
    /// Bit for the state "at rest".
    pub const AT_REST: u8 = 32;
    /// Bit for a magnetometer sample rejected as disturbed.
    pub const MAG_DISTURBED: u8 = 64;

    /// The flags of `lane` as bits (1 dt, 2 gyro, 4 accelerometer, 8 magnetometer skipped,
    /// 16 gated, 32 at rest, 64 magnetic disturbance): the `flags` column of estimates.
    pub fn bits(&self, lane: usize) -> u8 {
        [
            (self.dt, Self::DT),
            (self.gyr, Self::GYR),
            (self.acc, Self::ACC),
            (self.mag, Self::MAG),
            (self.acc_gated, Self::ACC_GATED),
            (self.at_rest, Self::AT_REST),
            (self.mag_disturbed, Self::MAG_DISTURBED),
        ]
        .iter()
        .filter(|(m, _)| (m.bitmask() >> lane) & 1 == 1)
        .fold(0, |bits, (_, b)| bits | b)
    }

    /// The flags of `lane` alone.
    pub fn lane(&self, lane: usize) -> SampleFlags<T::Scalar> {
        SampleFlags {
            dt: self.dt.test(lane),
            gyr: self.gyr.test(lane),
            acc: self.acc.test(lane),
            mag: self.mag.test(lane),
            acc_gated: self.acc_gated.test(lane),
            mag_disturbed: self.mag_disturbed.test(lane),
            at_rest: self.at_rest.test(lane),
        }
    }
}

/// Per-lane counts of what was skipped, by reason (each a `u64` per lane), and the flags of
/// the last sample.
#[derive(Clone, Copy, Debug, Default)]
pub struct Rejections<T: Lane> {
    /// Whole samples skipped: `dt` not finite, `≤ 0` or above `max_dt`.
    pub dt: T::Counts,
    /// Whole samples skipped: gyroscope not finite or above `max_gyr`.
    pub gyr: T::Counts,
    /// Accelerometer corrections skipped: not finite, zero or above `max_acc`.
    pub acc: T::Counts,
    /// Magnetometer corrections skipped (9D only): absent, not finite, zero or above
    /// `max_mag`.
    pub mag: T::Counts,
    /// Corrections skipped by the filter's own gate (e.g. acceleration norm, innovation test).
    pub gated: T::Counts,
    /// Magnetometer samples rejected as a disturbed field (filters that detect it).
    pub mag_disturbed: T::Counts,
    /// What happened to the last sample (set by the screening at the start of each update).
    pub last: SampleFlags<T>,
}

impl<T: Lane> Rejections<T> {
    /// Counts and flags corrections refused by the filter's own gate in the lanes of `mask`.
    #[inline]
    pub fn gate(&mut self, mask: T::Mask) {
        T::count(&mut self.gated, mask);
        self.last.acc_gated |= mask;
    }
    /// Counts and flags magnetometer samples rejected as a disturbed field.
    #[inline]
    pub fn reject_field(&mut self, mask: T::Mask) {
        T::count(&mut self.mag_disturbed, mask);
        self.last.mag_disturbed |= mask;
    }
    /// Total whole-sample skips in `lane`.
    pub fn samples_skipped(&self, lane: usize) -> u64 {
        self.dt.as_ref()[lane] + self.gyr.as_ref()[lane]
    }

    /// The counts and flags of `lane` alone.
    ///
    /// ```
    /// use rootfuse_attitude::filters::Rejections;
    /// use rootfuse_lane::{Lane, wide::f64x2};
    /// let mut r = Rejections::<f64x2>::default();
    /// r.gate(f64x2::from_fn(|i| i as f64).simd_gt(f64x2::zero()));
    /// assert_eq!((r.lane(0).gated, r.lane(1).gated), ([0], [1]));
    /// assert!(r.lane(1).last.acc_gated);
    /// ```
    pub fn lane(&self, lane: usize) -> Rejections<T::Scalar> {
        let one = |c: &T::Counts| {
            let mut out = <T::Scalar as Lane>::Counts::default();
            out.as_mut()[0] = c.as_ref()[lane];
            out
        };
        Rejections {
            dt: one(&self.dt),
            gyr: one(&self.gyr),
            acc: one(&self.acc),
            mag: one(&self.mag),
            gated: one(&self.gated),
            mag_disturbed: one(&self.mag_disturbed),
            last: self.last.lane(lane),
        }
    }
}

/// A sample after screening: unusable parts replaced by harmless values, with masks.
///
/// Where `step` is false, `gyr` and `dt` are zero, so propagation is the identity; where
/// `acc_ok`/`mag_ok` are false, the unit vectors are `+z`/`+y`, so the correction arithmetic
/// stays finite and is discarded by the caller's `select`.
#[derive(Clone, Copy, Debug)]
pub struct Screened<T: Lane> {
    /// Gyroscope and `dt` usable: the state may move.
    pub step: T::Mask,
    /// Angular rate, rad/s (zero where `!step`).
    pub gyr: Vec3<T>,
    /// Time step, s (zero where `!step`).
    pub dt: T,
    /// Accelerometer usable (finite, non-zero, at most `max_acc`; and `step`).
    pub acc_ok: T::Mask,
    /// Unit specific force (sensor frame).
    pub acc: Vec3<T>,
    /// Specific-force norm, m/s² (zero where unusable).
    pub acc_norm: T,
    /// Magnetometer usable (finite, non-zero, at most `max_mag`; and `step`); false for every
    /// 6D sample.
    pub mag_ok: T::Mask,
    /// Unit magnetic field (sensor frame).
    pub mag: Vec3<T>,
    /// Magnetic-field norm, input units (zero where unusable).
    pub mag_norm: T,
}

impl<T: Lane> Screened<T> {
    /// Screens `sample` against `bounds` ([`ScreenLimits::bounds`]) and counts the rejections.
    #[inline]
    pub fn new(
        sample: &ImuSample<T>,
        dt: T,
        bounds: &ScreenBounds<T>,
        counts: &mut Rejections<T>,
    ) -> Self {
        Self::screen(sample, dt, bounds, counts, true)
    }

    /// The screening; `with_mag` false (the same for every lane) leaves the magnetometer
    /// unusable without looking at it, which is what 6D operation discards anyway. Always
    /// inlined: the compiler left it out of line in the lanes, the screened sample passing
    /// through memory (Mahony's `f32x8` lanes 5.1 ns per update against 4.06 inlined).
    #[inline(always)]
    fn screen(
        sample: &ImuSample<T>,
        dt: T,
        bounds: &ScreenBounds<T>,
        counts: &mut Rejections<T>,
        with_mag: bool,
    ) -> Self {
        let zero = T::zero();
        let dt_ok = dt.simd_gt(zero) & dt.simd_le(T::splat(bounds.max_dt));
        let g2 = sample.gyr.norm_squared();
        let gyr_ok = g2.simd_le(T::splat(bounds.max_gyr2));
        let step = dt_ok & gyr_ok;

        // A sample beyond the physical limit is refused as a non-finite one is: with it the
        // direction would be right only by luck and any norm-based state (low-passes, rest and
        // disturbance detectors) would take in an absurd value. `≤` is false for NaN.
        let (acc, acc_dir_ok) = sample.acc.try_normalize();
        let acc_unit_ok = acc_dir_ok & sample.acc.norm_squared().simd_le(T::splat(bounds.max_acc2));
        let acc_ok = acc_unit_ok & step;
        // Almost every sample passes in every lane: one test of the mask every rejection
        // clears stands for the three counts and their flags.
        counts.last = if (!acc_ok).any() {
            let flags: SampleFlags<T> = SampleFlags {
                dt: !dt_ok,
                gyr: dt_ok & !gyr_ok,
                acc: step & !acc_unit_ok,
                ..SampleFlags::default()
            };
            T::count(&mut counts.dt, flags.dt);
            T::count(&mut counts.gyr, flags.gyr);
            T::count(&mut counts.acc, flags.acc);
            flags
        } else {
            SampleFlags::default()
        };

        let up = Vec3::new(zero, zero, T::one());
        let north = Vec3::new(zero, T::one(), zero);
        let (mag_ok, mag, mag_norm) = if with_mag {
            let (mag, mag_dir_ok) = sample.mag.try_normalize();
            let mag_unit_ok =
                mag_dir_ok & sample.mag.norm_squared().simd_le(T::splat(bounds.max_mag2));
            let mag_ok = mag_unit_ok & step;
            (
                mag_ok,
                Vec3::select(mag_ok, mag, north),
                T::select(mag_ok, sample.mag.norm(), zero),
            )
        } else {
            (<T::Mask as Mask>::splat(false), north, zero)
        };
        Self {
            step,
            gyr: Vec3::select(step, sample.gyr, Vec3::zero()),
            dt: T::select(step, dt, zero),
            acc_ok,
            acc: Vec3::select(acc_ok, acc, up),
            acc_norm: T::select(acc_ok, sample.acc.norm(), zero),
            mag_ok,
            mag,
            mag_norm,
        }
    }

    /// Screens `sample` for a filter running in 9D (`nine_d`: an unusable magnetometer is
    /// counted) or 6D (the magnetometer is ignored, uncounted: it is not even normalised).
    #[inline(always)]
    pub fn for_dof(
        sample: &ImuSample<T>,
        dt: T,
        bounds: &ScreenBounds<T>,
        counts: &mut Rejections<T>,
        nine_d: bool,
    ) -> Self {
        let s = Self::screen(sample, dt, bounds, counts, nine_d);
        if nine_d {
            s.count_mag(counts);
        }
        s
    }

    /// Marks the magnetometer unusable (6D operation) without counting it.
    pub fn without_mag(mut self) -> Self {
        self.mag_ok = <T::Mask as Mask>::splat(false);
        self
    }

    /// Counts a 9D magnetometer rejection for usable samples without a usable field.
    pub fn count_mag(&self, counts: &mut Rejections<T>) {
        let skipped = self.step & !self.mag_ok;
        T::count(&mut counts.mag, skipped);
        counts.last.mag = skipped;
    }
}
