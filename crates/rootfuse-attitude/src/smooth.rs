//! Offline forward-backward smoothing of a whole recording (the two-filter smoother).
//!
//! A filter runs forward in time and a second instance runs backward (samples in reverse
//! order, gyroscope negated); at every sample the two attitude estimates are fused with
//! their attitude-error covariances (Fraser & Potter 1969, "The optimum linear smoother as a
//! combination of two optimum linear filters", IEEE Trans. Automatic Control 14(4)), in the
//! global error convention of [`OrientationFilter::attitude_covariance`]:
//! `δ = Log(q_b ⊗ q_f*)`, `q_s = Exp(P_f·(P_f + P_b)⁻¹·δ) ⊗ q_f`. Each estimate sees the
//! data on one side of the sample, so the fusion uses all of it: the start-up transient
//! of the forward filter and the lag of its accelerometer low-pass are covered by the
//! backward one, and vice versa. The two estimates share the sample itself; counting it twice
//! is the usual, small approximation of the two-filter form.
//!
//! Where the filter asks for it ([`OrientationFilter::smoothing_gyro_tau`], the flagship's
//! `smoothing_gyro_tau`), the fused estimate is then refined by the gyroscope: a
//! complementary filter runs forward with the fused estimate as its measurement and another
//! backward with the first's output as its own, each integrating the rate (minus the forward
//! pass's bias) and turning by the fraction `1 − exp(−dt/τ)` toward its measurement (the
//! forward one starting from the backward filter's estimate at the first sample). The
//! correction to the integrated rate is thereby low-passed twice in opposite directions,
//! zero-phase: above `1/(2π·τ)` the result follows the gyroscope. Averaging the two passes
//! cancels their low-passes' lag but not the motion acceleration each lets through (the real
//! part of a second-order low-pass falls only as fast as the low-pass itself); this removes
//! it (simulated, 5 seeds × 120 s: the pendulum's smoothed inclination 0.695° → 0.662°,
//! level with VQF offline, the handheld translation's 0.611° → 0.564°; `docs/accuracy.md`).
//!
//! The estimates must share their earth frame: a 9D filter (magnetic north) does; a 6D
//! filter's heading is arbitrary per run, so for 6D the backward estimate is first turned
//! about earth-z by the circular mean of its heading difference to the forward estimate
//! (weights: inverse heading variances), which is the constant offset two 6D runs differ by.
//!
//! ```
//! use rootfuse_attitude::filters::{SqrtEskf, SqrtEskfParams};
//! use rootfuse_attitude::smooth::forward_backward;
//! use rootfuse_attitude::{Recording, Vec3};
//! // 1 s level and at rest, sampled at 100 Hz, with a magnetometer (9D).
//! let n = 100;
//! let rec = Recording {
//!     name: "rest".into(),
//!     t: (0..n).map(|i| i as f64 * 0.01).collect(),
//!     gyr: vec![Vec3::zero(); n],
//!     acc: vec![Vec3::new(0.0, 0.0, 9.81); n],
//!     mag: Some(vec![Vec3::new(0.0, 20.0, -40.0); n]),
//!     ..Default::default()
//! };
//! let p = SqrtEskfParams::default();
//! let out = forward_backward(&rec, || SqrtEskf::new(&p), true).unwrap();
//! assert_eq!(out.quat.len(), rec.len());
//! assert_eq!(out.forward_only, 0);
//! ```

use crate::blocks::{LowPassGain, integrate_gyro, turn_in_earth};
use crate::filters::{Rejections, SampleFlags};
use crate::registry::FilterSpec;
use crate::{Dof, ImuSample, Lane, OrientationFilter, Quat, Recording, Vec3};
use rootfuse_lane::Mask;
use rootfuse_lane::Mat;
use rootfuse_lane::wide::{f64x2, f64x4};
use std::vec::Vec;

