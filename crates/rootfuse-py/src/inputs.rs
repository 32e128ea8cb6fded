//! The input of one channel over borrowed NumPy arrays, as a [`rootfuse_batch::ChannelSource`]:
//! sample by sample for `Filter`, tile by tile (lane by lane, or a full chunk through
//! registers) for the batch engine.

use crate::arrays::{self, Steps, StepsRef};
use rootfuse_attitude::{ImuSample, Lane, Recording, Vec3};

/// The per-sample input of one channel over borrowed sensor values (`[x, y, z]` rows, float32
/// or float64 as given).
pub struct Inputs<'a> {
    pub gyr: arrays::Floats<'a>,
    pub acc: arrays::Floats<'a>,
    pub mag: Option<arrays::Floats<'a>>,
    pub steps: StepsRef<'a>,
    pub len: usize,
}

impl<'a> Inputs<'a> {
    /// The input of arrays read by [`imu_arrays`] with their steps.
    pub fn new(
        gyr: &'a arrays::SensorArray<'_>,
        acc: &'a arrays::SensorArray<'_>,
        mag: Option<&'a arrays::SensorArray<'_>>,
        steps: &'a Steps,
        len: usize,
    ) -> Self {
        Self {
            gyr: gyr.floats(),
            acc: acc.floats(),
            mag: mag.map(|m| m.floats()),
            steps: steps.borrowed(),
            len,
        }
    }

    #[inline]
    pub fn sample(&self, i: usize) -> ImuSample<f64> {
        let v =
            |a: &arrays::Floats<'_>| Vec3::new(a.get(3 * i), a.get(3 * i + 1), a.get(3 * i + 2));
        match &self.mag {
            Some(m) => ImuSample::new(v(&self.gyr), v(&self.acc), v(m)),
            None => ImuSample::six_d(v(&self.gyr), v(&self.acc)),
        }
    }
}

/// Writes rows `start..start + tile.len()` of `values` (`[x, y, z]` rows) into lane `lane` of
/// the vector `field` picks in each tile entry, rounded to the lane's precision once (from
/// `f32` directly: `f32 → f64 → f32` is exact).
#[inline]
fn fill_rows<T: Copy + Into<f64>, L: Lane>(
    values: &[T],
    start: usize,
    lane: usize,
    tile: &mut [(ImuSample<L>, L)],
    field: impl Fn(&mut ImuSample<L>) -> &mut Vec3<L>,
) {
    let Some(rows) = values.get(3 * start..3 * (start + tile.len())) else {
        return;
    };
    let cast = |x: T| <L::Scalar as Lane>::from_f64(x.into());
    for ((s, _), r) in tile.iter_mut().zip(rows.chunks_exact(3)) {
        let v = field(s);
        v.x.set_lane(lane, cast(r[0]));
        v.y.set_lane(lane, cast(r[1]));
        v.z.set_lane(lane, cast(r[2]));
    }
}

fn fill_floats<L: Lane>(
    values: &arrays::Floats<'_>,
    start: usize,
    lane: usize,
    tile: &mut [(ImuSample<L>, L)],
    field: impl Fn(&mut ImuSample<L>) -> &mut Vec3<L>,
) {
    match values {
        arrays::Floats::F32(v) => fill_rows(v, start, lane, tile, field),
        arrays::Floats::F64(v) => fill_rows(v, start, lane, tile, field),
    }
}

/// Writes one sensor's rows of all `lanes` (channel `i` into lane `i`) through
/// [`rootfuse_batch::fill_lanes`] when every channel stores them in the same float type;
/// `false` (nothing written) otherwise.
fn fill_floats_lanes<'s, 'a: 's, L: Lane>(
    lanes: &[&'s Inputs<'a>],
    values: impl Fn(&'s Inputs<'a>) -> Option<&'s arrays::Floats<'a>>,
    start: usize,
    tile: &mut [(ImuSample<L>, L)],
    field: impl Fn(&mut ImuSample<L>) -> &mut Vec3<L>,
) -> bool {
    use rootfuse_batch::MAX_LANES;
    if lanes.len() > MAX_LANES {
        return false;
    }
    let mut f32s: [&[f32]; MAX_LANES] = [&[]; MAX_LANES];
    let mut f64s: [&[f64]; MAX_LANES] = [&[]; MAX_LANES];
    let (mut n32, mut n64) = (0, 0);
    for &source in lanes {
        match values(source) {
            Some(arrays::Floats::F32(v)) => {
                f32s[n32] = v;
                n32 += 1;
            }
            Some(arrays::Floats::F64(v)) => {
                f64s[n64] = v;
                n64 += 1;
            }
            None => return false,
        }
    }
    match (n32, n64) {
        (n, 0) => rootfuse_batch::fill_lanes(&f32s[..n], start, tile, field),
        (0, n) => rootfuse_batch::fill_lanes(&f64s[..n], start, tile, field),
        _ => false,
    }
}

