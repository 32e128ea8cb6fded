//! The batch engine: every registered filter in lanes equals per-channel scalar runs bit for
//! bit (bad samples in single channels, ragged lengths, tail lanes, masked steps), and results
//! do not depend on the thread count.
use crate::common::same_bits;
use rootfuse::batch::{
    Batch, Channel, ChannelOutput, ChannelSource, Columns, Precision, RejectionTotals, fill_lanes,
    flag, run_final_states, run_recordings, run_recordings_with, run_sources,
    state_bytes_per_channel,
};
use rootfuse_attitude::registry::{FilterKind, FilterSpec};
use rootfuse_attitude::{ImuSample, Lane, OrientationFilter, Quat, Recording, Vec3};
use rootfuse_eval::sim::{scenario, scenario_names};
use rootfuse_lane::X2;
use rootfuse_lane::wide::{f32x8, f64x4};

/// One channel alone through the scalar filter, as `run_recordings` promises to reproduce.
fn scalar_run<S: Lane + Into<f64>>(spec: &FilterSpec, rec: &Recording) -> ChannelOutput {
    let mut f = spec.build::<S>();
    let mut out = ChannelOutput::default();
    for k in 0..rec.len() {
        let s = rec.sample(k);
        let c = |v: Vec3<f64>| Vec3::<S>::from_f64([v.x, v.y, v.z]);
        f.update(
            &ImuSample::new(c(s.gyr), c(s.acc), c(s.mag)),
            S::from_f64(rec.dt(k)),
        );
        let (q, b) = (f.quat(), f.bias());
        out.quat
            .push(Quat::new(q.w.into(), q.x.into(), q.y.into(), q.z.into()));
        out.bias.push(Vec3::new(b.x.into(), b.y.into(), b.z.into()));
    }
    out.rejections = RejectionTotals::of_lane(f.rejections(), 0);
    out
}

fn assert_same(a: &ChannelOutput, b: &ChannelOutput, what: &str) {
    assert_eq!(a.quat.len(), b.quat.len(), "{what}: length");
    assert_eq!(a.rejections, b.rejections, "{what}: counters");
    for (k, (qa, qb)) in a.quat.iter().zip(&b.quat).enumerate() {
        let same = qa
            .to_array()
            .into_iter()
            .zip(qb.to_array())
            .all(|(x, y)| same_bits(x, y));
        assert!(same, "{what}: quat at step {k}: {qa:?} vs {qb:?}");
    }
    for (k, (ba, bb)) in a.bias.iter().zip(&b.bias).enumerate() {
        let same = ba
            .to_array()
            .into_iter()
            .zip(bb.to_array())
            .all(|(x, y)| same_bits(x, y));
        assert!(same, "{what}: bias at step {k}: {ba:?} vs {bb:?}");
    }
}

/// `n` simulated recordings of different scenarios, lengths and rates; every third one drops
/// its magnetometer (6D data into 9D filters), and single channels get NaN, zero and huge
/// samples and bad time steps (negative, NaN, zero, a 5 s gap).
fn recordings(n: usize) -> Vec<Recording> {
    let names: Vec<&str> = scenario_names().collect();
    (0..n)
        .map(|i| {
            let duration = 0.6 + 0.25 * (i % 5) as f64;
            let rate = [100.0, 150.0, 200.0][i % 3];
            let mut rec = scenario(names[i % names.len()], i as u64, duration, rate).unwrap();
            if i % 3 == 2 {
                rec.mag = None;
            }
            if i % 2 == 1 {
                let len = rec.len();
                let at = |f: f64| ((len as f64 * f) as usize).min(len - 1);
                rec.gyr[at(0.2)] = Vec3::new(f64::NAN, 0.0, 0.0);
                rec.acc[at(0.3)] = Vec3::zero();
                rec.acc[at(0.35)] = Vec3::new(1e30, 1e30, 1e30);
                rec.gyr[at(0.4)] = Vec3::new(1e20, -1e20, 1e20);
                if let Some(mag) = &mut rec.mag {
                    mag[at(0.45)] = Vec3::new(f64::INFINITY, 0.0, 0.0);
                    mag[at(0.5)] = Vec3::zero();
                }
                let k = at(0.6);
                rec.t[k] = rec.t[k - 1] - 0.01; // negative step, then a double one
                rec.t[at(0.7)] = f64::NAN; // NaN steps on both sides
                let k = at(0.8);
                let gap = 5.0;
                for t in &mut rec.t[k..] {
                    *t += gap; // one step beyond max_dt
                }
                rec.t[at(0.9)] = rec.t[at(0.9) - 1]; // zero step
            }
            rec
        })
        .collect()
}

