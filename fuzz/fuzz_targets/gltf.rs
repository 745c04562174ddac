//! `formats::parse_gltf` on arbitrary bytes (glTF JSON or GLB), then the bytes of
//! the `b.bin` buffer and the `t.png` image it may name, after separators; the
//! materials' texture maps sampled.
#![no_main]

#[path = "../../tests/support/fuzz_checks.rs"]
mod fuzz_checks;
#[path = "../fuzz_dir.rs"]
mod fuzz_dir;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = fuzz_dir::private();
    fuzz_dir::single_thread().install(|| fuzz_checks::check_gltf(data, dir));
});
