//! The C allocator between shoppers: giving the memory a visit freed back to the system
//! ([`release_free_memory`]) and the allocator's own statistics ([`heap_usage`]) for the
//! soak. glibc only; elsewhere both do nothing.
//!
//! Why: each frame pair allocates and frees image-sized buffers (the decoded frames,
//! masks, scratch of the stages). glibc serves the first of them with `mmap`, raises its
//! mmap threshold to their size when the first one is freed (mallopt(3), dynamic mmap
//! threshold), and from then on carves them out of the main heap, where they interleave
//! with longer-lived allocations. The heap's free space then grows in steps as the
//! pattern shifts, and glibc keeps it: `fitstation soak` measured the heap in use flat
//! over 8 minutes (two values to 0.1 MB, 149.9 and 168.7 MB, by where in a visit a
//! sample fell) while malloc's heap grew 206.2 -> 206.6 -> 209.0 MB and the resident
//! memory with it, 33 MB above (20 minutes: +4.6 MB in two steps, 21.6 MB per hour).
//! Pinning the mmap threshold (`M_MMAP_THRESHOLD` 128 kB to 2 MB, which also stops its
//! adjustment) stopped the steps in 5-minute runs but maps and faults in every large
//! buffer afresh: 17 % (2 MB) to 50 % (128 kB) more CPU time per frame pair, measured
//! on the same soak. Releasing the free pages once per visit, when the shopper has
//! left, costs one `malloc_trim` and the page faults of refilling the working set at
//! the next visit: 26.7 ms of CPU per frame pair with it against 27.6 ms without
//! (6-minute soaks on the shared machine, so within noise), and the resident memory
//! between visits stays at 184.4-184.6 MB.

/// Returns the allocator's free pages to the system (glibc `malloc_trim(0)`, all
/// arenas, which it locks while it walks them). Call it when the station is idle, e.g.
/// when the subject is cleared. True when memory was released.
pub fn release_free_memory() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: malloc_trim takes the arena locks itself and only returns free pages
        // to the system; no allocation is moved or freed.
        unsafe { libc::malloc_trim(0) == 1 }
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        false
    }
}

/// What the program holds from malloc and what malloc holds from the system.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct HeapUsage {
    /// Bytes in allocations the program holds (`uordblks + hblkhd`).
    pub in_use_bytes: u64,
    /// Bytes malloc has from the system, in use or free (`arena + hblkhd`).
    pub mapped_bytes: u64,
}

/// The allocator's statistics over all arenas (glibc `mallinfo2`); zeros elsewhere.
pub fn heap_usage() -> HeapUsage {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: mallinfo2 only reads the allocator's statistics (it takes the arena
        // locks itself) and returns a plain struct.
        let mi = unsafe { libc::mallinfo2() };
        HeapUsage {
            in_use_bytes: (mi.uordblks + mi.hblkhd) as u64,
            mapped_bytes: (mi.arena + mi.hblkhd) as u64,
        }
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        HeapUsage::default()
    }
}
