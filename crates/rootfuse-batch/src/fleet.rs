//! [`FleetRunner`]: a fleet of devices streamed through the batch engine in blocks of rows.

use crate::batch::{Batch, ChannelSource, RejectionTotals};
use crate::recordings::{Columns, Precision, StepEstimates};
use rayon::prelude::*;
use rootfuse_attitude::registry::{FilterSpec, FilterVisitor, RegisteredFilter};
use rootfuse_attitude::{ImuSample, Lane, Quat, Vec3};
use rootfuse_lane::wide::{f32x8, f64x4};

/// One block of a fleet's rows: row `r` is the sample of device `device[r]` at time `t[r]`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FleetBlock {
    /// Device (channel) index of each row, `0..` in order of first appearance.
    pub device: Vec<u32>,
    /// Sample time, s; strictly increasing per device.
    pub t: Vec<f64>,
    /// Angular rate, rad/s, sensor frame.
    pub gyr: Vec<Vec3<f64>>,
    /// Specific force, m/s², sensor frame.
    pub acc: Vec<Vec3<f64>>,
    /// Magnetic field, sensor frame; `None` for 6D rows.
    pub mag: Option<Vec<Vec3<f64>>>,
}

impl FleetBlock {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Rows among `rows` with a NaN or infinite gyroscope, accelerometer or magnetometer
    /// value (dropped packets, which the filters skip and count).
    pub fn rows_with_missing_imu(&self, rows: core::ops::Range<usize>) -> usize {
        samples_with_missing_imu(
            &self.gyr[rows.clone()],
            &self.acc[rows.clone()],
            self.mag.as_ref().map(|m| &m[rows]),
        )
    }

    fn sample(&self, r: usize) -> ImuSample<f64> {
        match &self.mag {
            Some(mag) => ImuSample::new(self.gyr[r], self.acc[r], mag[r]),
            None => ImuSample::six_d(self.gyr[r], self.acc[r]),
        }
    }
}

/// Samples with a NaN or infinite gyroscope, accelerometer or magnetometer value (dropped
/// packets, which the filters skip and count); the slices are of one length.
pub fn samples_with_missing_imu(
    gyr: &[Vec3<f64>],
    acc: &[Vec3<f64>],
    mag: Option<&[Vec3<f64>]>,
) -> usize {
    let finite = |v: &Vec3<f64>| v.x.is_finite() && v.y.is_finite() && v.z.is_finite();
    (0..gyr.len().min(acc.len()))
        .filter(|&r| !finite(&gyr[r]) || !finite(&acc[r]) || mag.is_some_and(|m| !finite(&m[r])))
        .count()
}

/// The estimates of a block, row by row (`quat[r]` belongs to row `r` of the block).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BlockEstimates {
    /// Orientation after each row (sensor to earth, ENU); NaN for rows not [`kept`](Self::kept).
    pub quat: Vec<Quat<f64>>,
    /// Gyro-bias estimate after each row, rad/s (empty unless [`Columns::bias`]).
    pub bias: Vec<Vec3<f64>>,
    /// Attitude-error covariance after each row, `[xx, xy, xz, yy, yz, zz]`, rad² (empty
    /// unless [`Columns::covariance`] and the filter carries one).
    pub covariance: Vec<[f64; 6]>,
    /// What the filter skipped at each row, [`flag`](crate::flag) bits (empty unless
    /// [`Columns::flags`]).
    pub flags: Vec<u8>,
    /// False for the rows of a device that failed ([`OnError::DropDevice`]): from its bad row
    /// on, a failed device is not run and its rows have no estimate.
    pub kept: Vec<bool>,
    /// The devices that failed in this block (with [`OnError::DropDevice`]).
    pub failures: Vec<FleetError>,
}

/// A row the fleet cannot use. `row` is the row's index within the block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FleetError {
    /// The time stamp is NaN or infinite.
    TimeNotFinite {
        /// Row within the block.
        row: usize,
        /// The device.
        device: u32,
        /// The time read, s.
        value: f64,
    },
    /// The time stamp does not exceed the device's previous one.
    TimeNotIncreasing {
        /// Row within the block.
        row: usize,
        /// The device.
        device: u32,
        /// The time read, s.
        value: f64,
        /// The device's previous time, s.
        previous: f64,
    },
}

impl FleetError {
    /// The row within the block.
    pub fn row(&self) -> usize {
        match *self {
            Self::TimeNotFinite { row, .. } | Self::TimeNotIncreasing { row, .. } => row,
        }
    }

    /// The device.
    pub fn device(&self) -> u32 {
        match *self {
            Self::TimeNotFinite { device, .. } | Self::TimeNotIncreasing { device, .. } => device,
        }
    }
}

