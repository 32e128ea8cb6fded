//! `cfg(broad_data)` for the tests of BROAD data: the workspace's rule (see its build.rs): set
//! when the recordings are there or under CI, else those tests are ignored.
include!("../../build.rs");
