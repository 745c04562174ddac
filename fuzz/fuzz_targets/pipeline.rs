//! Parse, build and render a tiny image in all three modes: OBJ text, then a NUL
//! byte, then the text of the `m.mtl` file it may name.
#![no_main]

#[path = "../../tests/support/fuzz_checks.rs"]
mod fuzz_checks;
#[path = "../fuzz_dir.rs"]
mod fuzz_dir;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = fuzz_dir::private();
    // One worker: the fuzzer runs one job per core already.
    fuzz_dir::single_thread().install(|| fuzz_checks::check_pipeline(data, dir));
});
