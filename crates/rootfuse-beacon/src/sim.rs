//! A seeded beacon-and-walk simulator and the beacon experiment: a walker loops a
//! corridor (a rounded rectangle, left turns) for ten minutes with a phone held flat and
//! forward; beacons line the corridor; the IMU, the scans and the steps are simulated.

use super::fuse::{FusionConfig, HeadingFusion, Pdr, wrap};
use super::heading::{Fix, TrendConfig, heading_from_fixes, multilaterate, weak_heading};
use super::{
    Beacon, BeaconClass, BeaconMap, BeaconSet, LogDistanceModel, Reading, ScanMean, Scanner,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rootfuse_attitude::filters::{HeadingPipeline, HeadingPipelineParams};
use rootfuse_attitude::{Dof, ImuSample, OrientationFilter, Quat, Vec3};
use std::vec::Vec;

/// A zero-mean normal distribution of standard deviation `sd`; a negative or non-finite `sd`
/// (a bad configuration) gives the unit normal.
fn gaussian(sd: f64) -> Normal<f64> {
    let sd = if sd.is_finite() && sd >= 0.0 { sd } else { 1.0 };
    // Unreachable: `Normal::new` fails only for a negative or non-finite standard deviation.
    Normal::new(0.0, sd).expect("unreachable: sd is finite and non-negative")
}

/// Settings of the simulated walk.
#[derive(Clone, Debug, PartialEq)]
pub struct WalkConfig {
    /// RNG seed.
    pub seed: u64,
    /// Duration, s (default 600).
    pub duration: f64,
    /// IMU rate, Hz (default 100).
    pub rate: f64,
    /// Walking speed, m/s (default 1.2).
    pub speed: f64,
    /// Step frequency, Hz (default 1.8); step length is `speed / step_freq`.
    pub step_freq: f64,
    /// Corridor loop, east × north extent, m (default 40 × 20).
    pub loop_size: [f64; 2],
    /// Corner radius of the walked path, m (default 1.5).
    pub corner_radius: f64,
    /// Beacon spacing along the path, m (default 5); classes cycle weak, medium, weak, strong.
    pub beacon_spacing: f64,
    /// Beacon offset from the walked line (toward the outer wall), m (default 1).
    pub beacon_offset: f64,
    /// True path-loss exponent (default 2.0).
    pub path_loss_n: f64,
    /// Log-normal shadowing std (one draw per beacon and scan), dB (default 4).
    pub shadowing_db: f64,
    /// Per-reading fast-fading std, dB (default 2).
    pub fading_db: f64,
    /// Scan threshold, dBm (default −95).
    pub threshold: f64,
    /// Advertisements per beacon per 1 s scan (default 5), each received with `reception` (default 0.6).
    pub adverts_per_scan: usize,
    /// Probability of receiving one advertisement (default 0.6).
    pub reception: f64,
    /// Probability that a whole scan returns nothing (scan gap) (default 0.05).
    pub scan_gap: f64,
    /// Std of each gyro-bias axis (one draw per seed), rad/s (default 0.002).
    pub gyro_bias_std: f64,
    /// Gyro white noise per sample, rad/s (default 0.01).
    pub gyro_noise: f64,
    /// Accelerometer noise per sample, m/s² (default 0.2).
    pub acc_noise: f64,
    /// Magnetometer noise per sample, µT (default 0.5).
    pub mag_noise: f64,
    /// Amplitude of the indoor field disturbance (smooth in space), µT (default 15).
    pub mag_disturbance: f64,
    /// Magnetic declination, rad, east positive (default 0.087 ≈ 5°).
    pub declination: f64,
    /// The pipeline runs in 9D (disturbed magnetometer) or 6D (gyro heading) (default 6).
    pub dof: Dof,
    /// Beacon fixes also correct the PDR position (the source's "positioning correction")
    /// (default true).
    pub position_fixes: bool,
}

impl Default for WalkConfig {
    fn default() -> Self {
        Self {
            seed: 0,
            duration: 600.0,
            rate: 100.0,
            speed: 1.2,
            step_freq: 1.8,
            loop_size: [40.0, 20.0],
            corner_radius: 1.5,
            beacon_spacing: 5.0,
            beacon_offset: 1.0,
            path_loss_n: 2.0,
            shadowing_db: 4.0,
            fading_db: 2.0,
            threshold: -95.0,
            adverts_per_scan: 5,
            reception: 0.6,
            scan_gap: 0.05,
            gyro_bias_std: 0.002,
            gyro_noise: 0.01,
            acc_noise: 0.2,
            mag_noise: 0.5,
            mag_disturbance: 15.0,
            declination: 0.087,
            dof: Dof::Six,
            position_fixes: true,
        }
    }
}

/// The walked path: a rounded rectangle walked counter-clockwise, by arc length.
#[derive(Clone, Debug)]
pub struct Path {
    legs: [f64; 2],
    radius: f64,
    origin: [f64; 2],
    table: Vec<[f64; 2]>,
    ds: f64,
}

impl Path {
    /// The path inside `size` (east × north, m) with corners of `radius`.
    pub fn new(size: [f64; 2], radius: f64) -> Self {
        let legs = [size[0] - 2.0 * radius, size[1] - 2.0 * radius];
        let mut path = Self {
            legs,
            radius,
            origin: [radius, 0.0],
            table: Vec::new(),
            ds: 0.005,
        };
        let n = (path.perimeter() / path.ds).ceil() as usize + 1;
        let mut p = path.origin;
        path.table.reserve(n);
        for i in 0..n {
            path.table.push(p);
            let psi = path.heading((i as f64 + 0.5) * path.ds);
            p[0] -= path.ds * psi.sin();
            p[1] += path.ds * psi.cos();
        }
        path
    }
    /// Length of one loop, m.
    pub fn perimeter(&self) -> f64 {
        2.0 * (self.legs[0] + self.legs[1]) + core::f64::consts::TAU * self.radius
    }
    /// Heading (rad) at arc length `s` (m): straight legs east, north, west, south joined by
    /// quarter circles (left turns).
    pub fn heading(&self, s: f64) -> f64 {
        let arc = core::f64::consts::FRAC_PI_2 * self.radius;
        let mut s = s.rem_euclid(self.perimeter());
        let mut psi = -core::f64::consts::FRAC_PI_2;
        for k in 0..4 {
            let leg = self.legs[k % 2];
            if s < leg {
                return wrap(psi);
            }
            s -= leg;
            if s < arc {
                return wrap(psi + s / self.radius);
            }
            s -= arc;
            psi += core::f64::consts::FRAC_PI_2;
        }
        wrap(psi)
    }
    /// Position `[east, north]` (m) at arc length `s`.
    pub fn position(&self, s: f64) -> [f64; 2] {
        let i = (s.rem_euclid(self.perimeter()) / self.ds).round() as usize;
        self.table[i.min(self.table.len() - 1)]
    }
}

/// The beacons along a path: every `spacing` m, `offset` m to the right of the walk, classes
/// cycling weak (−77 dBm at 1 m), medium (−70), weak, strong (−60).
pub fn deploy(path: &Path, spacing: f64, offset: f64) -> BeaconSet {
    let n = (path.perimeter() / spacing).floor() as usize;
    BeaconSet::new((0..n).map(|k| {
        let s = k as f64 * spacing + 0.5 * spacing;
        let (p, psi) = (path.position(s), path.heading(s));
        // Right of the walking direction (−sin ψ, cos ψ) is (cos ψ, sin ψ).
        let pos = [p[0] + offset * psi.cos(), p[1] + offset * psi.sin()];
        let tx = [-77.0, -70.0, -77.0, -60.0][k % 4];
        Beacon::new(k as u32, pos, tx)
    }))
}

/// Simulated scan readings of one second ending at `t`, at position `p`: per beacon one
/// shadowing draw, then up to `adverts_per_scan` readings with fading, each received with
/// probability `reception`; below-threshold readings are not reported; with probability
/// `scan_gap` the scan is empty.
pub fn scan<R: Rng>(
    rng: &mut R,
    cfg: &WalkConfig,
    beacons: &BeaconSet,
    p: [f64; 2],
    t: f64,
) -> Vec<Reading> {
    let mut out = Vec::new();
    if rng.random::<f64>() < cfg.scan_gap {
        return out;
    }
    let shadow = gaussian(cfg.shadowing_db);
    let fade = gaussian(cfg.fading_db);
    for b in beacons.iter() {
        let d = (p[0] - b.position[0]).hypot(p[1] - b.position[1]).max(0.3);
        let mean = b.tx_power - 10.0 * cfg.path_loss_n * d.log10() + shadow.sample(rng);
        for j in 0..cfg.adverts_per_scan {
            if rng.random::<f64>() >= cfg.reception {
                continue;
            }
            let rssi = mean + fade.sample(rng);
            if rssi >= cfg.threshold {
                let tj = t - 1.0 + (j as f64 + 0.5) / cfg.adverts_per_scan as f64;
                out.push(Reading {
                    id: b.id,
                    rssi,
                    t: tj,
                });
            }
        }
    }
    out
}

/// Calibration of one beacon class (S42): scan means at 1 m steps out to `max_d` m, each from
/// 20 scans
/// (weight = readings heard / shadowing variance), fitted by [`LogDistanceModel::fit`].
pub fn calibrate<R: Rng>(
    rng: &mut R,
    cfg: &WalkConfig,
    tx_power: f64,
    max_d: usize,
) -> Result<LogDistanceModel, super::BeaconError> {
    let b = Beacon::new(0, [0.0, 0.0], tx_power);
    let set = BeaconSet::new([b]);
    let calm = WalkConfig {
        scan_gap: 0.0,
        ..cfg.clone()
    };
    let mut points = Vec::new();
    for d in 1..=max_d {
        for _ in 0..20 {
            let readings = scan(rng, &calm, &set, [d as f64, 0.0], 0.0);
            if !readings.is_empty() {
                let mean = readings.iter().map(|r| r.rssi).sum::<f64>() / readings.len() as f64;
                let var = cfg.shadowing_db.powi(2) + cfg.fading_db.powi(2) / readings.len() as f64;
                points.push((d as f64, mean, 1.0 / var));
            }
        }
    }
    LogDistanceModel::fit(&points)
}

/// The result of one simulated walk.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WalkReport {
    /// Heading error at the end, MEMS only, rad.
    pub final_mems: f64,
    /// Heading error at the end, with beacons, rad.
    pub final_beacon: f64,
    /// RMS heading error over the walk, MEMS only, rad.
    pub rms_mems: f64,
    /// RMS heading error over the walk, with beacons, rad.
    pub rms_beacon: f64,
    /// Largest PDR position error, MEMS heading only, m.
    pub max_pos_mems: f64,
    /// Largest PDR position error, with beacon heading (and fixes if enabled), m.
    pub max_pos_beacon: f64,
    /// Final PDR position error, MEMS only, m.
    pub final_pos_mems: f64,
    /// Final PDR position error, with beacons, m.
    pub final_pos_beacon: f64,
    /// Beacon headings fused / refused.
    pub headings: [u64; 2],
    /// Weak-beacon headings decided, fix headings decided.
    pub decisions: [u64; 2],
    /// RMS error of the decided beacon headings against the true mean heading over their
    /// span, rad: `[weak, fixes]` (all decisions, fused or not).
    pub beacon_heading_rms: [f64; 2],
    /// RMS position error of the multilateration fixes, m, and their count.
    pub fix_rms: (f64, u64),
    /// Fitted models `[A, n]` for medium and strong beacons.
    pub models: [[f64; 2]; 2],
}

