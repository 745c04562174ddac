//! Counters and measurements reported by `--stats` and the `bench` command.

use std::ops::AddAssign;

/// Rays traced, by kind. Counted per row and summed, so no shared state per ray.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayCounts {
    /// Camera rays.
    pub primary: u64,
    /// Shadow rays towards lights (any-hit queries).
    pub shadow: u64,
    /// Mirror reflection rays.
    pub reflected: u64,
    /// Refraction rays.
    pub refracted: u64,
    /// Rays a path tracer sent on after scattering at a surface (path mode).
    pub scattered: u64,
}

impl RayCounts {
    /// All rays of every kind.
    pub fn total(&self) -> u64 {
        self.primary + self.shadow + self.reflected + self.refracted + self.scattered
    }
}

impl AddAssign for RayCounts {
    fn add_assign(&mut self, other: RayCounts) {
        self.primary += other.primary;
        self.shadow += other.shadow;
        self.reflected += other.reflected;
        self.refracted += other.refracted;
        self.scattered += other.scattered;
    }
}

/// The process's peak resident memory in bytes (`VmHWM`), where the OS tells it.
pub fn peak_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}
