//! [`FleetRunner`]: a fleet of devices streamed through the batch engine in blocks of rows.

use crate::MAX_LANES;
use crate::batch::{Batch, ChannelSource, RejectionTotals, SpecMismatch, read_each_lane};
use crate::recordings::{Columns, Estimate, Precision};
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
    // `x·0` is 0 for a finite `x` and NaN otherwise, so a row's sum of them is 0 exactly when
    // every value is finite: one test per row, no branch per value.
    let zero = |v: &Vec3<f64>| v.x * 0.0 + v.y * 0.0 + v.z * 0.0;
    let mag_zero = |r: usize| mag.map_or(0.0, |m| zero(&m[r]));
    (0..gyr.len().min(acc.len()))
        .filter(|&r| zero(&gyr[r]) + zero(&acc[r]) + mag_zero(r) != 0.0)
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
        // No device has a spec of its own, so no spec can mismatch.
        Self::with_device_specs(spec, &[], precision, columns).unwrap_or_else(|_| {
            unreachable!("a fleet without per-device specs has no spec to refuse")
        })
    }

    /// A fleet whose devices `0 .. device_specs.len()` run with their own parameters
    /// (`device_specs[d]`, for example from a per-device calibration table) and later devices
    /// with `spec`.
    ///
    /// The devices with their own specs are planned into chunks before any row comes:
    /// devices whose specs agree on the structural parameters
    /// ([`FilterSpec::same_structure`]: `dof`, switches, window lengths, screening limits)
    /// share chunks, each lane with its own real-valued parameters, so every device's
    /// estimates equal a scalar run with its own spec bit for bit. A planned device that never
    /// gets a row only leaves its lane idle. An error names the first device whose spec is of
    /// another filter than `spec`.
    ///
    /// ```
    /// use rootfuse_attitude::registry::FilterSpec;
    /// use rootfuse_attitude::Vec3;
    /// use rootfuse_batch::{Columns, FleetBlock, FleetRunner, OnError, Precision};
    ///
    /// let spec = FilterSpec::new("mahony").unwrap();
    /// let mut stiff = spec.clone();
    /// stiff.set("kp=2.0").unwrap();
    /// // Device 0 with a stiffer gain, device 1 (not planned) with the defaults.
    /// let mut fleet =
    ///     FleetRunner::with_device_specs(&spec, &[stiff], Precision::F64, Columns::default())
    ///         .unwrap();
    /// let block = FleetBlock {
    ///     device: vec![0, 1, 0, 1],
    ///     t: vec![0.0, 0.0, 0.01, 0.01],
    ///     gyr: vec![Vec3::zero(); 4],
    ///     // The first sample sets the inclination, the second pulls toward another tilt.
    ///     acc: [[0.0, 3.0, 9.3], [0.0, 3.0, 9.3], [3.0, 0.0, 9.3], [3.0, 0.0, 9.3]]
    ///         .map(|[x, y, z]| Vec3::new(x, y, z))
    ///         .to_vec(),
    ///     mag: None,
    /// };
    /// let est = fleet.step(&block, None, OnError::Stop).unwrap();
    /// assert_ne!(est.quat[2], est.quat[3]); // the stiffer gain has moved further
    /// ```
    pub fn with_device_specs(
        spec: &FilterSpec,
        device_specs: &[FilterSpec],
        precision: Precision,
        columns: Columns,
    ) -> Result<Self, SpecMismatch> {
        let make = MakeEngine { device_specs };
        let engine = match precision {
            Precision::F32 => spec.visit::<f32x8, _>(make),
            Precision::F64 => spec.visit::<f64x4, _>(make),
        }?;
        Ok(Self {
            engine,
            columns,
            last_t: Vec::new(),
            failed: Vec::new(),
            groups: Vec::new(),
            before: Vec::new(),
        })
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
    /// Each step's samples of every lane gathered first, then each coordinate built as one
    /// vector (the default sets lane by lane, a vector read and written per value): the same
    /// values, rounded the same way.
    fn read_lanes<L: Lane>(lanes: &[&Self], start: usize, tile: &mut [(ImuSample<L>, L)]) {
        let n = lanes.len();
        if n != L::LANES || n > MAX_LANES || lanes.iter().any(|s| s.len() < start + tile.len()) {
            read_each_lane(lanes, start, tile);
            return;
        }
        let cast = |x: f64| <L::Scalar as Lane>::from_f64(x);
        let mut x = [ImuSample::six_d(Vec3::zero(), Vec3::zero()); MAX_LANES];
        let mut dts = [0.0; MAX_LANES];
        for (k, (s, dt)) in tile.iter_mut().enumerate() {
            for (l, source) in lanes.iter().enumerate() {
                x[l] = source.sample(start + k);
                dts[l] = source.dt(start + k);
            }
            s.gyr = gather(&x, |s| s.gyr);
            s.acc = gather(&x, |s| s.acc);
            s.mag = gather(&x, |s| s.mag);
            *dt = L::from_fn(|l| cast(dts[l]));
        }
    }
}

