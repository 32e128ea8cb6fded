//! Units of IMU readings: the units a file is declared to be in ([`Units`], converted to the
//! filters' units on read) and the units its data suggest ([`UnitCheck`]), so that a
//! recording in °/s, g, milliseconds or nanotesla is converted when declared and named when
//! not, instead of being filtered as if it were in rad/s, m/s², seconds and µT.
//!
//! The filters' units: time in s, angular rate in rad/s, specific force in m/s², magnetic
//! field in µT (the filters use the field's direction; its unit matters to the screening limit
//! `max_mag` and to the disturbance detectors).
//!
//! ```
//! use rootfuse_attitude::units::{Sensor, UnitCheck, Units};
//! use rootfuse_attitude::Vec3;
//!
//! // A file with time in ms, gyroscope in °/s, accelerometer in g:
//! let units: Units = "time=ms,gyro=deg/s,acc=g".parse().unwrap();
//! assert_eq!(units.get(Sensor::Time).factor(), 1e-3);
//! assert_eq!(units.to_string(), "time=ms,gyro=deg/s,acc=g,mag=uT");
//!
//! // Readings in g checked against the default (m/s²) units:
//! let mut check = UnitCheck::new(&Units::default());
//! for i in 0..500 {
//!     let t = i as f64 * 0.01;
//!     check.add(t, Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.0, 0.01, 1.0), None);
//! }
//! let findings = check.findings();
//! assert_eq!(findings.len(), 1);
//! assert_eq!(findings[0].sensor, Sensor::Accelerometer);
//! assert_eq!(findings[0].likely.map(|u| u.to_string()), Some("g".to_string()));
//! ```

use crate::Vec3;
use core::fmt;
use std::format;
use std::string::{String, ToString};
use std::vec::Vec;

/// Standard gravity, m/s² (the `g` of `acc=g`).
pub const STANDARD_GRAVITY: f64 = 9.80665;

/// One of the quantities a recording carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Sensor {
    /// Sample time (the filters' unit: s).
    Time,
    /// Angular rate (rad/s).
    Gyroscope,
    /// Specific force (m/s²).
    Accelerometer,
    /// Magnetic field (µT).
    Magnetometer,
}

impl Sensor {
    /// Every sensor, in the order of [`Units`]' text form.
    pub const ALL: [Sensor; 4] = [
        Sensor::Time,
        Sensor::Gyroscope,
        Sensor::Accelerometer,
        Sensor::Magnetometer,
    ];

    /// The key in a units list (`time`, `gyro`, `acc`, `mag`).
    pub fn key(self) -> &'static str {
        match self {
            Sensor::Time => "time",
            Sensor::Gyroscope => "gyro",
            Sensor::Accelerometer => "acc",
            Sensor::Magnetometer => "mag",
        }
    }

    /// The name in messages (`time`, `gyroscope`, …).
    pub fn name(self) -> &'static str {
        match self {
            Sensor::Time => "time",
            Sensor::Gyroscope => "gyroscope",
            Sensor::Accelerometer => "accelerometer",
            Sensor::Magnetometer => "magnetometer",
        }
    }

    /// The filters' unit of this quantity.
    pub fn si(self) -> Unit {
        NAMED
            .iter()
            .find(|n| n.sensor == self)
            .map(|n| Unit {
                sensor: self,
                name: Some(n.names[0]),
                factor: n.factor,
            })
            .unwrap_or(Unit {
                sensor: self,
                name: None,
                factor: 1.0,
            })
    }

    fn from_key(key: &str) -> Option<Sensor> {
        match key {
            "time" | "t" => Some(Sensor::Time),
            "gyro" | "gyr" | "gyroscope" => Some(Sensor::Gyroscope),
            "acc" | "accel" | "accelerometer" => Some(Sensor::Accelerometer),
            "mag" | "magnetometer" => Some(Sensor::Magnetometer),
            _ => None,
        }
    }
}

/// A named unit: the names it is written with (the first is how it is shown) and its factor to
/// the filters' unit.
struct Named {
    sensor: Sensor,
    names: &'static [&'static str],
    factor: f64,
}

