//! Hostile input, bounded: a compressed file that inflates to gigabytes of binary data
//! is refused after its first block, with a message naming it, and the process's peak
//! memory stays small. (Alone in this test binary: `getrusage(RUSAGE_CHILDREN)` must
//! see no other test's children.)

use std::io::Write;
use std::process::Command;

/// Peak resident memory, in bytes, of the largest child this process has waited for.
#[cfg(target_os = "linux")]
fn largest_child_peak_bytes() -> u64 {
    // SAFETY: `getrusage` only fills the struct it is given.
    let usage = unsafe {
        let mut usage = std::mem::zeroed::<libc::rusage>();
        assert_eq!(libc::getrusage(libc::RUSAGE_CHILDREN, &mut usage), 0);
        usage
    };
    usage.ru_maxrss as u64 * 1024
}

#[cfg(target_os = "linux")]
#[test]
fn a_compressed_scene_of_binary_data_is_refused_after_its_first_block() {
    let dir = tempfile::tempdir().unwrap();
    // 512 MiB of NUL bytes in about half a megabyte.
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    let block = vec![0u8; 1 << 20];
    for _ in 0..512 {
        encoder.write_all(&block).unwrap();
    }
    let bomb = encoder.finish().unwrap();
    let out = dir.path().join("out.png");
    for name in ["bomb.obj.gz", "bomb.toml.gz", "bomb.ply.gz"] {
        let path = dir.path().join(name);
        std::fs::write(&path, &bomb).unwrap();
        let output = Command::new(env!("CARGO_BIN_EXE_raytracer"))
            .arg("render")
            .arg(&path)
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{name}: {stderr}");
        assert!(stderr.contains(&path.display().to_string()), "{stderr}");
        assert!(
            stderr.contains("binary data") || stderr.contains("ply"),
            "{name}: {stderr}"
        );
        assert!(!out.exists());
    }
    let peak = largest_child_peak_bytes();
    assert!(peak < 64 << 20, "peak memory {} MB", peak >> 20);
}
