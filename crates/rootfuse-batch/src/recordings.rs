//! [`run_recordings`]: whole recordings as channels, what the CLI calls.

use crate::MAX_LANES;
use crate::batch::{Batch, ChannelSource, RejectionTotals, SpecMismatch};
use rayon::prelude::*;
use rootfuse_attitude::filters::SampleFlags;
use rootfuse_attitude::registry::{FilterSpec, FilterVisitor, RegisteredFilter};
use rootfuse_attitude::{Lane, OrientationFilter, Quat, Recording, Vec3};
use rootfuse_lane::X2;
use rootfuse_lane::wide::{f32x8, f64x4};

/// Arithmetic precision of a batch run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Precision {
    /// `f32`, eight channels per `f32x8`.
    F32,
    /// `f64`, four channels per `f64x4`.
    F64,
}

/// Which per-sample series [`run_recordings_with`] collects besides the orientation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Columns {
    /// The gyro-bias estimate ([`ChannelOutput::bias`]).
    pub bias: bool,
    /// The attitude-error covariance ([`ChannelOutput::covariance`]); filters without one
    /// leave it empty.
    pub covariance: bool,
    /// What was skipped at each sample ([`ChannelOutput::flags`]).
    pub flags: bool,
}

impl Default for Columns {
    /// The bias only, what [`run_recordings`] collects.
    fn default() -> Self {
        Self {
            bias: true,
            covariance: false,
            flags: false,
        }
    }
}

/// Bits of [`ChannelOutput::flags`], as
/// [`SampleFlags::bits`](rootfuse_attitude::filters::SampleFlags::bits) reports them: what
/// happened to the sample (1–16, 64) and the rest detector's state after it (32).
pub mod flag {
    use rootfuse_attitude::filters::SampleFlags;
    /// The whole sample was skipped: `dt` unusable.
    pub const DT: u8 = SampleFlags::<f32>::DT;
    /// The whole sample was skipped: gyroscope unusable.
    pub const GYR: u8 = SampleFlags::<f32>::GYR;
    /// The accelerometer correction was skipped: not finite or zero.
    pub const ACC: u8 = SampleFlags::<f32>::ACC;
    /// The magnetometer correction was skipped (9D): absent, not finite or zero.
    pub const MAG: u8 = SampleFlags::<f32>::MAG;
    /// A correction was refused by the filter's own gate (acceleration norm, innovation).
    pub const GATED: u8 = SampleFlags::<f32>::ACC_GATED;
    /// Status, not a skip: the filter detects the sensor at rest (gyro bias learned).
    pub const REST: u8 = SampleFlags::<f32>::AT_REST;
    /// The magnetometer sample was rejected as a disturbed field (counted apart from
    /// [`GATED`], in `RejectionTotals::mag_disturbed`).
    pub const MAG_DISTURBED: u8 = SampleFlags::<f32>::MAG_DISTURBED;
}

/// The estimates of one channel at every one of its samples, in `f64`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ChannelOutput {
    /// Orientation after each sample (sensor to earth, ENU).
    pub quat: Vec<Quat<f64>>,
    /// Gyro-bias estimate after each sample, rad/s (zero for filters without one; empty when
    /// not collected).
    pub bias: Vec<Vec3<f64>>,
    /// Attitude-error covariance after each sample, rad², as its upper triangle
    /// `[xx, xy, xz, yy, yz, zz]` in the convention of
    /// [`OrientationFilter::attitude_covariance`](rootfuse_attitude::OrientationFilter::attitude_covariance) (earth frame, ENU: `zz` is heading). Empty
    /// when not collected or when the filter carries none.
    pub covariance: Vec<[f64; 6]>,
    /// Per sample, the [`flag`] bits of what the filter skipped at that sample (empty when
    /// not collected).
    pub flags: Vec<u8>,
    /// What the filter skipped over the whole recording, by reason.
    pub rejections: RejectionTotals,
}

/// Bytes of the register file for 256-bit vectors (32 `ymm` registers with AVX-512VL, 16
/// without): the budget under which a filter's lane state is small enough to run two chunks
/// interleaved ([`X2`](rootfuse_lane::X2)) without spilling.
pub const INTERLEAVE_STATE_BYTES: usize = 1024;

