//! Bad samples cannot hurt (issue 27): bursts of absurd, non-finite or stuck values on one
//! axis of one sensor, on the 14 shared BROAD trials and in a proptest on simulated motion,
//! for every registered filter; and the exactness of the one low-pass gain.
//!
//! The reference of a corrupted run is the same recording where every gyroscope burst of an
//! absurd or non-finite value is *lost* (NaN, the whole sample skipped, as the screening
//! documents) and every other burst is clean. A gyroscope sample carries rotation that no
//! other sensor gives back: when it is unusable the filters skip it, and the 6D heading keeps
//! the rotation lost (the 9D one and the inclination recover at each filter's own rate).
//! What a bad sample must not do is cost more than losing it. A *stuck* gyroscope axis
//! cannot be told from a real reading: the filter integrates the wrong rotation, and no
//! filter can undo it in 2 s (the 6D heading never), so each such burst adds the rotation
//! error it integrated, `Σ |ω − ω_stuck|·dt` (degrees), to the bounds (the RMSE of the
//! difference of two error series is at most its largest value, so the RMSE moves by at
//! most the sum of these).
use crate::common::broad_dir;
use rand::{Rng, SeedableRng};
use rootfuse_attitude::blocks::{
    lowpass_gain, lowpass_gain_at_rate, lowpass_gains, lowpass_gains_at_rates,
};
use rootfuse_attitude::registry::{FilterKind, FilterSpec};
use rootfuse_attitude::{Dof, Lane, OrientationFilter, Quat, Recording, Vec3};
use rootfuse_batch::{Precision, run_recordings};
use rootfuse_eval::metrics::{Alignment, evaluate};
use rootfuse_io::read_csv;

/// What a burst writes into its axis.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Value {
    /// A fixed value for every sample of the burst (±1e3, ±1e6, ±1e30, NaN).
    Fixed(f64),
    /// The axis keeps the value it had just before the burst.
    Stuck,
}

const VALUES: [Value; 8] = [
    Value::Fixed(1e3),
    Value::Fixed(-1e3),
    Value::Fixed(1e6),
    Value::Fixed(-1e6),
    Value::Fixed(1e30),
    Value::Fixed(-1e30),
    Value::Fixed(f64::NAN),
    Value::Stuck,
];

/// One axis of one sensor (0 gyroscope, 1 accelerometer, 2 magnetometer) overwritten for
/// `len` samples from `start`.
#[derive(Clone, Copy, Debug)]
struct Burst {
    start: usize,
    len: usize,
    sensor: usize,
    axis: usize,
    value: Value,
}

fn axis(v: &mut Vec3<f64>, axis: usize) -> &mut f64 {
    match axis {
        0 => &mut v.x,
        1 => &mut v.y,
        _ => &mut v.z,
    }
}

fn sensor(rec: &mut Recording, sensor: usize) -> Option<&mut Vec<Vec3<f64>>> {
    match sensor {
        0 => Some(&mut rec.gyr),
        1 => Some(&mut rec.acc),
        _ => rec.mag.as_mut(),
    }
}

/// The corrupted recording, its reference and per burst the rotation error (degrees) a stuck
/// gyroscope axis integrates. The reference loses (NaN on all three axes of the sensor) the
/// samples of the bursts `lose` picks and has the others clean.
fn corrupt(
    clean: &Recording,
    bursts: &[Burst],
    lose: impl Fn(&Burst) -> bool,
) -> (Recording, Recording, Vec<f64>) {
    let (mut bad, mut reference) = (clean.clone(), clean.clone());
    let mut excuses = Vec::new();
    for b in bursts {
        let range = b.start..b.start + b.len;
        let mut excuse = 0.0;
        if b.sensor == 0 && b.value == Value::Stuck {
            let stuck = clean.gyr[b.start - 1].to_array()[b.axis];
            for i in range.clone() {
                excuse += (clean.gyr[i].to_array()[b.axis] - stuck).abs() * clean.dt(i) * 180.0
                    / core::f64::consts::PI;
            }
        }
        excuses.push(excuse);
        if let Some(series) = sensor(&mut bad, b.sensor) {
            let before = *axis(&mut series[b.start - 1], b.axis);
            for v in &mut series[range.clone()] {
                *axis(v, b.axis) = match b.value {
                    Value::Fixed(x) => x,
                    Value::Stuck => before,
                };
            }
        }
        if lose(b)
            && let Some(series) = sensor(&mut reference, b.sensor)
        {
            for v in &mut series[range] {
                *v = Vec3::new(f64::NAN, f64::NAN, f64::NAN);
            }
        }
    }
    (bad, reference, excuses)
}