/// Every named unit; the first of each sensor is the filters' own.
const NAMED: &[Named] = &[
    Named {
        sensor: Sensor::Time,
        names: &["s"],
        factor: 1.0,
    },
    Named {
        sensor: Sensor::Time,
        names: &["ms"],
        factor: 1e-3,
    },
    Named {
        sensor: Sensor::Time,
        names: &["us", "µs", "μs"],
        factor: 1e-6,
    },
    Named {
        sensor: Sensor::Time,
        names: &["ns"],
        factor: 1e-9,
    },
    Named {
        sensor: Sensor::Gyroscope,
        names: &["rad/s"],
        factor: 1.0,
    },
    Named {
        sensor: Sensor::Gyroscope,
        names: &["deg/s", "dps", "°/s"],
        factor: core::f64::consts::PI / 180.0,
    },
    Named {
        sensor: Sensor::Accelerometer,
        names: &["m/s2", "m/s^2", "m/s²"],
        factor: 1.0,
    },
    Named {
        sensor: Sensor::Accelerometer,
        names: &["g"],
        factor: STANDARD_GRAVITY,
    },
    Named {
        sensor: Sensor::Accelerometer,
        names: &["mg"],
        factor: STANDARD_GRAVITY * 1e-3,
    },
    Named {
        sensor: Sensor::Magnetometer,
        names: &["uT", "µT", "μT"],
        factor: 1.0,
    },
    Named {
        sensor: Sensor::Magnetometer,
        names: &["nT"],
        factor: 1e-3,
    },
    Named {
        sensor: Sensor::Magnetometer,
        names: &["G", "gauss"],
        factor: 100.0,
    },
    Named {
        sensor: Sensor::Magnetometer,
        names: &["mG", "mgauss"],
        factor: 0.1,
    },
];

/// The unit of one sensor's readings: a named unit (`deg/s`, `g`, `ms`, `nT`, …) or a plain
/// factor (raw counts: `acc=0.000598` multiplies each reading by 0.000598 to get m/s²).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Unit {
    sensor: Sensor,
    name: Option<&'static str>,
    factor: f64,
}

impl Unit {
    /// What a reading is multiplied by to be in the filters' unit.
    pub fn factor(self) -> f64 {
        self.factor
    }

    /// The sensor it belongs to.
    pub fn sensor(self) -> Sensor {
        self.sensor
    }

    /// True for the filters' own unit (nothing to convert).
    pub fn is_si(self) -> bool {
        self.factor == 1.0
    }

    /// The unit named `text` for `sensor` (any of its spellings; case-insensitive but for
    /// the magnetometer's `mG`), or a positive finite factor.
    pub fn parse(sensor: Sensor, text: &str) -> Option<Unit> {
        let text = text.trim();
        let named = NAMED.iter().filter(|n| n.sensor == sensor).find(|n| {
            n.names.iter().any(|name| {
                *name == text || (sensor != Sensor::Magnetometer && name.eq_ignore_ascii_case(text))
            })
        });
        if let Some(n) = named {
            return Some(Unit {
                sensor,
                name: Some(n.names[0]),
                factor: n.factor,
            });
        }
        text.parse::<f64>()
            .ok()
            .filter(|f| f.is_finite() && *f > 0.0)
            .map(|factor| Unit {
                sensor,
                name: None,
                factor,
            })
    }

    /// The spellings a sensor's units are written with, for messages.
    pub fn names(sensor: Sensor) -> String {
        let names: Vec<&str> = NAMED
            .iter()
            .filter(|n| n.sensor == sensor)
            .map(|n| n.names[0])
            .collect();
        names.join(", ")
    }
}

impl fmt::Display for Unit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.name {
            Some(name) => f.write_str(name),
            None => write!(f, "{}", self.factor),
        }
    }
}

/// Why a units list could not be read.
#[derive(Clone, Debug, PartialEq)]
pub enum UnitsError {
    /// An entry is not `sensor=unit`.
    Syntax(String),
    /// The sensor is not one of `time`, `gyro`, `acc`, `mag`.
    UnknownSensor(String),
    /// The unit is not one of the sensor's, nor a positive finite factor.
    UnknownUnit {
        /// The sensor.
        sensor: Sensor,
        /// The unit as written.
        unit: String,
    },
    /// A sensor is given twice.
    Repeated {
        /// The sensor.
        sensor: Sensor,
        /// The first entry.
        first: String,
        /// The second entry.
        second: String,
    },
}

impl fmt::Display for UnitsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            UnitsError::Syntax(entry) => write!(
                f,
                "units: `{entry}` is not sensor=unit (for example time=ms,gyro=deg/s,acc=g,mag=nT)"
            ),
            UnitsError::UnknownSensor(key) => {
                write!(f, "units: unknown sensor `{key}` (time, gyro, acc or mag)")
            }
            UnitsError::UnknownUnit { sensor, unit } => write!(
                f,
                "units: `{unit}` is no unit of {} ({}, or a positive factor to {})",
                sensor.key(),
                Unit::names(*sensor),
                sensor.si()
            ),
            UnitsError::Repeated {
                sensor,
                first,
                second,
            } => write!(
                f,
                "units: {} given twice ({first} and {second}); give it once",
                sensor.key()
            ),
        }
    }
}