impl Inputs<'_> {
    /// The magnetometer's rows (NaN for 6D input) into lane `lane` of `tile`.
    ///
    /// The engine keeps a channel in one lane of one tile for a whole run, and its tiles only
    /// shrink (the last one), so what the channel wrote into its first entry it wrote into
    /// every entry; the padding the tile starts with is finite. A lane whose first entry
    /// already holds NaN (6D data) holds it in every entry, and those stores are skipped.
    fn fill_mag_lane<L: Lane>(&self, start: usize, lane: usize, tile: &mut [(ImuSample<L>, L)]) {
        match &self.mag {
            Some(m) => fill_floats(m, start, lane, tile, |s| &mut s.mag),
            None if tile
                .first()
                .is_some_and(|(s, _)| Into::<f64>::into(s.mag.x.extract(lane)).is_nan()) => {}
            None => {
                let nan = <L::Scalar as Lane>::from_f64(f64::NAN);
                for (s, _) in tile.iter_mut() {
                    s.mag.x.set_lane(lane, nan);
                    s.mag.y.set_lane(lane, nan);
                    s.mag.z.set_lane(lane, nan);
                }
            }
        }
    }

    /// The steps into lane `lane` of `tile`. A fixed step already in the first entry (equal
    /// to the padding step, or written before: see [`fill_mag_lane`](Self::fill_mag_lane))
    /// is in every entry, and those stores are skipped (a fixed step is positive, so `==` is
    /// equality of bits).
    fn fill_steps_lane<L: Lane>(&self, start: usize, lane: usize, tile: &mut [(ImuSample<L>, L)]) {
        match self.steps {
            StepsRef::Fixed(dt) => {
                let dt = <L::Scalar as Lane>::from_f64(dt);
                if tile.first().is_some_and(|(_, d)| d.extract(lane) == dt) {
                    return;
                }
                for (_, d) in tile.iter_mut() {
                    d.set_lane(lane, dt);
                }
            }
            // The steps of the tile's samples from the slices themselves (what `StepsRef::at`
            // gives one by one, without its match and index tests per value). A tile past the
            // channel's end is empty.
            StepsRef::PerSample(v) => {
                for ((_, d), &dt) in tile.iter_mut().zip(v.get(start..).unwrap_or_default()) {
                    d.set_lane(lane, <L::Scalar as Lane>::from_f64(dt));
                }
            }
            StepsRef::Times(t) => {
                // The first step as `at` gives it (sample 0 has none of its own), the others
                // from consecutive times.
                let Some(((_, first), rest)) = tile.split_first_mut() else {
                    return;
                };
                first.set_lane(lane, <L::Scalar as Lane>::from_f64(self.steps.at(start)));
                let pairs = t.get(start..).unwrap_or_default().windows(2);
                for ((_, d), w) in rest.iter_mut().zip(pairs) {
                    d.set_lane(lane, <L::Scalar as Lane>::from_f64(w[1] - w[0]));
                }
            }
        }
    }
}

impl rootfuse_batch::ChannelSource for Inputs<'_> {
    fn len(&self) -> usize {
        self.len
    }
    fn sample(&self, i: usize) -> ImuSample<f64> {
        Inputs::sample(self, i)
    }
    fn dt(&self, i: usize) -> f64 {
        self.steps.at(i)
    }
    /// One pass over each sensor's rows (the batch engine's tiles): the same values as
    /// `sample` and `dt`, rounded the same way, without a call per value.
    fn read_into<L: Lane>(&self, start: usize, lane: usize, tile: &mut [(ImuSample<L>, L)]) {
        fill_floats(&self.gyr, start, lane, tile, |s| &mut s.gyr);
        fill_floats(&self.acc, start, lane, tile, |s| &mut s.acc);
        self.fill_mag_lane(start, lane, tile);
        self.fill_steps_lane(start, lane, tile);
    }
    /// The sensors' rows of a full chunk through registers ([`fill_floats_lanes`]), each
    /// channel's magnetometer (unless all have one) and steps lane by lane.
    fn read_lanes<L: Lane>(lanes: &[&Self], start: usize, tile: &mut [(ImuSample<L>, L)]) {
        let gyr_acc = fill_floats_lanes(lanes, |s| Some(&s.gyr), start, tile, |s| &mut s.gyr)
            && fill_floats_lanes(lanes, |s| Some(&s.acc), start, tile, |s| &mut s.acc);
        let mag = fill_floats_lanes(lanes, |s| s.mag.as_ref(), start, tile, |s| &mut s.mag);
        for (lane, source) in lanes.iter().enumerate() {
            if !gyr_acc {
                fill_floats(&source.gyr, start, lane, tile, |s| &mut s.gyr);
                fill_floats(&source.acc, start, lane, tile, |s| &mut s.acc);
            }
            if !mag {
                source.fill_mag_lane(start, lane, tile);
            }
            source.fill_steps_lane(start, lane, tile);
        }
    }
}

/// A `Recording` from arrays (what the smoother, metrics and writer take).
pub fn recording(
    input: &Inputs<'_>,
    t: Vec<f64>,
    truth: Option<Vec<f64>>,
    use_mask: Option<Vec<bool>>,
) -> Recording {
    let n = input.len;
    let v3 = |a: arrays::Floats<'_>| -> Vec<Vec3<f64>> {
        (0..n)
            .map(|i| Vec3::new(a.get(3 * i), a.get(3 * i + 1), a.get(3 * i + 2)))
            .collect()
    };
    Recording {
        name: "python".into(),
        t,
        gyr: v3(input.gyr),
        acc: v3(input.acc),
        mag: input.mag.map(v3),
        truth: truth.map(|q| {
            q.chunks_exact(4)
                .map(|c| rootfuse_attitude::Quat::new(c[0], c[1], c[2], c[3]))
                .collect()
        }),
        use_mask,
    }
}