/// The reference of the burst test: absurd or non-finite gyroscope bursts are lost
/// (the whole sample is skipped either way), the others clean.
fn lost_gyroscope(b: &Burst) -> bool {
    b.sensor == 0 && b.value != Value::Stuck
}

/// `count` bursts at seeded random places, one in each of `count` equal slots after the
/// first `lead` samples and before the last `tail`, each 1–10 samples long and starting in
/// the first half of its slot (so the check `tail` samples later lies before the next one).
/// `sensors` and `values` are the choices.
fn bursts(
    rng: &mut impl Rng,
    n: usize,
    (count, lead, tail): (usize, usize, usize),
    sensors: core::ops::Range<usize>,
    values: &[Value],
) -> Vec<Burst> {
    let slot = (n - lead - tail) / count;
    (0..count)
        .map(|k| Burst {
            start: lead + k * slot + rng.random_range(0..slot / 2),
            len: rng.random_range(1..=10),
            sensor: rng.random_range(sensors.clone()),
            axis: rng.random_range(0..3),
            value: values[rng.random_range(0..values.len())],
        })
        .collect()
}

/// The 14 shared BROAD trials with 20 bursts each (seeded) drawn from `sensors` and
/// `values`, the reference losing the bursts `lose` picks; `None` without the data.
fn broad_cases(
    seed: u64,
    sensors: core::ops::Range<usize>,
    values: &[Value],
    lose: impl Fn(&Burst) -> bool + Copy,
) -> Option<Vec<Case>> {
    let dir = broad_dir()?;
    let index = std::fs::read_to_string(dir.join("index.csv")).unwrap();
    let trials: Vec<&str> = index
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').next())
        .collect();
    assert_eq!(trials.len(), 14);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    Some(
        trials
            .iter()
            .map(|t| {
                let clean = read_csv(dir.join(format!("{t}.csv"))).unwrap();
                let b = bursts(
                    &mut rng,
                    clean.len(),
                    (20, LEAD, AFTER + 20),
                    sensors.clone(),
                    values,
                );
                let (bad, reference, excuses) = corrupt(&clean, &b, lose);
                (bad, reference, b, excuses)
            })
            .collect(),
    )
}

/// BROAD runs at 286 Hz: bursts from 10 s on, each checked 2 s (572 samples) after its end.
const LEAD: usize = 2860;
const AFTER: usize = 572;

