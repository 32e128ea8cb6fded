//! Moving a full chunk's samples into their lanes: each channel's rows of a block of steps
//! loaded, transposed in registers and stored into the tile ([`fill_lanes`]).

use rootfuse_attitude::{ImuSample, Lane, Vec3};

/// Most lanes of a chunk that [`ChannelSource::read_lanes`](crate::ChannelSource::read_lanes) and [`fill_lanes`] take at once
/// (the widest lane type, `X2<f32x8>`, has 16).
pub const MAX_LANES: usize = 16;

/// Writes samples `start .. start + tile.len()` of `L::LANES` channels into the vector `field`
/// picks in each tile entry, channel `i` into lane `i`, each value rounded to the lane's
/// precision once (`f32 → f64 → f32` is exact): `rows[i]` is channel `i`'s `[x, y, z]` rows.
/// Whole blocks of `LANES` steps are loaded one vector per channel and transposed in
/// registers ([`Lane::transpose_lanes`]); the steps after the last whole block are written
/// lane by lane. On x86-64 each block asks the cache for the rows a few blocks ahead (a
/// prefetch: a hint that changes no value). Returns `false`, writing nothing, unless there
/// are `LANES` channels (at most [`MAX_LANES`]) each with at least `3 · (start + tile.len())`
/// values.
///
/// ```
/// use rootfuse_attitude::Lane;
/// use rootfuse_batch::{fill_lanes, pad_sample};
/// use rootfuse_lane::wide::f64x4;
/// // Four channels of five samples; channel c's gyro x at step k is 10 c + k.
/// let rows: Vec<Vec<f32>> = (0..4)
///     .map(|c| (0..5).flat_map(|k| [(10 * c + k) as f32, 0.0, 0.0]).collect())
///     .collect();
/// let rows: Vec<&[f32]> = rows.iter().map(Vec::as_slice).collect();
/// let mut tile = [(pad_sample::<f64x4>(), f64x4::zero()); 5];
/// assert!(fill_lanes(&rows, 0, &mut tile, |s| &mut s.gyr));
/// assert_eq!(tile[4].0.gyr.x.extract(2), 24.0);
/// ```
pub fn fill_lanes<T: Copy + Into<f64>, L: Lane>(
    rows: &[&[T]],
    start: usize,
    tile: &mut [(ImuSample<L>, L)],
    field: impl Fn(&mut ImuSample<L>) -> &mut Vec3<L>,
) -> bool {
    let n = L::LANES;
    let end = 3 * (start + tile.len());
    if n > MAX_LANES || rows.len() != n || rows.iter().any(|r| r.len() < end) {
        return false;
    }
    let cast = |x: T| <L::Scalar as Lane>::from_f64(x.into());
    let whole = tile.len() / n * n;
    // Each channel's 3·n values of a block in the lane's precision: converted in one simple
    // loop per channel (vectorised), so that the loads, transposes and stores below are
    // the same code whatever the input's float type. Converting inside the vector loads
    // left that code too large to unroll: 16 instructions per value from `f64`, 5 from `f32`.
    let mut converted = [[<L::Scalar as Lane>::zero(); 3 * MAX_LANES]; MAX_LANES];
    let mut block = [L::zero(); MAX_LANES];
    let block = &mut block[..n];
    for b0 in (0..whole).step_by(n) {
        let first = 3 * (start + b0);
        #[cfg(target_arch = "x86_64")]
        for r in rows {
            let slice = core::mem::size_of::<T>() * first;
            let ahead = r.as_ptr().cast::<i8>().wrapping_add(slice + PREFETCH_BYTES);
            for line in (0..3 * n * core::mem::size_of::<T>()).step_by(64) {
                // SAFETY: a prefetch is a hint: it reads nothing and never faults.
                #[allow(unused_unsafe)]
                unsafe {
                    core::arch::x86_64::_mm_prefetch::<{ core::arch::x86_64::_MM_HINT_T0 }>(
                        ahead.wrapping_add(line),
                    );
                }
            }
        }
        for (values, r) in converted.iter_mut().zip(rows) {
            for (v, x) in values[..3 * n].iter_mut().zip(&r[first..first + 3 * n]) {
                *v = cast(*x);
            }
        }
        // Group `c`: the block's values c·n .. (c + 1)·n of every channel.
        for c in 0..3 {
            for (v, values) in block.iter_mut().zip(&converted) {
                let values = &values[c * n..(c + 1) * n];
                *v = L::from_fn(|k| values[k]);
            }
            // `block` holds `LANES` vectors, so this cannot refuse; if it did, the first
            // block returns before anything is written.
            if !L::transpose_lanes(block) {
                return false;
            }
            for (k, v) in block.iter().enumerate() {
                let m = c * n + k;
                let target = field(&mut tile[b0 + m / 3].0);
                match m % 3 {
                    0 => target.x = *v,
                    1 => target.y = *v,
                    _ => target.z = *v,
                }
            }
        }
    }
    for (lane, r) in rows.iter().enumerate() {
        for (k, (s, _)) in tile.iter_mut().enumerate().skip(whole) {
            let i = 3 * (start + k);
            let v = field(s);
            v.x.set_lane(lane, cast(r[i]));
            v.y.set_lane(lane, cast(r[i + 1]));
            v.z.set_lane(lane, cast(r[i + 2]));
        }
    }
    true
}

/// Bytes ahead of the block being read that [`fill_lanes`] asks the cache for, in each
/// channel's rows: the hardware prefetcher follows few of a chunk's 16 × 3 streams (256 to
/// 768 measured alike, 1024 slower: docs/performance.md, "Prefetch").
const PREFETCH_BYTES: usize = 512;
