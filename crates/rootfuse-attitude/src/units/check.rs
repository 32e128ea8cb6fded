//! The units a recording's data suggest ([`UnitCheck`]): magnitude histograms per sensor,
//! a time-step check and, for the gyroscope, a test against the accelerometer's tilt.

use super::histogram::LogHistogram;
use super::*;

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

/// A check stops earlier, once it has this many samples and its gyroscope test has seen
/// `DECIDED_TURN` (10 rad) of tilting (or of the magnetic field's turning, where a unit
/// explains it): every median then sits in its bin and the gyroscope's explained shares
/// average hundreds of windows, so more samples of the same file change no finding, and a
/// long fleet channel no longer pays the check at every sample (it cost a fifth of
/// `rootfuse run` on a fleet of 10-minute devices).
pub const DECIDED_SAMPLES: u64 = 10_000;

/// Tilting (rad, summed over judged windows) that, with [`DECIDED_SAMPLES`], ends a check:
/// twenty times what the gyroscope test needs to judge at all.
const DECIDED_TURN: f64 = 20.0 * MIN_TILT;

/// How often (in samples) a check asks whether it has decided.
const DECIDED_EVERY: u64 = 1024;

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
///
/// The magnetic field's direction is fixed in the earth too: the same test on the
/// magnetometer's readings judges the gyroscope where the gravity direction hardly turns (a
/// vehicle or turntable turning about the vertical). A disturbed field changes |m| (such
/// windows are not judged) or explains less under every unit (undecided, never wrong: a unit
/// 57 times too small predicts almost no turn and explains none).
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

    /// One sample: `gyr` the raw rate, `acc` the vector whose direction is fixed in the earth
    /// (specific force at rest, or the magnetic field).
    fn add(&mut self, dt: f64, gyr: Vec3<f64>, acc: Vec3<f64>) {
        let turn = gyr * dt;
        // A squared length that overflows is not finite either (a turn beyond it would make
        // every later prediction NaN).
        let finite = |v: Vec3<f64>| v.dot(v).is_finite();
        if !(finite(acc) && finite(turn)) {
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
        if !(a.is_finite() && a > 0.0) {
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

    /// The declared unit's share and the unit that explains the most with its share, when
    /// one explains at least [`MIN_EXPLAINED`] (much linear acceleration or a disturbed field
    /// leaves the test undecided).
    fn best(&self) -> Option<(f64, (Unit, f64))> {
        let explained = self.explained()?;
        let best = explained
            .iter()
            .copied()
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .filter(|(_, share)| *share >= MIN_EXPLAINED)?;
        Some((explained[0].1, best))
    }
}

/// `u` turned as a direction fixed in the earth turns in the sensor frame while the sensor
/// turns by the rotation vector `theta` (rad): by `−theta` (Rodrigues,
/// `u·cos φ + (u × θ)·sin φ/φ + θ·(θ·u)·(1 − cos φ)/φ²`). Below 0.01 rad (one sample's turn
/// in the right unit) the two ratios come from their series through `φ⁴`, whose next terms
/// are below rounding there: a few products instead of a `sincos`, a square root and two
/// divisions at every sample of every check.
fn turned(u: Vec3<f64>, theta: Vec3<f64>) -> Vec3<f64> {
    let phi2 = theta.dot(theta);
    let (cos, sinc, versc) = if phi2 < 1e-4 {
        let sinc = 1.0 - phi2 * (1.0 / 6.0) * (1.0 - phi2 * (1.0 / 20.0));
        let versc = 0.5 - phi2 * (1.0 / 24.0) * (1.0 - phi2 * (1.0 / 30.0));
        (1.0 - phi2 * versc, sinc, versc)
    } else {
        let phi = libm::sqrt(phi2);
        let (sin, cos) = libm::sincos(phi);
        (cos, sin / phi, (1.0 - cos) / phi2)
    };
    u * cos + u.cross(theta) * sinc + theta * (theta.dot(u) * versc)
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
    /// The gyroscope-unit test on the gravity direction, started once the time unit is known.
    tilt: Option<TiltTest>,
    /// The same test on the magnetic field's direction (9D samples only).
    field: Option<TiltTest>,
    /// Enough was seen ([`DECIDED_SAMPLES`], [`DECIDED_TURN`]): later samples are ignored.
    decided: bool,
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
            field: None,
            decided: false,
        }
    }

    /// Adds one sample's raw readings (time, angular rate, specific force, field as in the
    /// file; `mag` `None` for a 6D sample). Samples beyond [`CHECK_SAMPLES`] are ignored,
    /// and those after the check has decided ([`DECIDED_SAMPLES`] samples with its
    /// gyroscope test well past its threshold).
    pub fn add(&mut self, t: f64, gyr: Vec3<f64>, acc: Vec3<f64>, mag: Option<Vec3<f64>>) {
        if self.decided || self.samples >= CHECK_SAMPLES {
            return;
        }
        self.samples += 1;
        if self.samples.is_multiple_of(DECIDED_EVERY) && self.samples >= DECIDED_SAMPLES {
            // The field decides only where a unit explains it: a disturbed field's turning
            // must not end the check before the gravity direction has turned.
            self.decided = self.tilt.as_ref().is_some_and(|t| t.turned >= DECIDED_TURN)
                || (self.field.as_ref())
                    .is_some_and(|t| t.turned >= DECIDED_TURN && t.best().is_some());
        }
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
            let test = TiltTest::new(
                self.declared.get(Sensor::Gyroscope),
                time_factor,
                median * time_factor,
            );
            self.field = Some(test.clone());
            self.tilt = Some(test);
        }
        if let Some(tilt) = &mut self.tilt
            && dt > 0.0
        {
            tilt.add(dt, gyr, acc);
        }
        if let (Some(field), Some(m)) = (&mut self.field, mag)
            && dt > 0.0
        {
            field.add(dt, gyr, m);
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

    /// Samples added (at most [`CHECK_SAMPLES`]; fewer once the check has decided).
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Whether [`add`](Self::add) still reads samples: `false` once the check has decided or
    /// read [`CHECK_SAMPLES`], so that a caller feeding a stream can stop reading its input.
    pub fn wants_more(&self) -> bool {
        !self.decided && self.samples < CHECK_SAMPLES
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
                    decisive: false,
                    evidence: format!(
                        "every reading checked ({readings}) is {}",
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
                    decisive: false,
                    evidence: if declared.is_si() {
                        format!(
                            "the {what} is {} {si}, not within {lo}–{hi} {si}",
                            short(median)
                        )
                    } else if declared.name.is_none() {
                        // A factor declared for raw counts: the reading, then what it became.
                        format!(
                            "the {what} is {} counts × {} = {} {si}, not within {lo}–{hi} {si}",
                            short(median),
                            declared.factor,
                            short(median * declared.factor)
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
                decisive: false,
                evidence: format!("no reading checked ({readings}) is a number"),
            });
        }
        let deg = Unit::parse(Sensor::Gyroscope, "deg/s")?;
        // The unit that explains the most of the gravity direction's turning, else of the
        // magnetic field's (gravity hardly turns under rotation about the vertical).
        let judged = [(&self.tilt, "gravity"), (&self.field, "magnetic field")]
            .into_iter()
            .find_map(|(test, what)| {
                let test = test.as_ref()?;
                Some((test.best()?, test.turned, what))
            });
        if let Some(((declared_share, best), turned, what)) = judged {
            if best.1 < declared_share + CLEARLY_BETTER {
                return None;
            }
            return Some(UnitFinding {
                sensor: Sensor::Gyroscope,
                declared,
                likely: Some(best.0),
                dead: false,
                decisive: true,
                evidence: format!(
                    "as {declared} its readings explain {:.0} % of the {} rad the {what} direction turned, as {} {:.0} %",
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
            decisive: false,
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
    /// The readings were tested against the motion (the gyroscope against how the gravity
    /// direction, or the magnetic field's, turned) and the declared unit clearly failed: a run in it is known to be
    /// wrong, where a magnitude outside its usual range may still be a real one.
    pub decisive: bool,
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

    /// Why a run must not go on with this finding, ending "if the readings are in rad/s after
    /// all", and the units entry that says so (`gyro=rad/s`): for a [`decisive`](Self::decisive)
    /// finding whose sensor `units` did not declare. `None` where the finding may stand as a
    /// warning. `rootfuse run` and Python's `read_csv` refuse with it, each naming its own way
    /// to pass the entry.
    ///
    /// ```
    /// use rootfuse_attitude::units::{Sensor, Unit, UnitFinding, Units};
    /// let finding = UnitFinding {
    ///     sensor: Sensor::Gyroscope,
    ///     declared: Unit::parse(Sensor::Gyroscope, "rad/s").unwrap(),
    ///     likely: Unit::parse(Sensor::Gyroscope, "deg/s"),
    ///     evidence: "the readings turn 57 times faster than gravity".into(),
    ///     dead: false,
    ///     decisive: true,
    /// };
    /// let (why, entry) = finding.refusal(&Units::default()).unwrap();
    /// assert!(why.contains("wrong unit makes every estimate wrong"));
    /// assert_eq!(entry, "gyro=rad/s");
    /// // Declared, the finding stays a warning.
    /// assert!(finding.refusal(&"gyro=rad/s".parse().unwrap()).is_none());
    /// ```
    pub fn refusal(&self, units: &Units) -> Option<(String, String)> {
        if !self.decisive || units.is_declared(self.sensor) {
            return None;
        }
        let why = format!(
            "a {} in the wrong unit makes every estimate wrong, so this is an error; if the \
             readings are in {} after all",
            self.sensor.name(),
            self.declared
        );
        Some((why, format!("{}={}", self.sensor.key(), self.declared)))
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

    /// The small-angle series gives Rodrigues' formula from `sincos` to rounding, on either
    /// side of where it takes over, and a turn keeps the direction's length.
    #[test]
    fn small_turns_by_their_series_are_rodrigues_turns() {
        let exact = |u: Vec3<f64>, theta: Vec3<f64>| {
            let phi = theta.norm();
            let k = theta * (1.0 / phi);
            let (sin, cos) = libm::sincos(phi);
            u * cos + u.cross(k) * sin + k * (k.dot(u) * (1.0 - cos))
        };
        let u = Vec3::new(0.48, -0.6, 0.64);
        for phi in [1e-9, 1e-5, 3e-3, 9.999e-3, 1.0001e-2, 0.3, 2.0] {
            for axis in [Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.6, 0.0, -0.8)] {
                let (a, b) = (turned(u, axis * phi), exact(u, axis * phi));
                assert!((a - b).norm() < 4e-16, "{phi}: {:e}", (a - b).norm());
                assert!((a.norm() - 1.0).abs() < 4e-16, "{phi}");
            }
        }
        // Turning about the direction itself leaves it.
        assert!((turned(u, u * 1e-3) - u).norm() < 2e-16);
    }
}