/// Runs `specs` on `cases` and fails with every filter whose margin is positive.
fn check(specs: &[FilterSpec], cases: &[Case]) {
    let mut failures = Vec::new();
    for spec in specs {
        let started = std::time::Instant::now();
        let (rmse_bound, after_bound) = bounds(spec.kind());
        let w = run_filter(spec, cases, AFTER, (rmse_bound, after_bound));
        let name = format!(
            "{} {}D",
            spec.kind().name(),
            if spec.uses_magnetometer() { 9 } else { 6 }
        );
        eprintln!(
            "{name:>32}: margins RMSE {:+.4}° ({}), 2 s after {:+.4}° ({}) [{:.1} s]",
            w.rmse.0,
            w.rmse.1,
            w.after.0,
            w.after.1,
            started.elapsed().as_secs_f64()
        );
        if w.rmse.0 > 0.0 {
            failures.push(format!(
                "{name}: RMSE {:.4}° beyond its bound {rmse_bound}°: {}",
                w.rmse.0, w.rmse.1
            ));
        }
        if w.after.0 > 0.0 {
            failures.push(format!(
                "{name}: {:.4}° beyond {after_bound}° 2 s after {}",
                w.after.0, w.after.1
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Angle between two orientations, degrees.
fn angle_deg(a: Quat<f64>, b: Quat<f64>) -> f64 {
    let e = a * b.conj();
    2.0 * (e.x * e.x + e.y * e.y + e.z * e.z).sqrt().atan2(e.w.abs()) * 180.0
        / core::f64::consts::PI
}

/// Worst outcome of one filter over all trials, as margins over the bounds (degrees;
/// negative: within), with where.
#[derive(Debug, Default)]
struct Worst {
    rmse: (f64, String),
    after: (f64, String),
}

/// Case: corrupted recording, reference, bursts, their stuck-gyroscope excuses (degrees).
type Case = (Recording, Recording, Vec<Burst>, Vec<f64>);

/// Runs one filter on every case and returns the worst margins over the bounds: RMSE change
/// minus `rmse_bound` plus the excuses, and likewise 2 s after each burst.
fn run_filter(
    spec: &FilterSpec,
    cases: &[Case],
    after: usize,
    (rmse_bound, after_bound): (f64, f64),
) -> Worst {
    let align = if spec.uses_magnetometer() {
        Alignment::NineD
    } else {
        Alignment::SixD
    };
    let recs: Vec<Recording> = cases
        .iter()
        .flat_map(|(bad, reference, _, _)| [bad.clone(), reference.clone()])
        .collect();
    let out = run_recordings(spec, &recs, Precision::F64);
    let mut worst = Worst {
        rmse: (f64::NEG_INFINITY, String::new()),
        after: (f64::NEG_INFINITY, String::new()),
    };
    for (k, (bad, _, bursts, excuses)) in cases.iter().enumerate() {
        let (qb, qr) = (&out[2 * k].quat, &out[2 * k + 1].quat);
        let eb = evaluate(bad, qb, align).expect("truth").total;
        let er = evaluate(bad, qr, align).expect("truth").total;
        let total_excuse: f64 = excuses.iter().sum();
        // NaN (a diverged run) counts as the worst possible margin.
        let margin = |d: f64, bound: f64| if d.is_nan() { f64::INFINITY } else { d - bound };
        let m = margin((eb - er).abs(), rmse_bound + total_excuse);
        if m > worst.rmse.0 {
            worst.rmse = (
                m,
                format!(
                    "{}: {eb:.4}° vs reference {er:.4}° (excuse {total_excuse:.3}°)",
                    bad.name
                ),
            );
        }
        let mut excuse = 0.0;
        for (b, e) in bursts.iter().zip(excuses) {
            excuse += e;
            let i = b.start + b.len + after;
            let a = angle_deg(qb[i], qr[i]);
            let m = margin(a, after_bound + excuse);
            if m > worst.after.0 {
                worst.after = (
                    m,
                    format!("{} {a:.4}° (excuse {excuse:.3}°) {b:?}", bad.name),
                );
            }
        }
    }
    worst
}

/// Per filter: the bound on the total-RMSE change and on the distance 2 s after a burst,
/// degrees. The bounds (0.05°, 0.5°) unless argued here.
///
/// Looser for the complementary family, Mahony, the heading pipeline and lsq-fusion in 9D:
/// on the disturbed-field trials (29, the stationary magnet) their error is 10–60°, and
/// their magnetometer correction in the disturbed field amplifies any change of the tilt, so
/// losing 6–9 accelerometer corrections moves them by up to 1.6° two seconds later and
/// their RMSE by up to 0.07°. That is what *losing* the samples costs: the worst cases are
/// bursts beyond `max_acc` (±1e30), which the screening turns into exactly the run with the
/// accelerometer dropped (NaN), so no screening or gate could do better for these filters.
/// Measured worst (seed 27): 1.61° / 0.070°; bounds 2° / 0.1°.
fn bounds(kind: FilterKind) -> (f64, f64) {
    match kind.name() {
        "complementary"
        | "complementary-reconstruction"
        | "mahony"
        | "heading-pipeline"
        | "lsq-fusion" => (0.1, 2.0),
        _ => (0.05, 0.5),
    }
}

/// The filters and dimensions run: every filter in 9D (the magnetometer bursts matter
/// there), the flagship also in 6D.
fn specs() -> Vec<FilterSpec> {
    let mut specs: Vec<FilterSpec> = FilterKind::ALL
        .iter()
        .map(|k| {
            let mut s = FilterSpec::new(k.name()).unwrap();
            s.set_dof(Dof::Nine).unwrap();
            s
        })
        .collect();
    let mut six = FilterSpec::new("sqrt-eskf").unwrap();
    six.set_dof(Dof::Six).unwrap();
    specs.push(six);
    specs
}

/// The 14 shared BROAD trials, 20 bursts each (seeded), every registered filter: the total
/// RMSE within 0.05° of the reference run and, 2 s after each burst, the estimate within 0.5°
/// of it (per-filter exceptions in [`bounds`]).
#[test]
#[cfg_attr(
    not(broad_data),
    ignore = "BROAD data not found (../shared/broad_csv or $ROOTFUSE_BROAD_DIR)"
)]
fn bursts_on_broad_cost_no_more_than_losing_the_samples() {
    let Some(cases) = broad_cases(27, 0..3, &VALUES, lost_gyroscope) else {
        return;
    };
    check(&specs(), &cases);
}

/// The flagship on accelerometer bursts *within* `max_acc` (±500 and ±999 m/s² on one axis,
/// or a stuck axis), 20 per BROAD trial, 9D and 6D: its spike gate keeps them out of every
/// state, so they cost what losing the samples costs (same bounds, against the run that lost
/// the spike samples; against the clean run for a stuck axis).
#[test]
#[cfg_attr(
    not(broad_data),
    ignore = "BROAD data not found (../shared/broad_csv or $ROOTFUSE_BROAD_DIR)"
)]
fn flagship_gates_accelerometer_spikes_within_the_limit() {
    let values = [
        Value::Fixed(500.0),
        Value::Fixed(-500.0),
        Value::Fixed(999.0),
        Value::Fixed(-999.0),
        Value::Stuck,
    ];
    // A gated spike must cost what losing the sample costs, no more: the reference loses
    // the spike samples (a stuck axis is not gated: its reference is clean). Losing 6
    // accelerometer samples can itself move the flagship by ~2° two seconds later during a
    // fast translation (BROAD 18 at 143 s: a 6-sample burst of −500 m/s², −2000 m/s² or NaN
    // there gives the same 1.95°, so the gate makes a spike exactly a lost sample; why losing
    // samples costs that much there is not analysed yet).
    let lost_spikes = |b: &Burst| b.value != Value::Stuck;
    let Some(cases) = broad_cases(2027, 1..2, &values, lost_spikes) else {
        return;
    };
    let specs: Vec<FilterSpec> = [Dof::Nine, Dof::Six]
        .map(|d| {
            let mut s = FilterSpec::new("sqrt-eskf").unwrap();
            s.set_dof(d).unwrap();
            s
        })
        .into();
    check(&specs, &cases);
}

/// The example: `ax = 1e39` at row 20000 of BROAD trial 02, which, taken as a
/// measurement, moves the flagship's total RMSE from 1.247° to 94.2°. The sample is beyond
/// `max_acc`: only its accelerometer correction is skipped (counted, flag 4), and the RMSE
/// does not move; a spike of 500 m/s²,
/// within the limit, is gated by the flagship's `acc_spike` instead (counted as gated).
#[test]
#[cfg_attr(
    not(broad_data),
    ignore = "BROAD data not found (../shared/broad_csv or $ROOTFUSE_BROAD_DIR)"
)]
fn one_absurd_accelerometer_sample_on_trial_02() {
    let Some(dir) = broad_dir() else { return };
    let clean = read_csv(dir.join("02_undisturbed_slow_rotation_B.csv")).unwrap();
    let spec = FilterSpec::new("sqrt-eskf").unwrap();
    let rmse = |rec: &Recording| {
        let est = rec.estimate(&mut spec.build::<f64>());
        evaluate(rec, &est, Alignment::NineD).unwrap().total
    };
    let base = rmse(&clean);
    for (x, bit) in [(1e39, 4u8), (1e6, 4), (500.0, 16), (-500.0, 16)] {
        let mut bad = clean.clone();
        bad.acc[20000].x = x;
        let got = rmse(&bad);
        let mut f = spec.build::<f64>();
        let mut flags = 0;
        for i in 0..=20000 {
            f.update(&bad.sample(i), bad.dt(i));
            flags = f.flags().bits(0);
        }
        eprintln!("ax = {x:e} at row 20000: {got:.4}° (clean {base:.4}°), flags {flags}");
        assert!((got - base).abs() <= 0.01, "ax = {x:e}: {got}° vs {base}°");
        assert!(flags & bit != 0, "ax = {x:e}: flags {flags}");
    }
}

