//! No code: a dependency of the workspace's std crates that asks for every third-party crate
//! with the union of the features the workspace uses (written by `cargo hakari generate`, see
//! `.config/hakari.toml`), so that building one package (`cargo test -p rootfuse-io`, maturin's
//! build of `rootfuse-py`) reuses what `cargo test --workspace` compiled instead of compiling
//! a dependency again with other features.
