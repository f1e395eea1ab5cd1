//! `cargo fuzz run dataset`: see `mimicgen_tests::fuzz::dataset` (the input picks edits of the
//! bundled source demos; each mutated copy is written to a scratch file and read back).
#![no_main]

use std::sync::OnceLock;

static SEED: OnceLock<mimicgen_tests::fuzz::Seed> = OnceLock::new();

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let seed = SEED.get_or_init(mimicgen_tests::fuzz::Seed::new);
    mimicgen_tests::fuzz::dataset(&seed.root, data, &seed.scratch);
});