fn specs() -> Vec<(FilterSpec, u8)> {
    let mut out = Vec::new();
    for &kind in FilterKind::ALL {
        for dof in [6u8, 9] {
            let mut spec = FilterSpec::new(kind.name()).unwrap();
            spec.set_dof(crate::common::dof(dof)).unwrap();
            out.push((spec, dof));
        }
    }
    out
}

/// The core promise: for every registered filter, 6D and 9D, f32x8 and f64x4, channel counts
/// 1, 7 and 13 (tail lanes in both widths) with ragged lengths and bad data in single
/// channels, `run_recordings` equals the per-channel scalar runs bit for bit, counters too.
#[test]
fn every_filter_equals_scalar_runs() {
    let all = recordings(13);
    for (spec, dof) in specs() {
        for n in [1usize, 7, 13] {
            let recs = &all[13 - n..];
            let f32_out = run_recordings(&spec, recs, Precision::F32);
            let f64_out = run_recordings(&spec, recs, Precision::F64);
            assert_eq!((f32_out.len(), f64_out.len()), (n, n));
            for (i, rec) in recs.iter().enumerate() {
                let what = |p: &str| {
                    format!(
                        "{} {dof}D {p}, {n} channels, channel {i}",
                        spec.kind().name()
                    )
                };
                assert_same(&f32_out[i], &scalar_run::<f32>(&spec, rec), &what("f32"));
                assert_same(&f64_out[i], &scalar_run::<f64>(&spec, rec), &what("f64"));
            }
        }
    }
}

/// The bad data above is really exercised: the counters see it.
#[test]
fn bad_data_is_counted() {
    let recs = recordings(2);
    let spec = FilterSpec::new("mahony").unwrap();
    let out = run_recordings(&spec, &recs, Precision::F32);
    let (clean, bad) = (&out[0].rejections, &out[1].rejections);
    assert_eq!(clean.dt, 0);
    assert!(bad.dt >= 5 && bad.gyr >= 1 && bad.acc >= 2, "{bad:?}");
}

/// Masked steps (a channel without a sample) leave the channel exactly as if the step did not
/// exist: `update_masked` with random holes equals scalar runs that skip them, every filter.
#[test]
fn masked_steps_are_invisible() {
    type V = rootfuse_lane::wide::f64x4;
    let recs = recordings(6);
    let len = recs.iter().map(Recording::len).min().unwrap();
    // Lane i has no sample at step k when this says so (deterministic, different per lane).
    let hole = |i: usize, k: usize| (k * 7 + i * 13).is_multiple_of(5 + i);
    for (spec, dof) in specs() {
        let mut batch = Batch::<V>::new(&spec, recs.len());
        for k in 0..len {
            for (c, chunk) in batch.chunks_mut().iter_mut().enumerate() {
                let ch = |i: usize| recs.get(c * 4 + i).unwrap_or(&recs[0]);
                let sample = |i: usize| ch(i).sample(k);
                let s = ImuSample::new(
                    Vec3::<V>::from_lanes(|i| sample(i).gyr),
                    Vec3::<V>::from_lanes(|i| sample(i).acc),
                    Vec3::<V>::from_lanes(|i| sample(i).mag),
                );
                let active = (0..4)
                    .filter(|&i| !hole(c * 4 + i, k))
                    .fold(0u64, |m, i| m | 1 << i);
                chunk.update_masked(&s, V::from_fn(|i| ch(i).dt(k)), active);
            }
        }
        for (c, rec) in recs.iter().enumerate() {
            let mut f = spec.build::<f64>();
            for k in (0..len).filter(|&k| !hole(c, k)) {
                f.update(&rec.sample(k), rec.dt(k));
            }
            let what = format!("{} {dof}D channel {c}", spec.kind().name());
            let (a, b) = (batch.quat(c), f.quat());
            assert!(
                a.to_array()
                    .into_iter()
                    .zip(b.to_array())
                    .all(|(x, y)| same_bits(x, y)),
                "{what}: {a:?} vs {b:?}"
            );
            let expect = RejectionTotals::of_lane(f.rejections(), 0);
            assert_eq!(batch.rejections(c), expect, "{what}");
        }
    }
}

