//! The filters under bad samples, run through the batch engine (the attitude crate's own
//! tests are in crates/rootfuse-attitude/tests, which cannot use the engine above it).
mod bad_samples;
mod interop;
