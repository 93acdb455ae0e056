//! Read-only arrays on 2 MB pages, for the tree arrays the traversal reads at random.
//!
//! A bunny frame walks a 5.6 MB tree (nodes and leaf packets) at random, about 1 400 pages
//! of 4 KB against a first-level TLB of 64 entries (Zen 3), so most node loads also miss
//! the TLB, and in a VM each miss walks two page tables. Arrays of a megabyte or more are
//! therefore mapped on their own, 2 MB aligned, and Linux is asked to back them with
//! transparent huge pages (`madvise(MADV_HUGEPAGE)`, before their first touch: kernels
//! set to `madvise`, this project's machines among them, give huge pages only to memory
//! that asks). Where the kernel has none to give, the advice fails or is ignored and the
//! array stays on small pages; nothing else changes. Smaller arrays, and other systems,
//! use an ordinary allocation.

use std::ops::Deref;
use std::ptr::NonNull;

/// The page size asked for.
const HUGE: usize = 2 << 20;
/// Arrays from this size up get their own mapping (rounded up to whole huge pages).
const MIN_BYTES: usize = 1 << 20;

/// A fixed array of `T`, on huge pages where it is large and the system gives them.
pub(super) struct LargePages<T> {
    /// The first element (dangling when empty); valid for `len` elements while
    /// `owner` lives.
    ptr: NonNull<T>,
    len: usize,
    owner: Owner<T>,
}

/// What holds the elements' memory.
enum Owner<T> {
    Heap(#[allow(dead_code)] Box<[T]>),
    #[cfg(target_os = "linux")]
    Mapped {
        base: *mut libc::c_void,
        len: usize,
    },
}

// SAFETY: the array owns its elements (a box or a private mapping) and hands out only
// shared references, as a `Box<[T]>` would.
unsafe impl<T: Send> Send for LargePages<T> {}
// SAFETY: as above; `&LargePages<T>` gives only `&[T]`.
unsafe impl<T: Sync> Sync for LargePages<T> {}

impl<T: Copy> LargePages<T> {
    /// A copy of `items`.
    pub(super) fn new(items: &[T]) -> Self {
        #[cfg(target_os = "linux")]
        if std::mem::size_of_val(items) >= MIN_BYTES {
            if let Some(mapped) = Self::mapped(items) {
                return mapped;
            }
        }
        let boxed: Box<[T]> = items.into();
        let ptr = NonNull::new(boxed.as_ptr().cast_mut()).unwrap_or(NonNull::dangling());
        Self { ptr, len: items.len(), owner: Owner::Heap(boxed) }
    }

    /// A copy of `items` in a private anonymous mapping advised to huge pages; `None`
    /// when the mapping fails (the caller falls back to the heap).
    #[cfg(target_os = "linux")]
    fn mapped(items: &[T]) -> Option<Self> {
        let bytes = std::mem::size_of_val(items).next_multiple_of(HUGE);
        // One huge page more than needed, so that an aligned start lies inside.
        let len = bytes + HUGE;
        // SAFETY: a fresh private anonymous mapping; no existing memory is touched.
        let base = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                len,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                -1,
                0,
            )
        };
        if base == libc::MAP_FAILED {
            return None;
        }
        let offset = (base as usize).next_multiple_of(HUGE) - base as usize;
        // SAFETY: `offset + bytes <= len`, inside the mapping.
        let start = unsafe { base.cast::<u8>().add(offset) };
        // SAFETY: advice on a range of our own mapping, before any page of it is touched;
        // its failure (no transparent huge pages here) leaves ordinary pages.
        unsafe { libc::madvise(start.cast(), bytes, libc::MADV_HUGEPAGE) };
        let ptr = NonNull::new(start.cast::<T>())?;
        // SAFETY: `start` is 2 MB aligned (so aligned for `T`, whose alignment is far
        // smaller), writable for `bytes >= size_of_val(items)`, and not `items`' memory.
        unsafe { std::ptr::copy_nonoverlapping(items.as_ptr(), ptr.as_ptr(), items.len()) };
        Some(Self { ptr, len: items.len(), owner: Owner::Mapped { base, len } })
    }

    /// Whether the elements start on a huge-page boundary (they have their own mapping).
    #[cfg(test)]
    fn is_mapped(&self) -> bool {
        !matches!(self.owner, Owner::Heap(_))
    }
}

impl<T> Deref for LargePages<T> {
    type Target = [T];

    #[inline(always)]
    fn deref(&self) -> &[T] {
        // SAFETY: `ptr` is valid for `len` initialised elements while `owner` lives.
        unsafe { std::slice::from_raw_parts(self.ptr.as_ptr(), self.len) }
    }
}

impl<T> Drop for LargePages<T> {
    fn drop(&mut self) {
        #[cfg(target_os = "linux")]
        if let Owner::Mapped { base, len } = self.owner {
            // SAFETY: the whole mapping made in `mapped`, unmapped once; `T: Copy` needs
            // no drop. A failure could only leak the range.
            unsafe { libc::munmap(base, len) };
        }
    }
}

impl<T: Copy> Default for LargePages<T> {
    fn default() -> Self {
        Self::new(&[])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holds_a_copy_of_its_elements_at_every_size() {
        for n in [0usize, 1, 1000, MIN_BYTES / 4 - 1, MIN_BYTES / 4, 3 * HUGE / 4 + 5] {
            let items: Vec<u32> = (0..n as u32).map(|i| i.wrapping_mul(0x9e37_79b9)).collect();
            let pages = LargePages::new(&items);
            assert_eq!(&*pages, &items[..], "{n} elements");
            // A megabyte and more gets its own huge-page aligned mapping on Linux.
            let large = n * 4 >= MIN_BYTES;
            assert_eq!(pages.is_mapped(), large && cfg!(target_os = "linux"), "{n} elements");
            if pages.is_mapped() {
                assert_eq!(pages.as_ptr() as usize % HUGE, 0);
            }
        }
    }

    #[test]
    fn is_shared_across_threads() {
        let pages = std::sync::Arc::new(LargePages::new(&vec![7u64; MIN_BYTES / 8 + 1]));
        let sums: Vec<u64> = (0..2)
            .map(|_| {
                let pages = pages.clone();
                std::thread::spawn(move || pages.iter().sum::<u64>())
            })
            .map(|t| t.join().unwrap())
            .collect();
        assert_eq!(sums, [7 * (MIN_BYTES as u64 / 8 + 1); 2]);
    }
}
