//! [`run_recordings`]: whole recordings as channels, what the CLI calls.

use crate::batch::{Batch, ChannelSource, RejectionTotals};
use rayon::prelude::*;
use rootfuse_attitude::filters::SampleFlags;
use rootfuse_attitude::registry::{FilterSpec, FilterVisitor, RegisteredFilter};
use rootfuse_attitude::{Lane, Mat, OrientationFilter, Quat, Recording, Vec3};
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
    match precision {
        Precision::F32 => run_sources_with::<f32x8, _>(spec, recs, columns),
        Precision::F64 => run_sources_with::<f64x4, _>(spec, recs, columns),
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
    spec.visit::<L, _>(RunSources { sources, columns })
}

struct RunSources<'a, S> {
    sources: &'a [S],
    columns: Columns,
}

impl<L: Lane, S: ChannelSource> FilterVisitor<L> for RunSources<'_, S> {
    type Output = Vec<ChannelOutput>;
    fn visit<F: RegisteredFilter<L>>(self, spec: &FilterSpec) -> Vec<ChannelOutput> {
        run_typed::<L, F, S>(spec, self.sources, self.columns)
    }
}

fn run_typed<L: Lane, F: RegisteredFilter<L>, S: ChannelSource>(
    spec: &FilterSpec,
    sources: &[S],
    columns: Columns,
) -> Vec<ChannelOutput> {
    let mut batch = Batch::<L, F>::for_visited_spec(spec, sources.len());
    let capacity = |on: bool, len: usize| if on { len } else { 0 };
    let mut out: Vec<ChannelOutput> = sources
        .iter()
        .map(|s| ChannelOutput {
            quat: Vec::with_capacity(s.len()),
            bias: Vec::with_capacity(capacity(columns.bias, s.len())),
            covariance: Vec::with_capacity(capacity(columns.covariance, s.len())),
            flags: Vec::with_capacity(capacity(columns.flags, s.len())),
            rejections: RejectionTotals::default(),
        })
        .collect();
    batch
        .chunks_mut()
        .par_iter_mut()
        .zip(
            sources
                .par_chunks(L::LANES)
                .zip(out.par_chunks_mut(L::LANES)),
        )
        .for_each(|(chunk, (srcs, outs))| {
            let steps = srcs.iter().map(|s| s.len()).max().unwrap_or(0);
            chunk.run_sources(srcs, 0..steps, |_, chunk, active| {
                let view = StepEstimates::lanes(chunk.filter(), columns);
                for (i, o) in outs.iter_mut().enumerate() {
                    if (active >> i) & 1 == 0 {
                        continue;
                    }
                    let step = view.lane(i);
                    o.quat.push(step.quat);
                    o.bias.extend(step.bias);
                    o.covariance.extend(step.covariance);
                    o.flags.extend(step.flags);
                }
            });
            for (i, o) in outs.iter_mut().enumerate() {
                o.rejections = chunk.rejections(i);
            }
        });
    out
}

/// One step's estimates of every lane of a chunk, read lane by lane ([`StepLanes::lane`]).
pub(crate) struct StepLanes<L: Lane> {
    quat: Quat<L>,
    bias: Option<Vec3<L>>,
    covariance: Option<Mat<L, 3, 3>>,
    flags: Option<SampleFlags<L>>,
}

/// One lane's estimates after one step, in `f64`; `None` for a series not collected.
#[derive(Clone, Copy)]
pub(crate) struct StepEstimates {
    pub quat: Quat<f64>,
    pub bias: Option<Vec3<f64>>,
    pub covariance: Option<[f64; 6]>,
    pub flags: Option<u8>,
}

impl StepEstimates {
    /// The series of `columns` of every lane of `filter`, as they are after its last update.
    pub(crate) fn lanes<L: Lane, F: OrientationFilter<L>>(
        filter: &F,
        columns: Columns,
    ) -> StepLanes<L> {
        StepLanes {
            quat: filter.quat(),
            bias: columns.bias.then(|| filter.bias()),
            covariance: if columns.covariance {
                filter.attitude_covariance()
            } else {
                None
            },
            flags: columns.flags.then(|| filter.flags()),
        }
    }
}

impl<L: Lane> StepLanes<L> {
    /// Lane `i`'s estimates.
    pub(crate) fn lane(&self, i: usize) -> StepEstimates {
        let q = self.quat.lane(i);
        StepEstimates {
            quat: Quat::new(q.w.into(), q.x.into(), q.y.into(), q.z.into()),
            bias: self.bias.map(|b| {
                let b = b.lane(i);
                Vec3::new(b.x.into(), b.y.into(), b.z.into())
            }),
            covariance: self.covariance.as_ref().map(|p| {
                let at = |r: usize, c: usize| -> f64 { p.m[r][c].extract(i).into() };
                [at(0, 0), at(0, 1), at(0, 2), at(1, 1), at(1, 2), at(2, 2)]
            }),
            flags: self.flags.as_ref().map(|f| f.bits(i)),
        }
    }
}
