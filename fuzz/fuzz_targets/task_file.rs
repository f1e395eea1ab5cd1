//! `cargo fuzz run task_file`: see `mimicgen_tests::fuzz::task_file`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mimicgen_tests::fuzz::task_file(data));
