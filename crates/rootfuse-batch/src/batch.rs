//! [`Batch`]: N channels of one filter, [`Lane::LANES`] channels per chunk.

use crate::fill_lanes::MAX_LANES;
use rayon::prelude::*;
use rootfuse_attitude::registry::{AnyFilter, FilterSpec, RegisteredFilter};
use rootfuse_attitude::{ImuSample, Lane, OrientationFilter, Quat, Vec3};
use rootfuse_lane::Counts;

/// The time step fed to tail lanes (lanes past the last channel), s: a valid step, so those
/// lanes run the ordinary code path on a sensor at rest instead of a degenerate one.
pub const PAD_DT: f64 = 0.01;

/// The sample fed to tail lanes and to lanes whose channel has no sample at a step: gyroscope
/// zero, gravity along +z and a field of 64° dip towards north. It is consistent with the
/// identity orientation, so a lane running it stays at rest and finite.
pub fn pad_sample<S: Lane>() -> ImuSample<S> {
    ImuSample::new(
        Vec3::zero(),
        Vec3::from_f64([0.0, 0.0, 9.81]),
        Vec3::from_f64([0.0, 0.44, -0.9]),
    )
}

/// Per-channel counts of skipped samples and corrections, by reason (see
/// [`Rejections`](rootfuse_attitude::filters::Rejections)); steps where the channel had no
/// sample (masked) are not counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RejectionTotals {
    /// Whole samples skipped: `dt` not finite, `≤ 0` or above the filter's limit.
    pub dt: u64,
    /// Whole samples skipped: gyroscope not finite or saturated.
    pub gyr: u64,
    /// Accelerometer corrections skipped: not finite or zero.
    pub acc: u64,
    /// Magnetometer corrections skipped (9D only): absent, not finite or zero.
    pub mag: u64,
    /// Corrections skipped by the filter's own gate.
    pub gated: u64,
    /// Magnetometer samples rejected as a disturbed field.
    pub mag_disturbed: u64,
}

/// Counts summed reason by reason (totals over channels or devices).
impl core::ops::AddAssign for RejectionTotals {
    fn add_assign(&mut self, r: Self) {
        self.dt += r.dt;
        self.gyr += r.gyr;
        self.acc += r.acc;
        self.mag += r.mag;
        self.gated += r.gated;
        self.mag_disturbed += r.mag_disturbed;
    }
}

impl RejectionTotals {
    /// The counters of one lane of a filter's [`Rejections`](rootfuse_attitude::filters::Rejections).
    pub fn of_lane<T: Lane>(r: &rootfuse_attitude::filters::Rejections<T>, lane: usize) -> Self {
        Self {
            dt: r.dt.as_ref()[lane],
            gyr: r.gyr.as_ref()[lane],
            acc: r.acc.as_ref()[lane],
            mag: r.mag.as_ref()[lane],
            gated: r.gated.as_ref()[lane],
            mag_disturbed: r.mag_disturbed.as_ref()[lane],
        }
    }
}

/// One channel's input, sample by sample, in `f64` (converted to the lane's precision by
/// rounding to nearest, exactly like `as f32`).
pub trait ChannelSource: Sync {
    /// Number of samples.
    fn len(&self) -> usize;
    /// True when there are no samples.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Sample `i` (`i < len()`).
    fn sample(&self, i: usize) -> ImuSample<f64>;
    /// Time step before sample `i`, s.
    fn dt(&self, i: usize) -> f64;