impl core::fmt::Display for FleetError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::TimeNotFinite { value, .. } => write!(f, "time {value} is not finite"),
            Self::TimeNotIncreasing {
                value, previous, ..
            } => write!(
                f,
                "time {value} does not increase (the device's previous {previous})"
            ),
        }
    }
}

impl std::error::Error for FleetError {}

/// What [`FleetRunner::step`] does with a bad row.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum OnError {
    /// Return the error; nothing of the block is run.
    #[default]
    Stop,
    /// Stop that device (its rows from the bad one on are not [`kept`](BlockEstimates::kept),
    /// in this block and later ones), report it in [`BlockEstimates::failures`] and run the
    /// others.
    DropDevice,
}

/// The filters of a fleet's devices, fed block by block.
///
/// A fleet is a sequence of rows, each a sample of one device (its channel index) at one
/// time. Rows of different devices may interleave in any way; rows of one device must come
/// in time order. The runner keeps one filter per device in SIMD lanes (device `d` is lane
/// `d % LANES` of chunk `d / LANES`) and nothing else but each device's last time stamp, so
/// memory grows with the number of devices, never with the length of the recordings.
///
/// Each device's estimates equal, bit for bit, a run of that device's rows as one
/// [`Recording`](rootfuse_attitude::Recording) through [`run_recordings`](crate::run_recordings)
/// (and so through a scalar filter), whatever the block boundaries: a block runs every device
/// that has rows in it, step `k` feeding each device its `k`-th row of the block and masking
/// the devices that have fewer (see the crate docs on masking). The step before a device's
/// first sample is, as [`Recording::dt`](rootfuse_attitude::Recording::dt) defines it, the
/// step to its second sample; when that sample is not in the same block it is looked up in
/// the next block (the caller passes it), and a device whose second sample is further away
/// than that gets the step `0` (its first sample is skipped and counted as a `dt` rejection).
///
/// Throughput depends on the order of the rows: the lanes of a chunk are busy at a step only
/// when their devices all have a row there, so blocks in which many devices have many rows
/// (time-major order, or devices interleaved in groups) run at the batch engine's rate, while
/// a block holding a single device runs one lane of one chunk.
///
/// ```
/// use rootfuse_attitude::registry::FilterSpec;
/// use rootfuse_attitude::Vec3;
/// use rootfuse_batch::{Columns, FleetBlock, FleetRunner, OnError, Precision};
///
/// let spec = FilterSpec::new("mahony").unwrap();
/// let mut fleet = FleetRunner::new(&spec, Precision::F64, Columns::default());
/// // Two devices, time-major: rows alternate between device 0 and device 1.
/// let block = FleetBlock {
///     device: vec![0, 1, 0, 1],
///     t: vec![0.0, 0.0, 0.01, 0.01],
///     gyr: vec![Vec3::zero(); 4],
///     acc: vec![Vec3::new(0.0, 0.0, 9.81); 4],
///     mag: None,
/// };
/// let est = fleet.step(&block, None, OnError::Stop).unwrap();
/// assert_eq!(est.quat.len(), 4);
/// assert_eq!(fleet.devices(), 2);
/// ```
pub struct FleetRunner {
    engine: Box<dyn FleetEngine>,
    columns: Columns,
    /// Per device: its last time stamp (NaN before its first row).
    last_t: Vec<f64>,
    failed: Vec<bool>,
    /// Per device, the rows of the block being run (reused between blocks).
    groups: Vec<Vec<u32>>,
    /// Per device with rows in the block being run, its last time stamp before the block.
    before: Vec<f64>,
}

impl FleetRunner {
    /// An empty fleet of filters of `spec`; devices are added as their rows come.
    pub fn new(spec: &FilterSpec, precision: Precision, columns: Columns) -> Self {
        let engine = match precision {
            Precision::F32 => spec.visit::<f32x8, _>(MakeEngine),
            Precision::F64 => spec.visit::<f64x4, _>(MakeEngine),
        };
        Self {
            engine,
            columns,
            last_t: Vec::new(),
            failed: Vec::new(),
            groups: Vec::new(),
            before: Vec::new(),
        }
    }

    /// Number of devices seen so far.
    pub fn devices(&self) -> usize {
        self.last_t.len()
    }

    /// Rejection counters of device `d` so far (zero for a device not seen).
    pub fn rejections(&self, d: u32) -> RejectionTotals {
        if (d as usize) < self.devices() {
            self.engine.rejections(d as usize)
        } else {
            RejectionTotals::default()
        }
    }

    /// Bytes of filter state per device (see [`Batch::state_bytes_per_channel`]).
    pub fn state_bytes_per_device(&self) -> usize {
        self.engine.state_bytes_per_channel()
    }