/// The recovery property on simulated motion, every filter (9D): one burst of 1–10 samples
/// anywhere after the start, of any of the values, on any axis of any sensor; 2 s after it the
/// estimate is within 0.5° of the reference run (the same recording with a gyroscope burst
/// lost, see the module documentation).
mod recovery {
    use super::*;
    use proptest::prelude::*;
    use std::sync::OnceLock;

    fn clean() -> &'static Recording {
        static REC: OnceLock<Recording> = OnceLock::new();
        REC.get_or_init(|| rootfuse_eval::sim::scenario("slow-rotation", 7, 12.0, 100.0).unwrap())
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]
        #[test]
        fn a_burst_is_forgotten_within_2_s(
            start in 300usize..800,
            len in 1usize..=10,
            sensor in 0usize..3,
            axis in 0usize..3,
            value in 0usize..VALUES.len(),
        ) {
            let burst = Burst { start, len, sensor, axis, value: VALUES[value] };
            let (bad, reference, excuse) = corrupt(clean(), &[burst], lost_gyroscope);
            let i = start + len + 200;
            for spec in specs() {
                let out = run_recordings(&spec, &[bad.clone(), reference.clone()], Precision::F64);
                let a = angle_deg(out[0].quat[i], out[1].quat[i]);
                let bound = bounds(spec.kind()).1 + excuse[0];
                prop_assert!(a <= bound, "{}: {a}° > {bound}° after {burst:?}", spec.kind().name());
            }
        }
    }
}

