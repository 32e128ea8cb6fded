//! The batch engine: many IMU channels of one filter, [`Lane::LANES`] channels per SIMD
//! vector (`f32x8`: 8, `f64x4`: 4), chunks of lanes spread over cores with rayon.
//!
//! Every registered filter of `rootfuse-attitude` runs here through
//! [`AnyFilter<L>`](rootfuse_attitude::registry::AnyFilter): the same code as a scalar run,
//! so each channel's result equals running it alone through `spec.build::<f32>()` (or `f64`)
//! bit for bit (tested for every registered filter in the workspace's `tests/batch/engine.rs`).
//!
//! ```
//! use rootfuse_attitude::registry::FilterSpec;
//! use rootfuse_eval::sim::scenario;
//! use rootfuse_batch::{Precision, run_recordings};
//!
//! let mut spec = FilterSpec::new("ekf").unwrap();
//! spec.set_dof(rootfuse_attitude::Dof::Six).unwrap();
//! let recs: Vec<_> = (0..3).map(|seed| scenario("static", seed, 1.0, 100.0).unwrap()).collect();
//! let out = run_recordings(&spec, &recs, Precision::F64);
//! assert!(out.iter().all(|o| o.quat.len() == 100 && o.rejections.dt == 0));
//! ```
//!
//! # Layout
//! Channel `c` is lane `c % LANES` of chunk `c / LANES` ([`Batch`], [`Chunk`]) when all
//! channels share one [`FilterSpec`] ([`Batch::new`]). With per-channel parameters
//! ([`Batch::with_channel_specs`]) the parameters live in lanes: channels whose specs agree
//! on the structural parameters (`dof`, switches, window lengths, screening limits; see
//! [`FilterSpec::same_structure`](rootfuse_attitude::registry::FilterSpec::same_structure))
//! share chunks in order of first appearance, each lane with its own real-valued parameters
//! ([`LaneParams`](rootfuse_attitude::filters::LaneParams)), and
//! [`Batch::chunk_channels`] says which channel is in which lane. Every filter converts its
//! parameters to per-lane coefficients exactly as a scalar filter does, so results stay bit
//! for bit those of scalar runs with each channel's own parameters (tested for every
//! registered filter with eight different parameter sets in one `f32x8` chunk). State, time
//! steps and rejection counters are per channel.
//!
//! # Tail lanes and masking
//! The last chunk's lanes past the last channel are fed [`pad_sample`] (gyro zero, gravity
//! `[0, 0, 9.81]`, field `[0, 0.44, -0.9]`, consistent with the identity orientation) with a
//! valid step [`PAD_DT`]: they run the ordinary code path on a sensor at rest, never a
//! degenerate one, and are never reported. A channel without a sample at a step (its
//! recording has ended, or [`Chunk::update_masked`] leaves it out) gets the padding sample
//! with `dt = 0`: the shared input screening skips such a sample entirely for that lane (state
//! untouched, see `rootfuse_attitude::filters`), and the one `dt` rejection it counts is
//! subtracted again when counters are reported. The tests check for every registered filter
//! that a channel with masked steps equals a scalar run without them, bit for bit.
//!
//! # Memory and streaming
//! A [`Batch<L, F>`](Batch) stores chunks of one filter type `F`. With the default
//! `F = AnyFilter<L>` (a run-time choice, [`Batch::new`]) every channel costs the largest
//! registered filter ([`state_bytes_per_channel`]); with the concrete type (`Mahony<L>`, …,
//! [`Batch::try_new`]) a channel costs its own filter's state. [`run_recordings`] and
//! `throughput` (feature `throughput`) turn the run-time [`FilterSpec`] into the concrete type once per batch
//! ([`FilterSpec::visit`](rootfuse_attitude::registry::FilterSpec::visit)), so they use the
//! small layout and match nothing per sample. Bytes per channel
//! ([`Batch::state_bytes_per_channel`]: filter state, parameters, the per-lane `u64`
//! rejection counters, and the chunk's masking bookkeeping and padding sample), measured with
//! `target-cpu=native` (`cargo test state_bytes -- --nocapture`):
//!
//! | filter | `f32x8` | `f64x4` | `X2<f32x8>` |
//! |---|---|---|---|
//! | `gyro` | 156 | 264 | 150 |
//! | `complementary` | 184 | 312 | 176 |
//! | `mahony` | 196 | 344 | 188 |
//! | `madgwick` | 192 | 328 | 184 |
//! | `ekf` | 400 | 752 | 390 |
//! | `sqrt-eskf` | 1408 | 2768 | 1374 |
//! | `complementary-reconstruction` | 336 | 624 | 326 |
//! | `heading-pipeline` | 884 | 1568 | 848 |
//! | `lsq-fusion` | 1296 | 2304 | 1254 |
//! | `ecf-ekf` | 1760 | 3400 | 1732 |
//! | any filter as `AnyFilter<L>` | 1760 | | |
//!
//! (The workspace test `state_bytes_are_the_filters_own` checks this table.) So a run-time
//! typed Mahony batch would cost 1760 B per channel (the size of the largest variant,
//! `ecf-ekf`); typed, it costs 196. Of those, 48 B are the six `u64` rejection counters
//! (exact for any recording length, where an `f32` counter would stop at 2²⁴), 28 B the last
//! sample's flags (seven masks), and about 56 B the chunk's masking state and padding sample,
//! amortised over the lanes. Parameters are per-lane coefficients (so channels with
//! different parameters share a chunk): the flagship's 55 cost 220 B per channel in `f32x8`;
//! the parameter set as given (`params()`, one per chunk) adds its size divided by the lanes.
//!
//! Nothing is allocated per update: [`Chunk::update`] works on the SIMD state in place, and
//! array-of-structs input ([`Batch::run_channels`], [`run_recordings`]) is packed into lanes
//! a tile of [`tile_steps`] steps at a time (at most [`TILE_BYTES`], within L1d): each
//! channel writes its next samples into its
//! lane of a struct-of-arrays tile made once per chunk and call
//! ([`ChannelSource::read_into`]: one pass over the channel's memory, overridden by sources
//! over contiguous arrays, such as the Python package's NumPy input, to read `f32` or `f64`
//! as stored), then the filter runs the tile's steps on whole vectors from L1. Estimates go
//! where the caller wants them ([`EstimateSink`]: [`ChannelOutput`] vectors, or the caller's
//! own arrays, written as they come), and [`run_final_states`] keeps only each channel's last
//! state. Input is streamed in blocks: [`Batch::run_soa`] and [`Batch::run_channels`] take
//! one block (any number of steps) and keep the state for the next, so memory stays flat for
//! recordings of any length; [`Chunk::run_sources`] runs any step range of any
//! [`ChannelSource`]. Only [`run_recordings`] holds whole recordings, because its output is
//! the whole estimate.
//!
//! # Threads
//! Chunks are independent; rayon spreads them over its pool and each chunk runs its steps in
//! order on one thread, so results do not depend on the thread count (tested with 1 and 2
//! threads).
//!
//! # Throughput
//! `throughput` (feature `throughput`) measures scalar `f32`/`f64` loops, `f32x8`/`f64x4` lanes on one core and
//! `f32x8` lanes on all cores in one run (the CLI's `rootfuse throughput`), every mode on the
//! concrete filter type. A filter update is one long dependency chain per vector (the next
//! step needs this step's orientation, through square roots, divisions and products), so a
//! small filter such as Mahony leaves most execution ports idle and runs at the chain's
//! latency, scalar or vector alike. The lane modes therefore run small filters (state within
//! [`INTERLEAVE_STATE_BYTES`], see [`interleaves`]) as [`X2<L>`](rootfuse_lane::X2): two
//! chunks of `f32x8` (or `f64x4`) side by side in every instruction, two independent chains
//! sharing one latency. The arithmetic is the same `f32x8` arithmetic, lane for lane, so
//! results are unchanged (tested for every filter); the large filters (EKFs, flagship) are
//! bound by arithmetic and registers already and run as one vector. Use `Batch<X2<f32x8>>`
//! for the same effect in your own batches.
//!
//! ## Throughput against the number of channels
//! The plot is `docs/throughput-channels.png` in the repository, made by
//! `rootfuse throughput --filter mahony --dof 6 --sweep --plot docs/throughput-channels.png`
//! (Mahony 6D in `X2<f32x8>` on one core, about 0.5 s per point, best of 3; the dashed lines
//! mark where the channels' filter state fills L1d and L2, read from
//! `/sys/devices/system/cpu/cpu0/cache`); the measured rates are in `docs/performance.md` in
//! the repository. Two orders:
//! - **Chunk by chunk** (offline, whole recordings; `throughput::Order::ChunkMajor`): each chunk runs
//!   all its samples before the next, its state stays in registers, and the channel count
//!   does not matter: the rate is flat from 64 channels up. Below 16 channels the one chunk
//!   is partly empty (8 channels fill half of a 16-lane `X2` chunk, so half the work is
//!   padding).
//! - **Tick by tick** (real-time streaming of many sensors, one sample for every channel, then
//!   the next; `throughput::Order::Tick`): each chunk's filter state (94 B per channel for Mahony in `X2<f32x8>`,
//!   40 B of it the rejection counters) is loaded and stored once per sample. The input pool is the same
//!   1.3 MB either way. Within L1d a tick costs a little more than chunk by chunk (the loads,
//!   stores and loop per sample); within L2 more, the hardware prefetcher streaming the state
//!   in its sequential order; past L2 the state and the input pool compete for L2 and the
//!   state comes from L3: the cost of moving the state in and out every sample grows with
//!   the channel count. Beyond L3 it would be bound by memory bandwidth. Streaming
//!   applications should therefore feed blocks of several samples per channel
//!   ([`Batch::run_soa`] and [`Batch::run_channels`] take any number of steps per call) to
//!   get the chunk-by-chunk rate.
//!
//! [`Lane::LANES`]: rootfuse_lane::Lane::LANES
//! [`FilterSpec`]: rootfuse_attitude::registry::FilterSpec
#![warn(missing_docs)]