    /// Writes samples `start .. start + tile.len()` (all `< len()`) with the step before each
    /// into lane `lane` of `tile`, one entry per step, rounded to the lane's precision exactly
    /// as [`sample`](Self::sample) and [`dt`](Self::dt) would give them.
    ///
    /// The default reads them one at a time through `sample` and `dt`. Sources over
    /// contiguous arrays override it with one pass over their memory (and may read `f32`
    /// storage directly: `f32 → f64 → lane` rounds exactly as `f32 → lane`). Either way the
    /// engine calls it once per channel and tile of [`tile_steps`] steps, so the channel's
    /// memory is read in order and the filters take whole vectors from a tile in L1.
    fn read_into<L: Lane>(&self, start: usize, lane: usize, tile: &mut [(ImuSample<L>, L)]) {
        for (k, (s, dt)) in tile.iter_mut().enumerate() {
            let x = self.sample(start + k);
            set_sample_lane(s, lane, &x);
            dt.set_lane(lane, <L::Scalar as Lane>::from_f64(self.dt(start + k)));
        }
    }

    /// Writes samples `start .. start + tile.len()` of every channel of `lanes` (channel `i`
    /// into lane `i`; every one has them) into `tile`, exactly as
    /// [`read_into`](Self::read_into) lane by lane would: the default does that. Sources over
    /// contiguous arrays override it to move whole blocks of samples through registers
    /// ([`fill_lanes`](crate::fill_lanes)), which is where a cheap filter's time goes
    /// otherwise. The engine calls it for a full chunk (`lanes.len() == L::LANES`, at most
    /// [`MAX_LANES`]) whose channels all have the tile's steps.
    fn read_lanes<L: Lane>(lanes: &[&Self], start: usize, tile: &mut [(ImuSample<L>, L)])
    where
        Self: Sized,
    {
        read_each_lane(lanes, start, tile);
    }
}

/// [`ChannelSource::read_lanes`]'s default, for a source's own fallback: each channel's
/// samples written into its lane by [`read_into`](ChannelSource::read_into).
pub(crate) fn read_each_lane<S: ChannelSource, L: Lane>(
    lanes: &[&S],
    start: usize,
    tile: &mut [(ImuSample<L>, L)],
) {
    for (lane, source) in lanes.iter().enumerate() {
        source.read_into(start, lane, tile);
    }
}

/// Most steps per tile of [`Chunk::run_sources`]: each channel of a chunk hands over up to
/// this many samples at once ([`ChannelSource::read_into`]); [`tile_steps`] gives the number
/// for a lane type.
pub const TILE_STEPS: usize = 64;

/// Bytes of a tile at most: each channel of a chunk writes its lane of every entry, so the
/// whole tile is written once per channel before the filter reads it; a tile larger than L1d
/// (32 KiB on common cores) is evicted by its own writes and every lane store misses.
/// 16 KiB leaves room for the filter's state and the channels' input.
pub const TILE_BYTES: usize = 16 * 1024;

/// Steps per tile for lanes `L`: as many as fit in [`TILE_BYTES`], between 8 and
/// [`TILE_STEPS`] (64 for scalars, 32 for `f32x8` and `f64x4`, 16 for their `X2`).
pub const fn tile_steps<L: Lane>() -> usize {
    let steps = TILE_BYTES / core::mem::size_of::<(ImuSample<L>, L)>();
    let mut p = 8;
    while p * 2 <= steps && p * 2 <= TILE_STEPS {
        p *= 2;
    }
    p
}

/// Sets lane `lane` of `s` to the `f64` sample `x`, each value rounded to the lane's precision.
#[inline]
pub fn set_sample_lane<L: Lane>(s: &mut ImuSample<L>, lane: usize, x: &ImuSample<f64>) {
    let set = |v: &mut Vec3<L>, x: Vec3<f64>| {
        v.x.set_lane(lane, <L::Scalar as Lane>::from_f64(x.x));
        v.y.set_lane(lane, <L::Scalar as Lane>::from_f64(x.y));
        v.z.set_lane(lane, <L::Scalar as Lane>::from_f64(x.z));
    };
    set(&mut s.gyr, x.gyr);
    set(&mut s.acc, x.acc);
    set(&mut s.mag, x.mag);
}

impl ChannelSource for rootfuse_attitude::Recording {
    fn len(&self) -> usize {
        self.len()
    }
    fn sample(&self, i: usize) -> ImuSample<f64> {
        self.sample(i)
    }
    fn dt(&self, i: usize) -> f64 {
        self.dt(i)
    }
}