/// The walker's motion and IMU along a path: the start (arc length `s0`, m), the gyro bias,
/// the noise of each sensor and the field, disturbed periodically in space.
struct Walker<'a> {
    cfg: &'a WalkConfig,
    path: &'a Path,
    s0: f64,
    bias: Vec3<f64>,
    noise: [Normal<f64>; 3],
    earth: [f64; 3],
    phase: [f64; 2],
}

impl<'a> Walker<'a> {
    /// Draws the bias, the start and the field's phases from `rng`, in that order.
    fn new(rng: &mut ChaCha8Rng, cfg: &'a WalkConfig, path: &'a Path) -> Self {
        // `max` maps NaN to 0 as well: a missing noise setting means no noise.
        let normal = |s: f64| gaussian(s.max(0.0));
        let nb = normal(cfg.gyro_bias_std);
        let bias = Vec3::new(nb.sample(rng), nb.sample(rng), nb.sample(rng));
        let noise = [
            normal(cfg.gyro_noise),
            normal(cfg.acc_noise),
            normal(cfg.mag_noise),
        ];
        let s0 = rng.random::<f64>() * path.perimeter();
        let phase = [rng.random::<f64>() * 6.3, rng.random::<f64>() * 6.3];
        let (h, dip) = (25.0, 43.3);
        let earth = [h * cfg.declination.sin(), h * cfg.declination.cos(), -dip];
        Self {
            cfg,
            path,
            s0,
            bias,
            noise,
            earth,
            phase,
        }
    }

