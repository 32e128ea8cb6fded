//! Warnings about arrays handed to the filters from Python (`Filter.update_batch`,
//! `Filter.update`, `smooth`, `run_many`): steps most of which will be skipped, and the unit
//! check. The arrays carry no unit, so readings in °/s, g or nT would run as rad/s, m/s² and
//! µT without a word. Each finding is a `UserWarning` naming the sensor, what was seen and
//! the unit its readings fit.

use crate::arrays::StepsRef;
use crate::inputs::Inputs;
use pyo3::exceptions::PyUserWarning;
use pyo3::prelude::*;
use rootfuse_attitude::Vec3;
use rootfuse_attitude::filters::ScreenLimits;
use rootfuse_attitude::registry::{FilterKind, FilterSpec};
use rootfuse_attitude::units::{Sensor, UnitCheck, UnitFinding, Units};

/// A `UserWarning` where most of a call's steps (ten or more) will be skipped: not finite,
/// not positive, or beyond `max_dt` (sample times given as `dt`, times in ms). Decided from
/// the input before the filter runs, so a warning turned into an error leaves the filter as
/// it was.
pub fn warn_if_most_steps_skipped(
    py: Python<'_>,
    call: &str,
    steps: StepsRef<'_>,
    n: usize,
    max_dt: f64,
) -> PyResult<bool> {
    let skipped = (0..n)
        .filter(|&i| !step_usable(steps.at(i), max_dt))
        .count();
    if n < 10 || 2 * skipped <= n {
        return Ok(false);
    }
    let (skipped, n) = (skipped as u64, n as u64);
    warn_of_steps(py, call, skipped, n, max_dt)?;
    Ok(true)
}

/// The warning of [`warn_if_most_steps_skipped`]: `skipped` of `n` steps skipped.
fn warn_of_steps(py: Python<'_>, call: &str, skipped: u64, n: u64, max_dt: f64) -> PyResult<()> {
    let message = format!(
        "{call}: {skipped} of {n} samples will be skipped for their time step (flag 1): `dt` is the step before each sample in s (sample times go to `t=`), `t` is in s (divide ms by 1000), and a step beyond `max_dt` ({max_dt} s) is a gap"
    );
    let message = std::ffi::CString::new(message).unwrap_or_default();
    PyErr::warn(py, &py.get_type::<PyUserWarning>(), &message, 1)
}

/// Whether a filter takes a step of `dt` s: finite, positive and at most `max_dt`.
fn step_usable(dt: f64, max_dt: f64) -> bool {
    dt > 0.0 && dt <= max_dt
}

/// The sensors whose units matter to one filter's run, and so are worth a warning.
#[derive(Clone, Copy, Debug)]
pub struct Judged {
    /// The time step's unit (off where the steps' own warning covers it: a step in ms is
    /// beyond `max_dt`, where a slow but real rate, 2 Hz, is not).
    time: bool,
    acc: bool,
    /// The field's: a 9D filter at the default `max_mag`, which refuses a field in nT.
    mag: bool,
}

impl Judged {
    /// What `spec`'s filter reads: the accelerometer unless it integrates the gyroscope alone,
    /// the magnetometer in 9D unless `max_mag` was raised for the field's own unit.
    pub fn of(spec: &FilterSpec, time: bool) -> Self {
        Self {
            time,
            acc: spec.kind() != FilterKind::Gyro,
            mag: spec.uses_magnetometer()
                && spec.screen_limits().max_mag <= ScreenLimits::default().max_mag,
        }
    }

    /// Whether the field's readings are checked.
    pub fn field(&self) -> bool {
        self.mag
    }

    /// Whether `f` is about a sensor judged here.
    pub fn keeps(&self, f: &UnitFinding) -> bool {
        match f.sensor {
            Sensor::Time => self.time,
            Sensor::Gyroscope => true,
            Sensor::Accelerometer => self.acc,
            Sensor::Magnetometer => self.mag,
        }
    }
}

