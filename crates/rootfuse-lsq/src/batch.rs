//! Dense weighted least squares on faer.