impl std::error::Error for UnitsError {}

/// The units of a recording's time, gyroscope, accelerometer and magnetometer, each with its
/// factor to the filters' units (s, rad/s, m/s², µT, the default).
///
/// Read from a list like `time=ms,gyro=deg/s,acc=g,mag=nT` (sensors left out keep the
/// filters' unit); its text form lists every sensor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Units {
    units: [Unit; 4],
}

impl Default for Units {
    fn default() -> Self {
        Self {
            units: Sensor::ALL.map(Sensor::si),
        }
    }
}

impl Units {
    /// The unit of `sensor`.
    pub fn get(&self, sensor: Sensor) -> Unit {
        self.units[sensor as usize]
    }

    /// Sets the unit of its sensor.
    pub fn set(&mut self, unit: Unit) {
        self.units[unit.sensor as usize] = unit;
    }

    /// True when every unit is the filters' own (reading converts nothing).
    pub fn is_si(&self) -> bool {
        self.units.iter().all(|u| u.is_si())
    }

    /// Converts readings in place to the filters' units.
    pub fn convert(
        &self,
        t: &mut [f64],
        gyr: &mut [Vec3<f64>],
        acc: &mut [Vec3<f64>],
        mag: Option<&mut [Vec3<f64>]>,
    ) {
        let scale = |values: &mut [Vec3<f64>], unit: Unit| {
            if !unit.is_si() {
                for v in values {
                    *v = *v * unit.factor;
                }
            }
        };
        let time = self.get(Sensor::Time);
        if !time.is_si() {
            for v in t {
                *v *= time.factor;
            }
        }
        scale(gyr, self.get(Sensor::Gyroscope));
        scale(acc, self.get(Sensor::Accelerometer));
        if let Some(mag) = mag {
            scale(mag, self.get(Sensor::Magnetometer));
        }
    }

    /// Converts a whole recording in place (its truth and `use` columns are unit-free).
    pub fn convert_recording(&self, rec: &mut crate::Recording) {
        self.convert(
            &mut rec.t,
            &mut rec.gyr,
            &mut rec.acc,
            rec.mag.as_deref_mut(),
        );
    }
}

impl core::str::FromStr for Units {
    type Err = UnitsError;

    fn from_str(list: &str) -> Result<Self, UnitsError> {
        let mut units = Units::default();
        let mut given: [Option<&str>; 4] = [None; 4];
        for entry in list.split(',').map(str::trim).filter(|e| !e.is_empty()) {
            let (key, unit) = entry
                .split_once('=')
                .ok_or_else(|| UnitsError::Syntax(entry.to_string()))?;
            let sensor = Sensor::from_key(key.trim().to_ascii_lowercase().as_str())
                .ok_or_else(|| UnitsError::UnknownSensor(key.trim().to_string()))?;
            if let Some(first) = given[sensor as usize] {
                return Err(UnitsError::Repeated {
                    sensor,
                    first: first.to_string(),
                    second: entry.to_string(),
                });
            }
            given[sensor as usize] = Some(entry);
            units.set(
                Unit::parse(sensor, unit).ok_or_else(|| UnitsError::UnknownUnit {
                    sensor,
                    unit: unit.trim().to_string(),
                })?,
            );
        }
        Ok(units)
    }
}

impl fmt::Display for Units {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, unit) in self.units.iter().enumerate() {
            let sep = if i == 0 { "" } else { "," };
            write!(f, "{sep}{}={unit}", unit.sensor.key())?;
        }
        Ok(())
    }
}

/// A magnitude's distribution in bins of a tenth of a decade from 1e-9 to 1e12, plus the
/// readings that were zero or not finite: enough to tell units apart (they differ by factors
/// of 10 to 1e9) in constant memory per channel.
#[derive(Clone, Debug)]
struct LogHistogram {
    bins: Vec<u32>,
    zero: u64,
    non_finite: u64,
}

const DECADE_BINS: f64 = 10.0;
const LOG_MIN: f64 = -9.0;
const LOG_MAX: f64 = 12.0;