/// `lowpass_gain` is `−expm1(−dt/τ)`: relative error within 2ε in f64 and f32 over
/// `dt/τ ∈ [1e-12, 1e6]` (the series, the halvings and doublings, and libm's range), lanes
/// equal to scalars bit for bit, and the ends documented: `τ = 0` is no low-pass (gain 1),
/// `dt = 0` takes nothing in.
#[test]
fn lowpass_gain_is_exact() {
    use wide::{f32x8, f64x4};
    let xs: Vec<f64> = (0..=1800)
        .map(|k| 10f64.powf(-12.0 + k as f64 * 0.01))
        .collect();
    let (mut worst64, mut worst32) = (0.0f64, 0.0f64);
    for &x in &xs {
        let exact = -(-x).exp_m1();
        for tau in [1.0, 0.5, 3.0] {
            // dt = x·τ is exact for these τ only up to rounding: compare with the x it gives.
            let dt = x * tau;
            let exact = if tau == 1.0 {
                exact
            } else {
                -(-(dt / tau)).exp_m1()
            };
            let got = lowpass_gain(dt, tau);
            let ulps = (got - exact).abs() / (exact * f64::EPSILON);
            worst64 = worst64.max(ulps);
            let got32 = lowpass_gain(dt as f32, tau as f32);
            let exact32 = -(-(f64::from(dt as f32) / f64::from(tau as f32))).exp_m1();
            let ulps32 = (f64::from(got32) - exact32).abs() / (exact32 * f64::from(f32::EPSILON));
            worst32 = worst32.max(ulps32);
        }
    }
    eprintln!("lowpass_gain: worst relative error {worst64:.2}ε in f64, {worst32:.2}ε in f32");
    assert!(worst64 <= 2.0, "f64: {worst64} ulp");
    assert!(worst32 <= 2.0, "f32: {worst32} ulp");
    // Lanes equal scalars, with the ends in single lanes.
    let dts = [0.01, 0.0, 1e-9, 5.0, 0.01, f64::INFINITY, f64::NAN, 2.0];
    let taus = [0.0, 0.0, 1.0, 1e-3, 1e9, 1.0, 1.0, f64::INFINITY];
    for c in 0..2 {
        let v = f64x4::from_fn(|i| dts[4 * c + i]);
        let t = f64x4::from_fn(|i| taus[4 * c + i]);
        let g = lowpass_gain(v, t);
        for i in 0..4 {
            assert_eq!(
                g.extract(i).to_bits(),
                lowpass_gain(dts[4 * c + i], taus[4 * c + i]).to_bits()
            );
        }
    }
    let g = lowpass_gain(
        f32x8::from_fn(|i| dts[i] as f32),
        f32x8::from_fn(|i| taus[i] as f32),
    );
    for i in 0..8 {
        assert_eq!(
            g.extract(i).to_bits(),
            lowpass_gain(dts[i] as f32, taus[i] as f32).to_bits()
        );
    }
    // Every lane in the SIMD range (a jittered `dt`, and a few samples against a short τ):
    // the short series, the long one, and each lane halved and doubled as often as it needs
    // alone (0 to 3; the last lane's `x` is 3.8).
    let dts: [f32; 8] = core::array::from_fn(|i| 0.0035 * (1.0 + 0.01 * (i as f32 - 3.5)));
    let taus: [f32; 8] = [0.1, 0.15, 1.0, 20.0, 0.05, 0.012, 0.001, 0.00095];
    let g = lowpass_gain(f32x8::from_fn(|i| dts[i]), f32x8::from_fn(|i| taus[i]));
    let g64 = lowpass_gain(
        f64x4::from_fn(|i| f64::from(dts[i + 4])),
        f64x4::from_fn(|i| f64::from(taus[i + 4])),
    );
    for i in 0..8 {
        assert_eq!(
            g.extract(i).to_bits(),
            lowpass_gain(dts[i], taus[i]).to_bits()
        );
    }
    for i in 0..4 {
        let (d, t) = (f64::from(dts[i + 4]), f64::from(taus[i + 4]));
        assert_eq!(g64.extract(i).to_bits(), lowpass_gain(d, t).to_bits());
    }
    // Several time constants at once: the bits of one call each, in and out of the series'
    // range (a lane with τ = 0, one halved).
    let dt = f32x8::from_fn(|i| dts[i]);
    let tau = |t: f32| f32x8::from_fn(|i| if i == 2 { 0.0 } else { t });
    let taus4 = [tau(0.5), tau(1.0), tau(0.02), tau(8.0)];
    for (all, one) in [
        (
            lowpass_gains(dt, [taus4[0], taus4[1]]).to_vec(),
            &taus4[..2],
        ),
        (lowpass_gains(dt, taus4).to_vec(), &taus4[..]),
        (
            lowpass_gains(dt, [taus4[2], taus4[3]]).to_vec(),
            &taus4[2..],
        ),
    ] {
        for (g, &t) in all.iter().zip(one) {
            assert_eq!(
                g.to_array().map(f32::to_bits),
                lowpass_gain(dt, t).to_array().map(f32::to_bits)
            );
        }
    }
    let [a, b] = lowpass_gains(0.01_f64, [0.5, 0.05]);
    assert_eq!(
        (a.to_bits(), b.to_bits()),
        (
            lowpass_gain(0.01_f64, 0.5).to_bits(),
            lowpass_gain(0.01_f64, 0.05).to_bits()
        )
    );
    assert_eq!(lowpass_gain(0.01, 0.0), 1.0, "τ = 0: no low-pass");
    assert_eq!(lowpass_gain(0.0, 0.0), 0.0, "dt = 0 takes nothing in");
    assert_eq!(lowpass_gain(f64::NAN, 1.0), 0.0);
    assert_eq!(lowpass_gain(1.0, f64::INFINITY), 0.0);
    assert_eq!(lowpass_gain(f64::INFINITY, 1.0), 1.0);
    assert_eq!(lowpass_gain(1e6, 1.0), 1.0);
}

