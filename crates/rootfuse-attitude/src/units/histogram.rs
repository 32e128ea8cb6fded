//! A magnitude's distribution in constant memory: what the unit check reads of each sensor.

use std::vec::Vec;

/// A magnitude's distribution in bins of a tenth of a decade from 1e-9 to 1e12, plus the
/// readings that were zero or not finite: enough to tell units apart (they differ by factors
/// of 10 to 1e9) in constant memory per channel.
#[derive(Clone, Debug)]
pub(super) struct LogHistogram {
    bins: Vec<u32>,
    pub(super) zero: u64,
    pub(super) non_finite: u64,
}

const DECADE_BINS: f64 = 10.0;
const LOG_MIN: f64 = -9.0;
const LOG_MAX: f64 = 12.0;
const BINS: usize = ((LOG_MAX - LOG_MIN) * DECADE_BINS) as usize;

/// The bins' lower edges, `10^(LOG_MIN + b/DECADE_BINS)` for `b = 0..=BINS`.
fn bin_edges() -> &'static [f64; BINS + 1] {
    static EDGES: std::sync::OnceLock<[f64; BINS + 1]> = std::sync::OnceLock::new();
    EDGES
        .get_or_init(|| core::array::from_fn(|b| libm::pow(10.0, LOG_MIN + b as f64 / DECADE_BINS)))
}

/// Binary exponents of the cells of [`cell_bins`]: every bin's range and a cell beyond.
const CELL_EXP_MIN: i32 = -31;
const CELL_EXP_MAX: i32 = 41;
/// Leading mantissa bits that split an octave into cells (a sixteenth of an octave is 0.019
/// decades, a fifth of a bin).
const CELL_BITS: u32 = 4;

/// The index of `|x|`'s cell: its binary exponent (clamped to the cells') and leading mantissa
/// bits.
fn cell_of(x: f64) -> usize {
    let bits = x.abs().to_bits();
    let e = (((bits >> 52) & 0x7ff) as i32 - 1023).clamp(CELL_EXP_MIN - 1, CELL_EXP_MAX + 1);
    let m = (bits >> (52 - CELL_BITS)) & ((1 << CELL_BITS) - 1);
    ((e - CELL_EXP_MIN + 1) as usize) << CELL_BITS | m as usize
}

/// Per cell of `|x|`, the bin of its lowest value (from the binary exponent, one bin lower
/// against the product's rounding, and the edges): a lower bound of the bin of every value in
/// the cell, at most one bin below it.
fn cell_bins() -> &'static [u8] {
    static CELLS: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    CELLS.get_or_init(|| {
        let cells = ((CELL_EXP_MAX - CELL_EXP_MIN + 3) as usize) << CELL_BITS;
        let edges = bin_edges();
        (0..cells)
            .map(|c| {
                let e = (c >> CELL_BITS) as i32 + CELL_EXP_MIN - 1;
                let m = (c & ((1 << CELL_BITS) - 1)) as f64;
                let low = libm::ldexp(1.0 + m / f64::from(1u32 << CELL_BITS), e);
                let below = ((f64::from(e) * core::f64::consts::LOG10_2 - LOG_MIN) * DECADE_BINS)
                    .floor()
                    - 1.0;
                let mut b = below.clamp(0.0, (BINS - 1) as f64) as usize;
                while b + 1 < BINS && low >= edges[b + 1] {
                    b += 1;
                }
                // One below the cell's lowest value's bin: the edges' rounding.
                b.saturating_sub(1) as u8
            })
            .collect()
    })
}

/// The bin of a finite non-zero `x`: `⌊(log10|x| − LOG_MIN)·DECADE_BINS⌋`, clamped to the
/// bins, found without a logarithm (a check reads four magnitudes per sample, and the
/// logarithms were a twentieth of `rootfuse run` on a fleet): the cell of `|x|`'s exponent
/// and leading mantissa bits gives a bin at or below it ([`cell_bins`]), and the edges the
/// rest (at most two steps). The same bin as the logarithm's except within rounding of an
/// edge.
fn bin_of(x: f64) -> usize {
    let x = x.abs();
    let edges = bin_edges();
    let mut b = usize::from(cell_bins()[cell_of(x)]);
    while b + 1 < BINS && x >= edges[b + 1] {
        b += 1;
    }
    b
}

impl LogHistogram {
    pub(super) fn new() -> Self {
        Self {
            bins: std::vec![0; BINS],
            zero: 0,
            non_finite: 0,
        }
    }

    pub(super) fn add(&mut self, x: f64) {
        if !x.is_finite() {
            self.non_finite += 1;
        } else if x == 0.0 {
            self.zero += 1;
        } else {
            let b = bin_of(x);
            self.bins[b] = self.bins[b].saturating_add(1);
        }
    }

    pub(super) fn count(&self) -> u64 {
        self.bins.iter().map(|&c| u64::from(c)).sum()
    }

    /// The `q` quantile (0..1) of the non-zero finite values, at the centre of its bin.
    pub(super) fn quantile(&self, q: f64) -> Option<f64> {
        let n = self.count();
        if n == 0 {
            return None;
        }
        let rank = (q * (n - 1) as f64).round() as u64;
        let mut seen = 0u64;
        for (b, &c) in self.bins.iter().enumerate() {
            seen += u64::from(c);
            if seen > rank {
                return Some(libm::pow(10.0, LOG_MIN + (b as f64 + 0.5) / DECADE_BINS));
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bin found from the exponent and the edges is the logarithm's, over every decade
    /// and beyond both ends, except within rounding of an edge.
    #[test]
    fn bins_without_a_logarithm_are_the_logarithms() {
        let mut x = 1e-12_f64;
        let mut checked = 0;
        while x < 1e15 {
            let log = ((libm::log10(x) - LOG_MIN) * DECADE_BINS).floor();
            let expected = log.clamp(0.0, (BINS - 1) as f64) as usize;
            let position = (libm::log10(x) - LOG_MIN) * DECADE_BINS;
            if (position - position.round()).abs() > 1e-9 {
                assert_eq!(bin_of(x), expected, "{x}");
                assert_eq!(bin_of(-x), expected, "{x}");
                checked += 1;
            }
            x *= 1.0137;
        }
        assert!(checked > 3000, "{checked}");
        assert_eq!(bin_of(f64::MIN_POSITIVE / 4.0), 0);
        assert_eq!(bin_of(f64::MAX), BINS - 1);
    }

    #[test]
    fn histogram_quantiles_are_within_a_bin() {
        let mut h = LogHistogram::new();
        for i in 1..=1001 {
            h.add(i as f64);
        }
        let median = h.quantile(0.5).unwrap();
        assert!((median / 501.0 - 1.0).abs() < 0.13, "{median}");
        h.add(0.0);
        h.add(f64::NAN);
        assert_eq!((h.count(), h.zero, h.non_finite), (1001, 1, 1));
    }
}