impl LogHistogram {
    fn new() -> Self {
        Self {
            bins: std::vec![0; ((LOG_MAX - LOG_MIN) * DECADE_BINS) as usize],
            zero: 0,
            non_finite: 0,
        }
    }

    fn add(&mut self, x: f64) {
        if !x.is_finite() {
            self.non_finite += 1;
        } else if x == 0.0 {
            self.zero += 1;
        } else {
            let b = ((libm::log10(x.abs()) - LOG_MIN) * DECADE_BINS).floor();
            let b = b.clamp(0.0, (self.bins.len() - 1) as f64) as usize;
            self.bins[b] = self.bins[b].saturating_add(1);
        }
    }

    fn count(&self) -> u64 {
        self.bins.iter().map(|&c| u64::from(c)).sum()
    }

    /// The `q` quantile (0..1) of the non-zero finite values, at the centre of its bin.
    fn quantile(&self, q: f64) -> Option<f64> {
        let n = self.count();
        if n == 0 {
            return None;
        }
        let rank = (q * (n - 1) as f64).round() as u64;
        let mut seen = 0u64;
        for (b, &c) in self.bins.iter().enumerate() {
            seen += u64::from(c);
            if seen > rank {
                return Some(libm::pow(10.0, LOG_MIN + (b as f64 + 0.5) / DECADE_BINS));
            }
        }
        None
    }
}

/// The ranges in which a sensor's median magnitude is plausible, in the filters' units.
fn plausible(sensor: Sensor) -> (f64, f64) {
    match sensor {
        // 4 Hz to 10 kHz sampling.
        Sensor::Time => (1e-4, 0.25),
        // The median over any motion is within a few m/s² of g.
        Sensor::Accelerometer => (6.0, 14.0),
        // The geomagnetic field is 25–65 µT; indoors, near steel, 5–200 µT.
        Sensor::Magnetometer => (5.0, 200.0),
        // The median angular rate is no unit test: see `UnitCheck`.
        Sensor::Gyroscope => (0.0, f64::INFINITY),
    }
}

/// Fastest plausible angular rate, rad/s (2000 °/s, the range of common MEMS gyroscopes).
pub const MAX_PLAUSIBLE_RATE: f64 = 35.0;

/// Each channel's check stops after this many samples (the units do not change in a file).
pub const CHECK_SAMPLES: u64 = 200_000;

/// Duration (s) of a window of the gyroscope-unit test: long against the accelerometer's noise,
/// short against drift.
const WINDOW_SECONDS: f64 = 0.3;

/// Accelerometer samples averaged into one direction (centred, the gyroscope delayed to match).
const SMOOTH: usize = 5;

/// Time steps seen before the time unit is taken for the gyroscope-unit test.
const TIME_SAMPLES: u64 = 64;

/// Turn of the gravity direction (rad, summed over the test's windows) that must be seen
/// before the gyroscope's unit is judged from it: a few tens of degrees of tilting.
const MIN_TILT: f64 = 0.5;

/// Turn (rad) of the measured direction over a window for the window to be judged: above the
/// accelerometer's noise, so that still windows do not dilute the test.
const MIN_WINDOW_TURN: f64 = 0.02;

/// Share of the seen turn a unit's prediction must explain to fit.
const MIN_EXPLAINED: f64 = 0.25;

/// By how much more the best unit must explain than the declared one to be named instead.
const CLEARLY_BETTER: f64 = 0.2;

/// The gyroscope-unit test. Over windows of [`WINDOW_SECONDS`], the accelerometer's direction
/// (an average of [`SMOOTH`] samples) at the start is turned by the gyroscope's readings (as a
/// direction fixed in the earth turns in the sensor frame, `du/dt = u × ω`, exactly per sample)
/// under each candidate unit, and compared with the direction measured at the end. In the right
/// unit the prediction explains much of the turn (linear acceleration and noise the rest); in
/// one off by 57 it explains none. Windows whose |a| changes by more than 10 % (linear
/// acceleration) or that turn less than [`MIN_WINDOW_TURN`] (noise) are not judged.
#[derive(Clone, Debug)]
struct TiltTest {
    /// Each candidate unit and its factor from a raw reading × raw time step to radians.
    candidates: Vec<(Unit, f64)>,
    window: usize,
    /// The last [`SMOOTH`] accelerometer readings and gyroscope turns (raw rate × raw step).
    ring: [(Vec3<f64>, Vec3<f64>); SMOOTH],
    filled: usize,
    /// The measured direction and |a| at the window's start, and each candidate's prediction.
    start: Option<(Vec3<f64>, f64)>,
    predicted: Vec<Vec3<f64>>,
    len: usize,
    /// Σ angle(start, end) over judged windows, and per candidate Σ angle(prediction, end).
    turned: f64,
    missed: Vec<f64>,
}

