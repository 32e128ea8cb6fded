#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| rootfuse_fuzz::columnar_reader(data));
