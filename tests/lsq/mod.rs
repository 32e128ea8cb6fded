//! Least squares: the recursive forms and the dense weighted solvers.
mod dense;
mod rls;