impl TiltTest {
    /// The test of a gyroscope declared in `declared`, time in units of `time_factor` s,
    /// sampled every `dt` s.
    fn new(declared: Unit, time_factor: f64, dt: f64) -> Self {
        let mut candidates: Vec<(Unit, f64)> = Vec::new();
        let named = |n: &str| Unit::parse(Sensor::Gyroscope, n);
        for unit in [Some(declared), named("rad/s"), named("deg/s")]
            .into_iter()
            .flatten()
        {
            if !candidates.iter().any(|(u, _)| u.factor == unit.factor) {
                candidates.push((unit, unit.factor * time_factor));
            }
        }
        let n = candidates.len();
        let zero = Vec3::new(0.0, 0.0, 0.0);
        Self {
            candidates,
            window: libm::round(WINDOW_SECONDS / dt).clamp(10.0, 150.0) as usize,
            ring: [(zero, zero); SMOOTH],
            filled: 0,
            start: None,
            predicted: std::vec![zero; n],
            len: 0,
            turned: 0.0,
            missed: std::vec![0.0; n],
        }
    }

    fn add(&mut self, dt: f64, gyr: Vec3<f64>, acc: Vec3<f64>) {
        let turn = gyr * dt;
        if !(acc.norm().is_finite() && turn.norm().is_finite()) {
            self.filled = 0;
            self.start = None;
            return;
        }
        self.ring[self.filled % SMOOTH] = (acc, turn);
        self.filled += 1;
        if self.filled < SMOOTH {
            return;
        }
        // The average of the last SMOOTH readings stands for the middle one, whose turn the
        // gyroscope gives.
        let mean = self
            .ring
            .iter()
            .fold(Vec3::new(0.0, 0.0, 0.0), |s, r| s + r.0);
        let a = mean.norm();
        let turn = self.ring[(self.filled - 1 - SMOOTH / 2) % SMOOTH].1;
        if a.is_nan() || a <= 0.0 {
            self.start = None;
            return;
        }
        self.step(mean * (1.0 / a), a, turn);
    }

    fn step(&mut self, dir: Vec3<f64>, a: f64, turn: Vec3<f64>) {
        let Some((start, a0)) = self.start else {
            self.start = Some((dir, a));
            self.predicted.iter_mut().for_each(|p| *p = dir);
            self.len = 0;
            return;
        };
        for (p, (_, factor)) in self.predicted.iter_mut().zip(&self.candidates) {
            *p = turned(*p, turn * *factor);
        }
        self.len += 1;
        if self.len < self.window {
            return;
        }
        let seen = angle(start, dir);
        if (a / a0 - 1.0).abs() < 0.1 && seen > MIN_WINDOW_TURN {
            self.turned += seen;
            for (m, p) in self.missed.iter_mut().zip(&self.predicted) {
                *m += angle(*p, dir);
            }
        }
        self.start = Some((dir, a));
        self.predicted.iter_mut().for_each(|p| *p = dir);
        self.len = 0;
    }

    /// The share of the seen turn each candidate explains (the declared unit first), when
    /// enough turn was seen.
    fn explained(&self) -> Option<Vec<(Unit, f64)>> {
        (self.turned >= MIN_TILT).then(|| {
            self.candidates
                .iter()
                .zip(&self.missed)
                .map(|((u, _), m)| (*u, 1.0 - m / self.turned))
                .collect()
        })
    }
}

/// `u` turned as a direction fixed in the earth turns in the sensor frame while the sensor
/// turns by the rotation vector `theta` (rad): by `−theta` (Rodrigues).
fn turned(u: Vec3<f64>, theta: Vec3<f64>) -> Vec3<f64> {
    let phi = theta.norm();
    if phi < 1e-12 {
        return u + u.cross(theta);
    }
    let k = theta * (1.0 / phi);
    let (sin, cos) = (libm::sin(phi), libm::cos(phi));
    u * cos + u.cross(k) * sin + k * (k.dot(u) * (1.0 - cos))
}

/// The angle between two unit vectors, rad.
fn angle(a: Vec3<f64>, b: Vec3<f64>) -> f64 {
    libm::atan2(a.cross(b).norm(), a.dot(b))
}