/// Struct-of-arrays blocks and array-of-structs input give the same states; blocks can be fed
/// one after another (streaming).
#[test]
fn soa_blocks_equal_channel_input() {
    type V = rootfuse_lane::wide::f32x8;
    let recs = recordings(11);
    let len = recs.iter().map(Recording::len).min().unwrap();
    let spec = FilterSpec::new("ekf").unwrap();
    // Array-of-structs in two blocks.
    let aos: Vec<(Vec<ImuSample<f64>>, Vec<f64>)> = recs
        .iter()
        .map(|r| {
            (
                (0..len).map(|k| r.sample(k)).collect(),
                (0..len).map(|k| r.dt(k)).collect(),
            )
        })
        .collect();
    let mut by_channel = Batch::<V>::new(&spec, recs.len());
    let half = len / 2;
    for range in [0..half, half..len] {
        let block: Vec<Channel> = aos
            .iter()
            .map(|(s, d)| Channel {
                samples: &s[range.clone()],
                dt: &d[range.clone()],
            })
            .collect();
        by_channel.run_channels(&block);
    }
    // Struct-of-arrays, one block: step k of chunk c at c * len + k.
    let chunks = by_channel.chunks().len();
    let mut samples = Vec::with_capacity(chunks * len);
    let mut dts = Vec::with_capacity(chunks * len);
    for c in 0..chunks {
        for k in 0..len {
            // Tail lanes hold garbage here on purpose: the engine must pad them itself.
            let get = |i: usize| recs.get(c * 8 + i).map(|r| r.sample(k));
            let bad = ImuSample::new(Vec3::zero(), Vec3::zero(), Vec3::zero());
            let lane = |i: usize| {
                let s = get(i).unwrap_or(bad);
                let f = |v: Vec3<f64>| Vec3::new(v.x as f32, v.y as f32, v.z as f32);
                ImuSample::new(f(s.gyr), f(s.acc), f(s.mag))
            };
            samples.push(ImuSample::new(
                Vec3::<V>::from_lanes(|i| lane(i).gyr),
                Vec3::<V>::from_lanes(|i| lane(i).acc),
                Vec3::<V>::from_lanes(|i| lane(i).mag),
            ));
            dts.push(V::from_fn(|i| {
                recs.get(c * 8 + i).map_or(-1.0, |r| r.dt(k) as f32)
            }));
        }
    }
    let mut by_block = Batch::<V>::new(&spec, recs.len());
    by_block.run_soa(&samples, &dts);
    for c in 0..recs.len() {
        assert_eq!(by_block.quat(c), by_channel.quat(c), "channel {c}");
        assert_eq!(by_block.bias(c), by_channel.bias(c), "channel {c}");
        assert_eq!(
            by_block.rejections(c),
            by_channel.rejections(c),
            "channel {c}"
        );
    }
}