/// Array-of-structs input of one channel: samples with the time step before each.
/// The shorter of the two slices sets the length.
#[derive(Clone, Copy, Debug)]
pub struct Channel<'a> {
    /// The samples.
    pub samples: &'a [ImuSample<f64>],
    /// The time step before each sample, s.
    pub dt: &'a [f64],
}

/// A reference to a source is a source (so channels can be regrouped without copying).
impl<S: ChannelSource> ChannelSource for &S {
    fn len(&self) -> usize {
        (**self).len()
    }
    fn sample(&self, i: usize) -> ImuSample<f64> {
        (**self).sample(i)
    }
    fn dt(&self, i: usize) -> f64 {
        (**self).dt(i)
    }
    fn read_into<L: Lane>(&self, start: usize, lane: usize, tile: &mut [(ImuSample<L>, L)]) {
        (**self).read_into(start, lane, tile);
    }
    fn read_lanes<L: Lane>(lanes: &[&Self], start: usize, tile: &mut [(ImuSample<L>, L)]) {
        let (Some(&&first), true) = (lanes.first(), lanes.len() <= MAX_LANES) else {
            read_each_lane(lanes, start, tile);
            return;
        };
        let inner: [&S; MAX_LANES] = core::array::from_fn(|i| lanes.get(i).map_or(first, |s| **s));
        S::read_lanes(&inner[..lanes.len()], start, tile);
    }
}

impl ChannelSource for Channel<'_> {
    fn len(&self) -> usize {
        self.samples.len().min(self.dt.len())
    }
    fn sample(&self, i: usize) -> ImuSample<f64> {
        self.samples[i]
    }
    fn dt(&self, i: usize) -> f64 {
        self.dt[i]
    }
}

/// A mask with lane `i` set where bit `i` of `bits` is set.
#[inline]
fn mask_from_bits<L: Lane>(bits: u64) -> L::Mask {
    let one = <L::Scalar as Lane>::one();
    let zero = <L::Scalar as Lane>::zero();
    L::from_fn(|i| if (bits >> i) & 1 == 1 { one } else { zero }).simd_gt(L::zero())
}

#[inline]
fn select_sample<L: Lane>(m: L::Mask, a: &ImuSample<L>, b: &ImuSample<L>) -> ImuSample<L> {
    ImuSample::new(
        Vec3::select(m, a.gyr, b.gyr),
        Vec3::select(m, a.acc, b.acc),
        Vec3::select(m, a.mag, b.mag),
    )
}

#[inline]
fn quat_f64<S: Lane + Into<f64>>(q: Quat<S>) -> Quat<f64> {
    Quat::new(q.w.into(), q.x.into(), q.y.into(), q.z.into())
}

#[inline]
fn vec_f64<S: Lane + Into<f64>>(v: Vec3<S>) -> Vec3<f64> {
    Vec3::new(v.x.into(), v.y.into(), v.z.into())
}

/// [`Lane::LANES`] channels of one filter `F` (by default any registered filter,
/// [`AnyFilter`]; a concrete type such as `Mahony<L>` costs only its own state), with the
/// bookkeeping that makes unused and masked lanes invisible.
#[derive(Clone, Debug)]
pub struct Chunk<L: Lane, F = AnyFilter<L>> {
    filter: F,
    /// Bits of the lanes that carry a channel.
    used: u64,
    /// Per lane, the steps fed as a skip because the channel had no sample: the filter counts
    /// them as `dt` rejections, which are subtracted when reporting.
    masked: L::Counts,
    pad: ImuSample<L>,
    pad_dt: L,
}

impl<L: Lane, F: OrientationFilter<L>> Chunk<L, F> {
    fn new(filter: F, used_lanes: usize) -> Self {
        let used = if used_lanes >= 64 {
            u64::MAX
        } else {
            (1u64 << used_lanes) - 1
        };
        Self {
            filter,
            used,
            masked: L::Counts::default(),
            pad: pad_sample::<L>(),
            pad_dt: L::from_f64(PAD_DT),
        }
    }