/// One vector of lanes from each lane's `f64` sample (`pick` chooses which of its vectors),
/// each value rounded to the lane's precision.
#[inline(always)]
fn gather<L: Lane>(x: &[ImuSample<f64>], pick: impl Fn(&ImuSample<f64>) -> Vec3<f64>) -> Vec3<L> {
    let cast = |v: f64| <L::Scalar as Lane>::from_f64(v);
    Vec3::new(
        L::from_fn(|l| cast(pick(&x[l]).x)),
        L::from_fn(|l| cast(pick(&x[l]).y)),
        L::from_fn(|l| cast(pick(&x[l]).z)),
    )
}

/// The typed part of a fleet: chunks of one concrete filter type.
trait FleetEngine: Send {
    fn run(&mut self, sources: &[DeviceRows], columns: Columns, est: &mut BlockEstimates);
    fn rejections(&self, d: usize) -> RejectionTotals;
    fn state_bytes_per_channel(&self) -> usize;
    fn has_covariance(&self) -> bool;
}

struct MakeEngine<'a> {
    device_specs: &'a [FilterSpec],
}

impl<L: Lane> FilterVisitor<L> for MakeEngine<'_>
where
    L::Scalar: Lane,
{
    type Output = Result<Box<dyn FleetEngine>, SpecMismatch>;
    fn visit<F: RegisteredFilter<L>>(self, spec: &FilterSpec) -> Self::Output {
        let mut fleet = TypedFleet::<L, F> {
            spec: spec.clone(),
            batches: Vec::new(),
            slot: Vec::new(),
            open: None,
            rows: Vec::new(),
            extras: Vec::new(),
        };
        fleet.plan(self.device_specs)?;
        Ok(Box::new(fleet))
    }
}

/// One [`Batch`] of `LANES` channels per chunk of devices: planned devices (with specs of
/// their own) in chunks of their structural class, the others added as they come.
struct TypedFleet<L: Lane, F> {
    spec: FilterSpec,
    batches: Vec<Batch<L, F>>,
    /// Device `d` runs in lane `slot[d] % LANES` of batch `slot[d] / LANES`.
    slot: Vec<usize>,
    /// The batch of `spec` with free lanes for devices not planned, and its next free lane.
    open: Option<(usize, usize)>,
    /// The estimates of the block being run, chunk after chunk. Kept from block to block
    /// (as long as the longest block): fresh buffers for every block had the kernel map and
    /// clear their pages again each time, about a sixth of a Mahony fleet run.
    rows: Vec<RowQuat>,
    /// Bias, covariance and flags of the same rows, when asked for (else empty).
    extras: Vec<RowExtras>,
}

impl<L: Lane, F: RegisteredFilter<L>> TypedFleet<L, F> {
    /// Chunks for the devices with specs of their own, by structural class in order of first
    /// appearance; device `d`'s lane parameters are those of `specs[d]`.
    fn plan(&mut self, specs: &[FilterSpec]) -> Result<(), SpecMismatch> {
        if let Some(d) = specs.iter().position(|s| s.kind() != self.spec.kind()) {
            return Err(SpecMismatch { channel: d });
        }
        self.slot = vec![0; specs.len()];
        let mut classes: Vec<Vec<usize>> = Vec::new();
        for (d, s) in specs.iter().enumerate() {
            match classes.iter_mut().find(|c| specs[c[0]].same_structure(s)) {
                Some(c) => c.push(d),
                None => classes.push(vec![d]),
            }
        }
        for members in classes {
            for lanes in members.chunks(L::LANES) {
                let lane_specs: Vec<FilterSpec> = lanes.iter().map(|&d| specs[d].clone()).collect();
                let batch =
                    Batch::<L, F>::with_channel_specs(&lane_specs).map_err(|e| SpecMismatch {
                        channel: lanes[e.channel],
                    })?;
                for (lane, &d) in lanes.iter().enumerate() {
                    self.slot[d] = self.batches.len() * L::LANES + lane;
                }
                self.batches.push(batch);
            }
        }
        Ok(())
    }

    /// Gives the devices up to `devices` (exclusive) that have none a lane of `spec`.
    fn place(&mut self, devices: usize) {
        while self.slot.len() < devices {
            let (b, lane) = match self.open {
                Some((b, lane)) if lane < L::LANES => (b, lane),
                _ => {
                    // `MakeEngine` was visited with the spec's own filter type.
                    self.batches
                        .push(Batch::<L, F>::for_visited_spec(&self.spec, L::LANES));
                    (self.batches.len() - 1, 0)
                }
            };
            self.slot.push(b * L::LANES + lane);
            self.open = Some((b, lane + 1));
        }
    }
}