    /// Runs one block and returns its estimates row by row. `next` is the block that will
    /// follow (if known), used only for the first step of a device that has one row in
    /// `block` (see [`FleetRunner`]).
    pub fn step(
        &mut self,
        block: &FleetBlock,
        next: Option<&FleetBlock>,
        on_error: OnError,
    ) -> Result<BlockEstimates, FleetError> {
        let n = block.len();
        let devices = block
            .device
            .iter()
            .map(|&d| d as usize + 1)
            .max()
            .unwrap_or(0)
            .max(self.devices());
        self.last_t.resize(devices, f64::NAN);
        self.failed.resize(devices, false);
        self.groups.resize_with(devices, Vec::new);
        self.before.resize(devices, f64::NAN);
        for g in &mut self.groups {
            g.clear();
        }
        let mut failures = Vec::new();
        for (r, (&d, &t)) in block.device.iter().zip(&block.t).enumerate() {
            let di = d as usize;
            if self.failed[di] {
                continue;
            }
            let previous = self.last_t[di];
            let error = if !t.is_finite() {
                Some(FleetError::TimeNotFinite {
                    row: r,
                    device: d,
                    value: t,
                })
            } else if t <= previous {
                Some(FleetError::TimeNotIncreasing {
                    row: r,
                    device: d,
                    value: t,
                    previous,
                })
            } else {
                None
            };
            if let Some(e) = error {
                match on_error {
                    OnError::Stop => {
                        // Nothing of the block runs: its time stamps are forgotten too.
                        for (d, g) in self.groups.iter().enumerate() {
                            if !g.is_empty() {
                                self.last_t[d] = self.before[d];
                            }
                        }
                        return Err(e);
                    }
                    OnError::DropDevice => {
                        self.failed[di] = true;
                        failures.push(e);
                        continue;
                    }
                }
            }
            if self.groups[di].is_empty() {
                self.before[di] = previous;
            }
            self.groups[di].push(r as u32);
            self.last_t[di] = t;
        }
        let sources: Vec<DeviceRows> = (0..devices)
            .map(|d| {
                let rows = self.groups[d].as_slice();
                DeviceRows {
                    block,
                    rows,
                    first_dt: first_step(block, next, rows, d as u32, self.before[d]),
                }
            })
            .collect();
        let mut est = BlockEstimates {
            quat: vec![Quat::new(f64::NAN, f64::NAN, f64::NAN, f64::NAN); n],
            bias: vec![Vec3::zero(); if self.columns.bias { n } else { 0 }],
            covariance: Vec::new(),
            flags: vec![0; if self.columns.flags { n } else { 0 }],
            kept: vec![false; n],
            failures,
        };
        if self.columns.covariance && self.engine.has_covariance() {
            est.covariance = vec![[f64::NAN; 6]; n];
        }
        self.engine.run(&sources, self.columns, &mut est);
        Ok(est)
    }
}

/// The step before a device's first row of the block: from its previous row (earlier
/// block), else to its second row (this block, or the next one), else 0.
fn first_step(
    block: &FleetBlock,
    next: Option<&FleetBlock>,
    rows: &[u32],
    d: u32,
    previous: f64,
) -> f64 {
    let Some(&first) = rows.first() else {
        return 0.0;
    };
    let t0 = block.t[first as usize];
    if !previous.is_nan() {
        return t0 - previous;
    }
    if let Some(&second) = rows.get(1) {
        return block.t[second as usize] - t0;
    }
    next.and_then(|b| {
        b.device
            .iter()
            .position(|&x| x == d)
            .map(|r| b.t[r] - t0)
            .filter(|dt| *dt > 0.0)
    })
    .unwrap_or(0.0)
}

/// One device's rows of a block as a channel.
struct DeviceRows<'a> {
    block: &'a FleetBlock,
    rows: &'a [u32],
    first_dt: f64,
}

impl ChannelSource for DeviceRows<'_> {
    fn len(&self) -> usize {
        self.rows.len()
    }
    fn sample(&self, i: usize) -> ImuSample<f64> {
        self.block.sample(self.rows[i] as usize)
    }
    fn dt(&self, i: usize) -> f64 {
        if i == 0 {
            self.first_dt
        } else {
            self.block.t[self.rows[i] as usize] - self.block.t[self.rows[i - 1] as usize]
        }
    }
}

/// The typed part of a fleet: chunks of one concrete filter type.
trait FleetEngine: Send {
    fn run(&mut self, sources: &[DeviceRows], columns: Columns, est: &mut BlockEstimates);
    fn rejections(&self, d: usize) -> RejectionTotals;
    fn state_bytes_per_channel(&self) -> usize;
    fn has_covariance(&self) -> bool;
}

