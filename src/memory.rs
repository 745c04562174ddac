//! Big buffers: fresh ones backed by 2 MiB pages where those are cheap, freed ones
//! reused.
//!
//! The first write to each 4 KiB page of a fresh buffer takes a page fault, and on
//! the virtual machines this renderer is measured on a fault costs a few
//! microseconds: 2 MiB of small pages about 1.4 ms. One fault of a 2 MiB page
//! costs 0.1-0.2 ms when the memory behind it is warm, but 5-10 ms when it is
//! cold (see [`DEAR_HUGE_PAGE`]). Linux backs a range with such transparent huge
//! pages only when asked (`madvise` mode is the usual default), so the few arrays
//! of the scene build that are written once from end to end ask for them, and
//! time what they get. The `raytracer` command's global allocator,
//! [`RecyclingAllocator`], goes further: big blocks freed are handed out again, so
//! that most big buffers need no fresh pages at all.

/// The 2 MiB page of x86-64 and aarch64 Linux.
#[cfg(target_os = "linux")]
const HUGE_PAGE_BYTES: usize = 2 << 20;

/// A vector of `len` zeroed elements, backed with huge pages where they are cheap
/// ([`advise_huge_pages`]). The zeroes come from a zeroed allocation (`calloc`,
/// fresh pages for big sizes), so nothing is written before the advice.
pub(crate) fn zeroed_vec<T: bytemuck::Zeroable>(len: usize) -> Vec<T> {
    let v = bytemuck::zeroed_vec(len);
    advise_huge_pages(&v);
    v
}

/// Backs the part of `v`'s buffer that covers whole 2 MiB pages with huge pages
/// while they are cheap, faulting them in now (see [`back_with_huge_pages`]). For
/// a buffer that is written from end to end next: the pages of a sparse one would
/// all be faulted in.
pub(crate) fn advise_huge_pages<T>(v: &Vec<T>) {
    #[cfg(target_os = "linux")]
    {
        let start = v.as_ptr() as usize;
        let end = start + v.capacity() * size_of::<T>();
        back_with_huge_pages(
            start.next_multiple_of(HUGE_PAGE_BYTES),
            end / HUGE_PAGE_BYTES * HUGE_PAGE_BYTES,
        );
    }
    #[cfg(not(target_os = "linux"))]
    let _ = v;
}