/// The orientation of one row, computed in a chunk and scattered into the block's estimates.
/// Kept small (40 bytes): the scatter reads one per row, and a whole [`Estimate`] per row
/// (136 bytes) made that loop a cache-miss hot spot of a fleet run.
#[derive(Clone, Copy)]
struct RowQuat {
    row: u32,
    quat: Quat<f64>,
}

impl RowQuat {
    /// A slot not yet written.
    const UNSET: Self = Self {
        row: u32::MAX,
        quat: Quat::new(f64::NAN, f64::NAN, f64::NAN, f64::NAN),
    };
}

/// What else a row's estimate holds when asked for ([`Columns`]): at the same index as its
/// [`RowQuat`].
#[derive(Clone, Copy, Default)]
struct RowExtras {
    bias: Option<Vec3<f64>>,
    covariance: Option<[f64; 6]>,
    flags: Option<u8>,
}

impl<L: Lane, F: RegisteredFilter<L> + Send> FleetEngine for TypedFleet<L, F> {
    fn run(&mut self, sources: &[DeviceRows], columns: Columns, est: &mut BlockEstimates) {
        self.place(sources.len());
        // The devices in lane order, an empty source for a lane without a device here.
        let Some(first) = sources.first() else {
            return;
        };
        let idle = DeviceRows {
            block: first.block,
            rows: &[],
            first_dt: 0.0,
        };
        let mut by_slot: Vec<&DeviceRows> = vec![&idle; self.batches.len() * L::LANES];
        for (d, src) in sources.iter().enumerate() {
            by_slot[self.slot[d]] = src;
        }
        let sources = by_slot;
        // Each chunk writes its rows' estimates into its own part of `rows`: a chunk's lane
        // is active at step `k` exactly when its device has a `k`-th row, so a chunk fills
        // as many slots as its devices have rows.
        let total = sources.iter().map(|s| s.len()).sum();
        let extras = columns.bias || columns.covariance || columns.flags;
        self.rows.clear();
        self.rows.resize(total, RowQuat::UNSET);
        self.extras.clear();
        self.extras
            .resize(if extras { total } else { 0 }, RowExtras::default());
        let mut parts = Vec::with_capacity(self.batches.len());
        let (mut rest, mut rest_extras) = (self.rows.as_mut_slice(), self.extras.as_mut_slice());
        for srcs in sources.chunks(L::LANES) {
            let len = srcs.iter().map(|s| s.len()).sum();
            let (part, tail) = rest.split_at_mut(len);
            let (part_extras, tail_extras) = rest_extras.split_at_mut(if extras { len } else { 0 });
            parts.push((part, part_extras));
            (rest, rest_extras) = (tail, tail_extras);
        }
        self.batches
            .par_iter_mut()
            .zip(parts)
            .zip(sources.par_chunks(L::LANES))
            .for_each(|((batch, (part, part_extras)), srcs)| {
                let steps = srcs.iter().map(|s| s.len()).max().unwrap_or(0);
                if steps == 0 {
                    return;
                }
                let mut slots = part.iter_mut();
                let mut slots_extras = part_extras.iter_mut();
                let chunk = &mut batch.chunks_mut()[0];
                chunk.run_sources(srcs, 0..steps, |k, chunk, active| {
                    let view = Estimate::lanes(chunk.filter(), columns);
                    for (i, src) in srcs.iter().enumerate() {
                        if (active >> i) & 1 == 1
                            && let Some(slot) = slots.next()
                        {
                            let e = view.lane(i);
                            *slot = RowQuat {
                                row: src.rows[k],
                                quat: e.quat,
                            };
                            if let Some(x) = slots_extras.next() {
                                *x = RowExtras {
                                    bias: e.bias,
                                    covariance: e.covariance,
                                    flags: e.flags,
                                };
                            }
                        }
                    }
                });
            });
        for (j, r) in self.rows.iter().enumerate() {
            if r.row == u32::MAX {
                continue;
            }
            let i = r.row as usize;
            est.kept[i] = true;
            est.quat[i] = r.quat;
            let Some(x) = self.extras.get(j) else {
                continue;
            };
            if let Some(b) = x.bias {
                est.bias[i] = b;
            }
            if let (Some(p), Some(slot)) = (x.covariance, est.covariance.get_mut(i)) {
                *slot = p;
            }
            if let Some(f) = x.flags {
                est.flags[i] = f;
            }
        }
    }

    fn rejections(&self, d: usize) -> RejectionTotals {
        let Some(&slot) = self.slot.get(d) else {
            return RejectionTotals::default();
        };
        self.batches
            .get(slot / L::LANES)
            .map_or_else(RejectionTotals::default, |b| b.rejections(slot % L::LANES))
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