    /// Number of lanes that carry a channel (the last chunk may have fewer than `LANES`).
    pub fn used_lanes(&self) -> usize {
        self.used.count_ones() as usize
    }

    /// The filter of all lanes (unused lanes hold padding state: never report them).
    pub fn filter(&self) -> &F {
        &self.filter
    }

    /// One step with every used lane fed its sample (struct-of-arrays input). Unused tail lanes
    /// get the padding sample whatever `sample` holds there.
    #[inline]
    pub fn update(&mut self, sample: &ImuSample<L>, dt: L) {
        self.update_masked(sample, dt, u64::MAX);
    }

    /// One step where only the lanes whose bit is set in `active` have a sample; the other
    /// used lanes are left as they are (see the crate docs on masking).
    #[inline]
    pub fn update_masked(&mut self, sample: &ImuSample<L>, dt: L, active: u64) {
        let full = (1u64 << (L::LANES - 1) << 1).wrapping_sub(1);
        let fed = active & self.used;
        if fed | !full == u64::MAX {
            // Every lane carries a channel with a sample: the common case, no selects.
            self.filter.update(sample, dt);
            return;
        }
        // Lanes without a channel get the padding sample with a valid step (they run the
        // ordinary path); lanes whose channel has no sample get it with `dt = 0`, which the
        // shared screening skips entirely for that lane (state untouched, counted as a `dt`
        // rejection that `rejections` subtracts again).
        let m = mask_from_bits::<L>(fed);
        let tail = mask_from_bits::<L>(!self.used);
        let s = select_sample(m, sample, &self.pad);
        let dt = L::select(m, dt, L::select(tail, self.pad_dt, L::zero()));
        self.filter.update(&s, dt);
        self.masked.add_bitmask(self.used & !fed);
    }

    /// Orientation of lane `lane`, in `f64`.
    pub fn quat(&self, lane: usize) -> Quat<f64> {
        quat_f64(self.filter.quat().lane(lane))
    }

    /// Gyro-bias estimate of lane `lane`, rad/s, in `f64`.
    pub fn bias(&self, lane: usize) -> Vec3<f64> {
        vec_f64(self.filter.bias().lane(lane))
    }

    /// Rejection counters of lane `lane`, masked steps excluded.
    pub fn rejections(&self, lane: usize) -> RejectionTotals {
        let mut totals = RejectionTotals::of_lane(self.filter.rejections(), lane);
        totals.dt = totals.dt.saturating_sub(self.masked.as_ref()[lane]);
        totals
    }

