//! `cargo fuzz run spec_toml`: see `mimicgen_tests::fuzz::spec_toml`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mimicgen_tests::fuzz::spec_toml(data));