    /// The field (µT, ENU) at position `p` (m).
    fn field(&self, p: [f64; 2]) -> Vec3<f64> {
        let (a, earth, phase) = (self.cfg.mag_disturbance, self.earth, self.phase);
        let tau = core::f64::consts::TAU;
        Vec3::new(
            earth[0] + a * (tau * p[0] / 7.0 + phase[0]).sin() * (tau * p[1] / 9.0).cos(),
            earth[1] + a * (tau * p[0] / 11.0).cos() * (tau * p[1] / 5.0 + phase[1]).sin(),
            earth[2] + 0.5 * a * (tau * (p[0] + p[1]) / 13.0).sin(),
        )
    }

    /// The true orientation at time `t` (s): the path's heading with the gait's pitch and roll.
    fn truth_q(&self, t: f64) -> Quat<f64> {
        let s = self.s0 + self.cfg.speed * t;
        let (tau, f) = (core::f64::consts::TAU, self.cfg.step_freq);
        let pitch = 0.03 * (tau * f * t).sin();
        let roll = 0.03 * (0.5 * tau * f * t).sin();
        Quat::from_euler_zyx(self.path.heading(s), pitch, roll)
    }

    /// The IMU sample at time `t` for orientation `q` and body rate `omega` (rad/s): bias and
    /// noise drawn from `rng` (gyroscope, accelerometer, magnetometer in that order).
    fn imu(&self, rng: &mut ChaCha8Rng, q: Quat<f64>, omega: Vec3<f64>, t: f64) -> ImuSample<f64> {
        let s = self.s0 + self.cfg.speed * t;
        let pos = self.path.position(s);
        let psi_walk = self.path.heading(s);
        let (tau, f) = (core::f64::consts::TAU, self.cfg.step_freq);
        let lin = Vec3::new(
            -0.5 * (tau * f * t).cos() * psi_walk.sin(),
            0.5 * (tau * f * t).cos() * psi_walk.cos(),
            9.81 + (tau * f * t).sin(),
        );
        let noise3 =
            |d: &Normal<f64>, r: &mut ChaCha8Rng| Vec3::new(d.sample(r), d.sample(r), d.sample(r));
        let [ng, na, nm] = &self.noise;
        let gyr = omega + self.bias + noise3(ng, rng);
        let acc = q.rotate_inverse(lin) + noise3(na, rng);
        let mag = q.rotate_inverse(self.field(pos)) + noise3(nm, rng);
        ImuSample::new(gyr, acc, mag)
    }
}

