//! The beacon crate's integration tests: the heading pipeline with iBeacon headings.
mod heading_pipeline;
