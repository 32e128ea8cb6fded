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

pub use crate::blocks::STANDARD_GRAVITY;

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
/// filters' unit); its text form lists every sensor. Each sensor remembers whether its unit
/// was given ([`is_declared`](Self::is_declared)): `gyro=rad/s` is the default's factor, but
/// a statement that the readings are in rad/s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Units {
    units: [Unit; 4],
    declared: [bool; 4],
}

impl Default for Units {
    fn default() -> Self {
        Self {
            units: Sensor::ALL.map(Sensor::si),
            declared: [false; 4],
        }
    }
}

impl Units {
    /// The unit of `sensor`.
    pub fn get(&self, sensor: Sensor) -> Unit {
        self.units[sensor as usize]
    }

    /// Sets the unit of its sensor (which then counts as declared).
    pub fn set(&mut self, unit: Unit) {
        self.units[unit.sensor as usize] = unit;
        self.declared[unit.sensor as usize] = true;
    }

    /// True when the unit of `sensor` was given (by [`set`](Self::set) or in the list read),
    /// not left at the filters' own by default.
    ///
    /// ```
    /// use rootfuse_attitude::units::{Sensor, Units};
    /// let units: Units = "gyro=rad/s".parse().unwrap();
    /// assert!(units.is_declared(Sensor::Gyroscope) && units.get(Sensor::Gyroscope).is_si());
    /// assert!(!units.is_declared(Sensor::Time));
    /// ```
    pub fn is_declared(&self, sensor: Sensor) -> bool {
        self.declared[sensor as usize]
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

// What the data suggest: magnitude histograms, the tilt test, findings.
mod check;
mod histogram;
pub use check::{CHECK_SAMPLES, DECIDED_SAMPLES, MAX_PLAUSIBLE_RATE, UnitCheck, UnitFinding};
