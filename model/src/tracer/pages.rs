//! Large arrays of a prepared scene in memory the kernel is asked to back with 2 MB pages: a walk
//! reads a few lines here and there across megabytes of nodes, far boxes and items, and with 4 KB
//! pages most of those reads also miss the TLB. On Linux an array of at least 1 MB gets a mapping
//! of its own, whole 2 MB pages aligned to 2 MB and advised `MADV_HUGEPAGE` before it is first
//! written (transparent huge pages in their default `madvise` mode back such a mapping with huge
//! pages where they are free); a smaller array, another system, or a mapping refused keeps an
//! ordinary allocation. The contents are the same either way: only where they live differs.

/// Bytes of a huge page.
const HUGE: usize = 2 << 20;

/// The least array mapped on its own: half a huge page, so the memory a mapping rounds up to whole
/// huge pages is at most the array's own size again.
const LEAST_MAPPED: usize = HUGE / 2;

/// An immutable array, in 2 MB pages where the system grants them (see the module comment). Its
/// values are read through `ptr` and `len` whatever holds them, so a read costs what a `Vec`'s does.
pub(crate) struct PageBacked<T: Copy> {
    /// `len` initialised values, held by `storage` until the array is dropped.
    ptr: std::ptr::NonNull<T>,
    len: usize,
    storage: Storage<T>,
}

enum Storage<T> {
    /// The values' own `Vec` (never changed or grown: its buffer stays where `ptr` points).
    Heap(#[allow(dead_code)] Vec<T>),
    /// A mapping of `bytes` bytes (a multiple of [`HUGE`]) starting at `ptr`.
    #[cfg(target_os = "linux")]
    Mapped { bytes: usize },
}

// SAFETY: a `PageBacked` owns its values as a `Vec` would (the mapping is its own, freed once, by
// `drop`) and hands out only shared references to them after it is made.
unsafe impl<T: Copy + Send> Send for PageBacked<T> {}
// SAFETY: as for `Send`: `&PageBacked` gives `&[T]` alone.
unsafe impl<T: Copy + Sync> Sync for PageBacked<T> {}

impl<T: Copy> PageBacked<T> {
    /// The values of `values`, moved to a mapping of their own where they fill a huge page.
    pub(crate) fn new(values: Vec<T>) -> PageBacked<T> {
        #[cfg(target_os = "linux")]
        if let Some(mapped) = Self::mapped(&values) {
            return mapped;
        }
        PageBacked {
            // Moving the `Vec` below leaves its buffer where it is.
            ptr: std::ptr::NonNull::from(values.as_slice()).cast::<T>(),
            len: values.len(),
            storage: Storage::Heap(values),
        }
    }

    #[cfg(target_os = "linux")]
    fn mapped(values: &[T]) -> Option<PageBacked<T>> {
        let size = std::mem::size_of_val(values);
        if size < LEAST_MAPPED || std::mem::align_of::<T>() > HUGE {
            return None;
        }
        let bytes = size.checked_next_multiple_of(HUGE)?;
        let spare = bytes.checked_add(HUGE)?;
        // SAFETY: an anonymous private mapping of `spare` bytes at an address the kernel picks;
        // the result is checked before use.
        let base = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                spare,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                -1,
                0,
            )
        };
        if base == libc::MAP_FAILED {
            return None;
        }
        // The 2 MB-aligned part of `bytes` bytes, and what lies before and after it given back.
        let head = (HUGE - base as usize % HUGE) % HUGE;
        let start = base as usize + head;
        let tail = spare - head - bytes;
        // SAFETY: both ranges lie inside the mapping made above and outside the part kept; a
        // zero-length range is skipped. A failure leaves memory mapped, never unmaps the part kept.
        unsafe {
            if head > 0 {
                libc::munmap(base, head);
            }
            if tail > 0 {
                libc::munmap((start + bytes) as *mut libc::c_void, tail);
            }
            // Advice only: where it is refused the pages are ordinary ones.
            libc::madvise(start as *mut libc::c_void, bytes, libc::MADV_HUGEPAGE);
        }
        // A successful mapping is never at address 0 (no fixed address was asked for).
        let ptr = std::ptr::NonNull::new(start as *mut T)?;
        // SAFETY: the mapping holds `bytes ≥ size` writable bytes at `ptr`, aligned to 2 MB (so
        // to `T`), and does not overlap `values`.
        unsafe { std::ptr::copy_nonoverlapping(values.as_ptr(), ptr.as_ptr(), values.len()) };
        Some(PageBacked {
            ptr,
            len: values.len(),
            storage: Storage::Mapped { bytes },
        })
    }

    /// Whether the values have a mapping of their own (advised for huge pages).
    #[cfg(test)]
    pub(crate) fn is_mapped(&self) -> bool {
        !matches!(self.storage, Storage::Heap(_))
    }
}

impl<T: Copy> Default for PageBacked<T> {
    fn default() -> PageBacked<T> {
        PageBacked::new(Vec::new())
    }
}

impl<T: Copy> std::ops::Deref for PageBacked<T> {
    type Target = [T];

    #[inline]
    fn deref(&self) -> &[T] {
        // SAFETY: `len` initialised values at `ptr`, held by `storage` (a `Vec` never changed, or
        // a mapping `drop` alone unmaps) for as long as `self` lives.
        unsafe { std::slice::from_raw_parts(self.ptr.as_ptr(), self.len) }
    }
}

impl<T: Copy> Drop for PageBacked<T> {
    fn drop(&mut self) {
        #[cfg(target_os = "linux")]
        if let Storage::Mapped { bytes } = self.storage {
            // SAFETY: the mapping `mapped` kept, unmapped once; `T: Copy` has no drop of its own.
            unsafe { libc::munmap(self.ptr.as_ptr() as *mut libc::c_void, bytes) };
        }
    }
}

impl<T: Copy + std::fmt::Debug> std::fmt::Debug for PageBacked<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::{PageBacked, HUGE, LEAST_MAPPED};

    /// Small and large arrays read back what they were made of, the large ones from a mapping of
    /// their own on Linux; an empty one is empty.
    #[test]
    fn an_array_keeps_its_values_wherever_it_lives() {
        for len in [
            0usize,
            1,
            1000,
            LEAST_MAPPED / 8 - 1,
            LEAST_MAPPED / 8,
            3 * HUGE / 8 + 5,
        ] {
            let values: Vec<u64> = (0..len as u64)
                .map(|i| i.wrapping_mul(0x9E37_79B9))
                .collect();
            let backed = PageBacked::new(values.clone());
            assert_eq!(&*backed, &values[..], "{len} values");
            let large = len * 8 >= LEAST_MAPPED;
            assert_eq!(
                backed.is_mapped(),
                cfg!(target_os = "linux") && large,
                "{len}"
            );
            if backed.is_mapped() {
                assert_eq!(backed.as_ptr() as usize % HUGE, 0, "aligned to 2 MB");
            }
        }
    }
}
