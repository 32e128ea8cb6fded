//! Streaming, causal pre-processing of one signal per lane: allocation-free after
//! construction, branch-free per lane.
//!
//! A non-finite input (NaN, ±∞) in a lane is not let into the filter's memory, where it would
//! poison the next `N` outputs: it is replaced by that lane's last finite input
//! (sample-and-hold) and counted in `rejected`. Windows start filled with the first finite
//! sample, so there is no start-up transient toward zero.
//!
//! ```
//! use rootfuse_attitude::preprocess::{Hampel, MovingMedian};
//! let mut median = MovingMedian::<f64, 5>::new();
//! let out: Vec<f64> = [1.0, 1.0, 9.0, 1.0, 1.0].iter().map(|&x| median.update(x)).collect();
//! assert_eq!(out, [1.0, 1.0, 1.0, 1.0, 1.0]); // the spike never reaches the median
//! let mut hampel = Hampel::<f64, 7>::new(3.0);
//! for x in [1.0, 1.1, 0.9, 1.0, 1.05, 0.95] {
//!     hampel.update(x);
//! }
//! assert!((hampel.update(50.0) - 1.0).abs() < 0.1); // an outlier is replaced by the median
//! ```

use rootfuse_lane::{Lane, Mask};

/// State shared by the windowed filters: the window (oldest first), the first-sample fill,
/// the sample-and-hold of non-finite inputs and the rejection count.
///
/// A shift register rather than a ring buffer: a ring's write position is shared by all
/// lanes, so one lane could not skip a sample without disturbing the age order of its window.
#[derive(Clone, Debug)]
struct Window<T: Lane, const W: usize> {
    buf: [T; W],
    /// Samples in use, `1..=W`, the newest `len` slots at the end of `buf` (the moving
    /// mean's window may be chosen at run time; the same for every lane).
    len: usize,
    hold: Hold<T>,
}

impl<T: Lane, const W: usize> Window<T, W> {
    fn new() -> Self {
        const { assert!(W >= 1, "the window holds at least one sample") };
        Self {
            buf: [T::zero(); W],
            len: W,
            hold: Hold::new(),
        }
    }
    /// Stores the (held) sample in `active` lanes (the others keep their window exactly); the
    /// first finite sample of a lane fills its whole window.
    fn push_where(&mut self, x: T, active: T::Mask) -> T {
        let (x, fresh) = self.hold.accept_where(x, active);
        if fresh.any() {
            for slot in &mut self.buf {
                *slot = T::select(fresh, x, *slot);
            }
        }
        for i in W - self.len + 1..W {
            self.buf[i - 1] = T::select(active, self.buf[i], self.buf[i - 1]);
        }
        self.buf[W - 1] = T::select(active, x, self.buf[W - 1]);
        x
    }
}

/// Sample-and-hold of non-finite inputs, with the per-lane rejection count.
#[derive(Clone, Debug)]
struct Hold<T: Lane> {
    last: T,
    started: T::Mask,
    rejected: T::Counts,
}

impl<T: Lane> Hold<T> {
    fn new() -> Self {
        Self {
            last: T::zero(),
            started: <T::Mask as Mask>::splat(false),
            rejected: T::Counts::default(),
        }
    }
    /// In `active` lanes: `x` where finite, else the last finite input; and the lanes whose
    /// first finite input this is. Inactive lanes change nothing and count nothing.
    fn accept_where(&mut self, x: T, active: T::Mask) -> (T, T::Mask) {
        let finite = x.is_finite();
        T::count(&mut self.rejected, active & !finite);
        let ok = finite & active;
        let fresh = ok & !self.started;
        self.started |= ok;
        self.last = T::select(ok, x, self.last);
        (self.last, fresh)
    }
}

