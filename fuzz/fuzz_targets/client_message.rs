//! `cargo fuzz run client_message`: see `mimicgen_tests::fuzz::client_message` (the input is a
//! tab's WebSocket message, as JSON bytes).
#![no_main]

use std::sync::OnceLock;

static SERVED: OnceLock<mimicgen_tests::fuzz::ServedRoot> = OnceLock::new();

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let served = SERVED.get_or_init(mimicgen_tests::fuzz::ServedRoot::new);
    let _ = mimicgen_tests::fuzz::client_message(data, served);
});
