//! Evaluation: the BROAD recordings and metrics, the simulator.
mod broad;
mod sim;
