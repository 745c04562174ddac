//! The `raytracer` command: parses flags, calls the library, maps errors to exit 2
//! (as ripgrep does). Everything else lives in the library or in `cli/`.

mod cli;

use std::process::ExitCode;

/// Big freed buffers are reused rather than given back and asked for afresh (see
/// [`RecyclingAllocator`]); 64 MiB kept at most.
#[global_allocator]
static ALLOCATOR: raytracer::memory::RecyclingAllocator =
    raytracer::memory::RecyclingAllocator::new(64 << 20);

fn main() -> ExitCode {
    return_large_blocks_to_the_system();
    let args = cli::parse();
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::from(2)
        }
    }
}

/// Makes glibc serve every block of 256 KiB or more by `mmap` and unmap it on free.
/// By default the threshold grows with the largest block freed, after which the
/// parser's and builder's multi-megabyte buffers come from per-thread arenas and
/// stay resident once freed: the dragon's peak RSS was 170 MB instead of ~120.
fn return_large_blocks_to_the_system() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `mallopt` only sets an allocator parameter; called before any thread
    // starts.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 256 * 1024);
    }
}
