//! Reading and writing recordings and estimates.
mod csv;