/// Whether the batch engine runs `spec` as [`X2`](rootfuse_lane::X2) (two chunks interleaved per dependency
/// chain) rather than one vector: when its state over `L` fits [`INTERLEAVE_STATE_BYTES`].
///
/// Small filters (gyro, complementary, Mahony, Madgwick) are latency bound: one update is a
/// chain of dependent square roots, divisions and products, so a second independent chain in
/// the same instructions nearly doubles throughput. Large ones (the EKFs, the flagship) are
/// bound by arithmetic and registers already; interleaving them spills and slows them down.
pub fn interleaves<L: Lane>(spec: &FilterSpec) -> bool {
    struct Size;
    impl<L: Lane> FilterVisitor<L> for Size {
        type Output = usize;
        fn visit<F: RegisteredFilter<L>>(self, _: &FilterSpec) -> usize {
            core::mem::size_of::<F>()
        }
    }
    spec.visit::<L, _>(Size) <= INTERLEAVE_STATE_BYTES
}

/// Runs every recording as one channel (lanes of `f32x8` or `f64x4`), recordings of different
/// lengths and rates allowed; chunks spread over threads with rayon; result independent of
/// thread count.
///
/// Channel `i` of the result belongs to `recs[i]` and equals, bit for bit, running that
/// recording alone through `spec.build::<f32>()` (resp. `f64`) with `rec.sample(k)` rounded to
/// the precision and `rec.dt(k)`. A channel whose recording has ended is masked: it gets no
/// more samples and its counters stop.
///
/// ```
/// use rootfuse_attitude::registry::FilterSpec;
/// use rootfuse_eval::sim::scenario;
/// use rootfuse_batch::{Precision, run_recordings};
///
/// let spec = FilterSpec::new("mahony").unwrap();
/// let recs = vec![
///     scenario("static", 1, 2.0, 100.0).unwrap(),
///     scenario("slow-rotation", 2, 1.0, 200.0).unwrap(),
/// ];
/// let out = run_recordings(&spec, &recs, Precision::F32);
/// assert_eq!(out.len(), 2);
/// assert_eq!(out[0].quat.len(), recs[0].len());
/// assert_eq!(out[1].bias.len(), recs[1].len());
/// ```
pub fn run_recordings(
    spec: &FilterSpec,
    recs: &[Recording],
    precision: Precision,
) -> Vec<ChannelOutput> {
    run_recordings_with(spec, recs, precision, Columns::default())
}

/// [`run_recordings`], collecting the series chosen in `columns`.
///
/// ```
/// use rootfuse_attitude::registry::FilterSpec;
/// use rootfuse_eval::sim::scenario;
/// use rootfuse_batch::{Columns, Precision, flag, run_recordings_with};
///
/// let spec = FilterSpec::new("sqrt-eskf").unwrap();
/// let recs = vec![scenario("static", 1, 2.0, 100.0).unwrap()];
/// let columns = Columns { bias: false, covariance: true, flags: true };
/// let out = run_recordings_with(&spec, &recs, Precision::F64, columns);
/// assert!(out[0].bias.is_empty());
/// assert_eq!(out[0].covariance.len(), recs[0].len());
/// assert!(out[0].covariance.iter().all(|p| p[0] > 0.0 && p[3] > 0.0 && p[5] > 0.0));
/// // Nothing skipped; the sensor of the "static" scenario is detected at rest in the end.
/// assert!(out[0].flags.iter().all(|&f| f & (flag::REST - 1) == 0));
/// assert!(out[0].flags.last().is_some_and(|&f| f & flag::REST != 0));
/// ```
pub fn run_recordings_with(
    spec: &FilterSpec,
    recs: &[Recording],
    precision: Precision,
    columns: Columns,
) -> Vec<ChannelOutput> {
    let mut out: Vec<ChannelOutput> = recs
        .iter()
        .map(|r| ChannelOutput::with_capacity(r.len(), columns))
        .collect();
    run_into_sinks(spec, precision, recs, &mut out, columns);
    out
}