    /// Runs steps `steps` of the channels `sources` (at most `LANES`, one per used lane; a
    /// channel shorter than a step is masked there), calling `each(step, chunk, active)`
    /// after every step with the bits of the lanes that had a sample.
    ///
    /// Samples are packed into lanes a tile of [`tile_steps`] steps at a time: each channel
    /// writes its next samples into its lane of a struct-of-arrays tile
    /// ([`ChannelSource::read_into`], one pass over its memory), then the filter runs the
    /// tile's steps on whole vectors. The tile is made once per call: nothing is allocated
    /// per update. The filter sees exactly the samples and steps it saw step by step, so
    /// results do not depend on the tiling.
    pub fn run_sources<S: ChannelSource>(
        &mut self,
        sources: &[S],
        steps: core::ops::Range<usize>,
        mut each: impl FnMut(usize, &Self, u64),
    ) {
        let n = sources.len().min(self.used_lanes());
        let all = if n >= 64 { u64::MAX } else { (1u64 << n) - 1 };
        // Lanes past `n` keep the padding sample; `update_masked` decides what they get.
        let mut tile = [(self.pad, self.pad_dt); TILE_STEPS];
        let tile_len = tile_steps::<L>();
        // Per lane, the steps of the current tile its channel has.
        let mut avail = vec![0usize; n];
        // A full chunk's sources by reference, for `read_lanes` (made once per call; a full
        // chunk has at least one source).
        let full: Option<[&S; MAX_LANES]> = (n == L::LANES && n <= MAX_LANES)
            .then(|| core::array::from_fn(|i| &sources[i.min(n - 1)]));
        let mut k0 = steps.start;
        while k0 < steps.end {
            let len = (steps.end - k0).min(tile_len);
            let all_have_the_tile = sources[..n].iter().all(|s| s.len() >= k0 + len);
            if let Some(lanes) = full.as_ref().filter(|_| all_have_the_tile) {
                S::read_lanes(&lanes[..n], k0, &mut tile[..len]);
                avail.fill(len);
            } else {
                for (i, src) in sources[..n].iter().enumerate() {
                    let m = src.len().saturating_sub(k0).min(len);
                    src.read_into(k0, i, &mut tile[..m]);
                    avail[i] = m;
                }
            }
            // Every channel has every step of the tile up to the shortest one.
            let common = avail.iter().copied().min().unwrap_or(0);
            for (j, (sample, dt)) in tile[..len].iter().enumerate() {
                let active = if j < common {
                    all
                } else {
                    avail
                        .iter()
                        .enumerate()
                        .filter(|&(_, &m)| j < m)
                        .fold(0u64, |bits, (i, _)| bits | 1 << i)
                };
                self.update_masked(sample, *dt, active);
                each(k0 + j, self, active);
            }
            k0 += len;
        }
    }
}

/// A channel's spec that the batch's filter type cannot build (see [`Batch::try_new`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SpecMismatch {
    /// The first channel whose spec is of another filter than the batch's type.
    pub channel: usize,
}

impl core::fmt::Display for SpecMismatch {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "channel {}: the spec is of another filter than the batch's type",
            self.channel
        )
    }
}
impl std::error::Error for SpecMismatch {}

/// N channels of one registered filter, [`Lane::LANES`] channels per [`Chunk`].
///
/// `F` is the filter type of the chunks: [`AnyFilter<L>`] by default (any registered filter,
/// chosen at run time, each channel costing the largest filter's state), or a concrete type
/// such as `Mahony<L>` ([`Batch::try_new`]), which costs only its own state and dispatches
/// nothing per sample; [`FilterSpec::visit`] turns a run-time choice into a concrete type once
/// per batch (as [`run_recordings`](crate::run_recordings) does).
///
/// State, time steps and rejection counters are per channel; parameters are per chunk: with
/// [`Batch::new`] every channel shares one [`FilterSpec`], with
/// [`Batch::with_channel_specs`] each channel has its own.
///
/// ```
/// use rootfuse_attitude::registry::FilterSpec;
/// use rootfuse_attitude::{ImuSample, Vec3};
/// use rootfuse_batch::{Batch, Channel};
/// use rootfuse_lane::wide::f32x8;
///
/// let spec = FilterSpec::new("mahony").unwrap();
/// let mut batch = Batch::<f32x8>::new(&spec, 11); // two chunks, 5 tail lanes
/// let at_rest = vec![ImuSample::six_d(Vec3::zero(), Vec3::new(0.0, 0.0, 9.81)); 100];
/// let dt = vec![0.01; 100];
/// let channels: Vec<Channel> = (0..11).map(|_| Channel { samples: &at_rest, dt: &dt }).collect();
/// batch.run_channels(&channels);
/// assert!((batch.quat(10).w - 1.0).abs() < 1e-6);
/// assert_eq!(batch.rejections(3).acc, 0);
/// ```
#[derive(Clone, Debug)]
pub struct Batch<L: Lane, F = AnyFilter<L>> {
    channels: usize,
    chunks: Vec<Chunk<L, F>>,
    /// Where channel `c` runs: lane `slot[c] % LANES` of chunk `slot[c] / LANES`. Empty when
    /// channel `c` is simply slot `c` (one spec for all channels).
    slot: Vec<usize>,
}