/// What the data of one channel say about its units, sample by sample, in constant memory: the
/// median time step, the median magnitudes of the accelerometer and magnetometer, and how fast
/// the gyroscope says the gravity direction turns against how fast it turns.
///
/// Feed it raw readings, as in the file, with [`add`](Self::add); [`findings`](Self::findings)
/// names every sensor whose readings do not fit the declared unit, with the unit they fit.
#[derive(Clone, Debug)]
pub struct UnitCheck {
    declared: Units,
    samples: u64,
    previous_t: f64,
    dt: LogHistogram,
    acc: LogHistogram,
    mag: LogHistogram,
    gyr: LogHistogram,
    /// The gyroscope-unit test, started once the time unit is known.
    tilt: Option<TiltTest>,
}

impl UnitCheck {
    /// A check of readings declared in `declared`.
    pub fn new(declared: &Units) -> Self {
        Self {
            declared: *declared,
            samples: 0,
            previous_t: f64::NAN,
            dt: LogHistogram::new(),
            acc: LogHistogram::new(),
            mag: LogHistogram::new(),
            gyr: LogHistogram::new(),
            tilt: None,
        }
    }

    /// Adds one sample's raw readings (time, angular rate, specific force, field as in the
    /// file; `mag` `None` for a 6D sample). Samples beyond [`CHECK_SAMPLES`] are ignored.
    pub fn add(&mut self, t: f64, gyr: Vec3<f64>, acc: Vec3<f64>, mag: Option<Vec3<f64>>) {
        if self.samples >= CHECK_SAMPLES {
            return;
        }
        self.samples += 1;
        let dt = t - self.previous_t;
        if dt.is_finite() && dt > 0.0 {
            self.dt.add(dt);
        }
        self.previous_t = t;
        let a = acc.norm();
        self.acc.add(a);
        self.gyr.add(gyr.norm());
        if let Some(m) = mag {
            self.mag.add(m.norm());
        }
        if self.tilt.is_none()
            && self.dt.count() >= TIME_SAMPLES
            && let Some(median) = self.dt.quantile(0.5)
        {
            let time_factor = self.time_factor();
            self.tilt = Some(TiltTest::new(
                self.declared.get(Sensor::Gyroscope),
                time_factor,
                median * time_factor,
            ));
        }
        if let Some(tilt) = &mut self.tilt
            && dt > 0.0
        {
            tilt.add(dt, gyr, acc);
        }
    }

    /// [`add`](Self::add) for readings already converted from the declared units to the
    /// filters' (what a reader given the declared units returns): the readings as written are
    /// recovered by dividing by each unit's factor.
    pub fn add_si(&mut self, t: f64, gyr: Vec3<f64>, acc: Vec3<f64>, mag: Option<Vec3<f64>>) {
        let raw = |s: Sensor| 1.0 / self.declared.get(s).factor;
        let (ft, fg, fa, fm) = (
            raw(Sensor::Time),
            raw(Sensor::Gyroscope),
            raw(Sensor::Accelerometer),
            raw(Sensor::Magnetometer),
        );
        self.add(t * ft, gyr * fg, acc * fa, mag.map(|m| m * fm));
    }

    /// The findings of a whole recording, already converted to the filters' units from the
    /// `declared` ones (as [`Units::convert_recording`] or a reader with units leaves it).
    pub fn of_recording(rec: &crate::Recording, declared: &Units) -> Vec<UnitFinding> {
        let mut check = UnitCheck::new(declared);
        for i in 0..rec.len() {
            let mag = rec.mag.as_ref().map(|m| m[i]);
            check.add_si(rec.t[i], rec.gyr[i], rec.acc[i], mag);
        }
        check.findings()
    }

    /// Samples added (at most [`CHECK_SAMPLES`]).
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// The unit `sensor`'s readings fit, when the data decide it: the declared one when its
    /// median magnitude is plausible, else the one named unit that makes it so.
    fn fit(&self, sensor: Sensor, hist: &LogHistogram) -> Fit {
        const MIN_READINGS: u64 = 50;
        if hist.count() < MIN_READINGS {
            return Fit::Undecided;
        }
        let Some(median) = hist.quantile(0.5) else {
            return Fit::Undecided;
        };
        let (lo, hi) = plausible(sensor);
        let in_range = |unit: Unit| (lo..=hi).contains(&(median * unit.factor));
        let declared = self.declared.get(sensor);
        if in_range(declared) {
            return Fit::Declared;
        }
        // Of the named units that fit, the one that puts the median nearest the middle of the
        // plausible range (in decades).
        let middle = libm::sqrt(lo * hi);
        let best = NAMED
            .iter()
            .filter(|n| n.sensor == sensor)
            .map(|n| Unit {
                sensor,
                name: Some(n.names[0]),
                factor: n.factor,
            })
            .filter(|&u| in_range(u))
            .min_by(|a, b| {
                let d = |u: Unit| libm::fabs(libm::log10(median * u.factor / middle));
                d(*a).total_cmp(&d(*b))
            });
        Fit::Other(median, best)
    }