struct MakeEngine;

impl<L: Lane> FilterVisitor<L> for MakeEngine
where
    L::Scalar: Lane,
{
    type Output = Box<dyn FleetEngine>;
    fn visit<F: RegisteredFilter<L>>(self, spec: &FilterSpec) -> Box<dyn FleetEngine> {
        Box::new(TypedFleet::<L, F> {
            spec: spec.clone(),
            batches: Vec::new(),
            rows: Vec::new(),
        })
    }
}

/// One [`Batch`] of `LANES` channels per `LANES` devices, added as devices come.
struct TypedFleet<L: Lane, F> {
    spec: FilterSpec,
    batches: Vec<Batch<L, F>>,
    /// The estimates of the block being run, chunk after chunk. Kept from block to block
    /// (as long as the longest block): fresh buffers for every block had the kernel map and
    /// clear their pages again each time, about a sixth of a Mahony fleet run.
    rows: Vec<RowEstimate>,
}

/// The estimate of one row, computed in a chunk and scattered into the block's estimates.
#[derive(Clone, Copy)]
struct RowEstimate {
    row: u32,
    step: StepEstimates,
}

impl RowEstimate {
    /// A slot not yet written.
    const UNSET: Self = Self {
        row: u32::MAX,
        step: StepEstimates {
            quat: Quat::new(f64::NAN, f64::NAN, f64::NAN, f64::NAN),
            bias: None,
            covariance: None,
            flags: None,
        },
    };
}

impl<L: Lane, F: RegisteredFilter<L> + Send> FleetEngine for TypedFleet<L, F> {
    fn run(&mut self, sources: &[DeviceRows], columns: Columns, est: &mut BlockEstimates) {
        while self.batches.len() * L::LANES < sources.len() {
            // `MakeEngine` was visited with the spec's own filter type.
            self.batches
                .push(Batch::<L, F>::for_visited_spec(&self.spec, L::LANES));
        }
        // Each chunk writes its rows' estimates into its own part of `rows`: a chunk's lane
        // is active at step `k` exactly when its device has a `k`-th row, so a chunk fills
        // as many slots as its devices have rows.
        let total = sources.iter().map(|s| s.len()).sum();
        self.rows.clear();
        self.rows.resize(total, RowEstimate::UNSET);
        let mut parts = Vec::with_capacity(self.batches.len());
        let mut rest = self.rows.as_mut_slice();
        for srcs in sources.chunks(L::LANES) {
            let (part, tail) = rest.split_at_mut(srcs.iter().map(|s| s.len()).sum());
            parts.push(part);
            rest = tail;
        }
        self.batches
            .par_iter_mut()
            .zip(parts)
            .zip(sources.par_chunks(L::LANES))
            .for_each(|((batch, part), srcs)| {
                let steps = srcs.iter().map(|s| s.len()).max().unwrap_or(0);
                if steps == 0 {
                    return;
                }
                let mut slots = part.iter_mut();
                let chunk = &mut batch.chunks_mut()[0];
                chunk.run_sources(srcs, 0..steps, |k, chunk, active| {
                    let view = StepEstimates::lanes(chunk.filter(), columns);
                    for (i, src) in srcs.iter().enumerate() {
                        if (active >> i) & 1 == 1
                            && let Some(slot) = slots.next()
                        {
                            *slot = RowEstimate {
                                row: src.rows[k],
                                step: view.lane(i),
                            };
                        }
                    }
                });
            });
        for r in self.rows.iter().filter(|r| r.row != u32::MAX) {
            let i = r.row as usize;
            est.kept[i] = true;
            est.quat[i] = r.step.quat;
            if let Some(b) = r.step.bias {
                est.bias[i] = b;
            }
            if let (Some(p), Some(slot)) = (r.step.covariance, est.covariance.get_mut(i)) {
                *slot = p;
            }
            if let Some(f) = r.step.flags {
                est.flags[i] = f;
            }
        }
    }

    fn rejections(&self, d: usize) -> RejectionTotals {
        self.batches
            .get(d / L::LANES)
            .map_or_else(RejectionTotals::default, |b| b.rejections(d % L::LANES))
    }

    fn state_bytes_per_channel(&self) -> usize {
        match self.batches.first() {
            Some(b) => b.state_bytes_per_channel(),
            None => {
                Batch::<L, F>::try_new(&self.spec, 1).map_or(0, |b| b.state_bytes_per_channel())
            }
        }
    }

    fn has_covariance(&self) -> bool {
        F::from_spec(&self.spec).is_some_and(|f| f.attitude_covariance().is_some())
    }
}