/// One `UserWarning` per finding, attributed to the caller's line. `call` names the function
/// (`"smooth"`, `"update_batch"`, ...).
pub fn warn_findings<'f>(
    py: Python<'_>,
    call: &str,
    findings: impl IntoIterator<Item = &'f UnitFinding>,
) -> PyResult<()> {
    for f in findings {
        let advice = if f.dead {
            format!("{call}: {f}")
        } else {
            format!(
                "{call}: {f}: the arrays must be in s, rad/s, m/s2 and uT; convert this sensor's ({}) first",
                f.declaration()
            )
        };
        let message = std::ffi::CString::new(advice).unwrap_or_default();
        PyErr::warn(py, &py.get_type::<PyUserWarning>(), &message, 1)?;
    }
    Ok(())
}

/// The unit check of one stream of calls on a `Filter`: samples are read while the check
/// wants more ([`UnitCheck::wants_more`]: until it has decided, at most
/// [`CHECK_SAMPLES`](rootfuse_attitude::units::CHECK_SAMPLES)), and each finding is warned
/// of once per stream (until `reset()`).
#[derive(Clone, Debug)]
pub struct StreamCheck {
    check: UnitCheck,
    /// The stream's time, s: the sum of its usable steps (the check takes sample times).
    time: f64,
    /// The findings warned of: sensor, and whether it was found dead.
    warned: Vec<(Sensor, bool)>,
    /// The samples the check had read when it was last judged.
    judged_at: u64,
    /// Of the first [`JUDGE_EVERY`] steps (`Filter.update`, which has no other steps
    /// warning), those seen and those a filter skips; whether they were judged.
    steps: u64,
    skipped_steps: u64,
    steps_judged: bool,
}

/// Samples between two judgements of a stream fed one sample at a time (`Filter.update`): a
/// judgement costs what a few updates do.
pub const JUDGE_EVERY: u64 = 256;

/// The samples a stream's finding of a sensor dead in every reading so far waits for: a
/// stream's first chunk may hold no reading yet.
const DEAD_SAMPLES: u64 = 1000;

/// The samples a stream's rate rule (a gyroscope's 99.9th percentile beyond any gyroscope's
/// range) waits for: over fewer, one hard knock is the percentile.
const RATE_RULE_SAMPLES: u64 = 5000;

impl Default for StreamCheck {
    fn default() -> Self {
        Self {
            check: UnitCheck::new(&Units::default()),
            time: 0.0,
            warned: Vec::new(),
            judged_at: 0,
            steps: 0,
            skipped_steps: 0,
            steps_judged: false,
        }
    }
}

impl StreamCheck {
    /// Whether nothing is left to say: the check stopped reading and was judged since.
    pub fn settled(&self) -> bool {
        !self.check.wants_more() && self.judged_at == self.check.samples()
    }

    /// Counts one of the stream's first [`JUDGE_EVERY`] steps (`dt` s; `max_dt` the filter's
    /// limit).
    pub fn count_step(&mut self, dt: f64, max_dt: f64) {
        if self.steps < JUDGE_EVERY {
            self.steps += 1;
            self.skipped_steps += u64::from(!step_usable(dt, max_dt));
        }
    }

    /// The warning of the stream's first [`JUDGE_EVERY`] steps where most of them are skipped
    /// (time in ms), once they are all counted; nothing before, after, or when they are
    /// usable.
    pub fn warn_of_first_steps(&mut self, py: Python<'_>, call: &str, max_dt: f64) -> PyResult<()> {
        if self.steps_judged || self.steps < JUDGE_EVERY {
            return Ok(());
        }
        if 2 * self.skipped_steps > self.steps {
            warn_of_steps(py, call, self.skipped_steps, self.steps, max_dt)?;
        }
        self.steps_judged = true;
        Ok(())
    }

    /// Adds one sample (6D when `mag` is `None`) taken `dt` s after the last, while the check
    /// reads samples. A step that is not finite and positive leaves the time where it was
    /// (the check skips a zero step).
    pub fn add(&mut self, dt: f64, gyr: Vec3<f64>, acc: Vec3<f64>, mag: Option<Vec3<f64>>) {
        if !self.check.wants_more() {
            return;
        }
        if dt.is_finite() && dt > 0.0 {
            self.time += dt;
        }
        self.check.add(self.time, gyr, acc, mag);
    }

