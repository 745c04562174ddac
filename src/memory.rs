//! Big buffers: fresh ones backed by 2 MiB pages, freed ones reused.
//!
//! The first write to each 4 KiB page of a fresh buffer takes a page fault, and on
//! the virtual machines this renderer is measured on a fault costs several
//! microseconds: touching 28 MB took 50 ms, the same buffer on 2 MiB pages 15 ms.
//! Linux backs a range with such transparent huge pages only when asked (`madvise`
//! mode is the usual default), so the few arrays of the scene build that are written
//! once from end to end ask for them. The `raytracer` command's global allocator,
//! [`RecyclingAllocator`], goes further: big blocks freed are handed out again, so
//! that most big buffers need no fresh pages at all.

/// A vector of `len` zeroed elements whose buffer Linux is asked to back with huge
/// pages. The zeroes come from a zeroed allocation (`calloc`, fresh pages for big
/// sizes), so nothing is written before the advice takes effect.
pub(crate) fn zeroed_vec<T: bytemuck::Zeroable>(len: usize) -> Vec<T> {
    let v = bytemuck::zeroed_vec(len);
    advise_huge_pages(&v);
    v
}

/// Asks Linux to back the part of `v`'s buffer that covers whole 2 MiB pages with
/// huge pages. Call it before the buffer is first written; the advice only costs
/// memory for pages that end up touched.
pub(crate) fn advise_huge_pages<T>(v: &Vec<T>) {
    #[cfg(target_os = "linux")]
    {
        const HUGE_PAGE: usize = 2 << 20;
        let start = v.as_ptr() as usize;
        let end = start + v.capacity() * size_of::<T>();
        let aligned_start = start.next_multiple_of(HUGE_PAGE);
        let aligned_end = end / HUGE_PAGE * HUGE_PAGE;
        if aligned_end > aligned_start {
            // SAFETY: the range lies inside `v`'s allocation and starts on a page
            // boundary; `MADV_HUGEPAGE` changes how pages are backed, never their
            // contents. Failure (no THP support) leaves ordinary pages, so the result
            // is ignored.
            unsafe {
                libc::madvise(
                    aligned_start as *mut libc::c_void,
                    aligned_end - aligned_start,
                    libc::MADV_HUGEPAGE,
                );
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = v;
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
    #[cfg(target_arch = "x86_64")]
    {
        let start = (address as usize & !63) as *const i8;
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

/// The 2 MiB page of x86-64 and aarch64 Linux.
#[cfg(target_os = "linux")]
const HUGE_PAGE_BYTES: usize = 2 << 20;

/// Freed blocks kept for reuse at most, and their total size.
#[cfg(target_os = "linux")]
const CACHED_BLOCKS: usize = 8;

/// The global allocator of the `raytracer` command: big blocks (2 MiB and more)
/// that are freed are kept and handed out again for the next big request, instead
/// of being given back to the system and asked for afresh.
///
/// A render allocates far more big buffers over its life than it holds at once
/// (the dragon: the file's text, then the builder's references and node slots, then
/// the packets; about 200 MB in all for a peak of 120), and every fresh page costs
/// the kernel a page fault and zeroing it: about 0.5 ms per MB on the virtual
/// machines measured, a fifth of the whole process's CPU time. A recycled block
/// costs nothing (or a `memset` at memory speed for a zeroed request). At most
/// `cache_limit` bytes are kept, so the peak memory grows by no more than that,
/// and only while no request takes them.
///
/// Big blocks are whole 2 MiB pages mapped by `mmap` at 2 MiB boundaries (so that
/// the advice to use huge pages covers all of them), split when a request needs less than
/// a kept block holds; everything else goes to the system allocator. Outside Linux
/// this is the system allocator.
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
    /// smallest such, its rest kept), else fresh pages. Null if the system has none.
    fn take(&self, size: usize) -> (*mut u8, bool) {
        let bytes = size.next_multiple_of(HUGE_PAGE_BYTES);
        {
            let mut cache = self.lock();
            let count = cache.count;
            let best = (0..count)
                .filter(|&i| cache.blocks[i].1 >= bytes)
                .min_by_key(|&i| cache.blocks[i].1);
            if let Some(i) = best {
                let (address, kept) = cache.blocks[i];
                if kept > bytes {
                    cache.blocks[i] = (address + bytes, kept - bytes);
                } else {
                    cache.blocks.copy_within(i + 1..count, i);
                    cache.count -= 1;
                }
                return (address as *mut u8, true);
            }
        }
        (map_aligned(bytes), false)
    }

    /// Keeps the big block `(address, size)`, giving back the oldest kept blocks
    /// (or this one) beyond the limit.
    fn keep(&self, address: *mut u8, size: usize) {
        let bytes = size.next_multiple_of(HUGE_PAGE_BYTES);
        let mut cache = self.lock();
        if bytes > cache.limit {
            drop(cache);
            unmap(address as usize, bytes);
            return;
        }
        let mut total: usize = cache.blocks[..cache.count].iter().map(|b| b.1).sum();
        while cache.count > 0 && (cache.count == CACHED_BLOCKS || total + bytes > cache.limit) {
            let (oldest, oldest_bytes) = cache.blocks[0];
            let count = cache.count;
            cache.blocks.copy_within(1..count, 0);
            cache.count -= 1;
            total -= oldest_bytes;
            unmap(oldest, oldest_bytes);
        }
        let count = cache.count;
        cache.blocks[count] = (address as usize, bytes);
        cache.count += 1;
    }
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
            // Half written, half never touched; the written part in odd pages only,
            // so that the pages in memory come in many runs.
            for page in (0..1024).step_by(2) {
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
}