impl<L: Lane> Batch<L> {
    /// `channels` fresh filters of `spec`, in [`AnyFilter`] chunks.
    pub fn new(spec: &FilterSpec, channels: usize) -> Self {
        let build = |used: usize| Chunk::new(spec.build::<L>(), used);
        let chunks = (0..channels.div_ceil(L::LANES))
            .map(|c| build((channels - c * L::LANES).min(L::LANES)))
            .collect();
        Self {
            channels,
            chunks,
            slot: Vec::new(),
        }
    }
}

impl<L: Lane, F: RegisteredFilter<L>> Batch<L, F> {
    /// `channels` fresh filters of `spec` in chunks of type `F`; an error if `spec` is of
    /// another filter than `F`.
    ///
    /// ```
    /// use rootfuse_attitude::filters::Mahony;
    /// use rootfuse_attitude::registry::FilterSpec;
    /// use rootfuse_batch::Batch;
    /// use rootfuse_lane::wide::f32x8;
    ///
    /// let spec = FilterSpec::new("mahony").unwrap();
    /// let batch = Batch::<f32x8, Mahony<f32x8>>::try_new(&spec, 100).unwrap();
    /// assert!(batch.state_bytes_per_channel() < rootfuse_batch::state_bytes_per_channel::<f32x8>());
    /// assert!(Batch::<f32x8, Mahony<f32x8>>::try_new(&FilterSpec::new("ekf").unwrap(), 1).is_err());
    /// ```
    pub fn try_new(spec: &FilterSpec, channels: usize) -> Result<Self, SpecMismatch> {
        let first = F::from_spec(spec).ok_or(SpecMismatch { channel: 0 })?;
        let chunks = (0..channels.div_ceil(L::LANES))
            .map(|c| Chunk::new(first.clone(), (channels - c * L::LANES).min(L::LANES)))
            .collect();
        Ok(Self {
            channels,
            chunks,
            slot: Vec::new(),
        })
    }

    /// [`try_new`](Self::try_new) for a spec that
    /// [`FilterSpec::visit`](rootfuse_attitude::registry::FilterSpec::visit) handed to its
    /// visitor together with `F`: the engines that dispatch by visiting build their batches here.
    pub(crate) fn for_visited_spec(spec: &FilterSpec, channels: usize) -> Self {
        // Unreachable: `try_new` fails only when `F` is not the spec's filter type, and
        // `FilterSpec::visit` calls its visitor with exactly that type (`F::from_spec(spec)`
        // is `Some`).
        Self::try_new(spec, channels)
            .expect("unreachable: FilterSpec::visit hands over the spec's own filter type")
    }