/// The smoothed estimates of a recording.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct Smoothed {
    /// Smoothed orientation per sample (sensor to earth, same convention as the filter).
    pub quat: Vec<Quat<f64>>,
    /// Samples where the fusion was not possible (a covariance not finite or not positive
    /// definite, or an estimate not finite) and the forward estimate was kept as it is.
    pub forward_only: usize,
    /// What the forward run skipped, by reason (the backward run sees the same samples); a
    /// recording with gaps adds up its stretches' runs and counts each gap as a skipped step.
    pub rejections: Rejections<f64>,
    /// The gyroscope's scale error per sensor axis (a fraction, `ω_measured = (1 + s)·ω`) by
    /// which both passes' readings were divided ([`smooth_spec`] with
    /// `smoothing_gyro_scale`); `None` where they were not.
    pub gyro_scale: Option<Vec3<f64>>,
}

/// Why a recording could not be smoothed.
#[derive(Debug, Clone, PartialEq)]
pub enum SmoothError {
    /// The filter does not report an attitude covariance, so the two passes cannot be
    /// weighted ([`OrientationFilter::attitude_covariance`] returned `None`).
    NoCovariance,
}

impl core::fmt::Display for SmoothError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::NoCovariance => f.write_str(
                "the filter reports no attitude covariance, which the smoother needs as weights",
            ),
        }
    }
}
impl std::error::Error for SmoothError {}

/// [`forward_backward`] for a filter of the registry, as `rootfuse run --offline` and
/// Python's `smooth` run it: both passes built from [`FilterSpec::for_smoothing`], in two
/// `f64` lanes. Where the spec asks for it (`smoothing_gyro_scale = 1`, the flagship with
/// its scale estimate on, the default), the filter first runs forward once, online in `f32`
/// at half the recording's rate (each pair of samples one), and both
/// passes take the gyroscope's readings divided by `1 + s` per axis, `s` the scale error it
/// estimated ([`OrientationFilter::gyro_scale`] at the end; [`Smoothed::gyro_scale`]).
/// `nine_d` as in [`forward_backward`].
///
/// ```
/// use rootfuse_attitude::registry::FilterSpec;
/// use rootfuse_attitude::smooth::smooth_spec;
/// use rootfuse_attitude::{Recording, Vec3};
/// let n = 100;
/// let rec = Recording {
///     name: "rest".into(),
///     t: (0..n).map(|i| i as f64 * 0.01).collect(),
///     gyr: vec![Vec3::zero(); n],
///     acc: vec![Vec3::new(0.0, 0.0, 9.81); n],
///     mag: Some(vec![Vec3::new(0.0, 20.0, -40.0); n]),
///     ..Default::default()
/// };
/// let mut spec = FilterSpec::new("flagship").unwrap();
/// let out = smooth_spec(&rec, &spec, true).unwrap();
/// assert_eq!(out.quat.len(), n);
/// // One second at rest: no window closed, no scale estimated.
/// assert_eq!(out.gyro_scale, Some(Vec3::zero()));
/// // Without the online pass, no scale is reported.
/// spec.set("smoothing_gyro_scale=0").unwrap();
/// assert_eq!(smooth_spec(&rec, &spec, true).unwrap().gyro_scale, None);
/// ```
///
/// # Errors
/// [`SmoothError::NoCovariance`] if the filter has no attitude covariance.
pub fn smooth_spec(
    rec: &Recording,
    spec: &FilterSpec,
    nine_d: bool,
) -> Result<Smoothed, SmoothError> {
    let passes = spec.for_smoothing();
    let build = || passes.build::<f64x2>();
    let wanted = spec.get("smoothing_gyro_scale") == Some(1.0)
        && spec.get("gyr_scale_window").is_some_and(|w| w > 0.0);
    if !wanted {
        return forward_backward(rec, build, nine_d);
    }
    // Without a magnetometer the online run is 6D, whatever the spec's default: its scale
    // estimate then holds the axes together as a 6D run does (`gyr_scale_axis_ridge`).
    let mut online_spec = spec.clone();
    if rec.mag.is_none() && online_spec.uses_magnetometer() {
        online_spec.set_dof(Dof::Six).ok();
    }
    // A pair of samples spans two steps: twice the longest step the spec accepts, so that the
    // pass skips what the full rate would (a limit beyond the parameter's range keeps it).
    if let Some(max_dt) = spec.get("max_dt") {
        online_spec
            .set(&std::format!("max_dt={}", 2.0 * max_dt))
            .ok();
    }
    let mut online = online_spec.build::<f32>();
    pairs_for_scale(rec).run(&mut online, |_| ());
    let s = online.gyro_scale();
    let scale = Vec3::new(f64::from(s.x), f64::from(s.y), f64::from(s.z));
    // Dividing by exactly 1 where nothing was estimated keeps those readings' bits.
    let mut scaled = rec.clone();
    for g in &mut scaled.gyr {
        *g = Vec3::new(
            g.x / (1.0 + scale.x),
            g.y / (1.0 + scale.y),
            g.z / (1.0 + scale.z),
        );
    }
    let mut out = forward_backward(&scaled, build, nine_d)?;
    out.gyro_scale = Some(scale);
    Ok(out)
}

