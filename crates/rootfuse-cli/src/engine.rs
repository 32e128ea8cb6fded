//! The CLI's view of the batch engine: every recording is one channel in SIMD lanes
//! (`f32x8` or `f64x4`), chunks spread over the cores.
pub use rootfuse_batch::{Columns, Precision, run_recordings};

/// `--precision` on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum PrecisionArg {
    /// Single precision, eight channels per `f32x8`.
    F32,
    /// Double precision, four channels per `f64x4`.
    F64,
}

impl From<PrecisionArg> for Precision {
    fn from(p: PrecisionArg) -> Self {
        match p {
            PrecisionArg::F32 => Precision::F32,
            PrecisionArg::F64 => Precision::F64,
        }
    }
}