/// One thread or two: the same bits.
#[test]
fn thread_count_does_not_change_results() {
    let recs = recordings(13);
    let spec = FilterSpec::new("madgwick").unwrap();
    let run = |threads: usize| {
        let pool = rootfuse::batch::rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            (
                run_recordings(&spec, &recs, Precision::F32),
                run_recordings(&spec, &recs, Precision::F64),
            )
        })
    };
    let (one, two) = (run(1), run(2));
    for (i, (a, b)) in one.0.iter().zip(&two.0).enumerate() {
        assert_same(a, b, &format!("f32 channel {i}"));
    }
    for (i, (a, b)) in one.1.iter().zip(&two.1).enumerate() {
        assert_same(a, b, &format!("f64 channel {i}"));
    }
}

#[test]
fn empty_inputs_and_throughput_report() {
    let spec = FilterSpec::new("mahony").unwrap();
    assert!(run_recordings(&spec, &[], Precision::F32).is_empty());
    let empty = Recording::default();
    let out = run_recordings(&spec, &[empty], Precision::F64);
    assert!(out[0].quat.is_empty() && out[0].rejections == RejectionTotals::default());
    assert!(state_bytes_per_channel::<rootfuse_lane::wide::f32x8>() > 0);

    let report = rootfuse::batch::throughput(&spec, 9, 20);
    let modes: Vec<_> = report.results.iter().map(|r| r.mode).collect();
    assert_eq!(
        modes,
        [
            "scalar-f32",
            "scalar-f64",
            "lanes-f32x8",
            "lanes-f64x4",
            "lanes-f32x8-threads"
        ]
    );
    assert!(
        report
            .results
            .iter()
            .all(|r| r.updates_per_s > 0.0 && r.ns_per_update > 0.0)
    );
    let json = report.to_json();
    assert!(json.starts_with(r#"{"filter":"mahony","channels":9,"samples":20,"results":[{"mode":"scalar-f32","updates_per_s":"#), "{json}");
    assert!(json.ends_with("}]}"), "{json}");
}

/// The optional series: covariance and flags equal what the scalar filter reports after each
/// sample (bit for bit), flags mark exactly the samples whose counters grew, and switched-off
/// series stay empty.
#[test]
fn covariance_and_flags_equal_scalar_runs() {
    let recs = recordings(5);
    let columns = Columns {
        bias: false,
        covariance: true,
        flags: true,
    };
    for name in ["sqrt-eskf", "ekf", "mahony"] {
        for dof in [6u8, 9] {
            let mut spec = FilterSpec::new(name).unwrap();
            spec.set_dof(crate::common::dof(dof)).unwrap();
            let out = run_recordings_with(&spec, &recs, Precision::F64, columns);
            for (c, (rec, o)) in recs.iter().zip(&out).enumerate() {
                let what = format!("{name} {dof}D channel {c}");
                assert!(o.bias.is_empty(), "{what}");
                assert_eq!(o.flags.len(), rec.len(), "{what}");
                let mut f = spec.build::<f64>();
                let mut before = *f.rejections();
                for k in 0..rec.len() {
                    f.update(&rec.sample(k), rec.dt(k));
                    let r = f.rejections();
                    let grew = |now: &[u64; 1], then: &[u64; 1], bit: u8| {
                        if now[0] > then[0] { bit } else { 0 }
                    };
                    let expected = grew(&r.dt, &before.dt, flag::DT)
                        | grew(&r.gyr, &before.gyr, flag::GYR)
                        | grew(&r.acc, &before.acc, flag::ACC)
                        | grew(&r.mag, &before.mag, flag::MAG)
                        | grew(&r.gated, &before.gated, flag::GATED)
                        | grew(&r.mag_disturbed, &before.mag_disturbed, flag::MAG_DISTURBED)
                        | f.rest_detected()
                            .map_or(0, |rest| if rest { flag::REST } else { 0 });
                    // The per-sample flags agree with the counters that grew.
                    assert_eq!(f.flags().bits(0), expected, "{what}: flags() at {k}");
                    assert_eq!(o.flags[k], expected, "{what}: flags at {k}");
                    before = *r;
                    match f.attitude_covariance() {
                        None => assert!(o.covariance.is_empty(), "{what}"),
                        Some(p) => {
                            let want = rootfuse_eval::consistency::upper_triangle(&p);
                            let same = want
                                .iter()
                                .zip(&o.covariance[k])
                                .all(|(a, b)| same_bits(*a, *b));
                            assert!(same, "{what}: covariance at {k}");
                        }
                    }
                }
            }
            // The channels with bad data are flagged where they were damaged.
            assert!(
                out[1].flags.iter().any(|&f| f & flag::GYR != 0),
                "{name} {dof}D"
            );
            assert!(
                out[1].flags.iter().any(|&f| f & flag::DT != 0),
                "{name} {dof}D"
            );
            assert!(
                out[0]
                    .flags
                    .iter()
                    .all(|&f| f & (flag::GYR | flag::DT) == 0),
                "{name} {dof}D"
            );
        }
    }
}

/// Channels with their own parameters (`Batch::with_channel_specs`): each equals a scalar run
/// with its own spec, bit for bit, in `f32x8` and in the interleaved `X2<f32x8>`, with 6D and
/// 9D channels interleaved (two structural classes). The flagship's lanes mix one and two
/// accelerometer windows (`tau_acc_long` 0 beside 4 and 6 s), whose blend is a per-lane select,
/// and lanes that correct their inclination, or test the field, every 1, 3 and 8 samples.
#[test]
fn per_channel_specs_equal_scalar_runs() {
    let recs = recordings(11);
    for (name, key, values, also) in [
        ("mahony", "kp", [0.5, 2.0, 0.1], ""),
        ("ekf", "gyr_noise", [0.01, 0.05, 0.002], ""),
        ("sqrt-eskf", "tau_acc_long", [0.0, 4.0, 6.0], ""),
        // Lanes that correct their inclination at different samples.
        ("sqrt-eskf", "acc_update_every", [1.0, 3.0, 8.0], ""),
        ("sqrt-eskf", "mag_update_every", [1.0, 3.0, 8.0], ""),
        // Lanes that measure the bias at rest at different samples (the recordings are
        // short: rest is declared after 0.2 s, `static` and `long-rest` rest).
        (
            "sqrt-eskf",
            "rest_update_every",
            [1.0, 3.0, 8.0],
            "rest_time=0.2",
        ),
        ("sqrt-eskf", "acc_noise_rotation_share", [1.0, 0.3, 0.1], ""),
    ] {
        // Interleaved on purpose: channel c gets value c % 3, and every third one is 6D.
        let specs: Vec<FilterSpec> = (0..recs.len())
            .map(|c| {
                let mut s = FilterSpec::new(name).unwrap();
                s.set(&format!("{key}={}", values[c % 3])).unwrap();
                if !also.is_empty() {
                    s.set(also).unwrap();
                }
                s.set_dof(crate::common::dof(if c % 4 == 3 { 6 } else { 9 }))
                    .unwrap();
                s
            })
            .collect();
        check_against_scalar_runs::<rootfuse_lane::wide::f32x8>(
            &specs,
            &recs,
            &format!("{name} f32x8"),
        );
        check_against_scalar_runs::<rootfuse_lane::X2<rootfuse_lane::wide::f32x8>>(
            &specs,
            &recs,
            &format!("{name} X2<f32x8>"),
        );
    }
    // A concrete-type batch refuses a spec of another filter, naming the channel.
    let specs = [
        FilterSpec::new("mahony").unwrap(),
        FilterSpec::new("ekf").unwrap(),
    ];
    let err = Batch::<f32, rootfuse_attitude::filters::Mahony<f32>>::with_channel_specs(&specs);
    assert_eq!(err.unwrap_err().channel, 1);
}

/// Runs `specs` (channel `c` over `recs[c]`) in a batch of lanes `V` and checks each channel
/// against a scalar `f32` run of its own spec, bit for bit. Returns the batch's chunk count.
fn check_against_scalar_runs<V: Lane>(
    specs: &[FilterSpec],
    recs: &[Recording],
    what: &str,
) -> usize {
    let channels: Vec<(Vec<ImuSample<f64>>, Vec<f64>)> = recs
        .iter()
        .map(|r| {
            (
                (0..r.len()).map(|k| r.sample(k)).collect(),
                (0..r.len()).map(|k| r.dt(k)).collect(),
            )
        })
        .collect();
    let input: Vec<Channel> = channels
        .iter()
        .map(|(s, d)| Channel { samples: s, dt: d })
        .collect();
    let mut batch = Batch::<V>::with_channel_specs(specs).unwrap();
    batch.run_channels(&input);
    for (c, (spec, rec)) in specs.iter().zip(recs).enumerate() {
        let alone = scalar_run::<f32>(spec, rec);
        let q = *alone.quat.last().unwrap();
        let (a, b) = (batch.quat(c), q);
        assert!(
            a.to_array()
                .into_iter()
                .zip(b.to_array())
                .all(|(x, y)| same_bits(x, y)),
            "{what} channel {c}: {a:?} vs {b:?}"
        );
        assert_eq!(batch.rejections(c), alone.rejections, "{what} channel {c}");
    }
    batch.chunks().len()
}

/// Per-lane parameters: eight channels whose specs differ in every parameter that may vary
/// per lane run in ONE `f32x8` chunk (four `f64x4`-wide halves of the interleaved type), and
/// each equals the scalar run of its own spec bit for bit — for every registered filter, 6D
/// and 9D.
#[test]
fn per_lane_parameters_equal_scalar_runs_for_every_filter() {
    let recs = recordings(8);
    for &kind in FilterKind::ALL {
        for dof in [6u8, 9] {
            let specs: Vec<FilterSpec> = (0..8)
                .map(|c| {
                    let mut s = FilterSpec::new(kind.name()).unwrap();
                    s.set_dof(crate::common::dof(dof)).unwrap();
                    for info in kind.params().iter().filter(|i| i.per_lane) {
                        let step = (c + 1) as f64;
                        let v = if info.default == 0.0 {
                            (1e-3 * step).min(info.max)
                        } else {
                            (info.default * (1.0 + 0.07 * step)).clamp(info.min, info.max)
                        };
                        s.set(&format!("{}={v}", info.name)).unwrap();
                    }
                    s
                })
                .collect();
            assert!(
                specs
                    .windows(2)
                    .all(|w| w[0] != w[1] || kind.params().iter().all(|i| !i.per_lane))
            );
            let what = format!("{} {dof}D", kind.name());
            let chunks =
                check_against_scalar_runs::<rootfuse_lane::wide::f32x8>(&specs, &recs, &what);
            assert_eq!(chunks, 1, "{what}: all eight channels share one chunk");
        }
    }
}

/// The interleaved lane types (`X2`), which the engine uses for small filters, equal scalar
/// runs bit for bit for every registered filter, 6D and 9D, with tail lanes and bad data.
#[test]
fn interleaved_lanes_equal_scalar_runs() {
    let recs = recordings(13);
    for (spec, dof) in specs() {
        let f32_out = rootfuse::batch::run_sources::<
            rootfuse_lane::X2<rootfuse_lane::wide::f32x8>,
            _,
        >(&spec, &recs);
        let f64_out = rootfuse::batch::run_sources::<
            rootfuse_lane::X2<rootfuse_lane::wide::f64x4>,
            _,
        >(&spec, &recs);
        for (i, rec) in recs.iter().enumerate() {
            let what = |p: &str| format!("{} {dof}D {p}, channel {i}", spec.kind().name());
            assert_same(
                &f32_out[i],
                &scalar_run::<f32>(&spec, rec),
                &what("X2<f32x8>"),
            );
            assert_same(
                &f64_out[i],
                &scalar_run::<f64>(&spec, rec),
                &what("X2<f64x4>"),
            );
        }
    }
}

/// Each filter's batch costs its own state, not the largest filter's, and the table of bytes
/// per channel in the `rootfuse-batch` crate docs is what the filters cost (print it with
/// `cargo test state_bytes -- --nocapture`).
#[test]
fn state_bytes_are_the_filters_own() {
    use rootfuse_attitude::registry::{FilterVisitor, RegisteredFilter};
    struct PerChannel;
    impl<L: Lane> FilterVisitor<L> for PerChannel {
        type Output = usize;
        fn visit<F: RegisteredFilter<L>>(self, spec: &FilterSpec) -> usize {
            Batch::<L, F>::try_new(spec, 1)
                .unwrap()
                .state_bytes_per_channel()
        }
    }
    type F8 = rootfuse_lane::wide::f32x8;
    type D4 = rootfuse_lane::wide::f64x4;
    type X8 = rootfuse_lane::X2<F8>;
    // The documented table: rows "//! | `name` | f32x8 | f64x4 | X2 |".
    let docs = include_str!("../../crates/rootfuse-batch/src/lib.rs");
    let documented = |name: &str| -> Option<Vec<usize>> {
        let row = docs
            .lines()
            .find(|l| l.starts_with(&format!("//! | `{name}` |")))?;
        Some(
            row.split('|')
                .skip(2)
                .filter_map(|c| c.trim().parse().ok())
                .collect(),
        )
    };
    let any = Batch::<F8>::new(&FilterSpec::new("gyro").unwrap(), 1).state_bytes_per_channel();
    println!("| filter | f32x8 | f64x4 | X2<f32x8> |");
    let mut stale = Vec::new();
    for &kind in FilterKind::ALL {
        let spec = FilterSpec::new(kind.name()).unwrap();
        let (a, b, c) = (
            spec.visit::<F8, _>(PerChannel),
            spec.visit::<D4, _>(PerChannel),
            spec.visit::<X8, _>(PerChannel),
        );
        println!("| {} | {a} | {b} | {c} |", kind.name());
        assert!(
            a < any || a == any && kind == FilterKind::EcfEkf,
            "{}: {a} vs {any}",
            kind.name()
        );
        if documented(kind.name()) != Some(vec![a, b, c]) {
            stale.push(kind.name());
        }
    }
    // Every row is printed before failing, so one run gives the whole new table.
    assert!(
        stale.is_empty(),
        "the crate docs' table is out of date for {stale:?}"
    );
    println!("| AnyFilter | {any} | |");
    let any_row = docs.lines().find(|l| l.starts_with("//! | any filter as"));
    assert!(
        any_row.is_some_and(|l| l.contains(&format!("| {any} |"))),
        "AnyFilter row"
    );
}

/// One channel as `[x, y, z]` rows of `T` (6D data has NaN magnetometer rows), with its steps:
/// a source that moves whole blocks through registers ([`fill_lanes`]).
struct Rows<T> {
    gyr: Vec<T>,
    acc: Vec<T>,
    mag: Vec<T>,
    dt: Vec<f64>,
}

impl<T: Copy + Into<f64> + Sync> Rows<T> {
    fn new(rec: &Recording, cast: impl Fn(f64) -> T) -> Self {
        let rows = |v: &[Vec3<f64>]| v.iter().flat_map(|v| v.to_array()).map(&cast).collect();
        let nan = vec![Vec3::new(f64::NAN, f64::NAN, f64::NAN); rec.len()];
        Self {
            gyr: rows(&rec.gyr),
            acc: rows(&rec.acc),
            mag: rows(rec.mag.as_deref().unwrap_or(&nan)),
            dt: (0..rec.len()).map(|k| rec.dt(k)).collect(),
        }
    }
}

impl<T: Copy + Into<f64> + Sync> ChannelSource for Rows<T> {
    fn len(&self) -> usize {
        self.dt.len()
    }
    fn sample(&self, i: usize) -> ImuSample<f64> {
        let v = |r: &[T]| Vec3::new(r[3 * i].into(), r[3 * i + 1].into(), r[3 * i + 2].into());
        ImuSample::new(v(&self.gyr), v(&self.acc), v(&self.mag))
    }
    fn dt(&self, i: usize) -> f64 {
        self.dt[i]
    }
    fn read_lanes<L: Lane>(lanes: &[&Self], start: usize, tile: &mut [(ImuSample<L>, L)]) {
        let rows =
            |field: fn(&Self) -> &[T]| -> Vec<&[T]> { lanes.iter().map(|s| field(s)).collect() };
        assert!(fill_lanes(&rows(|s| &s.gyr), start, tile, |s| &mut s.gyr));
        assert!(fill_lanes(&rows(|s| &s.acc), start, tile, |s| &mut s.acc));
        assert!(fill_lanes(&rows(|s| &s.mag), start, tile, |s| &mut s.mag));
        for (lane, source) in lanes.iter().enumerate() {
            for (k, (_, dt)) in tile.iter_mut().enumerate() {
                dt.set_lane(lane, <L::Scalar as Lane>::from_f64(source.dt[start + k]));
            }
        }
    }
}

/// The same channel read lane by lane (the trait's defaults).
struct LaneByLane<'a, T>(&'a Rows<T>);

impl<T: Copy + Into<f64> + Sync> ChannelSource for LaneByLane<'_, T> {
    fn len(&self) -> usize {
        self.0.len()
    }
    fn sample(&self, i: usize) -> ImuSample<f64> {
        self.0.sample(i)
    }
    fn dt(&self, i: usize) -> f64 {
        self.0.dt(i)
    }
}