/// Runs `sources` (channel `i` into `sinks[i]`) on the engine's lanes for `precision`
/// ([`visit_lanes`]): [`run_sources_into`] with the lane type chosen as
/// [`run_recordings`] chooses it. Each channel's estimates equal a scalar run of it in that
/// precision, bit for bit.
pub fn run_into_sinks<S: ChannelSource, K: EstimateSink>(
    spec: &FilterSpec,
    precision: Precision,
    sources: &[S],
    sinks: &mut [K],
    columns: Columns,
) {
    visit_lanes(
        spec,
        precision,
        IntoSinks {
            sources,
            sinks,
            columns,
        },
    );
}

/// Visits `spec` with the engine's lanes for `precision`: `f32x8` or `f64x4`, as two vectors
/// interleaved ([`X2`]) for the small filters that gain from it ([`interleaves`]); the
/// results are the same bits either way. What [`run_recordings`] and [`run_final_states`]
/// run on, for callers with a [`FilterVisitor`] of their own.
pub fn visit_lanes<V>(
    spec: &FilterSpec,
    precision: Precision,
    visitor: V,
) -> <V as FilterVisitor<f64x4>>::Output
where
    V: FilterVisitor<f64x4>
        + FilterVisitor<X2<f64x4>, Output = <V as FilterVisitor<f64x4>>::Output>
        + FilterVisitor<f32x8, Output = <V as FilterVisitor<f64x4>>::Output>
        + FilterVisitor<X2<f32x8>, Output = <V as FilterVisitor<f64x4>>::Output>,
{
    match precision {
        Precision::F32 if interleaves::<f32x8>(spec) => spec.visit::<X2<f32x8>, _>(visitor),
        Precision::F32 => spec.visit::<f32x8, _>(visitor),
        Precision::F64 if interleaves::<f64x4>(spec) => spec.visit::<X2<f64x4>, _>(visitor),
        Precision::F64 => spec.visit::<f64x4, _>(visitor),
    }
}

/// One channel's state after its last sample (see [`run_final_states`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FinalState {
    /// Orientation, sensor to earth (ENU).
    pub quat: Quat<f64>,
    /// Gyro-bias estimate, rad/s (zero for filters without one).
    pub bias: Vec3<f64>,
    /// Gyroscope scale-error estimate per sensor axis, a fraction `s` in
    /// `ω_measured = (1 + s)·ω` (the flagship's `gyr_scale_window`; zero for filters without
    /// one): a fleet's per-device calibration.
    pub gyro_scale: Vec3<f64>,
    /// What the filter skipped over the whole channel, by reason.
    pub rejections: RejectionTotals,
}

/// Runs channel `i` of `sources` with `specs[i]` through the batch engine and keeps only
/// each channel's final state: no series is collected, so the engine runs at the rate of its
/// filters and of reading the input. Channels may differ in any parameter: those that agree
/// on the structural ones share chunks, each lane with its own parameters
/// ([`Batch::with_channel_specs`]); lanes by [`visit_lanes`]. Each channel equals a scalar
/// run with its own spec, bit for bit. An error names the first channel whose spec is of
/// another filter than `specs[0]`'s.
///
/// ```
/// use rootfuse_attitude::registry::FilterSpec;
/// use rootfuse_batch::{Precision, run_final_states, run_recordings};
/// use rootfuse_eval::sim::scenario;
///
/// let spec = FilterSpec::new("mahony").unwrap();
/// let recs = vec![scenario("slow-rotation", 3, 2.0, 100.0).unwrap(); 3];
/// let last = run_final_states(&vec![spec.clone(); 3], &recs, Precision::F32).unwrap();
/// let series = run_recordings(&spec, &recs, Precision::F32);
/// assert_eq!(last[2].quat, *series[2].quat.last().unwrap());
/// ```
pub fn run_final_states<S: ChannelSource>(
    specs: &[FilterSpec],
    sources: &[S],
    precision: Precision,
) -> Result<Vec<FinalState>, SpecMismatch> {
    match specs.first() {
        None => Ok(Vec::new()),
        Some(first) => visit_lanes(first, precision, FinalStates { specs, sources }),
    }
}

struct FinalStates<'a, S> {
    specs: &'a [FilterSpec],
    sources: &'a [S],
}

