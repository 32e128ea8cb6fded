//! Evaluation: the BROAD recordings and metrics, the simulator.
mod broad;
mod broad_flagship;
mod gyro_scale;
mod sim;
