//! [`run_recordings`]: whole recordings as channels, what the CLI calls.

use crate::batch::{Batch, ChannelSource, RejectionTotals};
use rayon::prelude::*;
use rootfuse_attitude::registry::FilterSpec;
use rootfuse_attitude::{Lane, OrientationFilter, Quat, Recording, Vec3};
use rootfuse_lane::wide::{f32x8, f64x4};

/// Arithmetic precision of a batch run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Precision {
    /// `f32`, eight channels per `f32x8`.
    F32,
    /// `f64`, four channels per `f64x4`.
    F64,
}

/// The estimates of one channel at every one of its samples, in `f64`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ChannelOutput {
    /// Orientation after each sample (sensor to earth, ENU).
    pub quat: Vec<Quat<f64>>,
    /// Gyro-bias estimate after each sample, rad/s (zero for filters without one).
    pub bias: Vec<Vec3<f64>>,
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
/// use rootfuse_attitude::sim::scenario;
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
    match precision {
        Precision::F32 => run_sources::<f32x8, _>(spec, recs),
        Precision::F64 => run_sources::<f64x4, _>(spec, recs),
    }
}

/// [`run_recordings`] for any lane type and any [`ChannelSource`].
pub fn run_sources<L: Lane, S: ChannelSource>(
    spec: &FilterSpec,
    sources: &[S],
) -> Vec<ChannelOutput> {
    let mut batch = Batch::<L>::new(spec, sources.len());
    let mut out: Vec<ChannelOutput> = sources
        .iter()
        .map(|s| ChannelOutput {
            quat: Vec::with_capacity(s.len()),
            bias: Vec::with_capacity(s.len()),
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
                let (q, b) = (chunk.filter().quat(), chunk.filter().bias());
                for (i, o) in outs.iter_mut().enumerate() {
                    if (active >> i) & 1 == 1 {
                        let (q, b) = (q.lane(i), b.lane(i));
                        o.quat
                            .push(Quat::new(q.w.into(), q.x.into(), q.y.into(), q.z.into()));
                        o.bias.push(Vec3::new(b.x.into(), b.y.into(), b.z.into()));
                    }
                }
            });
            for (i, o) in outs.iter_mut().enumerate() {
                o.rejections = chunk.rejections(i);
            }
        });
    out
}