    /// One channel per spec, each with its own parameters (for example per-sensor gains or
    /// noise levels); an error if `F` cannot build one of them (with [`AnyFilter`] any
    /// registered filter can, even mixed).
    ///
    /// Parameters live in lanes: channels whose specs agree on the structural parameters
    /// ([`FilterSpec::same_structure`](rootfuse_attitude::registry::FilterSpec::same_structure): `dof`, switches, window lengths, screening limits)
    /// share chunks in order of first appearance, each lane with its own real-valued
    /// parameters, and each channel's result equals a scalar run with its own spec, bit for
    /// bit. Each structural class costs at most one partly filled chunk (its tail lanes run
    /// padding). Use [`chunk_channels`](Self::chunk_channels) to pack struct-of-arrays input.
    ///
    /// ```
    /// use rootfuse_attitude::registry::FilterSpec;
    /// use rootfuse_attitude::{ImuSample, Vec3};
    /// use rootfuse_batch::{Batch, Channel};
    /// use rootfuse_lane::wide::f32x8;
    ///
    /// // Three sensors, the second with a stiffer Mahony gain.
    /// let specs: Vec<FilterSpec> = ["kp=0.5", "kp=2.0", "kp=0.5"]
    ///     .iter()
    ///     .map(|kp| {
    ///         let mut s = FilterSpec::new("mahony").unwrap();
    ///         s.set(kp).unwrap();
    ///         s.set_dof(rootfuse_attitude::Dof::Six).unwrap();
    ///         s
    ///     })
    ///     .collect();
    /// let mut batch = Batch::<f32x8>::with_channel_specs(&specs).unwrap();
    /// assert_eq!(batch.chunk_channels(0), [0, 1, 2]); // gains in lanes: one chunk
    /// let tilted = vec![ImuSample::six_d(Vec3::zero(), Vec3::new(0.0, 3.0, 9.3)); 50];
    /// let dt = vec![0.01; 50];
    /// let channels: Vec<Channel> = (0..3).map(|_| Channel { samples: &tilted, dt: &dt }).collect();
    /// batch.run_channels(&channels);
    /// assert_eq!(batch.quat(0), batch.quat(2));
    /// ```
    pub fn with_channel_specs(specs: &[FilterSpec]) -> Result<Self, SpecMismatch> {
        // Structural classes in order of first appearance, and each channel's class.
        let mut classes: Vec<&FilterSpec> = Vec::new();
        let mut class = Vec::with_capacity(specs.len());
        for spec in specs {
            let g = match classes.iter().position(|d| d.same_structure(spec)) {
                Some(g) => g,
                None => {
                    classes.push(spec);
                    classes.len() - 1
                }
            };
            class.push(g);
        }
        let mut chunks = Vec::new();
        let mut slot = vec![0; specs.len()];
        for g in 0..classes.len() {
            let members: Vec<usize> = (0..specs.len()).filter(|&c| class[c] == g).collect();
            for lanes in members.chunks(L::LANES) {
                let lane_specs: Vec<&FilterSpec> = lanes.iter().map(|&c| &specs[c]).collect();
                let filter =
                    F::from_lane_specs(&lane_specs).ok_or(SpecMismatch { channel: lanes[0] })?;
                for (lane, &c) in lanes.iter().enumerate() {
                    slot[c] = chunks.len() * L::LANES + lane;
                }
                chunks.push(Chunk::new(filter, lanes.len()));
            }
        }
        Ok(Self {
            channels: specs.len(),
            chunks,
            slot,
        })
    }
}

impl<L: Lane, F: OrientationFilter<L> + Send> Batch<L, F> {
    /// Number of channels.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Bytes of one chunk per lane: the filter's state and parameters plus the chunk's
    /// masking bookkeeping, `size_of::<Chunk<L, F>>() / LANES`.
    pub fn state_bytes_per_channel(&self) -> usize {
        core::mem::size_of::<Chunk<L, F>>() / L::LANES
    }

    /// Slot (`chunk × LANES + lane`) of channel `c`.
    #[inline]
    fn slot(&self, c: usize) -> usize {
        self.slot.get(c).copied().unwrap_or(c)
    }

    /// The channels in the lanes of chunk `chunk`, in lane order (fewer than `LANES` for a
    /// partly filled chunk; empty past the last chunk). With [`Batch::new`] chunk `k` holds
    /// channels `k × LANES ..`.
    pub fn chunk_channels(&self, chunk: usize) -> Vec<usize> {
        let Some(ch) = self.chunks.get(chunk) else {
            return Vec::new();
        };
        let lanes = ch.used_lanes();
        (0..lanes)
            .filter_map(|lane| {
                let s = chunk * L::LANES + lane;
                if self.slot.is_empty() {
                    Some(s)
                } else {
                    self.slot.iter().position(|&x| x == s)
                }
            })
            .collect()
    }

    /// The chunks (see [`chunk_channels`](Self::chunk_channels) for which channel is where).
    pub fn chunks(&self) -> &[Chunk<L, F>] {
        &self.chunks
    }

    /// The chunks, to drive them directly (e.g. from your own struct-of-arrays buffers).
    pub fn chunks_mut(&mut self) -> &mut [Chunk<L, F>] {
        &mut self.chunks
    }

