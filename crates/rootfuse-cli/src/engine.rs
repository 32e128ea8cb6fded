//! Runs recordings through a filter, one channel per recording.
//!
//! Until the batch engine lands this runs each recording through the scalar filter; the
//! signature is the batch engine's, so the switch is one line.
use rootfuse_attitude::registry::FilterSpec;
use rootfuse_attitude::{ImuSample, Lane, OrientationFilter, Quat, Recording, Vec3};

/// Arithmetic precision of a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Precision {
    /// Single precision.
    F32,
    /// Double precision.
    F64,
}

/// Rejected samples and corrections of one channel, by reason.
#[derive(Clone, Copy, Debug, Default)]
pub struct RejectionTotals {
    pub dt: u64,
    pub gyr: u64,
    pub acc: u64,
    pub mag: u64,
    pub gated: u64,
}

/// What one channel produced.
pub struct ChannelOutput {
    pub quat: Vec<Quat<f64>>,
    pub bias: Vec<Vec3<f64>>,
    pub rejections: RejectionTotals,
}

fn run_one<T: Lane>(spec: &FilterSpec, rec: &Recording) -> ChannelOutput {
    let to = |x: f64| T::from_f64(x);
    let back = |x: T| -> f64 { x.extract(0).into() };
    let v = |x: Vec3<f64>| Vec3::new(to(x.x), to(x.y), to(x.z));
    let mut f = spec.build::<T>();
    let mut quat = Vec::with_capacity(rec.len());
    let mut bias = Vec::with_capacity(rec.len());
    for i in 0..rec.len() {
        let s = rec.sample(i);
        f.update(&ImuSample::new(v(s.gyr), v(s.acc), v(s.mag)), to(rec.dt(i)));
        let q = f.quat();
        let b = f.bias();
        quat.push(Quat::new(back(q.w), back(q.x), back(q.y), back(q.z)));
        bias.push(Vec3::new(back(b.x), back(b.y), back(b.z)));
    }
    let r = f.rejections();
    let rejections = RejectionTotals {
        dt: r.dt.as_ref()[0],
        gyr: r.gyr.as_ref()[0],
        acc: r.acc.as_ref()[0],
        mag: r.mag.as_ref()[0],
        gated: r.gated.as_ref()[0],
    };
    ChannelOutput {
        quat,
        bias,
        rejections,
    }
}

/// Runs every recording as one channel.
pub fn run_recordings(
    spec: &FilterSpec,
    recs: &[Recording],
    precision: Precision,
) -> Vec<ChannelOutput> {
    recs.iter()
        .map(|rec| match precision {
            Precision::F32 => run_one::<f32>(spec, rec),
            Precision::F64 => run_one::<f64>(spec, rec),
        })
        .collect()
}