    /// The time unit the data fit (the declared one when it is plausible or undecided).
    fn time_factor(&self) -> f64 {
        match self.fit(Sensor::Time, &self.dt) {
            Fit::Other(_, Some(unit)) => unit.factor,
            _ => self.declared.get(Sensor::Time).factor,
        }
    }

    /// Every sensor whose readings do not fit its declared unit.
    pub fn findings(&self) -> Vec<UnitFinding> {
        let mut out = Vec::new();
        for (sensor, hist, what) in [
            (Sensor::Time, &self.dt, "median time step"),
            (Sensor::Accelerometer, &self.acc, "median |a|"),
            (Sensor::Magnetometer, &self.mag, "median |m|"),
        ] {
            let declared = self.declared.get(sensor);
            let readings = hist.count() + hist.zero + hist.non_finite;
            if sensor != Sensor::Time && readings > 0 && hist.count() == 0 {
                out.push(UnitFinding {
                    sensor,
                    declared,
                    likely: None,
                    dead: true,
                    evidence: format!(
                        "every reading ({readings}) is {}",
                        if hist.non_finite == 0 {
                            "zero"
                        } else {
                            "zero or not a number"
                        }
                    ),
                });
                continue;
            }
            if let Fit::Other(median, likely) = self.fit(sensor, hist) {
                let (lo, hi) = plausible(sensor);
                let si = sensor.si();
                out.push(UnitFinding {
                    sensor,
                    declared,
                    likely,
                    dead: false,
                    evidence: if declared.is_si() {
                        format!(
                            "the {what} is {} {si}, not within {lo}–{hi} {si}",
                            short(median)
                        )
                    } else {
                        format!(
                            "the {what} is {} {declared} ({} {si}), not within {lo}–{hi} {si}",
                            short(median),
                            short(median * declared.factor)
                        )
                    },
                });
            }
        }
        if let Some(f) = self.gyro_finding() {
            out.push(f);
        }
        out
    }

    fn gyro_finding(&self) -> Option<UnitFinding> {
        let declared = self.declared.get(Sensor::Gyroscope);
        let readings = self.gyr.count() + self.gyr.zero + self.gyr.non_finite;
        if readings > 0 && self.gyr.count() + self.gyr.zero == 0 {
            return Some(UnitFinding {
                sensor: Sensor::Gyroscope,
                declared,
                likely: None,
                dead: true,
                evidence: format!("no reading ({readings}) is a number"),
            });
        }
        let deg = Unit::parse(Sensor::Gyroscope, "deg/s")?;
        // The unit that explains the most of the tilting, if one explains enough of it (much
        // linear acceleration leaves the test undecided).
        let tilt = self
            .tilt
            .as_ref()
            .and_then(TiltTest::explained)
            .and_then(|explained| {
                let best = explained
                    .iter()
                    .copied()
                    .max_by(|a, b| a.1.total_cmp(&b.1))
                    .filter(|(_, share)| *share >= MIN_EXPLAINED)?;
                Some((explained[0].1, best))
            });
        if let Some((declared_share, best)) = tilt {
            if best.1 < declared_share + CLEARLY_BETTER {
                return None;
            }
            let turned = self.tilt.as_ref().map_or(0.0, |t| t.turned);
            return Some(UnitFinding {
                sensor: Sensor::Gyroscope,
                declared,
                likely: Some(best.0),
                dead: false,
                evidence: format!(
                    "as {declared} its readings explain {:.0} % of the {} rad the gravity direction turned, as {} {:.0} %",
                    100.0 * declared_share.max(0.0),
                    short(turned),
                    best.0,
                    100.0 * best.1,
                ),
            });
        }
        // Too little tilting to tell: only rates no gyroscope measures give the unit away.
        let fast = self.gyr.quantile(0.999)? * declared.factor;
        (fast > MAX_PLAUSIBLE_RATE).then(|| UnitFinding {
            sensor: Sensor::Gyroscope,
            declared,
            likely: (declared != deg).then_some(deg),
            dead: false,
            evidence: format!(
                "as {declared}, 0.1 % of its readings exceed {} rad/s, faster than a gyroscope measures ({MAX_PLAUSIBLE_RATE} rad/s)",
                short(fast)
            ),
        })
    }
}

