//! Helpers shared by the integration tests.
#![allow(dead_code)]

use proptest::prelude::*;

/// A float type with the special-value strategy used by the bit-identity tests.
pub trait SpecialFloat: Copy + core::fmt::Debug + 'static {
    /// Normal values of moderate size, the extremes, ±0, ±∞, NaN, subnormals.
    fn special() -> BoxedStrategy<Self>;
    /// Values in [-1, 1] (inputs of asin/acos) and just outside.
    fn unit() -> BoxedStrategy<Self>;
    /// Bit pattern, for bit-for-bit comparison.
    fn bits(self) -> u64;
    /// NaN test.
    fn nan(self) -> bool;
}

macro_rules! special_float {
    ($t:ident) => {
        impl SpecialFloat for $t {
            fn special() -> BoxedStrategy<Self> {
                prop_oneof![
                    6 => -10.0 as $t..10.0 as $t,
                    2 => -1e6 as $t..1e6 as $t,
                    2 => proptest::num::$t::ANY,
                    1 => proptest::num::$t::SUBNORMAL,
                    1 => prop::sample::select(vec![
                        $t::NAN, $t::INFINITY, $t::NEG_INFINITY, 0.0, -0.0, $t::MAX, $t::MIN,
                        $t::MIN_POSITIVE, 1e30 as $t, -1e30 as $t, 1.0, -1.0, 0.5, -0.5,
                        core::$t::consts::PI, -core::$t::consts::FRAC_PI_2,
                    ]),
                ]
                .boxed()
            }
            fn unit() -> BoxedStrategy<Self> {
                prop_oneof![
                    8 => -1.0 as $t..=1.0 as $t,
                    1 => prop::sample::select(vec![1.0, -1.0, 0.5, -0.5, 0.0, -0.0, 1.0000001, $t::NAN]),
                ]
                .boxed()
            }
            fn bits(self) -> u64 {
                self.to_bits() as u64
            }
            fn nan(self) -> bool {
                self.is_nan()
            }
        }
    };
}
special_float!(f32);
special_float!(f64);

/// Equal bit for bit, or both NaN (IEEE 754 leaves NaN payload propagation unspecified).
pub fn same_bits<S: SpecialFloat>(a: S, b: S) -> bool {
    a.bits() == b.bits() || (a.nan() && b.nan())
}

/// Where the BROAD CSV recordings are: `$ROOTFUSE_BROAD_DIR` or `../shared/broad_csv` beside
/// the workspace. Returns `None` outside CI when absent (a fresh clone of the code alone); in
/// CI (`CI` set) a missing data folder is an error, so a data test can never pass by not
/// running.
pub fn broad_dir() -> Option<std::path::PathBuf> {
    // The workspace root: the folder of Cargo.lock above the package (this file is also the
    // common module of member crates' tests).
    let manifest = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let root = manifest
        .ancestors()
        .find(|d| d.join("Cargo.lock").is_file())
        .unwrap_or(manifest);
    let dir = std::env::var_os("ROOTFUSE_BROAD_DIR")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| root.join("../shared/broad_csv"));
    if dir.join("index.csv").is_file() {
        Some(dir)
    } else if std::env::var_os("CI").is_some() {
        panic!(
            "BROAD data not found at {} (set ROOTFUSE_BROAD_DIR)",
            dir.display()
        );
    } else {
        eprintln!("note: BROAD data not found at {}; skipping", dir.display());
        None
    }
}

/// The [`Dof`](rootfuse_attitude::Dof) of a count (6 or 9) that a test iterates over.
pub fn dof(n: u8) -> rootfuse_attitude::Dof {
    rootfuse_attitude::Dof::from_count(n).expect("tests iterate over 6 and 9")
}