/// The readings of `rec` at half its rate: each pair of samples `(2i, 2i + 1)` becomes one,
/// stamped at the pair's second time, with the mean of the pair's angular rates (over the
/// pair's two steps, their rotation to first order) and the pair's second accelerometer and
/// magnetometer readings (a lone last sample is left out). The second reading, not the mean:
/// a mean lags the orientation at the stamp by half a step, and under rotation that lag
/// grows with the rate as a scale error does (simulated, 0.4 % on an axis: the mean found
/// 0.1 % more than the full rate, the second reading within 0.01 %). The scale estimate then
/// equals the full rate's to within its noise (BROAD 14 smoothed with either: 9D 1.547°,
/// 6D 1.911° / 1.910°), at half the cost of the online pass. A pair with a reading that is
/// not finite is not finite, and the online pass skips it as it would that sample.
fn pairs_for_scale(rec: &Recording) -> Recording {
    let pairs = rec.len() / 2;
    let second = |v: &[Vec3<f64>]| -> Vec<Vec3<f64>> { (0..pairs).map(|i| v[2 * i + 1]).collect() };
    Recording {
        name: rec.name.clone(),
        t: (0..pairs).map(|i| rec.t[2 * i + 1]).collect(),
        gyr: (0..pairs)
            .map(|i| (rec.gyr[2 * i] + rec.gyr[2 * i + 1]) * 0.5)
            .collect(),
        acc: second(&rec.acc),
        mag: rec.mag.as_deref().map(second),
        truth: None,
        use_mask: None,
    }
}

/// Why the filter skipped a sample whole.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Skipped {
    /// Its time step (not finite, not positive, or beyond `max_dt`).
    Step,
    /// Its angular rate (not finite or beyond `max_gyr`).
    Rate,
}

impl Skipped {
    /// Why lane 0 of a sample's `flags` was skipped whole, if it was.
    fn of_lane_0(flags: &SampleFlags<f64x2>) -> Option<Self> {
        if flags.dt.test(0) {
            Some(Self::Step)
        } else if flags.gyr.test(0) {
            Some(Self::Rate)
        } else {
            None
        }
    }
}

/// One pass: estimate and attitude covariance after each sample.
type Pass = Vec<(Quat<f64>, Option<Mat<f64, 3, 3>>)>;

