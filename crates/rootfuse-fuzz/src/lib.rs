//! Fuzz-target bodies: each is a `fn(&[u8])` that decodes the bytes into inputs for one
//! component, runs it and asserts the robustness invariants of `ROBUSTNESS.md` inside (a
//! failed invariant panics, which is what a fuzzer reports).
//!
//! The cargo-fuzz crate in `fuzz/` calls these one-liners; the workspace test
//! `tests/fuzz_corpus.rs` replays every file of `fuzz/corpus/<target>/` through the same
//! functions, so CI re-checks every input ever found.
//!
//! Bytes are decoded without the `arbitrary` crate ([`Bytes`]): floating-point values are
//! read as raw bit patterns part of the time, so NaN, ±∞, subnormals and huge values occur
//! as often as ordinary numbers.
#![warn(missing_docs)]

mod bytes;
mod columnar;
mod csv;
mod engine;
mod filter;
mod rls;

pub use bytes::Bytes;
pub use columnar::columnar_reader;
pub use csv::csv_reader;
pub use engine::batch_engine;
pub use filter::filter_update;
pub use rls::rls_forms;

/// A target body.
pub type Target = fn(&[u8]);

/// Every target: its name (the directory under `fuzz/corpus/` and the cargo-fuzz target) and
/// its body.
pub const TARGETS: &[(&str, Target)] = &[
    ("csv_reader", csv_reader),
    ("filter_update", filter_update),
    ("rls_forms", rls_forms),
    ("batch_engine", batch_engine),
    ("columnar_reader", columnar_reader),
];
