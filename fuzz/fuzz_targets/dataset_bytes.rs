//! `cargo fuzz run dataset_bytes`: see `mimicgen_tests::fuzz::dataset_bytes` (the input is a list
//! of byte edits of the seed file; each mutated copy is written to a scratch file and read back).
#![no_main]

use std::sync::OnceLock;

static SEED: OnceLock<mimicgen_tests::fuzz::Seed> = OnceLock::new();

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let seed = SEED.get_or_init(mimicgen_tests::fuzz::Seed::new);
    mimicgen_tests::fuzz::dataset_bytes(&seed.bytes, data, &seed.scratch);
});