/// Runs the filter `build()` makes forward and backward over `rec` and fuses the two passes
/// (see the module documentation). `nine_d` says the filter's heading is absolute
/// (magnetometer in use); otherwise the backward pass is first aligned to the forward one in
/// heading.
///
/// The filter is built in two `f64` lanes (`f64x2`): lane 0 runs forward, lane 1 backward,
/// in one loop. Each lane equals a scalar `f64` run of the same filter bit for bit (the
/// [`Lane`] contract), so the result is that of two scalar passes, at about the cost of one.
///
/// The passes are what `build` makes: the flagship's `smoothing_gyro_scale` is read by
/// [`smooth_spec`], not here. For the flagship, build the passes from
/// [`SqrtEskfParams::for_smoothing`]
/// (`FilterSpec::for_smoothing` in the registry; `rootfuse run --offline` and Python's
/// `smooth` do): offline the accelerometer time constant is longer than online.
///
/// [`SqrtEskfParams::for_smoothing`]: crate::SqrtEskfParams::for_smoothing
///
/// A gap (a positive time step the filter skipped as beyond its `max_dt`, samples missing)
/// splits the recording: each stretch between gaps is smoothed on its own, because a pass
/// that carried its orientation across the gap would be wrong by whatever turn the gap hid,
/// and confidently so, and the fusion would spread that into the other side (30 s missing
/// from a slow rotation moved the smoothed estimates before it by 18°). The first run over
/// the whole recording finds the gaps; with any, each stretch then runs again, so a
/// recording with gaps costs twice one without. [`Smoothed::rejections`] adds up the
/// stretches' own and counts each gap as a skipped step. A stretch of one sample (between
/// two gaps, or before or after one) is smoothed as that sample held for a step of 1 µs
/// (the smallest `max_dt` any filter takes): the filter starts from its accelerometer and magnetometer (a lone sample
/// has no step of its own, and was left at the filter's initial state). A time that is not
/// a number splits stretches too: the filter skips the steps on both sides of it.
///
/// # Errors
/// [`SmoothError::NoCovariance`] if the filter has no attitude covariance.
pub fn forward_backward<F: OrientationFilter<f64x2>>(
    rec: &Recording,
    mut build: impl FnMut() -> F,
    nine_d: bool,
) -> Result<Smoothed, SmoothError> {
    let (whole, gaps) = smooth_stretch(rec, &mut build, nine_d)?;
    if gaps.is_empty() {
        return Ok(whole);
    }
    let mut quat = Vec::with_capacity(rec.len());
    let mut forward_only = 0;
    let mut rejections = Rejections::<f64>::default();
    rejections.dt[0] = gaps.len() as u64;
    let mut from = 0;
    for end in gaps.into_iter().chain([rec.len()]) {
        let lone = end - from == 1;
        let stretch = if lone {
            held_still(rec, from)
        } else {
            rec.slice(from..end)
        };
        let (part, _) = smooth_stretch(&stretch, &mut build, nine_d)?;
        let estimated = part.quat.len().min(end - from);
        quat.extend(part.quat.into_iter().take(estimated));
        forward_only += part.forward_only.min(estimated);
        // Never fewer estimates than samples: a stretch the filter could not smooth (none
        // is known) holds the estimate before it, counted as not fused.
        let held = quat.last().copied().unwrap_or(Quat::identity());
        quat.resize(end, held);
        forward_only += end - from - estimated;
        // A held sample's copy repeats its readings: its counts are the sample's again.
        add_counts(&mut rejections, &part.rejections, if lone { 2 } else { 1 });
        from = end;
    }
    Ok(Smoothed {
        quat,
        forward_only,
        rejections,
        ..whole
    })
}

/// The step (s) a lone sample is held over: the smallest `max_dt` any filter takes, so that
/// no filter skips it (a lone sample tilted 60° came out within 0.7° in tilt, 2.6° in all;
/// its estimate is the filter's start from its readings).
const HELD_STEP: f64 = 1e-6;

/// Sample `i` of `rec` and a copy of it [`HELD_STEP`] later (its time, which may not be a
/// number, is not used): a stretch of one sample made one the filter can start from.
fn held_still(rec: &Recording, i: usize) -> Recording {
    let mut held = rec.slice(i..i + 1);
    held.t = std::vec![0.0, HELD_STEP];
    held.gyr.push(held.gyr[0]);
    held.acc.push(held.acc[0]);
    if let Some(m) = &mut held.mag {
        m.push(m[0]);
    }
    held.truth = None;
    held.use_mask = None;
    held
}

/// Adds `part`'s counts (lane 0) to `total`'s, each divided by `copies` (rounded up): the
/// counts of a sample run `copies` times.
fn add_counts(total: &mut Rejections<f64>, part: &Rejections<f64>, copies: u64) {
    let one = |c: u64| c.div_ceil(copies);
    total.dt[0] += one(part.dt[0]);
    total.gyr[0] += one(part.gyr[0]);
    total.acc[0] += one(part.acc[0]);
    total.mag[0] += one(part.mag[0]);
    total.gated[0] += one(part.gated[0]);
    total.mag_disturbed[0] += one(part.mag_disturbed[0]);
}

