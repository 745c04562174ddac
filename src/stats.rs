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

/// What the whole process had used up to some moment: CPU time on all its threads
/// and page faults served without I/O. The difference of two readings is what the
/// work between them cost, which `--stats` shows beside each stage's wall time: on
/// the virtual machines measured a fresh page's first touch costs a few
/// microseconds, so a stage that writes much fresh memory shows it as system time
/// and faults.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Usage {
    /// User and system CPU time of all threads.
    pub cpu: std::time::Duration,
    /// The system part of `cpu`: page faults, mappings, I/O.
    pub system: std::time::Duration,
    /// Page faults served without I/O (first touches of fresh memory, mostly).
    pub minor_faults: u64,
}

impl Usage {
    /// The process's usage so far, where the OS reports it (Unix).
    pub fn now() -> Option<Usage> {
        #[cfg(unix)]
        {
            // SAFETY: `getrusage` writes the whole struct, all integers, for which
            // zero is a valid start.
            let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
            // SAFETY: `usage` is a valid `rusage` to write.
            if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) } != 0 {
                return None;
            }
            let duration = |t: libc::timeval| {
                std::time::Duration::from_secs(t.tv_sec.max(0) as u64)
                    + std::time::Duration::from_micros(t.tv_usec.max(0) as u64)
            };
            let system = duration(usage.ru_stime);
            Some(Usage {
                cpu: duration(usage.ru_utime) + system,
                system,
                minor_faults: usage.ru_minflt.max(0) as u64,
            })
        }
        #[cfg(not(unix))]
        None
    }

    /// What was used from `earlier` to this reading.
    pub fn since(&self, earlier: &Usage) -> Usage {
        Usage {
            cpu: self.cpu.saturating_sub(earlier.cpu),
            system: self.system.saturating_sub(earlier.system),
            minor_faults: self.minor_faults.saturating_sub(earlier.minor_faults),
        }
    }
}

/// A moment of a run: the clock, and the process's [`Usage`] so far where the OS
/// reports it. Two moments give what the work between them took.
#[derive(Clone, Copy, Debug)]
pub struct Mark {
    /// When.
    pub at: std::time::Instant,
    /// The process's usage up to then.
    pub usage: Option<Usage>,
}

impl Mark {
    /// This moment.
    pub fn now() -> Mark {
        Mark {
            at: std::time::Instant::now(),
            usage: Usage::now(),
        }
    }

    /// The wall time from this moment to `later`, and the usage where both have it.
    pub fn to(&self, later: &Mark) -> (std::time::Duration, Option<Usage>) {
        let usage = match (self.usage, later.usage) {
            (Some(earlier), Some(later)) => Some(later.since(&earlier)),
            _ => None,
        };
        (later.at.saturating_duration_since(self.at), usage)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Touching fresh memory shows as page faults, and work as CPU time, between
    /// two readings; a reading never runs backwards.
    #[cfg(target_os = "linux")]
    #[test]
    fn usage_counts_the_work_and_faults_between_readings() {
        let before = Usage::now().expect("Linux reports usage");
        // 16 MiB of fresh pages, each written once: at least one fault per 2 MiB
        // even where huge pages back it, 4096 with small pages.
        const BYTES: usize = 16 << 20;
        let mut fresh: Vec<u8> = Vec::with_capacity(BYTES);
        for page in fresh.spare_capacity_mut().iter_mut().step_by(4096) {
            page.write(1);
        }
        // 30 ms of this thread's CPU time, however busy the machine is.
        let thread_cpu = crate::memory::thread_cpu_time;
        let busy_until = thread_cpu() + std::time::Duration::from_millis(30);
        let mut spins = 0u64;
        while thread_cpu() < busy_until {
            spins = std::hint::black_box(spins + 1);
        }
        let after = Usage::now().expect("Linux reports usage");
        let used = after.since(&before);
        assert!(used.minor_faults >= 8, "{used:?}");
        assert!(used.cpu >= std::time::Duration::from_millis(25), "{used:?}");
        assert!(used.system <= used.cpu, "{used:?}");
        assert_eq!(before.since(&after), Usage::default());
        let (start, end) = (Mark::now(), Mark::now());
        let (_, usage) = start.to(&end);
        assert!(usage.is_some(), "both moments have usage");
        let unreported = Mark { usage: None, ..end };
        assert_eq!(start.to(&unreported).1, None);
        drop(fresh);
    }
}