/// Moves the whole 2 MiB pages of `v`'s elements onto huge pages now, keeping their
/// contents (Linux's `MADV_COLLAPSE`: a copy of each 2 MiB into a huge page),
/// whatever [`advise_huge_pages`] decided when they were written. For data that
/// rays will read at random many times over, such as a mesh that thousands of
/// instances place: its nodes and packets outgrow what the processor's TLB maps
/// with small pages, and each visit of a copy then waits for page walks as well as
/// for the caches. Nothing happens where the kernel cannot (no THP support, a
/// kernel before 6.1, no free huge page): a hint, which changes no contents.
pub(crate) fn collapse_into_huge_pages<T>(v: &[T]) {
    #[cfg(target_os = "linux")]
    {
        /// `MADV_COLLAPSE` of `<linux/mman.h>` (not exported by `libc` on every
        /// target environment).
        const MADV_COLLAPSE: libc::c_int = 25;
        let start = (v.as_ptr() as usize).next_multiple_of(HUGE_PAGE_BYTES);
        let end =
            (v.as_ptr() as usize + std::mem::size_of_val(v)) / HUGE_PAGE_BYTES * HUGE_PAGE_BYTES;
        if end <= start {
            return;
        }
        for advice in [libc::MADV_HUGEPAGE, MADV_COLLAPSE] {
            // SAFETY: the range lies inside `v`'s buffer, mapped and ours, and is
            // 2 MiB aligned; both advices change how its pages are backed, never
            // their contents. Failure leaves small pages, so results are ignored.
            unsafe { libc::madvise(start as *mut libc::c_void, end - start, advice) };
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = v;
}

/// Whether fresh huge pages have been found dear in this process.
#[cfg(target_os = "linux")]
static HUGE_PAGES_DEAR: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// A fresh huge page whose first write takes longer than this is dear: small pages
/// would have cost less. On the virtual machines measured, the 512 small-page
/// faults of 2 MiB cost about 1.4 ms, and a huge page 0.1-0.2 ms when the guest's
/// memory was in use a moment ago, but 5-10 ms once it has lain free for a few
/// seconds (the guest reports free memory to its host, which takes it back and
/// must find it again): a render started after a pause paid for the dragon's ~100
/// MB of huge pages with 0.3 s of CPU time, three times what small pages cost.
/// Even back to back, the memory a render finds cheap runs out after 20-70 MB.
#[cfg(target_os = "linux")]
const DEAR_HUGE_PAGE: std::time::Duration = std::time::Duration::from_millis(1);

/// Backs `start..end` (whole 2 MiB pages, mapped and ours) with huge pages while
/// they are cheap: they are faulted in now, on all threads and each timed, and the
/// first [dear](DEAR_HUGE_PAGE) one switches the process to small pages, for the
/// rest of this range and every later one. The contents are kept.
///
/// Timing makes the pages' kind depend on the machine's state, never a result: a
/// buffer's contents are the same on pages of either size.
#[cfg(target_os = "linux")]
fn back_with_huge_pages(start: usize, end: usize) {
    use std::sync::atomic::Ordering::Relaxed;
    if end <= start {
        return;
    }
    let advise = |from: usize, advice: libc::c_int| {
        // SAFETY: the range is mapped, page aligned, and ours; the advice changes
        // how pages are backed, never their contents. Failure (no THP support)
        // leaves ordinary pages, so the result is ignored.
        unsafe { libc::madvise(from as *mut libc::c_void, end - from, advice) };
    };
    if HUGE_PAGES_DEAR.load(Relaxed) {
        // Explicitly, in case huge pages are the system's default.
        advise(start, libc::MADV_NOHUGEPAGE);
        return;
    }
    advise(start, libc::MADV_HUGEPAGE);
    // On all threads, as the buffer's writes would have faulted them.
    use rayon::prelude::*;
    (start..end)
        .into_par_iter()
        .step_by(HUGE_PAGE_BYTES)
        .for_each(|page| {
            if HUGE_PAGES_DEAR.load(Relaxed) {
                return;
            }
            let first = page as *mut std::mem::MaybeUninit<u8>;
            let began = thread_cpu_time();
            // SAFETY: the page is mapped and ours, and no other thread touches it
            // here; its first byte is written back as it was read (whatever it
            // holds), which faults the page in.
            unsafe { first.write_volatile(first.read_volatile()) };
            if thread_cpu_time().saturating_sub(began) > DEAR_HUGE_PAGE {
                HUGE_PAGES_DEAR.store(true, Relaxed);
            }
        });
    if HUGE_PAGES_DEAR.load(Relaxed) {
        // The pages not faulted in yet get small ones; those that were stay.
        advise(start, libc::MADV_NOHUGEPAGE);
    }
}

/// Marks huge pages dear for the rest of the process, as a slow fault would: for
/// tests of what asks for huge pages whatever they cost.
#[cfg(all(test, target_os = "linux"))]
pub(crate) fn find_huge_pages_dear() {
    HUGE_PAGES_DEAR.store(true, std::sync::atomic::Ordering::Relaxed);
}

/// Whether the kernel has transparent huge pages at all (`madvise` for them fails
/// otherwise).
#[cfg(all(test, target_os = "linux"))]
pub(crate) fn thp_supported() -> bool {
    std::path::Path::new("/sys/kernel/mm/transparent_hugepage/enabled").exists()
}

/// The CPU time of the calling thread: a fault's cost, not the time the thread was
/// preempted meanwhile (the host's work for a cold page counts, as the guest's
/// system time).
#[cfg(target_os = "linux")]
pub(crate) fn thread_cpu_time() -> std::time::Duration {
    let mut time = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `time` is a valid `timespec` to write.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut time) };
    std::time::Duration::new(time.tv_sec as u64, time.tv_nsec as u32)
}