/// [`forward_backward`] over `rec` as one stretch, or, where the forward lane skipped a
/// positive step (a gap), no estimates and the indices of the samples that follow the gaps
/// (ascending, none at 0).
fn smooth_stretch<F: OrientationFilter<f64x2>>(
    rec: &Recording,
    build: &mut impl FnMut() -> F,
    nine_d: bool,
) -> Result<(Smoothed, Vec<usize>), SmoothError> {
    let n = rec.len();
    let mut filter = build();
    if n > 0 && filter.attitude_covariance().is_none() {
        return Err(SmoothError::NoCovariance);
    }
    // The two passes are independent until they are fused, so they run as the two lanes of
    // one filter: lane 0 forward, lane 1 backward. Lanes equal scalar runs bit for bit, and
    // a two-lane update costs about what one scalar update does.
    let mut forward: Pass = Vec::with_capacity(n);
    let mut backward: Pass = Vec::with_capacity(n);
    let mut bias = Vec::with_capacity(n);
    // The steps the forward lane skipped whole (its `dt` or gyroscope rejected): the
    // refinement by the gyroscope below takes the same readings and must not step on them.
    let mut step_skipped: Vec<Option<Skipped>> = Vec::with_capacity(n);
    for k in 0..n {
        // Backward in time: arriving at sample i from sample i + 1 uses the rate measured
        // over [t_i, t_{i+1}] (sample i + 1's gyroscope), negated, over that interval, and
        // then corrects with sample i's accelerometer and magnetometer.
        let i = n - 1 - k;
        let (gyr_from, dt_back) = if i + 1 < n {
            (i + 1, rec.dt(i + 1))
        } else {
            (i, rec.dt(i))
        };
        let (ahead, back) = (rec.sample(k), rec.sample(i));
        let back = ImuSample::new(-rec.sample(gyr_from).gyr, back.acc, back.mag);
        let pair = |a: Vec3<f64>, b: Vec3<f64>| {
            Vec3::new(
                f64x2::new([a.x, b.x]),
                f64x2::new([a.y, b.y]),
                f64x2::new([a.z, b.z]),
            )
        };
        let sample = ImuSample::new(
            pair(ahead.gyr, back.gyr),
            pair(ahead.acc, back.acc),
            pair(ahead.mag, back.mag),
        );
        filter.update(&sample, f64x2::new([rec.dt(k), dt_back]));
        let (q, p) = (filter.quat(), filter.attitude_covariance());
        let p_lane = |lane: usize| p.map(|p| Mat::from_fn(|r, c| p.m[r][c].extract(lane)));
        forward.push((q.lane(0), p_lane(0)));
        backward.push((q.lane(1), p_lane(1)));
        bias.push(filter.bias().lane(0));
        step_skipped.push(Skipped::of_lane_0(&filter.flags()));
    }
    let gaps = gaps(rec, &step_skipped);
    if !gaps.is_empty() {
        // Each stretch is smoothed on its own: no estimates to form here.
        let skipped = Smoothed {
            quat: Vec::new(),
            forward_only: 0,
            rejections: filter.rejections().lane(0),
            gyro_scale: None,
        };
        return Ok((skipped, gaps));
    }
    backward.reverse();
    if !nine_d {
        let offset = heading_offset(&forward, &backward);
        let turn = Quat::from_heading(offset);
        // A turn about earth-z rotates the earth-frame covariance with it.
        let (r, r_t) = (
            turn.to_rotation_matrix(),
            turn.to_rotation_matrix().transpose(),
        );
        for (q, p) in &mut backward {
            *q = (turn * *q).normalize();
            if let Some(p) = p {
                *p = r * *p * r_t;
            }
        }
    }
    let (mut quat, forward_only) = fuse_passes(&forward, &backward);
    let tau = filter.smoothing_gyro_tau();
    if tau > 0.0 {
        // The backward pass has seen every sample when it reaches the first: a settled start.
        let start = backward
            .first()
            .map(|b| b.0)
            .filter(|q| q.is_finite())
            .or(quat.first().copied());
        if let Some(start) = start {
            refine_by_gyro(rec, &mut quat, &bias, &step_skipped, start, tau);
        }
    }
    Ok((
        Smoothed {
            quat,
            forward_only,
            rejections: filter.rejections().lane(0),
            gyro_scale: None,
        },
        Vec::new(),
    ))
}

