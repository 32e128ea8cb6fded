//! Reading and writing recordings and estimates.
mod csv;
mod files;
