//! The batch engine: SIMD lanes against scalar runs of the same channels.

use crate::Bytes;
use crate::filter::{sample_from, spec_from};
use rootfuse_attitude::registry::FilterSpec;
use rootfuse_attitude::{ImuSample, Lane, OrientationFilter, Vec3};
use rootfuse_batch::{Batch, Channel, RejectionTotals};
use rootfuse_lane::wide::{f32x8, f64x4};

/// Most channels and steps per channel of one input.
const MAX_CHANNELS: usize = 12;
const MAX_STEPS: usize = 48;

/// Fuzz target `batch_engine`: a registered filter (chosen like [`filter_update`]) over up
/// to 12 channels of different lengths with arbitrary samples and time steps, run by
/// [`Batch`] in `f32x8` lanes (or `f64x4`), each channel compared with a scalar run of its own
/// data.
///
/// Invariants: no panic; every channel's quaternion, bias and rejection counters equal the
/// scalar run's bit for bit (channels shorter than the longest are masked, tail lanes padded:
/// neither may leak into a channel).
///
/// [`filter_update`]: crate::filter_update
pub fn batch_engine(data: &[u8]) {
    let mut input = Bytes::new(data);
    let spec = spec_from(&mut input);
    let mode = input.u8();
    let single = mode & 1 == 0;
    let channels = 1 + usize::from(mode >> 1) % MAX_CHANNELS;
    let lens: Vec<usize> = (0..channels)
        .map(|_| usize::from(input.u8()) % (MAX_STEPS + 1))
        .collect();
    let data: Vec<(Vec<ImuSample<f64>>, Vec<f64>)> = lens
        .iter()
        .map(|&n| (0..n).map(|_| sample_from(&mut input, single)).unzip())
        .collect();
    let chans: Vec<Channel> = data
        .iter()
        .map(|(s, dt)| Channel { samples: s, dt })
        .collect();
    if single {
        compare::<f32x8, f32>(&spec, &chans);
    } else {
        compare::<f64x4, f64>(&spec, &chans);
    }
}

fn compare<L: Lane<Scalar = S>, S: Lane<Scalar = S> + Into<f64>>(
    spec: &FilterSpec,
    chans: &[Channel],
) {
    let name = spec.kind().name();
    let mut batch = Batch::<L>::new(spec, chans.len());
    batch.run_channels(chans);
    for (c, ch) in chans.iter().enumerate() {
        let mut f = spec.build::<S>();
        for (s, &dt) in ch.samples.iter().zip(ch.dt) {
            let v = |v: Vec3<f64>| Vec3::<S>::from_f64([v.x, v.y, v.z]);
            f.update(
                &ImuSample::new(v(s.gyr), v(s.acc), v(s.mag)),
                S::from_f64(dt),
            );
        }
        let q = f.quat().to_array().map(Into::<f64>::into);
        let b = f.bias().to_array().map(Into::<f64>::into);
        let (bq, bb) = (batch.quat(c).to_array(), batch.bias(c).to_array());
        assert_eq!(
            q.map(f64::to_bits),
            bq.map(f64::to_bits),
            "{name} channel {c}: {bq:?} vs scalar {q:?}"
        );
        assert_eq!(
            b.map(f64::to_bits),
            bb.map(f64::to_bits),
            "{name} channel {c}: bias {bb:?} vs scalar {b:?}"
        );
        assert_eq!(
            batch.rejections(c),
            RejectionTotals::of_lane(f.rejections(), 0),
            "{name} channel {c}: rejections"
        );
    }
}