/// The samples that follow a gap: skipped for their step, which, measured from the last
/// sample with a finite time (a time that is not a number hides no gap), is positive.
fn gaps(rec: &Recording, step_skipped: &[Option<Skipped>]) -> Vec<usize> {
    let mut out = Vec::new();
    let mut last = rec.t.first().copied().filter(|t| t.is_finite());
    for (k, &t) in rec.t.iter().enumerate().skip(1) {
        if step_skipped.get(k) == Some(&Some(Skipped::Step))
            && let Some(previous) = last
            && t - previous > 0.0
        {
            out.push(k);
        }
        if t.is_finite() {
            last = Some(t);
        }
    }
    out
}

/// The passes fused sample by sample (see the module documentation), with the number of
/// samples that could not be fused and kept the forward estimate.
fn fuse_passes(forward: &Pass, backward: &Pass) -> (Vec<Quat<f64>>, usize) {
    // The fusion of one sample does not depend on any other: four at a time in `f64x4`
    // lanes (bit for bit the scalar fusion, by the `Lane` contract).
    let mut forward_only = 0;
    let mut quat = Vec::with_capacity(forward.len());
    for (f, b) in forward.chunks(4).zip(backward.chunks(4)) {
        let at = |i: usize| i.min(f.len() - 1);
        let q = |pass: &[(Quat<f64>, Option<Mat<f64, 3, 3>>)]| {
            Quat::new(
                f64x4::from_fn(|i| pass[at(i)].0.w),
                f64x4::from_fn(|i| pass[at(i)].0.x),
                f64x4::from_fn(|i| pass[at(i)].0.y),
                f64x4::from_fn(|i| pass[at(i)].0.z),
            )
        };
        // A pass without a covariance at a sample is not finite there: not fused.
        let p = |pass: &[(Quat<f64>, Option<Mat<f64, 3, 3>>)]| {
            Mat::from_fn(|r, c| f64x4::from_fn(|i| pass[at(i)].1.map_or(f64::NAN, |p| p.m[r][c])))
        };
        let (fused, ok) = fuse(q(f), p(f), q(b), p(b));
        for (i, (qf, _)) in f.iter().enumerate() {
            if ok.test(i) {
                quat.push(fused.lane(i));
            } else {
                forward_only += 1;
                quat.push(*qf);
            }
        }
    }
    (quat, forward_only)
}

/// Refines `quat` by the gyroscope (rates minus `bias`) above `1/(2π·tau)`, zero-phase (see
/// the module documentation): a forward pass toward `quat`, then a backward pass toward the
/// forward one's output. Each pass starts where the data have settled it, not at a first
/// sample that may be an outlier (a filter that could not initialise on unusable first
/// samples): the forward pass at `start` (the backward filter's estimate at sample 0), the
/// backward pass at the forward pass's last state. `skipped[k]`: the filter skipped sample
/// `k` whole, and why; its rate is not used.
fn refine_by_gyro(
    rec: &Recording,
    quat: &mut [Quat<f64>],
    bias: &[Vec3<f64>],
    skipped: &[Option<Skipped>],
    start: Quat<f64>,
    tau: f64,
) {
    let n = quat
        .len()
        .min(bias.len())
        .min(rec.gyr.len())
        .min(skipped.len());
    if n < 2 {
        return;
    }
    let quat = &mut quat[..n];
    let mut gain = LowPassGain::new(tau);
    let mut forward = Vec::with_capacity(n);
    forward.push(start);
    for k in 1..n {
        // Sample k's rate covers [t_{k-1}, t_k].
        let next = gyro_step(
            rec,
            bias,
            (k, skipped[k]),
            1.0,
            forward[k - 1],
            quat[k],
            &mut gain,
        );
        forward.push(next);
    }
    quat[n - 1] = forward[n - 1];
    for k in (0..n - 1).rev() {
        // Backward, sample k + 1's rate, negated, covers [t_k, t_{k+1}].
        let step = (k + 1, skipped[k + 1]);
        quat[k] = gyro_step(rec, bias, step, -1.0, quat[k + 1], forward[k], &mut gain);
    }
}