    /// Adds a call's samples, as many as the check still reads (the field only if `with_mag`).
    pub fn add_inputs(&mut self, input: &Inputs<'_>, with_mag: bool) {
        let with_mag = with_mag && input.mag.is_some();
        for i in 0..input.len {
            if !self.check.wants_more() {
                break;
            }
            let s = input.sample(i);
            self.add(input.steps.at(i), s.gyr, s.acc, with_mag.then_some(s.mag));
        }
    }

    /// The findings `judged` keeps that were not warned of yet (see
    /// [`mark_warned`](Self::mark_warned)), judged once `every` samples were read since the
    /// last judgement or the check stopped reading (nothing otherwise). In a stream that may
    /// go on (`complete` false) a dead sensor waits for [`DEAD_SAMPLES`] and the rate rule for
    /// [`RATE_RULE_SAMPLES`].
    pub fn findings(&mut self, judged: &Judged, every: u64, complete: bool) -> Vec<UnitFinding> {
        let samples = self.check.samples();
        let read = samples - self.judged_at;
        if !(read >= every.max(1) || (read > 0 && !self.check.wants_more())) {
            return Vec::new();
        }
        self.judged_at = samples;
        let complete = complete || !self.check.wants_more();
        (self.check.findings().into_iter())
            .filter(|f| judged.keeps(f) && !self.warned.contains(&(f.sensor, f.dead)))
            .filter(|f| {
                let rate_rule = f.sensor == Sensor::Gyroscope && !f.decisive && !f.dead;
                complete
                    || !(f.dead && samples < DEAD_SAMPLES
                        || rate_rule && samples < RATE_RULE_SAMPLES)
            })
            .collect()
    }

    /// Records that `findings` were warned of (after the warnings went out: one raised as an
    /// error is found again).
    pub fn mark_warned(&mut self, findings: &[UnitFinding]) {
        self.warned
            .extend(findings.iter().map(|f| (f.sensor, f.dead)));
    }

    /// Judges again at the next sample (a warning of the last judgement was raised as an
    /// error and not delivered).
    pub fn judge_again(&mut self) {
        self.judged_at = 0;
    }
}

/// Warns of `findings` in turn, recording each in `delivered` as it goes out: where one is
/// raised as an error, those before it stay warned of and the rest are found again.
pub fn deliver(
    py: Python<'_>,
    call: &str,
    findings: &[UnitFinding],
    delivered: &mut StreamCheck,
) -> PyResult<()> {
    for f in findings {
        warn_findings(py, call, [f])?;
        delivered.mark_warned(core::slice::from_ref(f));
    }
    Ok(())
}

/// The channels of a fleet whose units [`channel_findings`] checks: the first, the last and
/// two between, spread over the fleet (a fleet's channels usually share their source's units;
/// checking every one would cost several times the filters).
pub const CHECKED_CHANNELS: usize = 4;

/// The channels [`channel_findings`] checks, in order, without repeats.
pub fn checked_channels(count: usize) -> Vec<usize> {
    let mut picked: Vec<usize> = (0..CHECKED_CHANNELS)
        .map(|k| k * count.saturating_sub(1) / (CHECKED_CHANNELS - 1))
        .filter(|&c| c < count)
        .collect();
    picked.dedup();
    picked
}

/// The findings of the [`checked_channels`] of `sources` (each judged by its own filter's
/// `specs[c]`), each sensor once (the first channel that shows it), with the channel's index.
pub fn channel_findings(sources: &[Inputs<'_>], specs: &[FilterSpec]) -> Vec<(usize, UnitFinding)> {
    let mut out: Vec<(usize, UnitFinding)> = Vec::new();
    for c in checked_channels(sources.len()) {
        let Some(spec) = specs.get(c) else { continue };
        let judged = Judged::of(spec, false);
        let mut check = StreamCheck::default();
        check.add_inputs(&sources[c], judged.field());
        for f in check.findings(&judged, 1, true) {
            if !out.iter().any(|(_, seen)| seen.sensor == f.sensor) {
                out.push((c, f));
            }
        }
    }
    out
}
