//! The SIMD batch engine.
mod engine;
mod fleet;