/// The largest position errors of both dead reckonings so far, and at the last sample
/// (`last`: the heading errors then, rad) the final errors.
fn track_positions(
    report: &mut WalkReport,
    [mems, beacon]: [&Pdr; 2],
    pos: [f64; 2],
    last: Option<[f64; 2]>,
) {
    let dist = |p: [f64; 2]| (p[0] - pos[0]).hypot(p[1] - pos[1]);
    report.max_pos_mems = report.max_pos_mems.max(dist(mems.position));
    report.max_pos_beacon = report.max_pos_beacon.max(dist(beacon.position));
    if let Some([em, eb]) = last {
        report.final_mems = em;
        report.final_beacon = eb;
        report.final_pos_mems = dist(mems.position);
        report.final_pos_beacon = dist(beacon.position);
    }
}

/// The circular mean of the true headings `(t, ψ)` in `h` over the time span `span` (s).
fn span_truth(h: &std::collections::VecDeque<(f64, f64)>, span: [f64; 2]) -> f64 {
    let (s, c) = h
        .iter()
        .filter(|(t, _)| *t >= span[0] && *t <= span[1])
        .fold((0.0, 0.0), |(s, c), (_, p): &(f64, f64)| {
            (s + p.sin(), c + p.cos())
        });
    s.atan2(c)
}