/// The rate form `lowpass_gain_at_rate(dt, 1/τ)` (the flagship's, with its rates converted
/// from `f64` once): relative error within 3ε of `−expm1(−dt/τ)` in f64 and f32 over
/// `dt/τ ∈ [1e-12, 1e6]` (the short and long series, the halvings and doublings, libm's
/// range), lanes equal to scalars bit for bit with every range side by side in one vector,
/// several rates at once the bits of one call each, and the ends: a rate of ∞ (`τ = 0`) is
/// no low-pass, ±0 (`τ = ±∞`) holds, `dt = 0` takes nothing in.
#[test]
fn lowpass_gain_at_rate_is_exact() {
    use wide::{f32x8, f64x4};
    let (mut worst64, mut worst32) = (0.0f64, 0.0f64);
    for k in 0..=1800 {
        let x = 10f64.powf(-12.0 + k as f64 * 0.01);
        for tau in [1.0, 0.5, 3.0, 0.3] {
            let dt = x * tau;
            let exact = -(-(dt / tau)).exp_m1();
            let got = lowpass_gain_at_rate(dt, 1.0 / tau);
            worst64 = worst64.max((got - exact).abs() / (exact * f64::EPSILON));
            let dt32 = dt as f32;
            let exact32 = -(-(f64::from(dt32) / tau)).exp_m1();
            let got32 = lowpass_gain_at_rate(dt32, (1.0 / tau) as f32);
            let ulps32 = (f64::from(got32) - exact32).abs() / (exact32 * f64::from(f32::EPSILON));
            worst32 = worst32.max(ulps32);
        }
    }
    eprintln!(
        "lowpass_gain_at_rate: worst relative error {worst64:.2}ε in f64, {worst32:.2}ε in f32"
    );
    assert!(worst64 <= 3.0, "f64: {worst64} ulp");
    assert!(worst32 <= 3.0, "f32: {worst32} ulp");
    // Lanes equal scalars: the ends in single lanes; then `x` of 0.0002 to 3.8 (the short
    // series, the long one, one to three halvings) side by side in the SIMD path; then the
    // same beside one lane out of its range (every lane through the scalar form).
    let dts = [0.01, 0.0, 1e-9, 5.0, 0.01, f64::INFINITY, f64::NAN, 0.01];
    let rates = [f64::INFINITY, 0.0, 1.0, 1e3, -0.0, 1.0, 1.0, f64::NAN];
    let mixed_dts: [f64; 8] = core::array::from_fn(|i| 0.0035 * (1.0 + 0.01 * (i as f64 - 3.5)));
    let mixed_rates = [10.0, 40.0, 1.0, 0.05, 250.0, 500.0, 1000.0, 1050.0];
    let mut one_out = mixed_rates;
    one_out[4] = f64::INFINITY;
    for (dts, rates) in [(dts, rates), (mixed_dts, mixed_rates), (mixed_dts, one_out)] {
        for c in 0..2 {
            let g = lowpass_gain_at_rate(
                f64x4::from_fn(|i| dts[4 * c + i]),
                f64x4::from_fn(|i| rates[4 * c + i]),
            );
            for i in 0..4 {
                let one = lowpass_gain_at_rate(dts[4 * c + i], rates[4 * c + i]);
                assert_eq!(g.extract(i).to_bits(), one.to_bits());
            }
        }
        let (dt, rate) = (
            f32x8::from_fn(|i| dts[i] as f32),
            f32x8::from_fn(|i| rates[i] as f32),
        );
        let g = lowpass_gain_at_rate(dt, rate);
        for i in 0..8 {
            let one = lowpass_gain_at_rate(dts[i] as f32, rates[i] as f32);
            assert_eq!(g.extract(i).to_bits(), one.to_bits());
        }
        // Several rates at once: the bits of one call each.
        let other = f32x8::from_fn(|i| [2.0, 0.5, 30.0][i % 3]);
        let [a, b] = lowpass_gains_at_rates(dt, [rate, other]);
        assert_eq!(a.to_array(), lowpass_gain_at_rate(dt, rate).to_array());
        assert_eq!(b.to_array(), lowpass_gain_at_rate(dt, other).to_array());
    }
    assert_eq!(
        lowpass_gain_at_rate(0.01, f64::INFINITY),
        1.0,
        "τ = 0: no low-pass"
    );
    assert_eq!(lowpass_gain_at_rate(0.01, 0.0), 0.0, "τ = ∞ holds");
    assert_eq!(
        lowpass_gain_at_rate(0.01_f32, -0.0).to_bits(),
        0.0_f32.to_bits()
    );
    assert_eq!(
        lowpass_gain_at_rate(0.0, f64::INFINITY),
        0.0,
        "dt = 0 takes nothing in"
    );
    assert_eq!(lowpass_gain_at_rate(f64::INFINITY, 1.0), 1.0);
    assert_eq!(lowpass_gain_at_rate(0.01, -1.0), 1.0);
}
