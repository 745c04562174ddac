//! `formats::parse_obj` on arbitrary bytes, beside a fixed small MTL file.
#![no_main]

#[path = "../../tests/support/fuzz_checks.rs"]
mod fuzz_checks;
#[path = "../fuzz_dir.rs"]
mod fuzz_dir;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = fuzz_dir::with_fixed_mtl();
    fuzz_checks::check_obj(data, dir);
});