/// Ranges to the medium and strong beacons of a scan heard at least 10 dB above the
/// threshold: `(position, distance, its standard deviation)` from the class's fitted model.
fn strong_ranges(
    means: &[ScanMean],
    beacons: &BeaconSet,
    cfg: &WalkConfig,
    model: &impl Fn(BeaconClass) -> LogDistanceModel,
) -> Vec<([f64; 2], f64, f64)> {
    means
        .iter()
        .filter_map(|m| {
            let b = beacons.get(m.id)?;
            let strong_enough = m.rssi >= cfg.threshold + 10.0;
            (b.class != BeaconClass::Weak && strong_enough).then(|| {
                let md = model(b.class);
                (
                    b.position,
                    md.distance(m.rssi),
                    md.range_std(m.rssi, cfg.shadowing_db),
                )
            })
        })
        .collect()
}

/// The report's means from the walk's sums: heading RMS of both pipelines over `n` samples,
/// the fixes' position RMS and the beacon headings' RMS per kind.
fn summarise(report: &mut WalkReport, (sum_m, sum_b): (f64, f64), n: usize, hd_err: [f64; 2]) {
    report.rms_mems = (sum_m / n as f64).sqrt();
    report.rms_beacon = (sum_b / n as f64).sqrt();
    report.fix_rms.0 = (report.fix_rms.0 / report.fix_rms.1.max(1) as f64).sqrt();
    for ((rms, err), count) in report
        .beacon_heading_rms
        .iter_mut()
        .zip(hd_err)
        .zip(report.decisions)
    {
        *rms = (err / count.max(1) as f64).sqrt();
    }
}

