//! Quaternions, frames, pre-processing, the filters and their configuration.
mod bad_samples;
mod configuration;
mod filters;
mod flagship;
mod flagship_accuracy;
mod frames;
mod heading_pipeline;
mod lsq_fusion;
mod preprocess;
mod quat;
mod reconstruction_and_ecf_ekf;