/// Median of `W` lanes-values by an odd-even transposition network of compare-exchanges
/// (`min`/`max`), so every lane does the same work and lanes equal scalar runs.
fn median<T: Lane, const W: usize>(values: &[T; W]) -> T {
    let mut v = *values;
    for round in 0..W {
        let mut i = round % 2;
        while i + 1 < W {
            let (a, b) = (v[i], v[i + 1]);
            v[i] = a.min(b);
            v[i + 1] = a.max(b);
            i += 2;
        }
    }
    v[W / 2]
}

/// First-order low-pass `y(n) = a·x(n) + (1 − a)·y(n−1)`, `a ∈ (0, 1]`, started at the first
/// finite sample.
#[derive(Clone, Debug)]
pub struct LowPass<T: Lane> {
    a: T,
    y: T,
    hold: Hold<T>,
}

impl<T: Lane> LowPass<T> {
    /// A low-pass with smoothing factor `a` (1 = pass-through); `a` is clamped to `(0, 1]`.
    pub fn new(a: f64) -> Self {
        Self::with_factor(T::from_f64(low_pass_factor(a)))
    }
    /// A low-pass whose factor is already in lanes (per-lane factors; each one as
    /// [`low_pass_factor`] makes it).
    pub fn with_factor(a: T) -> Self {
        Self {
            a,
            y: T::zero(),
            hold: Hold::new(),
        }
    }
    /// The factor `a = 1 − exp(−dt/τ)` of a time constant `tau` (s) at sample interval `dt`
    /// (s): the exact discretisation ([`lowpass_gain`](crate::blocks::lowpass_gain)), where
    /// `dt/(τ + dt)` is first order only. `tau = 0` is no low-pass (`a = 1`).
    pub fn from_time_constant(tau: f64, dt: f64) -> Self {
        Self::new(crate::blocks::lowpass_gain(dt, tau))
    }
    /// Filters one sample.
    pub fn update(&mut self, x: T) -> T {
        self.update_where(x, <T::Mask as Mask>::splat(true))
    }
    /// Filters one sample in `active` lanes; the other lanes keep their state exactly (a
    /// sample their caller rejected) and return their last output.
    pub fn update_where(&mut self, x: T, active: T::Mask) -> T {
        let (x, fresh) = self.hold.accept_where(x, active);
        let previous = T::select(fresh, x, self.y);
        let y = self.a.mul_add(x - previous, previous);
        self.y = T::select(active, y, self.y);
        self.y
    }
    /// Per-lane count of rejected (non-finite) inputs.
    pub fn rejected(&self) -> &T::Counts {
        &self.hold.rejected
    }
}

/// Moving mean over the last `N` samples.
#[derive(Clone, Debug)]
pub struct MovingMean<T: Lane, const N: usize> {
    window: Window<T, N>,
}

impl<T: Lane, const N: usize> Default for MovingMean<T, N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Lane, const N: usize> MovingMean<T, N> {
    /// A moving mean of window `N`.
    pub fn new() -> Self {
        Self::with_len(N)
    }
    /// A moving mean over the last `len` samples, `len` clamped to `1..=N` (`N` is the
    /// capacity): for a window chosen at run time.
    pub fn with_len(len: usize) -> Self {
        let mut window = Window::new();
        window.len = len.clamp(1, N);
        Self { window }
    }
    /// The number of samples averaged.
    pub fn window_len(&self) -> usize {
        self.window.len
    }
    /// Filters one sample.
    pub fn update(&mut self, x: T) -> T {
        self.update_where(x, <T::Mask as Mask>::splat(true))
    }
    /// Filters one sample in the `active` lanes; the other lanes are left exactly as if the
    /// sample did not exist (their current mean is returned).
    pub fn update_where(&mut self, x: T, active: T::Mask) -> T {
        self.window.push_where(x, active);
        // Summing the window each time (N is small) avoids the drift of a running sum in f32.
        let mut sum = T::zero();
        for v in &self.window.buf[N - self.window.len..] {
            sum += *v;
        }
        sum / T::from_f64(self.window.len as f64)
    }
    /// Per-lane count of rejected (non-finite) inputs.
    pub fn rejected(&self) -> &T::Counts {
        &self.window.hold.rejected
    }
}

