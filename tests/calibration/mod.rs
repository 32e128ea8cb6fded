//! The online hard-iron estimator of `rootfuse-attitude` run through the filters (the batch
//! fits are tested beside their crate, `crates/rootfuse-calibration/tests`).
mod online;
