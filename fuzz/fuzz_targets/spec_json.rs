//! `cargo fuzz run spec_json`: see `mimicgen_tests::fuzz::spec_json`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mimicgen_tests::fuzz::spec_json(data));