/// Runs the beacon experiment on one simulated walk: [`HeadingPipeline`] on the simulated
/// IMU (6D or 9D), PDR with its heading (MEMS only), and PDR with the beacon-fused heading
/// (and beacon position fixes when `position_fixes`).
///
/// The beacon side: per 1 s scan, the [`Scanner`] means go into a [`BeaconMap`] of 8 records;
/// weak beacons give a heading by [`weak_heading`] (then the map is cleared); medium and
/// strong beacons heard in the scan at least 10 dB above the threshold (weaker means are
/// biased high by the censoring) are ranged with their class's fitted model (σ from the
/// shadowing) and multilaterated; the fixes of the last 12 s give (when they moved 10 m or more) a heading by
/// [`heading_from_fixes`] (then they are cleared). Headings go to a [`HeadingFusion`] with
/// [`FusionConfig::default`].
///
/// In 6D the pipeline has no heading reference; both runs start from the true initial
/// heading (the MEMS heading is offset once by the truth at the first sample, standing for
/// a known start direction).
pub fn run_walk(cfg: &WalkConfig) -> Result<WalkReport, super::BeaconError> {
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let path = Path::new(cfg.loop_size, cfg.corner_radius);
    let beacons = deploy(&path, cfg.beacon_spacing, cfg.beacon_offset);
    // Out to where the mean RSSI is 10 dB above the threshold: further out, readings lost
    // below the threshold censor the data and bias `n` low.
    let medium = calibrate(&mut rng, cfg, -70.0, 10)?;
    let strong = calibrate(&mut rng, cfg, -60.0, 20)?;
    let model = |c: BeaconClass| {
        if c == BeaconClass::Strong {
            strong
        } else {
            medium
        }
    };

    let walker = Walker::new(&mut rng, cfg, &path);

    let dt = 1.0 / cfg.rate;
    let n = (cfg.duration * cfg.rate).round() as usize;
    let f = cfg.step_freq;
    let params = HeadingPipelineParams {
        declination: cfg.declination,
        dof: cfg.dof,
        ..HeadingPipelineParams::default()
    };
    let mut filter = HeadingPipeline::<f64>::new(&params);
    let mut fusion = HeadingFusion::new(FusionConfig::default());
    let start = path.position(walker.s0);
    let mut pdr_mems = Pdr::new(start, 0.0, 0.01);
    let mut pdr_beacon = Pdr::new(start, 0.0, 0.01);
    let mut scanner = Scanner::new(cfg.threshold);
    let mut map = BeaconMap::new(8);
    let mut fixes: Vec<Fix> = Vec::new();
    let mut report = WalkReport {
        models: [[medium.a, medium.n], [strong.a, strong.n]],
        ..WalkReport::default()
    };
    let (mut sum_m, mut sum_b) = (0.0, 0.0);
    let mut offset0 = None;
    let step_len = cfg.speed / f;
    let mut next_step = 1.0 / f;
    let mut next_scan = 1.0;
    let mut q_prev = walker.truth_q(0.0);
    let mut truth_hist: std::collections::VecDeque<(f64, f64)> = Default::default();
    let mut hd_err = [0.0f64; 2];
    for k in 1..=n {
        let t = k as f64 * dt;
        let q = walker.truth_q(t);
        let omega = (q_prev.conj() * q).to_rotation_vector() * (1.0 / dt);
        q_prev = q;
        let pos = path.position(walker.s0 + cfg.speed * t);
        filter.update(&walker.imu(&mut rng, q, omega, t), dt);

        let (psi_true, _) = q.heading_inclination();
        let raw = filter.heading();
        let off = if cfg.dof == Dof::Six {
            *offset0.get_or_insert(wrap(psi_true - raw))
        } else {
            0.0
        };
        let psi_mems = wrap(raw + off);
        let psi_fused = fusion.push_mems(t, psi_mems);
        truth_hist.push_back((t, psi_true));
        while truth_hist.front().is_some_and(|(t0, _)| *t0 < t - 40.0) {
            truth_hist.pop_front();
        }

        if t >= next_step {
            next_step += 1.0 / f;
            pdr_mems.step(step_len, psi_mems);
            pdr_beacon.step(step_len, psi_fused);
        }
        if t >= next_scan {
            next_scan += 1.0;
            for r in scan(&mut rng, cfg, &beacons, pos, t) {
                // Simulated readings are always valid; bad ones would be counted by `scanner`.
                let _ = scanner.add(r, &beacons);
            }
            let means = scanner.finish();
            map.push_scan(t, &means);
            if let Some(hd) = weak_heading(&map, &beacons, &TrendConfig::default()) {
                report.decisions[0] += 1;
                hd_err[0] += wrap(hd.psi - span_truth(&truth_hist, hd.span)).powi(2);
                let ok = fusion.update(&hd);
                report.headings[usize::from(!ok)] += 1;
                map.clear();
            }
            let ranges = strong_ranges(&means, &beacons, cfg, &model);
            if let Ok(fix) = multilaterate(t, &ranges) {
                if cfg.position_fixes {
                    pdr_beacon.correct(&fix);
                }
                report.fix_rms.0 +=
                    (fix.position[0] - pos[0]).powi(2) + (fix.position[1] - pos[1]).powi(2);
                report.fix_rms.1 += 1;
                fixes.push(fix);
                fixes.retain(|f| f.t > t - 12.0);
                if let Some(hd) = heading_from_fixes(&fixes, 10.0) {
                    report.decisions[1] += 1;
                    hd_err[1] += wrap(hd.psi - span_truth(&truth_hist, hd.span)).powi(2);
                    let ok = fusion.update(&hd);
                    report.headings[usize::from(!ok)] += 1;
                    fixes.clear();
                }
            }
        }
        let errors = [wrap(psi_mems - psi_true), wrap(psi_fused - psi_true)];
        sum_m += errors[0] * errors[0];
        sum_b += errors[1] * errors[1];
        track_positions(
            &mut report,
            [&pdr_mems, &pdr_beacon],
            pos,
            (k == n).then_some(errors),
        );
    }
    summarise(&mut report, (sum_m, sum_b), n, hd_err);
    Ok(report)
}