    /// Orientation of channel `c`, in `f64` (panics if `c >= channels()`).
    pub fn quat(&self, c: usize) -> Quat<f64> {
        assert!(c < self.channels, "channel {c} out of range");
        let s = self.slot(c);
        self.chunks[s / L::LANES].quat(s % L::LANES)
    }

    /// Gyro-bias estimate of channel `c`, rad/s, in `f64` (panics if `c >= channels()`).
    pub fn bias(&self, c: usize) -> Vec3<f64> {
        assert!(c < self.channels, "channel {c} out of range");
        let s = self.slot(c);
        self.chunks[s / L::LANES].bias(s % L::LANES)
    }

    /// Gyroscope scale-error estimate of channel `c` per sensor axis, a fraction `s` in
    /// `ω_measured = (1 + s)·ω` (zero for filters without one), in `f64` (panics if
    /// `c >= channels()`).
    pub fn gyro_scale(&self, c: usize) -> Vec3<f64> {
        assert!(c < self.channels, "channel {c} out of range");
        let s = self.slot(c);
        let chunk = &self.chunks[s / L::LANES];
        vec_f64(chunk.filter.gyro_scale().lane(s % L::LANES))
    }

    /// Rejection counters of channel `c` (panics if `c >= channels()`).
    pub fn rejections(&self, c: usize) -> RejectionTotals {
        assert!(c < self.channels, "channel {c} out of range");
        let s = self.slot(c);
        self.chunks[s / L::LANES].rejections(s % L::LANES)
    }

    /// Feeds one block of struct-of-arrays input: `samples[c * steps + k]` and
    /// `dt[c * steps + k]` are step `k` of chunk `c`, with `steps = samples.len() / chunks`
    /// (lane `i` of chunk `c` is channel `chunk_channels(c)[i]`).
    /// Chunks run in parallel (rayon); each chunk's steps run in order, so the result does not
    /// depend on the thread count. Extra entries past `chunks × steps` are ignored.
    pub fn run_soa(&mut self, samples: &[ImuSample<L>], dt: &[L]) {
        let chunks = self.chunks.len();
        if chunks == 0 {
            return;
        }
        let steps = samples.len().min(dt.len()) / chunks;
        if steps == 0 {
            return;
        }
        self.chunks
            .par_iter_mut()
            .zip(samples.par_chunks(steps).zip(dt.par_chunks(steps)))
            .for_each(|(chunk, (s, d))| {
                for (s, d) in s.iter().zip(d) {
                    chunk.update(s, *d);
                }
            });
    }

    /// Feeds one block of array-of-structs input, one entry per channel (extra entries are
    /// ignored, missing ones are masked); channels of different lengths are allowed, a channel
    /// is masked at the steps past its end. Chunks run in parallel (rayon).
    pub fn run_channels<S: ChannelSource>(&mut self, channels: &[S]) {
        let steps = channels.iter().map(|c| c.len()).max().unwrap_or(0);
        let channels = &channels[..channels.len().min(self.channels)];
        if self.slot.is_empty() {
            self.chunks
                .par_iter_mut()
                .zip(channels.par_chunks(L::LANES))
                .for_each(|(chunk, srcs)| chunk.run_sources(srcs, 0..steps, |_, _, _| {}));
            return;
        }
        // Regrouped channels: gather each chunk's sources by reference (one small vector per
        // chunk and call, not per update). A chunk's lanes are filled from lane 0, so a
        // missing channel can only be at the end, where `run_sources` masks it.
        let mut by_chunk: Vec<Vec<&S>> = vec![Vec::new(); self.chunks.len()];
        for (c, src) in channels.iter().enumerate() {
            by_chunk[self.slot[c] / L::LANES].push(src);
        }
        self.chunks
            .par_iter_mut()
            .zip(by_chunk.par_iter())
            .for_each(|(chunk, srcs)| chunk.run_sources(srcs, 0..steps, |_, _, _| {}));
    }
}