impl<L: Lane, S: ChannelSource> FilterVisitor<L> for FinalStates<'_, S> {
    type Output = Result<Vec<FinalState>, SpecMismatch>;
    fn visit<F: RegisteredFilter<L>>(self, _: &FilterSpec) -> Self::Output {
        let mut batch = Batch::<L, F>::with_channel_specs(self.specs)?;
        batch.run_channels(self.sources);
        Ok((0..self.specs.len().min(batch.channels()))
            .map(|c| FinalState {
                quat: batch.quat(c),
                bias: batch.bias(c),
                gyro_scale: batch.gyro_scale(c),
                rejections: batch.rejections(c),
            })
            .collect())
    }
}

/// [`run_recordings`] for any lane type and any [`ChannelSource`].
pub fn run_sources<L: Lane, S: ChannelSource>(
    spec: &FilterSpec,
    sources: &[S],
) -> Vec<ChannelOutput> {
    run_sources_with::<L, S>(spec, sources, Columns::default())
}

/// [`run_recordings_with`] for any lane type and any [`ChannelSource`].
pub fn run_sources_with<L: Lane, S: ChannelSource>(
    spec: &FilterSpec,
    sources: &[S],
    columns: Columns,
) -> Vec<ChannelOutput> {
    // One dispatch to the concrete filter type: chunks hold only that filter's state and
    // nothing is matched per sample.
    let mut out: Vec<ChannelOutput> = sources
        .iter()
        .map(|s| ChannelOutput::with_capacity(s.len(), columns))
        .collect();
    run_sources_into::<L, S, ChannelOutput>(spec, sources, &mut out, columns);
    out
}

impl ChannelOutput {
    /// Empty series with room for `len` samples of the `columns` collected.
    fn with_capacity(len: usize, columns: Columns) -> Self {
        let capacity = |on: bool| if on { len } else { 0 };
        Self {
            quat: Vec::with_capacity(len),
            bias: Vec::with_capacity(capacity(columns.bias)),
            covariance: Vec::with_capacity(capacity(columns.covariance)),
            flags: Vec::with_capacity(capacity(columns.flags)),
            rejections: RejectionTotals::default(),
        }
    }
}

/// Where [`run_sources_into`] puts one channel's estimates, sample by sample.
///
/// [`ChannelOutput`] collects them into vectors; a caller with its own storage (the Python
/// package writes straight into NumPy arrays allocated once) implements this to receive
/// them in place. Each channel's sink is called from one thread, in sample order.
pub trait EstimateSink: Send {
    /// The estimates after sample `k` of the channel: orientation (sensor to earth, ENU),
    /// and, as [`Columns`] asked (`None` otherwise, or for a filter without a covariance),
    /// the gyro bias (rad/s), the attitude-error covariance `[xx, xy, xz, yy, yz, zz]` (rad²)
    /// and the [`flag`] bits.
    fn push(&mut self, k: usize, estimate: &Estimate);
    /// The orientation after sample `k`, where [`Columns`] asked for nothing else: the
    /// default [`push_quat_lanes`](Self::push_quat_lanes) calls this per lane instead of
    /// [`push`](Self::push) then. By default `push` with the
    /// other columns `None`; a sink that stores the orientation directly overrides it and
    /// skips building the [`Estimate`] (a quaternion series is written at every sample of
    /// every channel, where a cheap filter's whole update is a few dozen instructions).
    #[inline]
    fn push_quat(&mut self, k: usize, quat: Quat<f64>) {
        let estimate = Estimate {
            quat,
            bias: None,
            covariance: None,
            flags: None,
        };
        self.push(k, &estimate);
    }
    /// The orientations after step `k` of a chunk's channels, `sinks[i]` the sink of lane
    /// `i`, for the lanes set in `active` (bit `i`), where [`Columns`] asked for nothing
    /// else: the engine calls this once per step of each chunk. By default each lane's value, in `f64`, to
    /// its sink's [`push_quat`](Self::push_quat); a sink that stores quaternions directly can
    /// move a whole step's lanes at once (the NumPy sink transposes them in registers).
    #[inline]
    fn push_quat_lanes<L: Lane>(sinks: &mut [Self], active: u64, k: usize, quat: &Quat<L>)
    where
        Self: Sized,
    {
        push_quat_per_lane(sinks, active, k, quat);
    }
    /// The channel's counters once its last sample has run.
    fn finish(&mut self, rejections: RejectionTotals);
}

