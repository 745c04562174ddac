//! `formats::parse_ply` on arbitrary bytes (ascii and binary bodies alike).
#![no_main]

#[path = "../../tests/support/fuzz_checks.rs"]
mod fuzz_checks;
#[path = "../fuzz_dir.rs"]
mod fuzz_dir;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // One worker: the fuzzer runs one job per core already.
    fuzz_dir::single_thread().install(|| fuzz_checks::check_ply(data));
});
