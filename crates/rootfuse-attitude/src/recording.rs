//! Whole recordings in `f64`: what the CSV reader and the simulator produce and the metrics
//! and the CLI consume.

use crate::filters::OrientationFilter;
use crate::quat::Quat;
use crate::sample::ImuSample;
use crate::vec3::Vec3;
use rootfuse_lane::Lane;
use std::string::String;
use std::vec::Vec;

/// A recording of one IMU, column-wise, in `f64`, in the conventions of this crate.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Recording {
    /// A name for reports (file stem or scenario name).
    pub name: String,
    /// Sample times, s, strictly increasing.
    pub t: Vec<f64>,
    /// Angular rate, rad/s, sensor frame.
    pub gyr: Vec<Vec3<f64>>,
    /// Specific force, m/s², sensor frame.
    pub acc: Vec<Vec3<f64>>,
    /// Magnetic field, sensor frame; `None` for a 6D recording.
    pub mag: Option<Vec<Vec3<f64>>>,
    /// Ground-truth orientation (sensor to earth, ENU); NaN where unknown.
    pub truth: Option<Vec<Quat<f64>>>,
    /// Which samples count for error evaluation (BROAD's `use` column); all when `None`.
    pub use_mask: Option<Vec<bool>>,
}

impl Recording {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }
    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
    /// The samples in `range` (indices) as a recording of their own, with the same name:
    /// a stretch to score or align on its own.
    ///
    /// # Panics
    /// When `range` is not within `0..len()`, as slice indexing does.
    ///
    /// ```
    /// # use rootfuse_attitude::{Recording, Vec3};
    /// let still = vec![Vec3::new(0.0, 0.0, 0.0); 3];
    /// let gravity = vec![Vec3::new(0.0, 0.0, 9.81); 3];
    /// let rec = Recording { t: vec![0.0, 0.01, 0.02], gyr: still, acc: gravity, ..Recording::default() };
    /// assert_eq!(rec.slice(1..3).t, [0.01, 0.02]);
    /// assert_eq!(rec.slice(1..3).acc.len(), 2);
    /// ```
    pub fn slice(&self, range: core::ops::Range<usize>) -> Recording {
        Recording {
            name: self.name.clone(),
            t: self.t[range.clone()].to_vec(),
            gyr: self.gyr[range.clone()].to_vec(),
            acc: self.acc[range.clone()].to_vec(),
            mag: self.mag.as_ref().map(|v| v[range.clone()].to_vec()),
            truth: self.truth.as_ref().map(|v| v[range.clone()].to_vec()),
            use_mask: self.use_mask.as_ref().map(|v| v[range].to_vec()),
        }
    }

    /// Sample `i` (NaN magnetometer for a 6D recording).
    pub fn sample(&self, i: usize) -> ImuSample<f64> {
        match &self.mag {
            Some(mag) => ImuSample::new(self.gyr[i], self.acc[i], mag[i]),
            None => ImuSample::six_d(self.gyr[i], self.acc[i]),
        }
    }
    /// Runs `filter` over every sample in order and returns its orientation after each one,
    /// in `f64`. Samples and steps are converted to `T` (`f32`: rounded once); with a SIMD `T`
    /// every lane gets the same sample and lane 0 is returned.
    ///
    /// ```
    /// use rootfuse_attitude::filters::{Mahony, MahonyParams};
    /// use rootfuse_attitude::{Recording, Vec3};
    /// // 1 s level and at rest, sampled at 100 Hz, with a magnetometer (9D).
    /// let n = 100;
    /// let rec = Recording {
    ///     name: "rest".into(),
    ///     t: (0..n).map(|i| i as f64 * 0.01).collect(),
    ///     gyr: vec![Vec3::zero(); n],
    ///     acc: vec![Vec3::new(0.0, 0.0, 9.81); n],
    ///     mag: Some(vec![Vec3::new(0.0, 20.0, -40.0); n]),
    ///     ..Default::default()
    /// };
    /// let est = rec.estimate(&mut Mahony::<f32>::new(&MahonyParams::default()));
    /// assert_eq!(est.len(), rec.len());
    /// ```
    pub fn estimate<T: Lane>(&self, filter: &mut impl OrientationFilter<T>) -> Vec<Quat<f64>> {
        let mut out = Vec::with_capacity(self.len());
        self.run(filter, |f| {
            let q = f.quat().lane(0);
            out.push(Quat::new(q.w.into(), q.x.into(), q.y.into(), q.z.into()));
        });
        out
    }
    /// Runs `filter` over every sample in order, converted as by
    /// [`estimate`](Self::estimate), and calls `each` with it after every update (where
    /// only the final state is wanted, `|_| ()`).
    ///
    /// ```
    /// use rootfuse_attitude::filters::{Mahony, MahonyParams};
    /// use rootfuse_attitude::{OrientationFilter, Recording, Vec3};
    /// let rec = Recording {
    ///     t: vec![0.0, 0.01, 0.02],
    ///     gyr: vec![Vec3::zero(); 3],
    ///     acc: vec![Vec3::new(0.0, 0.0, 9.81); 3],
    ///     ..Default::default()
    /// };
    /// let mut filter = Mahony::<f64>::new(&MahonyParams::default());
    /// let mut updates = 0;
    /// rec.run(&mut filter, |_| updates += 1);
    /// assert_eq!(updates, 3);
    /// assert!((filter.quat().norm() - 1.0).abs() < 1e-12);
    /// ```
    pub fn run<T: Lane, F: OrientationFilter<T>>(&self, filter: &mut F, mut each: impl FnMut(&F)) {
        let v = |x: Vec3<f64>| Vec3::<T>::from_f64([x.x, x.y, x.z]);
        for i in 0..self.len() {
            let s = self.sample(i);
            filter.update(
                &ImuSample::new(v(s.gyr), v(s.acc), v(s.mag)),
                T::from_f64(self.dt(i)),
            );
            each(filter);
        }
    }
    /// Time step before sample `i`, s (the first sample uses the second interval).
    pub fn dt(&self, i: usize) -> f64 {
        match i {
            _ if self.t.len() < 2 => 0.0,
            0 => self.t[1] - self.t[0],
            _ => self.t[i] - self.t[i - 1],
        }
    }
}
