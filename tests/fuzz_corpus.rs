//! Replays every input the fuzzers ever kept (`fuzz/corpus/<target>/`) through the target
//! bodies of `rootfuse-fuzz`, so the invariants they assert are re-checked by every CI run.

use std::path::Path;

fn corpus(target: &str) -> Vec<(String, Vec<u8>)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/corpus")
        .join(target);
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    files
        .into_iter()
        .map(|p| (p.display().to_string(), std::fs::read(&p).unwrap()))
        .collect()
}

fn replay(target: &str) {
    let body = rootfuse_fuzz::TARGETS
        .iter()
        .find(|(n, _)| *n == target)
        .unwrap()
        .1;
    let inputs = corpus(target);
    assert!(!inputs.is_empty(), "{target}: empty corpus");
    for (name, data) in &inputs {
        if std::panic::catch_unwind(|| body(data)).is_err() {
            panic!("{target}: invariant failed on {name}");
        }
    }
}

#[test]
fn every_target_has_a_corpus() {
    for (target, _) in rootfuse_fuzz::TARGETS {
        assert!(!corpus(target).is_empty(), "{target}");
    }
}

#[test]
fn csv_reader_corpus() {
    replay("csv_reader");
}

#[test]
fn filter_update_corpus() {
    replay("filter_update");
}

#[test]
fn rls_forms_corpus() {
    replay("rls_forms");
}

#[test]
fn batch_engine_corpus() {
    replay("batch_engine");
}

#[test]
fn columnar_reader_corpus() {
    replay("columnar_reader");
}

/// Pseudo-random inputs (a fixed xorshift stream), so each body is exercised beyond the
/// corpus, the same way on every run.
#[test]
fn random_inputs_keep_the_invariants() {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for (target, body) in rootfuse_fuzz::TARGETS {
        for _ in 0..300 {
            let len = (next() % 1500) as usize;
            let data: Vec<u8> = (0..len).map(|_| next() as u8).collect();
            if std::panic::catch_unwind(|| body(&data)).is_err() {
                panic!("{target}: invariant failed on {data:?}");
            }
        }
    }
}
