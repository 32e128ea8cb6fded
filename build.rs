// Decides whether the BROAD data tests can run: `cfg(broad_data)` when the recordings are
// at `$ROOTFUSE_BROAD_DIR` (or `../shared/broad_csv`), or when `CI` is set (CI must have
// them: there a missing folder fails the tests instead of skipping them). Without it the
// data tests are marked ignored, so a run says they were skipped rather than passing them.
use std::path::PathBuf;

fn main() {
    println!("cargo::rustc-check-cfg=cfg(broad_data)");
    println!("cargo::rerun-if-env-changed=ROOTFUSE_BROAD_DIR");
    println!("cargo::rerun-if-env-changed=CI");
    // The workspace root (this file is also the build script of crates that test with BROAD
    // data, by `include!`): the folder of Cargo.lock above the package.
    let manifest = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let root = manifest
        .ancestors()
        .find(|d| d.join("Cargo.lock").is_file())
        .unwrap_or(&manifest)
        .to_path_buf();
    let dir = std::env::var_os("ROOTFUSE_BROAD_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("../shared/broad_csv"));
    let index = dir.join("index.csv");
    println!("cargo::rerun-if-changed={}", index.display());
    if index.is_file() || std::env::var_os("CI").is_some() {
        println!("cargo::rustc-cfg=broad_data");
    }
}