/// One channel's estimates after one sample, in `f64` (see [`EstimateSink::push`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// Orientation, sensor to earth (ENU).
    pub quat: Quat<f64>,
    /// Gyro-bias estimate, rad/s, when collected.
    pub bias: Option<Vec3<f64>>,
    /// Attitude-error covariance `[xx, xy, xz, yy, yz, zz]`, rad², when collected and the
    /// filter carries one.
    pub covariance: Option<[f64; 6]>,
    /// [`flag`] bits of what the filter skipped, when collected.
    pub flags: Option<u8>,
}

impl EstimateSink for ChannelOutput {
    fn push(&mut self, _k: usize, e: &Estimate) {
        self.quat.push(e.quat);
        self.bias.extend(e.bias);
        self.covariance.extend(e.covariance);
        self.flags.extend(e.flags);
    }
    fn finish(&mut self, rejections: RejectionTotals) {
        self.rejections = rejections;
    }
}

/// Runs `sources` (channel `i` into `sinks[i]`; the shorter of the two sets the count) on
/// lanes `L`, the concrete filter type of `spec`, chunks spread over threads with rayon:
/// [`run_sources_with`] with the estimates handed to the caller's sinks as they come
/// instead of collected. Each channel's estimates equal a scalar run of it, bit for bit.
///
/// ```
/// use rootfuse_attitude::registry::FilterSpec;
/// use rootfuse_batch::{Columns, Estimate, EstimateSink, RejectionTotals, run_sources_into};
/// use rootfuse_eval::sim::scenario;
/// use rootfuse_lane::wide::f64x4;
///
/// /// Keeps the last orientation only.
/// #[derive(Default)]
/// struct Last(Option<Estimate>, RejectionTotals);
/// impl EstimateSink for Last {
///     fn push(&mut self, _k: usize, e: &Estimate) { self.0 = Some(*e); }
///     fn finish(&mut self, r: RejectionTotals) { self.1 = r; }
/// }
/// let spec = FilterSpec::new("mahony").unwrap();
/// let recs = vec![scenario("static", 1, 1.0, 100.0).unwrap(); 3];
/// let mut sinks: Vec<Last> = (0..3).map(|_| Last::default()).collect();
/// run_sources_into::<f64x4, _, _>(&spec, &recs, &mut sinks, Columns::default());
/// assert!(sinks.iter().all(|s| s.0.is_some() && s.1.dt == 0));
/// ```
pub fn run_sources_into<L: Lane, S: ChannelSource, K: EstimateSink>(
    spec: &FilterSpec,
    sources: &[S],
    sinks: &mut [K],
    columns: Columns,
) {
    spec.visit::<L, _>(IntoSinks {
        sources,
        sinks,
        columns,
    });
}

struct IntoSinks<'a, S, K> {
    sources: &'a [S],
    sinks: &'a mut [K],
    columns: Columns,
}

impl<L: Lane, S: ChannelSource, K: EstimateSink> FilterVisitor<L> for IntoSinks<'_, S, K> {
    type Output = ();
    fn visit<F: RegisteredFilter<L>>(self, spec: &FilterSpec) {
        run_typed::<L, F, S, K>(spec, self.sources, self.sinks, self.columns);
    }
}

