//! Sensor calibration: batch ellipsoid fit, rest-phase gyro and accelerometer calibration,
//! the online hard-iron estimator.
mod batch;
mod inertial;
mod online;
