//! `formats::parse_mtl` with texture maps: MTL text, a NUL byte, then the bytes of
//! the image `t.png` its maps may name (any format the decoder recognises); every
//! map decoded, then sampled.
#![no_main]

#[path = "../../tests/support/fuzz_checks.rs"]
mod fuzz_checks;
#[path = "../fuzz_dir.rs"]
mod fuzz_dir;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = fuzz_dir::private();
    fuzz_dir::single_thread().install(|| fuzz_checks::check_textures(data, dir));
});