/// One step of [`refine_by_gyro`]'s passes: `from` turned by sample `k`'s rate (minus its
/// bias, times `sign`) over its `dt`, then the fraction `1 − exp(−dt/tau)` of the earth-frame
/// rotation toward `to`, taken as twice the vector part of `to ⊗ moved*` (the rotation vector
/// to within `θ²/24` of the angle `θ`, and the step is a small fraction of it). A sample the
/// filter skipped (`skipped`: a rate beyond `max_gyr`, a repeated time), or whose rate or
/// step is not usable (not finite, `dt ≤ 0`, a turn that is not finite), does not turn the
/// estimate: it is held over that sample's step. (A gap, a step beyond `max_dt`, never
/// reaches here: [`forward_backward`] smooths the stretches between gaps apart.)
fn gyro_step(
    rec: &Recording,
    bias: &[Vec3<f64>],
    (k, skipped): (usize, Option<Skipped>),
    sign: f64,
    from: Quat<f64>,
    to: Quat<f64>,
    gain: &mut LowPassGain<f64>,
) -> Quat<f64> {
    let (w, dt) = (rec.gyr[k] - bias[k], rec.dt(k));
    if skipped.is_some() || !(w.is_finite() && dt.is_finite() && dt > 0.0) {
        return from;
    }
    let moved = integrate_gyro(from, w * sign, dt);
    if !moved.is_finite() {
        return from;
    }
    let d = to * moved.conj();
    let phi = d.vector() * (2.0_f64.copysign(d.w));
    if phi.is_finite() {
        turn_in_earth(moved, phi * gain.gain(dt))
    } else {
        moved
    }
}

/// `Exp(P_f·(P_f + P_b)⁻¹·δ) ⊗ q_f` with `δ = Log(q_b ⊗ q_f*)`, per lane, with the mask of
/// the lanes where it could be formed (finite input, `P_f + P_b` positive definite, a finite
/// result); the other lanes hold garbage.
fn fuse<T: Lane>(
    qf: Quat<T>,
    pf: Mat<T, 3, 3>,
    qb: Quat<T>,
    pb: Mat<T, 3, 3>,
) -> (Quat<T>, T::Mask) {
    let finite = qf.is_finite() & qb.is_finite() & pf.is_finite() & pb.is_finite();
    let delta = (qb * qf.conj()).to_rotation_vector();
    let sum = Mat::from_fn(|i, j| pf.m[i][j] + pb.m[i][j]);
    let (l, positive) = sum.cholesky();
    let x = l.cholesky_solve(&Mat::from_column(delta.to_array()));
    let k_delta = pf * x;
    let step = Vec3::new(k_delta.m[0][0], k_delta.m[1][0], k_delta.m[2][0]);
    let q = (Quat::from_rotation_vector(step) * qf).normalize();
    let ok = finite & positive & q.is_finite();
    (q, ok)
}

/// Circular mean of the heading of `q_f ⊗ q_b*` over the samples, weighted by the inverse of
/// the summed heading variances (rad): the heading turn that brings the backward 6D
/// estimates into the forward one's frame.
fn heading_offset(forward: &Pass, backward: &Pass) -> f64 {
    let (mut s, mut c) = (0.0, 0.0);
    for ((qf, pf), (qb, pb)) in forward.iter().zip(backward) {
        let var = match (pf, pb) {
            (Some(a), Some(b)) => a.m[2][2] + b.m[2][2],
            _ => continue,
        };
        // Heading of the error qf ⊗ qb* (earth frame), as the BROAD 6D alignment defines it.
        let e = *qf * qb.conj();
        let psi = 2.0 * e.z.atan2(e.w);
        let w = 1.0 / var;
        if psi.is_finite() && w.is_finite() && w > 0.0 {
            s += w * psi.sin();
            c += w * psi.cos();
        }
    }
    if s == 0.0 && c == 0.0 {
        0.0
    } else {
        s.atan2(c)
    }
}