enum Fit {
    /// Too few readings to tell.
    Undecided,
    /// The declared unit fits.
    Declared,
    /// It does not: the median seen and the named unit that fits, if any.
    Other(f64, Option<Unit>),
}

/// Three significant digits, for messages.
fn short(x: f64) -> String {
    let s = format!("{x:.3e}");
    // Plain notation between 0.001 and 1e5 reads better.
    if (1e-3..1e5).contains(&x.abs()) {
        let digits = (2 - libm::floor(libm::log10(x.abs())) as i32).max(0) as usize;
        format!("{x:.digits$}")
    } else {
        s
    }
}

/// A sensor whose readings do not fit the unit they were declared in.
#[derive(Clone, Debug, PartialEq)]
pub struct UnitFinding {
    /// The sensor.
    pub sensor: Sensor,
    /// The unit it was declared in (the filters' own unless given).
    pub declared: Unit,
    /// The named unit its readings fit, if one does.
    pub likely: Option<Unit>,
    /// What was seen, in words.
    pub evidence: String,
    /// The sensor gave no usable reading at all (every one zero or not a number): no unit
    /// is in question.
    pub dead: bool,
}

impl fmt::Display for UnitFinding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.sensor.name(), self.evidence)?;
        match self.likely {
            _ if self.dead => Ok(()),
            Some(unit) => write!(f, "; the readings look like {unit}"),
            None => write!(f, "; no unit fits (raw counts?)"),
        }
    }
}

impl UnitFinding {
    /// The units entry that declares what the readings look like (`gyro=deg/s`), or the form
    /// of one when no named unit fits (`gyro=<factor to rad/s>`).
    pub fn declaration(&self) -> String {
        match self.likely {
            Some(unit) => format!("{}={unit}", self.sensor.key()),
            None => format!("{}=<factor to {}>", self.sensor.key(), self.sensor.si()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_round_trip_and_refuse_what_they_cannot_read() {
        let u: Units = "acc=g, gyro=dps,time=us,mag=gauss".parse().unwrap();
        assert_eq!(u.to_string(), "time=us,gyro=deg/s,acc=g,mag=G");
        assert_eq!(u.to_string().parse::<Units>().unwrap(), u);
        assert_eq!(u.get(Sensor::Magnetometer).factor(), 100.0);
        let counts: Units = "acc=0.000598".parse().unwrap();
        assert_eq!(counts.get(Sensor::Accelerometer).factor(), 0.000598);
        assert_eq!(counts.to_string(), "time=s,gyro=rad/s,acc=0.000598,mag=uT");
        assert!(Units::default().is_si());
        assert_eq!(
            "acc=g,acc=m/s2".parse::<Units>().unwrap_err().to_string(),
            "units: acc given twice (acc=g and acc=m/s2); give it once"
        );
        assert!(matches!(
            "gyro=furlongs".parse::<Units>(),
            Err(UnitsError::UnknownUnit { .. })
        ));
        assert!(matches!(
            "acc=-1".parse::<Units>(),
            Err(UnitsError::UnknownUnit { .. })
        ));
        assert!(matches!(
            "speed=1".parse::<Units>(),
            Err(UnitsError::UnknownSensor(_))
        ));
        assert!(matches!("acc".parse::<Units>(), Err(UnitsError::Syntax(_))));
        // The magnetometer's mG and G differ by case; the accelerometer's g and mg do not.
        assert_eq!(
            Unit::parse(Sensor::Magnetometer, "mG").unwrap().factor(),
            0.1
        );
        assert!(Unit::parse(Sensor::Magnetometer, "mg").is_none());
        assert_eq!(
            Unit::parse(Sensor::Accelerometer, "G").unwrap().factor(),
            STANDARD_GRAVITY
        );
    }

    #[test]
    fn histogram_quantiles_are_within_a_bin() {
        let mut h = LogHistogram::new();
        for i in 1..=1001 {
            h.add(i as f64);
        }
        let median = h.quantile(0.5).unwrap();
        assert!((median / 501.0 - 1.0).abs() < 0.13, "{median}");
        h.add(0.0);
        h.add(f64::NAN);
        assert_eq!((h.count(), h.zero, h.non_finite), (1001, 1, 1));
    }
}
