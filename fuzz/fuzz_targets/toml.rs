//! `formats::parse_toml` on arbitrary bytes, beside fixed small OBJ, PLY and MTL
//! files that its `[[mesh]]` tables may name; the options resolved as the command
//! line resolves them.
#![no_main]

#[path = "../../tests/support/fuzz_checks.rs"]
mod fuzz_checks;
#[path = "../fuzz_dir.rs"]
mod fuzz_dir;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = fuzz_dir::with_toml_meshes();
    fuzz_dir::single_thread().install(|| fuzz_checks::check_toml(data, dir));
});
