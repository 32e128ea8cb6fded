//! What `rootfuse run` says about each input once it has run: the units its data look like
//! (an error where the gyroscope fails against the motion and its unit was not declared, a
//! warning otherwise; every one an error under `--strict`) and a sensor whose every sample or correction
//! the filter skipped (always an error: the estimate would be silently wrong).
use rootfuse_attitude::units::{Sensor, UnitCheck, UnitFinding, Units};
use rootfuse_attitude::{Recording, Vec3};
use rootfuse_batch::{FleetBlock, RejectionTotals};

/// Fewest samples of a device before its skips are judged (a file of a few rows says little).
const MIN_JUDGED: u64 = 10;

/// The unit checks of every device (a CSV file is one device) of a run.
pub struct InputChecks {
    units: Units,
    strict: bool,
    checks: Vec<UnitCheck>,
    samples: Vec<u64>,
}

/// What to say about one device.
#[derive(Default)]
pub struct Verdict {
    /// Lines to print as warnings.
    pub warnings: Vec<String>,
    /// The device's estimate must not be kept.
    pub error: Option<String>,
}

impl InputChecks {
    /// Checks against the declared `units`; `strict` turns unit findings into errors.
    pub fn new(units: Units, strict: bool) -> Self {
        Self {
            units,
            strict,
            checks: Vec::new(),
            samples: Vec::new(),
        }
    }

    /// Adds a block's rows (already in the filters' units) to their devices' checks.
    pub fn observe(&mut self, block: &FleetBlock) {
        for (i, &d) in block.device.iter().enumerate() {
            let mag = block.mag.as_ref().map(|m| m[i]);
            self.add(d, block.t[i], block.gyr[i], block.acc[i], mag);
        }
    }

    /// Adds a whole recording (in the filters' units) as device `d`.
    pub fn observe_recording(&mut self, d: u32, rec: &Recording) {
        for i in 0..rec.len() {
            let mag = rec.mag.as_ref().map(|m| m[i]);
            self.add(d, rec.t[i], rec.gyr[i], rec.acc[i], mag);
        }
    }

    fn add(&mut self, d: u32, t: f64, gyr: Vec3<f64>, acc: Vec3<f64>, mag: Option<Vec3<f64>>) {
        let d = d as usize;
        if d >= self.checks.len() {
            self.checks
                .resize_with(d + 1, || UnitCheck::new(&self.units));
            self.samples.resize(d + 1, 0);
        }
        self.samples[d] += 1;
        self.checks[d].add_si(t, gyr, acc, mag);
    }

    /// Rows of device `d` observed so far.
    pub fn rows(&self, d: u32) -> u64 {
        self.samples.get(d as usize).copied().unwrap_or(0)
    }

    /// The unit findings of device `d`.
    pub fn findings(&self, d: u32) -> Vec<UnitFinding> {
        self.checks
            .get(d as usize)
            .map(UnitCheck::findings)
            .unwrap_or_default()
    }

    /// What to say about device `d` of `what` (a file, or a file's device): its unit findings
    /// and, from its `rejections`, any sensor the filter could not use at all (`nine_d`: the
    /// filter uses the magnetometer and the input has one; otherwise the magnetometer's unit
    /// does not matter and is not judged).
    pub fn judge(&self, what: &str, d: u32, rejections: RejectionTotals, nine_d: bool) -> Verdict {
        let mut findings = self.findings(d);
        if !nine_d {
            findings.retain(|f| f.sensor != Sensor::Magnetometer);
        }
        let mut verdict = Verdict::default();
        let hint = |sensor: Sensor| {
            findings
                .iter()
                .find(|f| f.sensor == sensor)
                .map(|f| format!(" ({})", advice(f)))
                .unwrap_or_default()
        };
        let n = self.samples.get(d as usize).copied().unwrap_or(0);
        if n >= MIN_JUDGED {
            let r = rejections;
            // The first sample has no time step of its own.
            let stepped = n - 1;
            let processed = n.saturating_sub(r.dt + r.gyr);
            let skipped_all = if r.dt + r.gyr >= stepped {
                Some(format!(
                    "every sample was skipped ({} for the time step, {} for the gyroscope){}{}",
                    r.dt,
                    r.gyr,
                    hint(Sensor::Time),
                    hint(Sensor::Gyroscope)
                ))
            } else if r.acc >= processed {
                Some(format!(
                    "every accelerometer correction was skipped ({} of {processed}: not finite, zero or beyond max_acc){}",
                    r.acc,
                    hint(Sensor::Accelerometer)
                ))
            } else if r.gated >= processed {
                Some(format!(
                    "the filter gated every correction ({} of {processed}){}",
                    r.gated,
                    hint(Sensor::Accelerometer)
                ))
            } else if nine_d && r.mag >= processed {
                Some(format!(
                    "every magnetometer correction was skipped ({} of {processed}: not finite, zero or beyond max_mag){}; run without it with --dof 6",
                    r.mag,
                    hint(Sensor::Magnetometer)
                ))
            } else {
                None
            };
            if let Some(why) = skipped_all {
                verdict.error = Some(format!("{what}: {why}"));
                return verdict;
            }
        }
        for f in &findings {
            let line = format!("{what}: {}", advice(f));
            if self.strict {
                verdict.error = Some(format!("{line} (--strict)"));
                return verdict;
            }
            // A gyroscope whose readings fail against the motion itself (the turning of the
            // gravity direction) turns every estimate wrong, whatever the filter: an error
            // unless its unit was declared (then the readings are taken as declared, and the
            // finding stays a warning). Magnitudes outside their usual range (a slow logger's
            // time step, a fast spin) stay warnings: they may be real; time so far off that
            // every step is skipped is an error above.
            if let Some((why, entry)) = f.refusal(&self.units) {
                verdict.error = Some(format!("{line} ({why}, say so: --units {entry})"));
                return verdict;
            }
            verdict.warnings.push(line);
        }
        verdict
    }
}

/// A finding with what to do about it.
fn advice(f: &UnitFinding) -> String {
    if f.dead {
        f.to_string()
    } else {
        format!("{f}: run with --units {}", f.declaration())
    }
}

/// `--units` on the command line.
pub fn parse_units(list: &str) -> Result<rootfuse_attitude::units::Units, String> {
    list.parse()
        .map_err(|e: rootfuse_attitude::units::UnitsError| e.to_string())
}