/// Moving median over the last `W = 2N + 1` samples (`W` odd).
#[derive(Clone, Debug)]
pub struct MovingMedian<T: Lane, const W: usize> {
    window: Window<T, W>,
}

impl<T: Lane, const W: usize> Default for MovingMedian<T, W> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Lane, const W: usize> MovingMedian<T, W> {
    /// A moving median of odd window `W`.
    pub fn new() -> Self {
        const { assert!(W % 2 == 1, "the median window is 2N + 1 samples") };
        Self {
            window: Window::new(),
        }
    }
    /// Filters one sample.
    pub fn update(&mut self, x: T) -> T {
        self.update_where(x, <T::Mask as Mask>::splat(true))
    }
    /// Filters one sample in the `active` lanes; the other lanes are left exactly as if the
    /// sample did not exist (their current median is returned).
    pub fn update_where(&mut self, x: T, active: T::Mask) -> T {
        self.window.push_where(x, active);
        median(&self.window.buf)
    }
    /// Per-lane count of rejected (non-finite) inputs.
    pub fn rejected(&self) -> &T::Counts {
        &self.window.hold.rejected
    }
}

/// Hampel outlier replacement (causal): a sample further than `k·1.4826·MAD` from the median
/// of the last `W` samples (itself included) is replaced by that median; `1.4826·MAD`
/// estimates the standard deviation of Gaussian data.
#[derive(Clone, Debug)]
pub struct Hampel<T: Lane, const W: usize> {
    k: T,
    window: Window<T, W>,
    replaced: T::Counts,
}

impl<T: Lane, const W: usize> Hampel<T, W> {
    /// A Hampel filter of odd window `W` and threshold `k` (standard deviations; 3 is usual).
    pub fn new(k: f64) -> Self {
        Self::with_threshold(T::from_f64(hampel_threshold(k)))
    }
    /// A Hampel filter whose threshold `k·1.4826` is already in lanes (per-lane thresholds;
    /// each one as [`hampel_threshold`] makes it).
    pub fn with_threshold(k_mad: T) -> Self {
        const { assert!(W % 2 == 1, "the Hampel window is 2N + 1 samples") };
        Self {
            k: k_mad,
            window: Window::new(),
            replaced: T::Counts::default(),
        }
    }
    /// Filters one sample.
    pub fn update(&mut self, x: T) -> T {
        self.update_where(x, <T::Mask as Mask>::splat(true))
    }
    /// Filters one sample in `active` lanes; the other lanes keep their window exactly (a
    /// sample their caller rejected), count nothing, and return their held input.
    pub fn update_where(&mut self, x: T, active: T::Mask) -> T {
        let x = self.window.push_where(x, active);
        let m = median(&self.window.buf);
        let deviations = self.window.buf.map(|v| (v - m).abs());
        let mad = median(&deviations);
        let outlier = (x - m).abs().simd_gt(self.k * mad) & active;
        T::count(&mut self.replaced, outlier);
        T::select(outlier, m, x)
    }
    /// Per-lane count of rejected (non-finite) inputs.
    pub fn rejected(&self) -> &T::Counts {
        &self.window.hold.rejected
    }
    /// Per-lane count of outliers replaced by the median.
    pub fn replaced(&self) -> &T::Counts {
        &self.replaced
    }
}

/// The factor a [`LowPass`] uses for a requested `a`: clamped to `(0, 1]` (a non-positive or
/// NaN `a` becomes the smallest positive value, which holds the first input).
pub fn low_pass_factor(a: f64) -> f64 {
    if a > 0.0 {
        a.min(1.0)
    } else {
        f64::MIN_POSITIVE
    }
}

/// The threshold a [`Hampel`] filter compares with the median absolute deviation: `k·1.4826`
/// (1.4826·MAD estimates the standard deviation of Gaussian data).
pub fn hampel_threshold(k: f64) -> f64 {
    k * 1.4826
}
