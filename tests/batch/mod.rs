//! The SIMD batch engine.
mod engine;
