//! Decoding fuzz bytes into numbers.

/// A cursor over fuzz input; reads past the end yield zeros, so every byte string decodes.
#[derive(Clone, Debug)]
pub struct Bytes<'a> {
    data: &'a [u8],
    pos: usize,
}

/// Values that break naive numerics, tried on purpose.
const SPECIAL: [f64; 16] = [
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    0.0,
    -0.0,
    f64::MIN_POSITIVE,
    5e-324,
    f64::MAX,
    -f64::MAX,
    1e-30,
    1e30,
    9.81,
    1.0,
    -1.0,
    1e-3,
    35.0,
];

impl<'a> Bytes<'a> {
    /// A cursor at the start of `data`.
    pub fn new(data: &'a [u8]) -> Self {
        Self { data, pos: 0 }
    }

    /// True once every byte has been read.
    pub fn is_empty(&self) -> bool {
        self.pos >= self.data.len()
    }

    /// The next byte (0 past the end).
    pub fn u8(&mut self) -> u8 {
        let b = self.data.get(self.pos).copied().unwrap_or(0);
        self.pos += 1;
        b
    }

    fn le<const K: usize>(&mut self) -> [u8; K] {
        let mut out = [0u8; K];
        for b in &mut out {
            *b = self.u8();
        }
        out
    }

    /// A number that is exactly representable in `f32` when `single`: a tag byte chooses
    /// raw bits (NaN payloads, subnormals, huge values), a special value, or a moderate
    /// decimal `i16·10^k` with `k ∈ [−7, 0]`.
    pub fn value(&mut self, single: bool) -> f64 {
        let tag = self.u8();
        let v = match tag % 8 {
            0 | 1 => {
                if single {
                    f64::from(f32::from_bits(u32::from_le_bytes(self.le())))
                } else {
                    f64::from_bits(u64::from_le_bytes(self.le()))
                }
            }
            2 => SPECIAL[usize::from(self.u8()) % SPECIAL.len()],
            _ => {
                let m = f64::from(i16::from_le_bytes(self.le()));
                m * 10f64.powi(-i32::from((tag >> 3) % 8))
            }
        };
        if single { f64::from(v as f32) } else { v }
    }

    /// A time step, s: mostly a plausible one (1–256 ms), sometimes any [`value`](Self::value).
    pub fn dt(&mut self, single: bool) -> f64 {
        let tag = self.u8();
        if tag.is_multiple_of(4) {
            self.value(single)
        } else {
            let v = f64::from(tag) * 1e-3;
            if single { f64::from(v as f32) } else { v }
        }
    }
}