fn run_typed<L: Lane, F: RegisteredFilter<L>, S: ChannelSource, K: EstimateSink>(
    spec: &FilterSpec,
    sources: &[S],
    sinks: &mut [K],
    columns: Columns,
) {
    let count = sources.len().min(sinks.len());
    let (sources, sinks) = (&sources[..count], &mut sinks[..count]);
    let mut batch = Batch::<L, F>::for_visited_spec(spec, count);
    batch
        .chunks_mut()
        .par_iter_mut()
        .zip(
            sources
                .par_chunks(L::LANES)
                .zip(sinks.par_chunks_mut(L::LANES)),
        )
        .for_each(|(chunk, (srcs, outs))| {
            let steps = srcs.iter().map(|s| s.len()).max().unwrap_or(0);
            let quat_only = !(columns.bias || columns.covariance || columns.flags);
            chunk.run_sources(srcs, 0..steps, |k, chunk, active| {
                if quat_only {
                    K::push_quat_lanes(outs, active, k, &chunk.filter().quat());
                    return;
                }
                let view = Estimate::lanes(chunk.filter(), columns);
                for (i, o) in outs.iter_mut().enumerate() {
                    if (active >> i) & 1 == 1 {
                        o.push(k, &view.lane(i));
                    }
                }
            });
            for (i, o) in outs.iter_mut().enumerate() {
                o.finish(chunk.rejections(i));
            }
        });
}

/// [`EstimateSink::push_quat_lanes`]'s default, for a sink's own fallback: each active
/// lane's orientation, in `f64`, to its sink's [`push_quat`](EstimateSink::push_quat).
#[inline]
pub fn push_quat_per_lane<K: EstimateSink, L: Lane>(
    sinks: &mut [K],
    active: u64,
    k: usize,
    quat: &Quat<L>,
) {
    let [w, x, y, z] = [quat.w, quat.x, quat.y, quat.z].map(lane_values);
    for (i, o) in sinks.iter_mut().enumerate() {
        if (active >> i) & 1 == 1 {
            o.push_quat(k, Quat::new(w[i], x[i], y[i], z[i]));
        }
    }
}

/// One step's estimates of every lane of a chunk, read lane by lane ([`StepLanes::lane`]):
/// the lanes' values taken out of their vectors once per step, in `f64`, so that reading a
/// lane is a load per value, not a vector spilled per value.
pub(crate) struct StepLanes {
    quat: [[f64; MAX_LANES]; 4],
    bias: Option<[[f64; MAX_LANES]; 3]>,
    covariance: Option<[[f64; MAX_LANES]; 6]>,
    flags: Option<[u8; MAX_LANES]>,
}

/// Every lane of `x` in `f64` (lanes past `L::LANES` zero).
#[inline]
fn lane_values<L: Lane>(x: L) -> [f64; MAX_LANES] {
    const { assert!(L::LANES <= MAX_LANES, "a lane type wider than MAX_LANES") };
    let mut values = [0.0; MAX_LANES];
    for (i, v) in values.iter_mut().enumerate().take(L::LANES) {
        *v = x.extract(i).into();
    }
    values
}

impl Estimate {
    /// The series of `columns` of every lane of `filter`, as they are after its last update.
    pub(crate) fn lanes<L: Lane, F: OrientationFilter<L>>(
        filter: &F,
        columns: Columns,
    ) -> StepLanes {
        let q = filter.quat();
        StepLanes {
            quat: [q.w, q.x, q.y, q.z].map(lane_values),
            bias: columns.bias.then(|| {
                let b = filter.bias();
                [b.x, b.y, b.z].map(lane_values)
            }),
            covariance: if columns.covariance {
                filter.attitude_covariance().map(|p| {
                    let m = &p.m;
                    [m[0][0], m[0][1], m[0][2], m[1][1], m[1][2], m[2][2]].map(lane_values)
                })
            } else {
                None
            },
            flags: columns.flags.then(|| {
                let f: SampleFlags<L> = filter.flags();
                core::array::from_fn(|i| if i < L::LANES { f.bits(i) } else { 0 })
            }),
        }
    }
}

impl StepLanes {
    /// Lane `i`'s estimates.
    #[inline]
    pub(crate) fn lane(&self, i: usize) -> Estimate {
        let q = &self.quat;
        Estimate {
            quat: Quat::new(q[0][i], q[1][i], q[2][i], q[3][i]),
            bias: self
                .bias
                .as_ref()
                .map(|b| Vec3::new(b[0][i], b[1][i], b[2][i])),
            covariance: self
                .covariance
                .as_ref()
                .map(|p| core::array::from_fn(|j| p[j][i])),
            flags: self.flags.as_ref().map(|f| f[i]),
        }
    }
}