fn registers_equal_lane_by_lane<L: Lane, T: Copy + Into<f64> + Sync>(
    recs: &[Recording],
    cast: impl Fn(f64) -> T,
) {
    let rows: Vec<Rows<T>> = recs.iter().map(|r| Rows::new(r, &cast)).collect();
    let lane_by_lane: Vec<LaneByLane<'_, T>> = rows.iter().map(LaneByLane).collect();
    for (name, dof) in [("mahony", 6), ("sqrt-eskf", 9)] {
        let mut spec = FilterSpec::new(name).unwrap();
        spec.set_dof(crate::common::dof(dof)).unwrap();
        let what = format!("{name} {dof}D, {} lanes", L::LANES);
        // Chunks of the sources themselves.
        let fast = run_sources::<L, _>(&spec, &rows);
        let slow = run_sources::<L, _>(&spec, &lane_by_lane);
        for (c, (a, b)) in fast.iter().zip(&slow).enumerate() {
            assert_same(a, b, &format!("{what}, channel {c}"));
        }
        // Chunks regrouped by spec (sources by reference).
        let specs = vec![spec.clone(); rows.len()];
        let precision = if L::EPSILON > 1e-10 {
            Precision::F32
        } else {
            Precision::F64
        };
        let fast = run_final_states(&specs, &rows, precision).unwrap();
        let slow = run_final_states(&specs, &lane_by_lane, precision).unwrap();
        for (c, (a, b)) in fast.iter().zip(&slow).enumerate() {
            let same = a
                .quat
                .to_array()
                .into_iter()
                .zip(b.quat.to_array())
                .all(|(x, y)| same_bits(x, y));
            assert!(
                same && a.rejections == b.rejections,
                "{what}, final state of channel {c}"
            );
        }
    }
}

/// `fill_lanes` (whole blocks through registers, the rest lane by lane) hands the filters
/// exactly the tiles that lane-by-lane reads do: 37 channels (two full chunks of 16 and a
/// tail), ragged lengths (so full chunks run out mid-tile), bad data, float32 and float64 rows.
#[test]
fn rows_through_registers_equal_lane_by_lane() {
    let recs = recordings(37);
    registers_equal_lane_by_lane::<X2<f32x8>, f32>(&recs, |x| x as f32);
    registers_equal_lane_by_lane::<X2<f32x8>, f64>(&recs, |x| x);
    registers_equal_lane_by_lane::<f32x8, f32>(&recs, |x| x as f32);
    registers_equal_lane_by_lane::<f64x4, f64>(&recs, |x| x);
    registers_equal_lane_by_lane::<f64x4, f32>(&recs, |x| x as f32);
}
