//! Recursive least squares.
