#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| rootfuse_fuzz::batch_engine(data));