mod batch;
mod fill_lanes;
mod fleet;
mod recordings;
#[cfg(feature = "throughput")]
mod throughput;

/// The rayon this crate spreads chunks with (configure its pools, e.g. the thread count).
pub use rayon;

pub use batch::{
    Batch, Channel, ChannelSource, Chunk, PAD_DT, RejectionTotals, SpecMismatch, TILE_BYTES,
    TILE_STEPS, pad_sample, set_sample_lane, tile_steps,
};
pub use fill_lanes::{MAX_LANES, fill_lanes};
pub use fleet::{
    BlockEstimates, FleetBlock, FleetError, FleetRunner, OnError, samples_with_missing_imu,
};
pub use recordings::{
    ChannelOutput, Columns, Estimate, EstimateSink, FinalState, INTERLEAVE_STATE_BYTES, Precision,
    flag, interleaves, push_quat_per_lane, run_final_states, run_into_sinks, run_recordings,
    run_recordings_with, run_sources, run_sources_into, run_sources_with, visit_lanes,
};
#[cfg(feature = "throughput")]
pub use throughput::{ModeResult, Order, ROUNDS, SweepPoint, ThroughputReport, sweep, throughput};

/// State bytes per channel of a run-time typed batch over lanes `L` (`Batch<L>`, chunks of
/// `AnyFilter<L>`): `size_of::<AnyFilter<L>>() / LANES`, the largest registered filter. A batch
/// of a concrete filter type costs less: see [`Batch::state_bytes_per_channel`] (which also
/// counts the chunk's masking bookkeeping) and the table in the crate docs.
pub fn state_bytes_per_channel<L: rootfuse_lane::Lane>() -> usize {
    core::mem::size_of::<rootfuse_attitude::registry::AnyFilter<L>>() / L::LANES
}
