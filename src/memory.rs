//! Big fresh buffers backed by 2 MiB pages.
//!
//! The first write to each 4 KiB page of a fresh buffer takes a page fault, and on
//! the virtual machines this renderer is measured on a fault costs several
//! microseconds: touching 28 MB took 50 ms, the same buffer on 2 MiB pages 15 ms.
//! Linux backs a range with such transparent huge pages only when asked (`madvise`
//! mode is the usual default), so the few arrays of the scene build that are written
//! once from end to end ask for them.

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