/// Gives the whole pages of `v`'s unused capacity back to the system, keeping the
/// capacity: they cost no memory until written again (and then read as zeroes).
/// For a vector that ends up much shorter than it was reserved, where shrinking
/// would copy it (as `realloc` does for alignments above 16).
pub(crate) fn release_spare_capacity<T>(v: &Vec<T>) {
    #[cfg(target_os = "linux")]
    {
        const PAGE: usize = 4096;
        let start = v.as_ptr() as usize;
        let used_end = (start + v.len() * size_of::<T>()).next_multiple_of(PAGE);
        let end = (start + v.capacity() * size_of::<T>()) / PAGE * PAGE;
        if end > used_end {
            // SAFETY: the range lies inside `v`'s allocation, past its elements, and
            // is page aligned; `MADV_DONTNEED` on private anonymous memory only
            // replaces its (unused, uninitialized) contents with zero pages.
            unsafe {
                libc::madvise(
                    used_end as *mut libc::c_void,
                    end - used_end,
                    libc::MADV_DONTNEED,
                );
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = v;
}

/// Asks the processor to bring `lines` cache lines, from the one holding `address`
/// on, into the caches without waiting for them: for reads from random places whose
/// addresses are known ahead (a traversal's next nodes and leaves, a gather's next
/// elements). A hint, which never faults, whatever the address, and changes no
/// result.
#[inline(always)]
pub(crate) fn prefetch_lines<T>(address: *const T, lines: usize) {
    prefetch_aligned_lines((address as usize & !63) as *const u8, lines);
}

/// [`prefetch_lines`] of an address known to start a cache line (64-byte aligned):
/// no rounding down.
#[inline(always)]
pub(crate) fn prefetch_aligned_lines<T>(address: *const T, lines: usize) {
    debug_assert!((address as usize).is_multiple_of(64));
    #[cfg(target_arch = "x86_64")]
    {
        let start = address.cast::<i8>();
        for line in 0..lines {
            // SAFETY: prefetching is a hint that never faults; SSE is part of the
            // x86_64 baseline.
            unsafe {
                std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
                    start.wrapping_add(64 * line),
                );
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (address, lines);
}

/// Requests of at least this many bytes are served by [`RecyclingAllocator`] from
/// whole 2 MiB pages; smaller ones by the system allocator.
#[cfg(target_os = "linux")]
const BIG_BLOCK: usize = 2 << 20;

/// Freed blocks kept for reuse at most, and their total size.
#[cfg(target_os = "linux")]
const CACHED_BLOCKS: usize = 64;

/// The global allocator of the `raytracer` command: big blocks (2 MiB and more)
/// that are freed are kept and handed out again for the next big request, instead
/// of being given back to the system and asked for afresh.
///
/// A render allocates far more big buffers over its life than it holds at once
/// (the dragon: the description, then the builder's references and node slots, then
/// the packets; about 200 MB in all for a peak of 110), and every fresh page costs
/// the kernel a page fault and zeroing it: about 0.5 ms per MB on the virtual
/// machines measured, a fifth of the whole process's CPU time. A recycled block
/// costs nothing (or a `memset` at memory speed for a zeroed request). At most
/// `cache_limit` bytes are kept, so the peak memory grows by no more than that,
/// and only while no request takes them.
///
/// Big blocks are whole 2 MiB pages mapped by `mmap` at 2 MiB boundaries (so that
/// the advice to use huge pages covers all of them), split when a request needs less
/// than a kept block holds, and gathered by `mremap` when it needs more than any one
/// holds. Only pages in memory are kept: those never written cost nothing to map
/// afresh. Everything else goes to the system allocator. Outside Linux this is the
/// system allocator.
pub struct RecyclingAllocator {
    #[cfg(target_os = "linux")]
    cache: std::sync::Mutex<BlockCache>,
}

#[cfg(target_os = "linux")]
struct BlockCache {
    /// Kept blocks `(address, bytes)`, oldest first, `bytes` a multiple of 2 MiB.
    blocks: [(usize, usize); CACHED_BLOCKS],
    count: usize,
    limit: usize,
}

impl RecyclingAllocator {
    /// An allocator keeping at most `cache_limit` bytes of freed big blocks.
    pub const fn new(cache_limit: usize) -> RecyclingAllocator {
        #[cfg(not(target_os = "linux"))]
        let _ = cache_limit;
        RecyclingAllocator {
            #[cfg(target_os = "linux")]
            cache: std::sync::Mutex::new(BlockCache {
                blocks: [(0, 0); CACHED_BLOCKS],
                count: 0,
                limit: cache_limit,
            }),
        }
    }

    /// Bytes of freed blocks kept now.
    pub fn cached_bytes(&self) -> usize {
        #[cfg(target_os = "linux")]
        {
            let cache = self.lock();
            cache.blocks[..cache.count].iter().map(|b| b.1).sum()
        }
        #[cfg(not(target_os = "linux"))]
        0
    }
}

#[cfg(target_os = "linux")]
impl RecyclingAllocator {
    fn lock(&self) -> std::sync::MutexGuard<'_, BlockCache> {
        // Nothing inside the lock can panic; a poisoned lock is still consistent.
        self.cache
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Whether a request of this layout is a big block.
    fn is_big(layout: std::alloc::Layout) -> bool {
        layout.size() >= BIG_BLOCK && layout.align() <= HUGE_PAGE_BYTES
    }

    /// A big block of at least `size` bytes: a kept one if one is large enough (the
    /// smallest such, its rest kept), else a fresh address range into which kept
    /// blocks are moved, largest first, and which fresh pages fill up. Returns null if
    /// the system has no memory, and whether any kept pages were used.
    fn take(&self, size: usize) -> (*mut u8, bool) {
        let bytes = size.next_multiple_of(HUGE_PAGE_BYTES);
        let mut cache = self.lock();
        let count = cache.count;
        let best = (0..count)
            .filter(|&i| cache.blocks[i].1 >= bytes)
            .min_by_key(|&i| cache.blocks[i].1);
        if let Some(i) = best {
            let address = cache.blocks[i].0;
            cache.take_front(i, bytes);
            return (address as *mut u8, true);
        }
        let block = map_aligned(bytes);
        if block.is_null() || count == 0 {
            return (block, false);
        }
        // No kept block is large enough, but their pages in memory are worth more
        // than fresh ones: the packets the dragon's build makes (38 MB) are bigger
        // than any block freed before them, yet all those blocks together hold 30
        // MB of pages in memory. `mremap` moves pages, not bytes.
        let mut filled = 0;
        while filled < bytes && cache.count > 0 {
            let count = cache.count;
            let i = (0..count)
                .max_by_key(|&i| cache.blocks[i].1)
                .expect("count > 0");
            let (address, kept) = cache.blocks[i];
            let wanted = kept.min(bytes - filled);
            let Some(moved) = move_pages(address, wanted, block as usize + filled) else {
                // A hole in the new block that could not be filled: give it all back
                // (with what was moved into it).
                drop(cache);
                unmap(block as usize, bytes);
                return (std::ptr::null_mut(), false);
            };
            cache.take_front(i, moved);
            filled += moved;
            if moved < wanted {
                break;
            }
        }
        (block, filled > 0)
    }

    /// Keeps the pages of the big block `(address, size)` that are in memory,
    /// giving back the rest (fresh pages never written cost nothing to map again)
    /// and the oldest kept blocks beyond the limit.
    fn keep(&self, address: *mut u8, size: usize) {
        let bytes = size.next_multiple_of(HUGE_PAGE_BYTES);
        let start = address as usize;
        // Runs of 2 MiB pages alike in being in memory or not.
        let mut run_start = start;
        let mut run_resident = false;
        for chunk in (start..start + bytes).step_by(HUGE_PAGE_BYTES) {
            let resident = in_memory(chunk);
            if resident != run_resident && chunk > run_start {
                self.keep_or_unmap(run_start, chunk - run_start, run_resident);
                run_start = chunk;
            }
            run_resident = resident;
        }
        self.keep_or_unmap(run_start, start + bytes - run_start, run_resident);
    }

    /// Keeps a run of pages in memory (`resident`) as one block, or gives back one
    /// of pages never written.
    fn keep_or_unmap(&self, address: usize, bytes: usize, resident: bool) {
        if !resident {
            unmap(address, bytes);
            return;
        }
        let mut cache = self.lock();
        if bytes > cache.limit {
            drop(cache);
            unmap(address, bytes);
            return;
        }
        let mut total: usize = cache.blocks[..cache.count].iter().map(|b| b.1).sum();
        while cache.count > 0 && (cache.count == CACHED_BLOCKS || total + bytes > cache.limit) {
            let (oldest, oldest_bytes) = cache.remove(0);
            total -= oldest_bytes;
            unmap(oldest, oldest_bytes);
        }
        let count = cache.count;
        cache.blocks[count] = (address, bytes);
        cache.count += 1;
    }
}

#[cfg(target_os = "linux")]
impl BlockCache {
    /// Hands out the first `bytes` of kept block `i`, keeping its rest.
    fn take_front(&mut self, i: usize, bytes: usize) {
        let (address, kept) = self.blocks[i];
        if kept > bytes {
            self.blocks[i] = (address + bytes, kept - bytes);
        } else {
            self.remove(i);
        }
    }

    /// Takes kept block `i` out of the cache, keeping the others' order.
    fn remove(&mut self, i: usize) -> (usize, usize) {
        let block = self.blocks[i];
        let count = self.count;
        self.blocks.copy_within(i + 1..count, i);
        self.count -= 1;
        block
    }
}

/// Whether any 4 KiB page of the 2 MiB page at `chunk` is in memory.
#[cfg(target_os = "linux")]
fn in_memory(chunk: usize) -> bool {
    let mut resident = [0u8; HUGE_PAGE_BYTES / 4096];
    // SAFETY: the range is mapped (a big block's page); `resident` has a byte per
    // 4 KiB page of it.
    let known = unsafe {
        libc::mincore(
            chunk as *mut libc::c_void,
            HUGE_PAGE_BYTES,
            resident.as_mut_ptr(),
        )
    } == 0;
    !known || resident.iter().any(|&r| r & 1 == 1)
}

/// Moves the pages of `bytes` (whole 2 MiB pages) at `from` to `to`, which must be
/// mapped by us, one 2 MiB page at a time (a page lies in one mapping, as `mremap`
/// needs, where a longer range may not). Returns the bytes moved, which stop short
/// at the first page that cannot be moved (that page of `to` is mapped afresh), or
/// `None` if `to` was left with a hole.
#[cfg(target_os = "linux")]
fn move_pages(from: usize, bytes: usize, to: usize) -> Option<usize> {
    for offset in (0..bytes).step_by(HUGE_PAGE_BYTES) {
        // SAFETY: both pages are ours: `from`'s a kept block's, which nothing else
        // uses, and `to`'s in the block being made; the old page is unmapped by the
        // move and leaves the cache with it.
        let moved = unsafe {
            libc::mremap(
                (from + offset) as *mut libc::c_void,
                HUGE_PAGE_BYTES,
                HUGE_PAGE_BYTES,
                libc::MREMAP_MAYMOVE | libc::MREMAP_FIXED,
                (to + offset) as *mut libc::c_void,
            )
        };
        if moved != libc::MAP_FAILED {
            continue;
        }
        // A failed move may have unmapped the target first: map it again.
        // SAFETY: `to + offset` is a page of the block being made.
        let remapped = unsafe {
            libc::mmap(
                (to + offset) as *mut libc::c_void,
                HUGE_PAGE_BYTES,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_PRIVATE | libc::MAP_ANONYMOUS | libc::MAP_FIXED,
                -1,
                0,
            )
        };
        return (remapped != libc::MAP_FAILED).then_some(offset);
    }
    Some(bytes)
}

/// Fresh pages of `bytes` (a multiple of 2 MiB) at a 2 MiB boundary, or null.
#[cfg(target_os = "linux")]
fn map_aligned(bytes: usize) -> *mut u8 {
    let Some(mapped) = bytes.checked_add(HUGE_PAGE_BYTES) else {
        return std::ptr::null_mut();
    };
    // SAFETY: an anonymous private mapping that nothing else refers to.
    let start = unsafe {
        libc::mmap(
            std::ptr::null_mut(),
            mapped,
            libc::PROT_READ | libc::PROT_WRITE,
            libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
            -1,
            0,
        )
    };
    if start == libc::MAP_FAILED {
        return std::ptr::null_mut();
    }
    let start = start as usize;
    let aligned = start.next_multiple_of(HUGE_PAGE_BYTES);
    // The mapping's pages before the boundary and after the block go back.
    unmap(start, aligned - start);
    unmap(aligned + bytes, start + mapped - (aligned + bytes));
    if HUGE_PAGES_DEAR.load(std::sync::atomic::Ordering::Relaxed) {
        // Small pages, in case huge ones are the system's default.
        // SAFETY: advice on the block just mapped, which changes no contents.
        unsafe { libc::madvise(aligned as *mut libc::c_void, bytes, libc::MADV_NOHUGEPAGE) };
    }
    aligned as *mut u8
}

/// Zeroes the first `size` bytes of a kept block: pages in memory with `memset`,
/// the others (never written, or given back: a block reserved and freed unused, as a
/// fallible `try_reserve` check does) by giving them back again, which costs no
/// page fault now and reads as zeroes later (and discards any swapped-out contents).
///
/// # Safety
/// `block` must be page aligned and own whole pages covering `size` bytes.
#[cfg(target_os = "linux")]
unsafe fn zero_pages(block: *mut u8, size: usize) {
    const PAGE: usize = 4096;
    const WINDOW: usize = 1024;
    let pages = size.div_ceil(PAGE);
    let mut resident = [0u8; WINDOW];
    let mut page = 0;
    while page < pages {
        let count = WINDOW.min(pages - page);
        let window = block as usize + page * PAGE;
        // SAFETY: the window lies in the block; `resident` has a byte per page.
        let known = unsafe {
            libc::mincore(
                window as *mut libc::c_void,
                count * PAGE,
                resident.as_mut_ptr(),
            )
        } == 0;
        let mut run = 0;
        while run < count {
            let in_memory = !known || resident[run] & 1 == 1;
            let end = (run..count)
                .find(|&p| (!known || resident[p] & 1 == 1) != in_memory)
                .unwrap_or(count);
            let start = window + run * PAGE;
            if in_memory {
                let bytes = (end - run) * PAGE;
                let bytes = bytes.min(block as usize + size - start);
                // SAFETY: inside the block.
                unsafe { (start as *mut u8).write_bytes(0, bytes) };
            } else {
                // SAFETY: whole pages of the block, which nothing else uses.
                unsafe {
                    libc::madvise(
                        start as *mut libc::c_void,
                        (end - run) * PAGE,
                        libc::MADV_DONTNEED,
                    )
                };
            }
            run = end;
        }
        page += count;
    }
}

#[cfg(target_os = "linux")]
fn unmap(address: usize, bytes: usize) {
    if bytes > 0 {
        // SAFETY: the callers own these whole pages of a mapping made by
        // `map_aligned` and no longer hand them out.
        unsafe { libc::munmap(address as *mut libc::c_void, bytes) };
    }
}

// SAFETY: big blocks are whole pages owned by exactly one allocation at a time (kept
// blocks are in the cache only, and a block taken from it leaves it), aligned to
// 2 MiB, which satisfies every alignment they are used for; the rest is `System`.
#[cfg(target_os = "linux")]
unsafe impl std::alloc::GlobalAlloc for RecyclingAllocator {
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        if !Self::is_big(layout) {
            // SAFETY: forwarded as received.
            return unsafe { std::alloc::System.alloc(layout) };
        }
        self.take(layout.size()).0
    }

    unsafe fn alloc_zeroed(&self, layout: std::alloc::Layout) -> *mut u8 {
        if !Self::is_big(layout) {
            // SAFETY: forwarded as received.
            return unsafe { std::alloc::System.alloc_zeroed(layout) };
        }
        let (block, recycled) = self.take(layout.size());
        if recycled {
            // SAFETY: the block is ours, of whole pages covering `layout.size()`.
            // Fresh pages read as zeroes already.
            unsafe { zero_pages(block, layout.size()) };
        }
        block
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
        if Self::is_big(layout) {
            self.keep(ptr, layout.size());
        } else {
            // SAFETY: a small block comes from `System` with this layout.
            unsafe { std::alloc::System.dealloc(ptr, layout) }
        }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: std::alloc::Layout, new_size: usize) -> *mut u8 {
        // SAFETY: `layout.align()` is valid and `new_size` does not overflow when
        // rounded up to it (the caller's contract).
        let new_layout =
            unsafe { std::alloc::Layout::from_size_align_unchecked(new_size, layout.align()) };
        match (Self::is_big(layout), Self::is_big(new_layout)) {
            // SAFETY: forwarded as received.
            (false, false) => unsafe { std::alloc::System.realloc(ptr, layout, new_size) },
            (true, true)
                if new_size.next_multiple_of(HUGE_PAGE_BYTES)
                    == layout.size().next_multiple_of(HUGE_PAGE_BYTES) =>
            {
                ptr
            }
            _ => {
                // SAFETY: as `alloc`, then a copy between two live blocks of at least
                // the copied length, then the old block is freed as it was made.
                unsafe {
                    let new = self.alloc(new_layout);
                    if !new.is_null() {
                        std::ptr::copy_nonoverlapping(ptr, new, layout.size().min(new_size));
                        self.dealloc(ptr, layout);
                    }
                    new
                }
            }
        }
    }
}

#[cfg(not(target_os = "linux"))]
// SAFETY: every call forwarded to `System` as received.
unsafe impl std::alloc::GlobalAlloc for RecyclingAllocator {
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        unsafe { std::alloc::System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: std::alloc::Layout) -> *mut u8 {
        unsafe { std::alloc::System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
        unsafe { std::alloc::System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: std::alloc::Layout, new_size: usize) -> *mut u8 {
        unsafe { std::alloc::System.realloc(ptr, layout, new_size) }
    }
}

/// The line `field` (such as `"Rss:"`) of `/proc/self/smaps` for the mapping holding
/// `address`, without its name: for tests of how memory is backed.
#[cfg(all(test, target_os = "linux"))]
pub(crate) fn smaps_field(address: usize, field: &str) -> String {
    let smaps = std::fs::read_to_string("/proc/self/smaps").unwrap();
    let mut inside = false;
    for line in smaps.lines() {
        let range = line.split_whitespace().next().unwrap_or("");
        if let Some((start, end)) = range.split_once('-')
            && let (Ok(start), Ok(end)) = (
                usize::from_str_radix(start, 16),
                usize::from_str_radix(end, 16),
            )
        {
            inside = (start..end).contains(&address);
        } else if inside && let Some(value) = line.strip_prefix(field) {
            return value.to_string();
        }
    }
    panic!("no mapping holds {address:#x}");
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use std::alloc::{GlobalAlloc, Layout};

    use super::*;

    const MIB: usize = 1 << 20;

    fn layout(bytes: usize) -> Layout {
        Layout::from_size_align(bytes, 64).unwrap()
    }

    /// A freed big block serves the next big request that fits (the smallest
    /// that does), its rest kept for another; small requests never touch the cache.
    #[test]
    fn freed_big_blocks_are_handed_out_again() {
        let allocator = RecyclingAllocator::new(64 * MIB);
        unsafe {
            let a = allocator.alloc(layout(9 * MIB));
            let b = allocator.alloc(layout(5 * MIB));
            assert_eq!(a as usize % HUGE_PAGE_BYTES, 0, "big blocks start on 2 MiB");
            a.write_bytes(1, 9 * MIB);
            b.write_bytes(2, 5 * MIB);
            allocator.dealloc(a, layout(9 * MIB));
            allocator.dealloc(b, layout(5 * MIB));
            assert_eq!(allocator.cached_bytes(), 16 * MIB);
            let small = allocator.alloc(layout(1000));
            assert_eq!(allocator.cached_bytes(), 16 * MIB);
            allocator.dealloc(small, layout(1000));
            // 3 MiB takes 4 MiB of the 6 MiB block, not of the 10 MiB one.
            let c = allocator.alloc(layout(3 * MIB));
            assert_eq!(c, b);
            assert_eq!(allocator.cached_bytes(), 12 * MIB);
            let d = allocator.alloc(layout(10 * MIB));
            assert_eq!(d, a);
            assert_eq!(allocator.cached_bytes(), 2 * MIB);
            allocator.dealloc(c, layout(3 * MIB));
            allocator.dealloc(d, layout(10 * MIB));
        }
    }

    /// A zeroed request served from a used block reads as zeroes, both where the
    /// block was written (in memory) and where it never was.
    #[test]
    fn recycled_zeroed_blocks_are_zero() {
        let allocator = RecyclingAllocator::new(64 * MIB);
        unsafe {
            let a = allocator.alloc(layout(8 * MIB));
            // Half written, half never touched: every other 4 KiB page, so that
            // each 2 MiB page is kept and the pages in memory come in many runs.
            for page in (0..2048).step_by(2) {
                a.add(page * 4096).write_bytes(0xab, 4096);
            }
            allocator.dealloc(a, layout(8 * MIB));
            let b = allocator.alloc_zeroed(layout(8 * MIB - 100));
            assert_eq!(a, b);
            let bytes = std::slice::from_raw_parts(b, 8 * MIB - 100);
            assert!(bytes.iter().all(|&x| x == 0));
            allocator.dealloc(b, layout(8 * MIB - 100));
        }
    }

    /// No more than the limit is kept: the oldest blocks go back first, and a
    /// block larger than the limit goes back at once.
    #[test]
    fn kept_blocks_stay_within_the_limit() {
        let allocator = RecyclingAllocator::new(10 * MIB);
        unsafe {
            let blocks: Vec<*mut u8> = (0..3).map(|_| allocator.alloc(layout(4 * MIB))).collect();
            let big = allocator.alloc(layout(12 * MIB));
            for &block in &blocks {
                block.write_bytes(3, 4 * MIB);
            }
            big.write_bytes(4, 12 * MIB);
            for &block in &blocks {
                allocator.dealloc(block, layout(4 * MIB));
            }
            assert_eq!(allocator.cached_bytes(), 8 * MIB);
            allocator.dealloc(big, layout(12 * MIB));
            assert_eq!(allocator.cached_bytes(), 8 * MIB);
            // The two kept are the last two freed.
            assert_eq!(allocator.alloc(layout(4 * MIB)), blocks[1]);
            assert_eq!(allocator.alloc(layout(4 * MIB)), blocks[2]);
            assert_eq!(allocator.cached_bytes(), 0);
            allocator.dealloc(blocks[1], layout(4 * MIB));
            allocator.dealloc(blocks[2], layout(4 * MIB));
        }
    }

    /// Growing a big block within its 2 MiB pages keeps it in place; beyond them,
    /// or from a small block, the contents move.
    #[test]
    fn realloc_keeps_contents() {
        let allocator = RecyclingAllocator::new(64 * MIB);
        unsafe {
            let small = allocator.alloc(layout(1000));
            small.write_bytes(7, 1000);
            let a = allocator.realloc(small, layout(1000), 3 * MIB);
            assert!(std::slice::from_raw_parts(a, 1000).iter().all(|&x| x == 7));
            a.add(1000).write_bytes(8, 3 * MIB - 1000);
            let b = allocator.realloc(a, layout(3 * MIB), 4 * MIB);
            assert_eq!(a, b, "within the same pages");
            let c = allocator.realloc(b, layout(4 * MIB), 9 * MIB);
            let moved = std::slice::from_raw_parts(c, 3 * MIB);
            assert!(moved[..1000].iter().all(|&x| x == 7));
            assert!(moved[1000..].iter().all(|&x| x == 8));
            let d = allocator.realloc(c, layout(9 * MIB), 500);
            assert!(std::slice::from_raw_parts(d, 500).iter().all(|&x| x == 7));
            allocator.dealloc(d, layout(500));
        }
    }

    /// Only the 2 MiB pages of a freed block that were written are kept; the
    /// others go back to the system.
    #[test]
    fn only_pages_in_memory_are_kept() {
        let allocator = RecyclingAllocator::new(64 * MIB);
        unsafe {
            let a = allocator.alloc(layout(8 * MIB));
            a.write_bytes(5, 100);
            a.add(4 * MIB + 10).write(6);
            allocator.dealloc(a, layout(8 * MIB));
            assert_eq!(allocator.cached_bytes(), 4 * MIB);
            // The two kept pages are separate blocks: a 4 MiB request fits in
            // neither and gathers both.
            let b = allocator.alloc(layout(2 * MIB));
            assert!(b == a || b == a.add(4 * MIB));
            allocator.dealloc(b, layout(2 * MIB));
        }
    }

    /// A request bigger than every kept block gets their pages, moved into one
    /// range (largest first) with their contents, and fresh pages for the rest.
    #[test]
    fn kept_blocks_are_gathered_for_a_bigger_request() {
        let allocator = RecyclingAllocator::new(64 * MIB);
        unsafe {
            let a = allocator.alloc(layout(2 * MIB));
            let b = allocator.alloc(layout(4 * MIB));
            a.write_bytes(0xaa, 2 * MIB);
            b.write_bytes(0xbb, 4 * MIB);
            allocator.dealloc(a, layout(2 * MIB));
            allocator.dealloc(b, layout(4 * MIB));
            assert_eq!(allocator.cached_bytes(), 6 * MIB);
            let c = allocator.alloc(layout(10 * MIB));
            assert_eq!(allocator.cached_bytes(), 0, "both kept blocks are used");
            let bytes = std::slice::from_raw_parts_mut(c, 10 * MIB);
            assert!(bytes[..4 * MIB].iter().all(|&x| x == 0xbb));
            assert!(bytes[4 * MIB..6 * MIB].iter().all(|&x| x == 0xaa));
            assert!(bytes[6 * MIB..].iter().all(|&x| x == 0));
            bytes.fill(0xcc);
            allocator.dealloc(c, layout(10 * MIB));
            // Gathered into a zeroed request, the kept pages read as zeroes too.
            let d = allocator.alloc_zeroed(layout(16 * MIB));
            assert_eq!(allocator.cached_bytes(), 0);
            let bytes = std::slice::from_raw_parts(d, 16 * MIB);
            assert!(bytes.iter().all(|&x| x == 0));
            allocator.dealloc(d, layout(16 * MIB));
        }
    }

    /// The `VmFlags` line of `/proc/self/smaps` for the mapping holding `address`.
    fn vm_flags(address: usize) -> String {
        smaps_field(address, "VmFlags:")
    }

    /// Even once huge pages have been found dear, a collapse asks for them (the
    /// mapping is marked `hg`, where the kernel has transparent huge pages) and keeps
    /// the contents.
    #[test]
    fn collapse_asks_for_huge_pages_and_keeps_contents() {
        let data: Vec<u32> = (0..2 * MIB as u32).collect();
        find_huge_pages_dear();
        advise_huge_pages(&data);
        let inside = (data.as_ptr() as usize).next_multiple_of(HUGE_PAGE_BYTES);
        collapse_into_huge_pages(&data);
        assert!(data.iter().enumerate().all(|(i, &x)| x == i as u32));
        if thp_supported() {
            assert!(vm_flags(inside).contains(" hg"), "{}", vm_flags(inside));
        }
    }

    /// Once huge pages have been found dear, fresh blocks and buffers written end
    /// to end ask for small pages; and backing a buffer keeps its contents.
    #[test]
    fn dear_huge_pages_give_small_pages() {
        let mut data: Vec<u8> = Vec::with_capacity(8 * MIB);
        data.extend((0..3 * MIB).map(|i| i as u8));
        // Whatever it costs here, the buffer's contents stay.
        advise_huge_pages(&data);
        assert!(data.iter().enumerate().all(|(i, &x)| x == i as u8));

        HUGE_PAGES_DEAR.store(true, std::sync::atomic::Ordering::Relaxed);
        let allocator = RecyclingAllocator::new(64 * MIB);
        unsafe {
            let a = allocator.alloc(layout(4 * MIB));
            assert!(
                vm_flags(a as usize).contains(" nh"),
                "{}",
                vm_flags(a as usize)
            );
            allocator.dealloc(a, layout(4 * MIB));
        }
        let v: Vec<u64> = Vec::with_capacity(MIB);
        advise_huge_pages(&v);
        let page = (v.as_ptr() as usize).next_multiple_of(HUGE_PAGE_BYTES);
        assert!(vm_flags(page).contains(" nh"), "{}", vm_flags(page));
    }
}
